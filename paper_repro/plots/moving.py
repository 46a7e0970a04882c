"""Figures of moving obstacles: clearance over time, the crossing, the prediction study."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from paper_repro.analysis import metrics
from paper_repro.plots.animation import save_animation
from paper_repro.plots.common import (
    AXIS_LABELS,
    CLOUD_COLOR,
    LINESTYLES,
    MAX_POINTS,
    SPHERE_COLOR,
    axes_or_new,
    envelope_indices,
    stride_indices,
)
from paper_repro.plots.flight import steps_in
from paper_repro.plots.studies import METRIC_COLOURS
from paper_repro.problem.scan import region_shift
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER

# --- moving obstacles (nmpc.prediction: static, oracle, kalman) ------------------------

PREDICTION_COLOURS = {"static": "tab:gray", "oracle": "tab:green", "kalman": "tab:orange"}
"""Colour of each way of predicting a moving region (``NMPCParams.prediction``)."""

GHOST_COLOR = "tab:blue"


def prediction_velocities(result) -> np.ndarray:
    """The velocity of each region that the controller was given at each step of ``result``,
    as the closed loop logged it (``SimulationResult.region_velocities``):

    * ``"static"`` (the paper): zeros, the regions are taken to stay where they are seen;
    * ``"oracle"``: the regions' true velocities at t_k
      (:func:`~paper_repro.world.truth.scene_velocities`);
    * ``"kalman"``: the estimates of the run's :class:`~paper_repro.world.tracking.RegionTracker`.

    Parameters
    ----------
    result : a :class:`~paper_repro.sim.result.SimulationResult`.

    Returns
    -------
    (K, n_regions, 3) array, m/s, K = ``result.steps``.
    """
    if result.config.nmpc.prediction == "static":
        return np.zeros((result.steps, len(result.scene.clouds), result.scene.dim))
    if result.region_velocities is None:
        raise ValueError(f"{result.scene.name}: this result was saved before the closed loop "
                         "logged the regions' velocities; fly it again")
    return result.region_velocities


def plot_clearance_time(results, labels, ax=None, t_range=None,
                        collision: float = metrics.COLLISION_CLEARANCE,
                        max_points: int = MAX_POINTS, top: float | None = None):
    """Clearance against time for several runs, with the collision threshold.

    One line per run: the true minimum distance from the UAV to any cloud point (where the
    regions are at t), m, against t, s; a dot at each run's minimum, given in the legend.

    Parameters
    ----------
    results : SimulationResults (e.g. one scene flown with each prediction).
    labels : one legend entry each; a label that names a prediction (``"static"``,
        ``"oracle"``, ``"kalman"``) gets its colour of :data:`PREDICTION_COLOURS`.
    ax : an Axes to draw into (a new figure if omitted).
    t_range : (t0, t1) s, the same for every run (all steps when ``None``).
    collision : m, the collision threshold (dotted line).
    max_points : cap on the points drawn per line (min/max envelope).
    top : m, the top of the clearance axis; default: the LiDAR range plus 1 m (farther away
        nothing is seen, and a long axis would squash the closest approach).

    Returns
    -------
    matplotlib Figure.
    """
    results, labels = list(results), list(labels)
    if not results or len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    fig, ax = axes_or_new(ax, (7.0, 3.4))
    for i, (result, label) in enumerate(zip(results, labels, strict=True)):
        k = steps_in(result, t_range)
        t, c = np.asarray(result.t, float)[k], np.asarray(result.clearance, float)[k]
        colour = PREDICTION_COLOURS.get(label, f"C{i}")
        idx = envelope_indices(c, max_points)
        j = int(np.argmin(c))
        ax.plot(t[idx], c[idx], color=colour, lw=1.3, ls=LINESTYLES[i],
                label=f"{label}: min {c[j]:.3f} m at {t[j]:.2f} s")
        ax.plot(t[j], c[j], "o", color=colour, ms=5)
    ax.axhline(collision, color="k", ls=":", lw=1, label=f"collision < {collision:g} m")
    top = top if top is not None else results[0].config.sensor.range + 1.0
    ax.set_ylim(0.0, top)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("clearance [m]")
    ax.set_title(f"clearance ({results[0].config.distance.metric} distance)", fontsize=9)
    ax.legend(fontsize="small", frameon=False)
    ax.grid(alpha=0.3)
    return fig


def _plane_index(plane: str) -> list[int]:
    if plane not in ("xy", "xz", "yz"):
        raise ValueError(f"plane must be 'xy', 'xz' or 'yz', got {plane!r}")
    return ["xyz".index(c) for c in plane]


def _draw_crossing(ax, result, k: int, plane: str, velocities=None, stages=(),
                   trail: bool = True):
    """The state of a moving-region run at step k in one plane; returns the artists drawn.

    The path up to k (black), the UAV (black dot) and the section of its LiDAR sphere (blue
    circle), each region's cloud where it is at t_k (red, faint), the points the controller was
    handed at step k (orange, :meth:`~paper_repro.sim.result.SimulationResult.scan`) and, with
    ``velocities`` ((n_regions, 3) m/s at step k), the scanned points moved by v_i·τ_j for each
    stage j of ``stages``, τ_j = j·h: where the controller predicted them (blue rings, fainter
    with j)."""
    i0, i1 = _plane_index(plane)
    cfg = result.config
    r_s = cfg.sensor.range
    k_log = min(k, len(result.t) - 1)  # the state after the last step has no scan
    t = float(result.t[k_log])
    pos = result.positions
    artists = []
    for c in result.scene.clouds_at(t):
        artists.append(ax.scatter(c[:, i0], c[:, i1], s=6, color=CLOUD_COLOR, alpha=0.35, lw=0,
                                  zorder=2))
    seen = result.scan(k_log)
    if any(len(v) for v in seen):
        pts = np.concatenate([v for v in seen if len(v)])
        artists.append(ax.scatter(pts[:, i0], pts[:, i1], s=12, color="orange",
                                  edgecolor="darkred", lw=0.4, zorder=3))
    if velocities is not None and stages:
        stages = sorted(stages)
        alphas = np.linspace(0.8, 0.3, len(stages))
        for j, alpha in zip(stages, alphas, strict=True):
            shift = [region_shift(np.asarray(w, float), cfg.nmpc.stage_time(j))
                     for w in velocities]
            moved = [v + shift[i] for i, v in enumerate(seen) if len(v)]
            if moved:
                pts = np.concatenate(moved)
                artists.append(ax.scatter(pts[:, i0], pts[:, i1], s=16, facecolors="none",
                                          edgecolors=GHOST_COLOR, lw=0.7, alpha=alpha,
                                          zorder=3))
    if trail:
        upto = pos[: k + 1]
        idx = stride_indices(len(upto), MAX_POINTS)
        (line,) = ax.plot(upto[idx, i0], upto[idx, i1], color="black", lw=1.0, zorder=4)
        artists.append(line)
    artists.append(ax.add_patch(plt.Circle((pos[k, i0], pos[k, i1]), r_s, fill=False,
                                           color=SPHERE_COLOR, lw=0.8, alpha=0.7)))
    (dot,) = ax.plot(pos[k, i0], pos[k, i1], "o", color="black", ms=4, zorder=5)
    artists.append(dot)
    return artists


def _crossing_limits(result, steps, plane: str, pad: float):
    """(lo, hi) per axis of the plane: the UAV's positions at ``steps`` ± ``pad`` (m), within
    the workspace."""
    i0, i1 = _plane_index(plane)
    p = result.positions[np.asarray(steps, int)][:, [i0, i1]]
    lo = np.maximum(p.min(axis=0) - pad, WORKSPACE_LOWER[[i0, i1]])
    hi = np.minimum(p.max(axis=0) + pad, WORKSPACE_UPPER[[i0, i1]])
    return lo, hi


def _crossing_handles(stages, nmpc) -> list:
    """Legend entries of :func:`_draw_crossing`; ``nmpc`` (``NMPCParams``) gives τ_j."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="black", lw=1.0, marker="o", ms=4, label="UAV path"),
               Line2D([], [], ls="", marker="o", ms=4, color=CLOUD_COLOR, alpha=0.5,
                      label="cloud at t"),
               Line2D([], [], ls="", marker="o", ms=5, color="orange", mec="darkred",
                      label="in view"),
               Line2D([], [], color=SPHERE_COLOR, lw=0.8, label="LiDAR range")]
    if stages:
        taus = ", ".join(f"{nmpc.stage_time(j):g}" for j in sorted(stages))
        handles.append(Line2D([], [], ls="", marker="o", ms=5, mfc="none", mec=GHOST_COLOR,
                              label=f"predicted at τ = {taus} s"))
    return handles


def plot_crossing_closest(results, labels, velocities=None, planes=("xy", "yz"),
                          stages=(0, 17, 35), pad: float = 3.5):
    """Runs of one moving scene side by side at their closest approach.

    One column per run, one row per plane of ``planes``: the path up to the closest approach
    (black) and after it (grey), the clouds where they are then (red), the points in view
    (orange), the LiDAR's range (blue circle), and a segment from the UAV to the nearest
    point; the title gives the minimum clearance (m) and its time (s). With ``velocities``,
    the points in view moved by v_i·τ_j, τ_j = j·h, for each stage j of ``stages``: where the
    controller predicted them (blue rings).

    Parameters
    ----------
    results : SimulationResults of the same scene.   labels : one column title each.
    velocities : ``None``, or one entry per run: ``None`` or a (K, n_regions, 3) array of the
        velocities the controller used (m/s; :func:`prediction_velocities`).
    planes : planes drawn, each ``"xy"``, ``"xz"`` or ``"yz"``.
    stages : horizon stages j of the predicted positions (0 ≤ j ≤ N).
    pad : m, margin around the UAV's positions from the first step with a point in view to
        the last (the whole run when none); every column shares these limits.

    Returns
    -------
    matplotlib Figure; its Axes form a (len(planes), len(results)) grid.
    """
    results, labels = list(results), list(labels)
    if not results or len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    velocities = [None] * len(results) if velocities is None else list(velocities)
    if len(velocities) != len(results):
        raise ValueError(f"velocities must hold one entry per run ({len(results)}), got "
                         f"{len(velocities)}")
    fig, axes = plt.subplots(len(planes), len(results),
                             figsize=(3.6 * len(results) + 0.4, 3.4 * len(planes)),
                             squeeze=False, constrained_layout=True)
    for row, plane in enumerate(planes):
        i0, i1 = _plane_index(plane)
        lows, highs = [], []
        for col, (result, label, vel) in enumerate(zip(results, labels, velocities,
                                                       strict=True)):
            ax = axes[row, col]
            k = int(np.argmin(result.clearance))
            t = float(result.t[k])
            pos = result.positions
            rest = pos[k:]
            idx = stride_indices(len(rest), MAX_POINTS)
            ax.plot(rest[idx, i0], rest[idx, i1], color="0.6", lw=0.8, zorder=1)
            _draw_crossing(ax, result, k, plane, None if vel is None else vel[k],
                           stages if vel is not None else ())
            cloud = np.concatenate(result.scene.clouds_at(t))
            near = cloud[int(np.argmin(np.linalg.norm(cloud - pos[k], axis=1)))]
            ax.plot([pos[k, i0], near[i0]], [pos[k, i1], near[i1]], color="k", lw=1.2,
                    zorder=6)
            collided = result.clearance[k] < metrics.COLLISION_CLEARANCE
            ax.set_title(f"{label}: min clearance {result.clearance[k]:.3f} m\nat t = {t:.2f} s"
                         + (" (collision)" if collided else ""), fontsize=9)
            seen = np.flatnonzero(np.asarray(result.visible_points) > 0)
            span = np.arange(seen[0], seen[-1] + 1) if len(seen) else np.arange(len(result.t))
            lo, hi = _crossing_limits(result, span, plane, pad)
            lows.append(lo)
            highs.append(hi)
            ax.set_xlabel(AXIS_LABELS[i0])
            ax.set_ylabel(AXIS_LABELS[i1])
            ax.grid(alpha=0.3)
        lo, hi = np.min(lows, axis=0), np.max(highs, axis=0)
        for ax in axes[row]:
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            ax.set_aspect("equal")
    handles = _crossing_handles(stages if any(v is not None for v in velocities) else (),
                                results[0].config.nmpc)
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles),
               fontsize="small", frameon=False)
    return fig


def animate_crossing(result, path, velocities=None, planes=("xy", "yz"), stages=(0, 17, 35),
                     frames: int = 45, fps: int = 8, dpi: int = 72, t_range=None,
                     pad: float = 3.5):
    """GIF of a run with moving regions, one panel per plane: the UAV's path so far, the
    clouds where they are at t, the points in view, the LiDAR's range, and where the
    controller predicted the points in view at t + τ_j (blue rings, τ_j = j·h for each stage
    j of ``stages``).

    Parameters
    ----------
    result : a :class:`~paper_repro.sim.result.SimulationResult` (its scene's motions place
        the clouds at t).
    path : output file (``.gif``).
    velocities : (K, n_regions, 3) m/s, the velocities the controller used at each step;
        ``None``: :func:`prediction_velocities` of the run (zeros for ``"static"``: the
        predicted points then lie on the scan).
    planes : one panel per plane, each ``"xy"``, ``"xz"`` or ``"yz"``.
    stages : horizon stages j drawn (0 ≤ j ≤ N; ``()``: none).
    frames : number of frames, evenly spaced in ``t_range``.   fps : frames per second.
    dpi : resolution (each panel is 4.5 × 4.5 in).
    t_range : (t0, t1) s; default: from 1 s before the first step with a point in view to
        1 s after the last (the whole run when none).
    pad : m, margin around the UAV's positions over ``t_range`` (fixed limits).

    Returns the path written.
    """
    if not (isinstance(frames, int) and frames >= 1):
        raise ValueError(f"frames must be an integer >= 1, got {frames!r}")
    for plane in planes:
        _plane_index(plane)
    if velocities is None:
        velocities = prediction_velocities(result)
    velocities = np.asarray(velocities, float)
    n_regions = len(result.scene.clouds)
    if velocities.shape != (result.steps, n_regions, 3):
        raise ValueError(f"velocities must be ({result.steps}, {n_regions}, 3) m/s, got shape "
                         f"{velocities.shape}")
    t = np.asarray(result.t, float)
    if t_range is None:
        seen = np.flatnonzero(np.asarray(result.visible_points) > 0)
        t_range = ((t[seen[0]] - 1.0, t[seen[-1]] + 1.0) if len(seen) else (t[0], t[-1]))
    window = steps_in(result, t_range)
    steps = np.unique(np.linspace(window[0], window[-1], frames).round().astype(int))
    fig, axes = plt.subplots(1, len(planes), figsize=(4.5 * len(planes), 4.5), dpi=dpi,
                             squeeze=False)
    axes = axes[0]
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.24, top=0.93, wspace=0.2)
    for ax, plane in zip(axes, planes, strict=True):
        i0, i1 = _plane_index(plane)
        lo, hi = _crossing_limits(result, window, plane, pad)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_xlabel(AXIS_LABELS[i0])
        ax.set_ylabel(AXIS_LABELS[i1])
        ax.grid(alpha=0.3)
    handles = _crossing_handles(stages, result.config.nmpc)
    fig.legend(handles=handles, loc="lower center", ncols=3, fontsize="small", frameon=False)
    title = fig.suptitle("", fontsize="medium")
    prediction = result.config.nmpc.prediction
    drawn = []

    def update(k):
        for a in drawn:
            a.remove()
        drawn.clear()
        for ax, plane in zip(axes, planes, strict=True):
            drawn.extend(_draw_crossing(ax, result, k, plane, velocities[k], stages))
        title.set_text(f"{result.scene.name}, prediction {prediction}: t = {t[k]:5.2f} s, "
                       f"clearance {result.clearance[k]:.2f} m")
        return []

    return save_animation(fig, update, steps, path, fps, dpi)


def plot_prediction_study(table, events=("completed", "collision", "stalled", "step_limit"),
                          collision: float = metrics.COLLISION_CLEARANCE):
    """A moving-obstacle study per prediction (x axis) and metric (colour).

    One panel per event of ``events``: its rate with the 95 % Clopper–Pearson interval
    (:func:`paper_repro.analysis.statistics.rates` by prediction and metric); then, per run, the
    minimum
    clearance (m, with the collision threshold) and the total variation of u per second
    (N/s, log axis), the median of each group as a black bar. Runs that failed count in the
    rates and are left out of the per-run panels.

    Parameters
    ----------
    table : a study table with the columns ``prediction`` and ``metric`` and those of
        :func:`paper_repro.analysis.metrics.summary_row` (``moving_obstacles``).
    events : outcomes of :data:`paper_repro.analysis.statistics.EVENTS`, one panel each.
    collision : m, the collision threshold (dotted line).

    Returns
    -------
    matplotlib Figure with ``len(events) + 2`` Axes (in rows of three), less the events no
    run had (named in the figure's title instead of drawn as empty panels).
    """
    from paper_repro.analysis.statistics import rates as outcome_rates

    order = ("static", "oracle", "kalman")
    present = list(dict.fromkeys(table["prediction"]))
    predictions = [p for p in order if p in present] + [p for p in present if p not in order]
    metrics_ = list(dict.fromkeys(table["metric"]))
    rates = outcome_rates(table, by=["prediction", "metric"])
    never = [e for e in events if not rates.loc[rates["event"] == e, "k"].any()]
    events = [e for e in events if e not in never]  # no empty panel: named in the title
    n_panels = len(events) + 2
    rows = int(np.ceil(n_panels / 3))
    fig, grid = plt.subplots(rows, 3, figsize=(12.0, 3.3 * rows), constrained_layout=True,
                             squeeze=False)
    axes = grid.ravel()
    for ax in axes[n_panels:]:
        ax.remove()
    if never:
        fig.suptitle("no run of any group ended " + " or ".join(e.replace("_", " ")
                                                                for e in never), fontsize=9)
    width = 0.8 / max(len(metrics_), 1)
    x = np.arange(len(predictions))
    for ax, event in zip(axes, events):
        _event_panel(ax, rates, event, predictions, metrics_, width)
    axes[0].set_ylabel("share of runs")
    axes[0].legend(fontsize="x-small", frameon=False)
    ok = table[table["status"] == "ok"]
    jitter = np.random.default_rng(0)
    per_run = ((axes[len(events)], "min_clearance_m", "minimum clearance [m]", False),
               (axes[len(events) + 1], "tv_u_rate_N_per_s", "total variation of u per s [N/s]",
                True))
    for ax, column, title, log in per_run:
        _per_run_panel(ax, ok, column, predictions, metrics_, width, log, jitter)
        ax.set_title(title, fontsize=9)
    axes[len(events)].axhline(collision, color="k", ls=":", lw=1,
                              label=f"collision < {collision:g} m")
    axes[len(events)].legend(fontsize="x-small", frameon=False)
    for ax in axes[:n_panels]:
        ax.set_xticks(x, predictions)
        ax.set_xlim(-0.6, len(predictions) - 0.4)
        ax.set_xlabel("prediction")
        ax.grid(alpha=0.3, axis="y")
    return fig


def _event_panel(ax, rates, event: str, predictions, metrics_, width: float) -> None:
    """A rate panel of :func:`plot_prediction_study`: the rate of ``event`` per prediction,
    one bar per metric, with its 95 % interval."""
    x = np.arange(len(predictions))
    for i, m in enumerate(metrics_):
        r = rates[(rates["metric"] == m) & (rates["event"] == event)].set_index(
            "prediction").loc[predictions]
        xs = x + (i - (len(metrics_) - 1) / 2) * width
        ax.bar(xs, r["rate"], width, color=METRIC_COLOURS.get(m, f"C{i}"), alpha=0.8,
               label=f"{m} (n = {int(r['n'].iloc[0])})")
        ax.errorbar(xs, r["rate"], yerr=[r["rate"] - r["low"], r["high"] - r["rate"]],
                    fmt="none", ecolor="k", capsize=3, lw=1)
    ax.set_ylim(0, 1.05)
    ax.set_title(f"{event} rate", fontsize=9)


def _per_run_panel(ax, ok, column: str, predictions, metrics_, width: float, log: bool,
                   jitter) -> None:
    """A per-run panel of :func:`plot_prediction_study`: each run's ``column`` per prediction
    and metric, jittered by ``jitter``, the median of each group as a black bar; a log axis
    when ``log`` and every value is positive."""
    values = []
    for i, m in enumerate(metrics_):
        offset = (i - (len(metrics_) - 1) / 2) * width
        for j, p in enumerate(predictions):
            v = ok.loc[(ok["metric"] == m) & (ok["prediction"] == p), column].to_numpy(float)
            v = v[np.isfinite(v)]
            if not len(v):
                continue
            values.append(v)
            ax.scatter(j + offset + jitter.uniform(-0.06, 0.06, len(v)), v, s=12,
                       color=METRIC_COLOURS.get(m, f"C{i}"), alpha=0.7, lw=0, zorder=3)
            ax.hlines(np.median(v), j + offset - 0.12, j + offset + 0.12, color="k", lw=2,
                      zorder=4)
    if log and values and np.concatenate(values).min() > 0:
        ax.set_yscale("log")

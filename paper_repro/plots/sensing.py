"""Figures of the smooth sensing window: thrusts and input changes at scan changes."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from paper_repro.analysis import metrics
from paper_repro.plots.common import MAX_POINTS, axes_or_new, envelope_indices
from paper_repro.plots.flight import steps_in
from paper_repro.plots.studies import rate_bars

# --- the smooth sensing window ----------------------------------------------------------------

def scan_change_times(result) -> np.ndarray:
    """Times (s) of the steps whose scan holds a different number of points from the scan
    before: the changes of the visible set of
    :func:`paper_repro.analysis.metrics.scan_change_steps`.
    """
    change = np.flatnonzero(metrics.scan_changes(result)) + 1
    return np.asarray(result.t, float)[change]


def plot_sensing_window(sensor_range: float = 3.0, widths=(0.25, 0.5, 1.0), ax=None,
                        n: int = 400):
    """The weight ψ(r) of a visible point against its range r, for each window width w.

    The hard cut-off (w = 0, the paper's LiDAR) is the grey step; each width is the C∞ step of
    :func:`paper_repro.problem.distance.sensing_window`, with a dot where full weight ends (r_s − w)
    and one at half weight (r_s − w/2).

    Parameters
    ----------
    sensor_range : r_s, m.
    widths : window widths w, m, each 0 < w < r_s.
    ax : an Axes to draw into (a new figure if omitted).
    n : points per curve.

    Returns
    -------
    matplotlib Figure.
    """
    from paper_repro.problem.distance import sensing_window

    widths = tuple(float(w) for w in widths)
    if not widths or not all(0 < w < sensor_range for w in widths):
        raise ValueError(f"widths must be non-empty, each in (0, {sensor_range}) m, got "
                         f"{widths!r}")
    fig, ax = axes_or_new(ax, (6.0, 3.2))
    lo = max(0.0, sensor_range - 1.5 * max(widths))
    hi = sensor_range + 0.1 * (sensor_range - lo)
    r = np.linspace(lo, hi, n)
    ax.plot(r, (r < sensor_range).astype(float), color="0.5", lw=1.5, ds="steps-post",
            label="w = 0 (hard cut-off)")
    colours = plt.cm.viridis(np.linspace(0.15, 0.85, len(widths)))
    for w, c in zip(widths, colours, strict=True):
        ax.plot(r, np.exp(sensing_window(r, sensor_range, w)), color=c, lw=1.5,
                label=f"w = {w:g} m: full weight to {sensor_range - w:g} m, "
                      f"half at {sensor_range - w / 2:g} m")
        ax.plot([sensor_range - w, sensor_range - w / 2], [1.0, 0.5], "o", color=c, ms=4)
    ax.axvline(sensor_range, color="k", ls=":", lw=1)
    ax.set_xlim(lo, hi)
    ax.set_ylim(-0.05, 1.1)
    ax.set_xlabel("range of the point from the sensor r [m]")
    ax.set_ylabel("weight ψ(r)")
    ax.set_title(f"sensing window (r_s = {sensor_range:g} m)", fontsize=10)
    ax.legend(loc="lower left", fontsize="small", frameon=False)
    ax.grid(alpha=0.3)
    return fig


def plot_scan_change_thrusts(results, labels, t_range=None, max_points: int = MAX_POINTS,
                             threshold: float = metrics.SCAN_STEP_THRESHOLD,
                             rotors=(0, 1, 2, 3), du_floor: float | None = None):
    """Rotor thrusts of several runs side by side, with the changes of the visible set marked.

    One column per run: f1..f4 (N) against time, then the largest rotor step
    max_i |u_{k,i} − u_{k−1,i}| (N, log axis) with the steps at changes of the visible set
    (:func:`scan_change_times`) as orange dots. Thin orange lines mark the changes in every
    panel. The thrust rows share their y axis across runs, so the columns compare directly.

    Parameters
    ----------
    results : SimulationResults (e.g. the same mission without and with the window).
    labels : one column title each.
    t_range : (t0, t1) s, the same for every run (e.g. :func:`avoidance_window` of the first).
    max_points : cap on the points drawn per line (min/max envelope).
    threshold : N, a step above it at a change counts as a jump (dotted line).
    rotors : the rotors drawn (indices into f1..f4), one row each.
    du_floor : N, the bottom of the step axis (``None``: wherever the smallest step is).

    Returns
    -------
    matplotlib Figure; its Axes form a (len(rotors) + 1, len(results)) grid, titled with the
    runs' metric.
    """
    results, labels = list(results), list(labels)
    if not results or len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    rotors = list(rotors)
    rows = len(rotors) + 1
    fig, axes = plt.subplots(rows, len(results),
                             figsize=(4.2 * len(results) + 0.8, 1.6 * rows + 1.6),
                             sharex="col", sharey="row", squeeze=False,
                             constrained_layout=True)
    for j, (result, label) in enumerate(zip(results, labels, strict=True)):
        k = steps_in(result, t_range)
        t, u = result.t[k], result.u[k]
        col = axes[:, j]
        changes = scan_change_times(result)
        changes = changes[(changes >= t[0]) & (changes <= t[-1])]
        for row, i in enumerate(rotors):
            idx = envelope_indices(u[:, i], max_points)
            col[row].plot(t[idx], u[idx, i], color="tab:blue", lw=0.8)
            if j == 0:
                col[row].set_ylabel(f"$f_{i + 1}$ [N]")
        du = np.abs(np.diff(np.asarray(result.u, float), axis=0)).max(axis=1)
        kd = k[k >= 1]  # step k: the change from u_{k-1} to u_k
        du_k = du[kd - 1]
        idx = envelope_indices(du_k, max_points)
        col[-1].plot(result.t[kd][idx], du_k[idx], color="tab:blue", lw=0.6)
        at = np.isin(result.t[kd], changes)
        col[-1].plot(result.t[kd][at], du_k[at], "o", color="tab:orange", ms=3,
                    label="change of the visible set")
        col[-1].axhline(threshold, color="k", ls=":", lw=1, label=f"{threshold * 1e3:g} mN")
        col[-1].set_yscale("log")
        if du_floor is not None:
            col[-1].set_ylim(bottom=du_floor)
        col[-1].set_xlabel("t [s]")
        if j == 0:
            col[-1].set_ylabel("max$_i$ |Δf$_i$| [N]")
            col[-1].legend(loc="lower right", fontsize="x-small", frameon=False)
        for ax in col:
            for tc in changes:
                ax.axvline(tc, color="tab:orange", lw=0.5, alpha=0.5)
            ax.grid(alpha=0.3)
        jumps = int(np.sum(du_k[at] > threshold))
        col[0].set_title(f"{label}\n{len(changes)} changes of the visible set, {jumps} with a "
                         f"step > {threshold * 1e3:g} mN", fontsize=9)
    metrics_ = ", ".join(dict.fromkeys(r.config.distance.metric for r in results))
    fig.suptitle(f"rotor thrusts around the changes of the visible set ({metrics_} distance)",
                 fontsize=10)
    return fig


def plot_scan_change_du(results, labels, ax=None, floor: float = 1e-7,
                        threshold: float = metrics.SCAN_STEP_THRESHOLD,
                        neighbourhood: int | None = metrics.SCAN_NEIGHBOURHOOD):
    """ECDFs of the thrust steps max_i |Δf_i| (N, log axis) at changes of the visible set
    (solid) and at the steps around them (dashed), one colour per run
    (:func:`paper_repro.analysis.metrics.scan_change_steps`).

    Parameters
    ----------
    results : SimulationResults.   labels : one legend entry each.
    ax : an Axes to draw into (a new figure if omitted).
    floor : N, steps below it (exact zeros) are drawn at ``floor``, so the log axis keeps them.
    threshold : N, drawn as a dotted line (a jump).
    neighbourhood : steps either side of a change that form the comparison (``None``: every
        step that is not a change).

    Returns
    -------
    matplotlib Figure.
    """
    from paper_repro.analysis.statistics import ecdf

    results, labels = list(results), list(labels)
    if len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    fig, ax = axes_or_new(ax, (6.0, 3.6))
    for i, (result, label) in enumerate(zip(results, labels, strict=True)):
        colour = f"C{i}"
        at, other = metrics.scan_change_steps(result, neighbourhood)
        where = ("elsewhere" if neighbourhood is None else
                 f"within {neighbourhood * result.config.nmpc.ts:g} s around")
        for values, ls, name in ((at, "-", "at changes"), (other, "--", where)):
            if len(values):
                x, f = ecdf(np.maximum(values, floor))
                ax.step(x, f, ls, where="post", color=colour,
                        label=f"{label}, {name} ({len(values)} steps)")
    ax.axvline(threshold, color="k", ls=":", lw=1, label=f"{threshold * 1e3:g} mN")
    ax.set_xscale("log")
    ax.set_xlabel("thrust step max$_i$ |Δf$_i$| [N]")
    ax.set_ylabel("share of steps ≤ x")
    ax.legend(fontsize="x-small", frameon=False, loc="lower right")
    ax.grid(alpha=0.3, which="both")
    return fig


def plot_scan_change_study(table, by: str = "window_m", label: str = "sensing window w [m]",
                           events=("completed", "stalled", "collision"),
                           steps=("du_scan_change_median_N", "du_around_changes_median_N"),
                           threshold: float = metrics.SCAN_STEP_THRESHOLD,
                           collision: float = metrics.COLLISION_CLEARANCE):
    """A study over a setting ``by`` (the sensing window's width w, m), one panel each:

    1. outcome rates with 95 % Clopper–Pearson intervals
    (:func:`paper_repro.analysis.statistics.rates`);
    2. per run, the share of changes of the visible set with a thrust step above
       ``threshold`` (``scan_change_jump_share``), the median as a bar;
    3. per run, the median thrust step at changes (filled) and around them (open), N, log
       axis (the two columns ``steps``);
    4. per run, the minimum clearance, m, with the collision threshold.

    Runs that failed are left out of panels 2-4 (they count in panel 1); runs without a change
    of the visible set have no value in panels 2-3 (a note says how many).

    Parameters
    ----------
    table : a study table (:func:`paper_repro.studies.engine.run_study`) with a column ``by`` and
        the
        columns of :func:`paper_repro.analysis.metrics.summary_row`.
    by : the setting, one group of runs per value.   label : its axis label.
    events : the outcomes of panel 1 (:data:`paper_repro.analysis.statistics.EVENTS`).
    steps : the columns of panel 3, medians over each run of |Δu| (N) at changes and around.
    threshold : N, a jump (dotted line in panel 3).   collision : m (dotted line in panel 4).

    Returns
    -------
    matplotlib Figure with four Axes.
    """
    settings = sorted(table[by].dropna().unique())
    colours = dict(zip(settings, plt.cm.viridis(np.linspace(0.15, 0.85, len(settings))),
                       strict=True))
    fig, axes = plt.subplots(1, 4, figsize=(14.0, 3.4), constrained_layout=True)
    _rates_panel(axes[0], table, by, label, settings, colours, events)
    ok = table[table["status"] == "ok"]
    jitter = np.random.default_rng(0)  # one generator, drawn panel after panel
    panels = ((axes[1], ("scan_change_jump_share",), f"share of changes with a step "
               f"> {threshold * 1e3:g} mN", False),
              (axes[2], tuple(steps), "median thrust step [N]: at changes (●), around (○)",
               True),
              (axes[3], ("min_clearance_m",), "minimum clearance [m]", False))
    for ax, columns, title, log in panels:
        _runs_panel(ax, ok, by, label, settings, colours, columns, log, jitter)
        ax.set_title(title, fontsize=9)
    axes[1].axhline(0.0, color="0.6", lw=0.8)
    axes[2].axhline(threshold, color="k", ls=":", lw=1)
    axes[3].axhline(collision, color="k", ls=":", lw=1)
    return fig


def _rates_panel(ax, table, by: str, label: str, settings, colours, events) -> None:
    """Panel 1 of :func:`plot_scan_change_study`: the rate of each of ``events`` per setting,
    bars with 95 % Clopper–Pearson intervals."""
    from paper_repro.analysis.statistics import rates as outcome_rates

    rate_bars(ax, outcome_rates(table, by=[by]), by, settings, colours, events, alpha=0.85,
              name=lambda s: f"{s:g}")
    ax.legend(title=label, fontsize="x-small", title_fontsize="x-small", frameon=False)


def _runs_panel(ax, ok, by: str, label: str, settings, colours, columns, log: bool,
                jitter) -> None:
    """A per-run panel of :func:`plot_scan_change_study`: each run's value of each of
    ``columns`` per setting (the first filled, the second open), jittered by ``jitter``, with
    the median as a bar; a log axis when ``log`` and every value is positive."""
    drawn = []
    for i, s in enumerate(settings):
        group = ok[ok[by] == s]
        for c, column in enumerate(columns):
            v = group[column].to_numpy(float)
            v = v[np.isfinite(v)]
            drawn.append(v)
            if not len(v):
                continue
            offset = (c - (len(columns) - 1) / 2) * 0.3
            xs = i + offset + jitter.uniform(-0.08, 0.08, len(v))
            ax.scatter(xs, v, s=14, facecolors=colours[s] if c == 0 else "none",
                       edgecolors=colours[s], lw=1, zorder=3)
            ax.hlines(np.median(v), i + offset - 0.15, i + offset + 0.15, color="k",
                      lw=2, zorder=4)
    values = np.concatenate(drawn) if drawn else np.array([])
    missing = int(sum(np.sum(~np.isfinite(ok.loc[ok[by] == s, columns[0]].to_numpy(float)))
                      for s in settings))
    if not len(values):
        ax.text(0.5, 0.5, "no change of the visible set", transform=ax.transAxes,
                ha="center", color="0.5")
    elif log and values.min() > 0:
        ax.set_yscale("log")
    if missing and columns[0] != "min_clearance_m":
        ax.text(0.02, 0.02, f"{missing} run(s) without a change", transform=ax.transAxes,
                va="bottom", fontsize=7, color="0.4")
    ax.set_xticks(np.arange(len(settings)), [f"{s:g}" for s in settings])
    ax.set_xlim(-0.6, len(settings) - 0.4)
    ax.set_xlabel(label)
    ax.grid(alpha=0.3, axis="y")

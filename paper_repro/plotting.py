"""One function per figure of the paper (Section V), the tutorial figures, and the animation.

=======================  ====================================================================
Fig. 1                   :func:`plot_flight_3d` — trajectory, clouds, LiDAR spheres, targets
Figs. 2, 3               :func:`plot_projection` with ``plane="xz"`` / ``"xy"``
Figs. 4, 8               :func:`plot_thrusts` — f1..f4 and the artificial input u_a
Figs. 5, 7               :func:`plot_tracking_errors` — e_x, e_y, e_z, e = y − y_t (signed)
Fig. 6                   :func:`plot_states` — x, y, z with the artificial state y_a
summary                  :func:`plot_solve_times`, :func:`plot_input_spectrum`
the clock (issue 12)     :func:`plot_clock_levers`, :func:`plot_flight_clocks`
tutorial (eq. 8–13)      :func:`plot_distance_slice`, :func:`plot_eta_sigma`,
                         :func:`plot_gradient_field`, :func:`plot_half_squared_limit`
studies                  :func:`plot_rates`, :func:`plot_paired`, :func:`plot_paired_by`,
                         :func:`plot_clearance_ecdf`, :func:`plot_study_solve_times`,
                         :func:`plot_sweep`
sensing window           :func:`plot_sensing_window`, :func:`plot_scan_change_thrusts`,
                         :func:`plot_scan_change_du`, :func:`plot_scan_change_study`
moving obstacles         :func:`prediction_velocities`, :func:`plot_clearance_time`,
                         :func:`plot_crossing_closest`, :func:`plot_prediction_study`
video                    :func:`animate_flight`, :func:`animate_crossing` (GIF)
=======================  ====================================================================

Each function takes a :class:`~paper_repro.simulation.SimulationResult` (and the
:class:`~paper_repro.scene.Scene` it flew in, ``result.scene``) and returns the matplotlib
Figure; pass ``ax``/``axes`` to draw into an existing one. Long runs are decimated for drawing
(at most ``max_points`` per line) with a min/max envelope, so chattering keeps its visible
amplitude. :func:`save_figure` writes PDF (without a creation date, so byte-stable) and PNG.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial import cKDTree

from . import metrics
from .distance import (
    CloudWeights,
    euclidean_distance,
    smooth_distance,
    smooth_projection,
)
from .scene import WORKSPACE_LOWER, WORKSPACE_UPPER, Lidar

MAX_POINTS = 5000
"""Default cap on the points drawn per line (a full mission has ≈135,000 steps)."""

CLOUD_COLOR = "tab:red"
SPHERE_COLOR = "tab:blue"
AXIS_LABELS = ("x [m]", "y [m]", "z [m]")
_LINESTYLES = ("-", "--", "-.", ":") * 4  # runs that coincide stay distinguishable


# --- figures of the paper -------------------------------------------------------------------

def plot_flight_3d(result, scene, ax=None, sphere_steps=None, n_spheres: int = 4,
                   max_points: int = MAX_POINTS):
    """Fig. 1: 3-D flight (black), clouds (red), translucent LiDAR spheres (blue), start, targets.

    Parameters
    ----------
    result : SimulationResult.   scene : the Scene it flew in.
    ax : a 3-D Axes to draw into (a new figure if omitted).
    sphere_steps : steps at which to draw the LiDAR sphere; by default
        :func:`lidar_instants` (closest approach to each region, else evenly spaced).
    n_spheres : number of spheres when ``sphere_steps`` is None.
    max_points : cap on drawn trajectory points.
    """
    fig, ax = _axes3d(ax)
    pos = result.x[:, :3]
    for i, cloud in enumerate(scene.clouds):
        ax.scatter(*cloud.T, s=2, color=CLOUD_COLOR, alpha=0.6, depthshade=False,
                   label="point clouds" if i == 0 else None)
    idx = stride_indices(len(pos), max_points)
    ax.plot(*pos[idx].T, color="black", lw=1.2, label="trajectory")
    if sphere_steps is None:
        sphere_steps = lidar_instants(result, scene, n_spheres)
    r_s = result.config.simulation.lidar_range
    for j, k in enumerate(sphere_steps):
        _draw_sphere(ax, pos[k], r_s, label=f"LiDAR range ($r_s$ = {r_s:g} m)" if j == 0 else None)
    _mark_start_and_targets(ax, scene, three_d=True)
    _workspace_limits(ax, three_d=True)
    ax.legend(loc="upper left", fontsize="small")
    return fig


def plot_projection(result, scene, plane: str = "xz", ax=None, max_points: int = MAX_POINTS):
    """Figs. 2 and 3: the trajectory and the clouds projected onto the XZ or XY plane."""
    if plane not in ("xz", "xy", "yz"):
        raise ValueError(f"plane must be 'xz', 'xy' or 'yz', got {plane!r}")
    axes_idx = ["xyz".index(c) for c in plane]
    fig, ax = _axes(ax, figsize=(7, 4.5 if plane == "xy" else 3.5))
    for i, cloud in enumerate(scene.clouds):
        ax.scatter(cloud[:, axes_idx[0]], cloud[:, axes_idx[1]], s=3, color=CLOUD_COLOR,
                   alpha=0.6, lw=0, label="point clouds" if i == 0 else None)
    pos = result.x[:, :3]
    idx = stride_indices(len(pos), max_points)
    ax.plot(pos[idx, axes_idx[0]], pos[idx, axes_idx[1]], color="black", lw=1.2,
            label="trajectory")
    start = np.asarray(scene.start, float)
    targets = np.atleast_2d(np.asarray(scene.targets, float))
    ax.plot(start[axes_idx[0]], start[axes_idx[1]], "o", color="tab:green", label="start")
    ax.plot(targets[:, axes_idx[0]], targets[:, axes_idx[1]], "*", ms=11, color="tab:purple",
            label="targets")
    ax.set_xlim(WORKSPACE_LOWER[axes_idx[0]], WORKSPACE_UPPER[axes_idx[0]])
    ax.set_ylim(WORKSPACE_LOWER[axes_idx[1]], WORKSPACE_UPPER[axes_idx[1]])
    ax.set_aspect("equal")
    ax.set_xlabel(AXIS_LABELS[axes_idx[0]])
    ax.set_ylabel(AXIS_LABELS[axes_idx[1]])
    ax.set_title(f"projection onto the {plane.upper()}-plane")
    ax.legend(loc="best", fontsize="small")
    ax.grid(alpha=0.3)
    return fig


def plot_thrusts(result, axes=None, max_points: int = MAX_POINTS, t_range=None):
    """Figs. 4 and 8: thrusts f1..f4 (N) against time, with the artificial input u_a (dashed).

    ``axes`` : four Axes (a new 4×1 figure if omitted). ``t_range`` : (t0, t1) s to draw only
    part of the run, e.g. :func:`avoidance_window`.
    """
    fig, axes = _axes_column(axes, 4, figsize=(7, 6.5))
    k = _steps_in(result, t_range)
    t, u, u_a = result.t[k], result.u[k], result.u_a[k]
    for i, ax in enumerate(axes):
        idx = envelope_indices(u[:, i], max_points)
        ax.plot(t[idx], u[idx, i], color="tab:blue", lw=0.8, label=f"$f_{i + 1}$")
        idx = envelope_indices(u_a[:, i], max_points)
        ax.plot(t[idx], u_a[idx, i], "--", color="tab:orange", lw=1.0,
                label=f"$u_{{a,{i + 1}}}$")
        ax.set_ylabel(f"$f_{i + 1}$ [N]")
        ax.legend(loc="upper right", fontsize="small", ncol=2)
        ax.grid(alpha=0.3)
        _mark_target_switches(ax, result, t)
    axes[-1].set_xlabel("t [s]")
    axes[0].set_title(f"rotor thrusts ({result.config.distance.metric} distance)")
    return fig


def plot_tracking_errors(result, ax=None, max_points: int = MAX_POINTS, t_range=None,
                         signed: bool = True):
    """Figs. 5 and 7: the output tracking errors e_x, e_y, e_z (m), e = y − y_t.

    As the paper defines them, signed: e_x = x_I − x_t (its axes go negative), so an
    approach from the target's negative side shows as a negative error rising to 0.
    ``signed=False`` draws |e_x|, |e_y|, |e_z| instead, easier to read on a log scale or when
    only the size matters. y_t is the set-point active at each step; dotted lines mark the
    target switches. ``t_range`` : (t0, t1) s to draw only part of the run.
    """
    fig, ax = _axes(ax, figsize=(7, 3.5))
    k = _steps_in(result, t_range)
    e = metrics.tracking_error(result)[k]
    t, e = result.t[k], (e if signed else np.abs(e))
    for i, name in enumerate("xyz"):
        idx = envelope_indices(e[:, i], max_points)
        label = f"$e_{name}$" if signed else f"$|e_{name}|$"
        ax.plot(t[idx], e[idx, i], lw=1.0, label=label)
    if signed:
        ax.axhline(0.0, color="grey", lw=0.6)
    _mark_target_switches(ax, result, t)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("error [m]" if signed else "absolute error [m]")
    ax.set_title(f"output tracking error ({result.config.distance.metric} distance)")
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(alpha=0.3)
    return fig


def plot_states(result, axes=None, max_points: int = MAX_POINTS, t_range=None):
    """Fig. 6: position x, y, z (m) against time with the artificial state y_a and the target.

    ``t_range`` : (t0, t1) s to draw only part of the run.
    """
    fig, axes = _axes_column(axes, 3, figsize=(7, 5.5))
    k = _steps_in(result, t_range)
    t, pos, pos_a = result.t[k], result.x[:-1, :3][k], result.x_a[k, :3]
    target = np.asarray(result.targets, float)[np.asarray(result.target_index, int)[k]]
    for i, ax in enumerate(axes):
        name = "xyz"[i]
        idx = envelope_indices(pos[:, i], max_points)
        ax.plot(t[idx], pos[idx, i], color="black", lw=1.0, label=f"${name}_\\mathcal{{I}}$")
        idx = envelope_indices(pos_a[:, i], max_points)
        ax.plot(t[idx], pos_a[idx, i], "--", color="tab:orange", lw=1.0, label=f"${name}_a$")
        idx = stride_indices(len(t), max_points)
        ax.plot(t[idx], target[idx, i], ":", color="tab:purple", lw=1.0, label=f"${name}_t$")
        ax.set_ylabel(f"{name} [m]")
        ax.legend(loc="upper right", fontsize="small", ncol=3)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[0].set_title(f"UAV position ({result.config.distance.metric} distance)")
    return fig


def avoidance_window(result, half_width: float = 10.0) -> tuple[float, float]:
    """(t0, t1) s: ``half_width`` seconds either side of the closest approach to a cloud (the
    step of minimum clearance), clipped to the run; for a zoomed view of the avoidance."""
    t = np.asarray(result.t, float)
    tc = t[int(np.argmin(result.clearance))]
    return float(max(t[0], tc - half_width)), float(min(t[-1], tc + half_width))


# --- summary figures ------------------------------------------------------------------------

def plot_solve_times(results, ax=None, max_points: int = MAX_POINTS):
    """Empirical distribution (CDF) of the solve times of each run, ms, log scale."""
    fig, ax = _axes(ax, figsize=(6, 3.5))
    for r, ls in zip(results, _LINESTYLES):
        ms = np.sort(np.asarray(r.solve_time) * 1e3)
        idx = stride_indices(len(ms), max_points)
        ax.step(ms[idx], (idx + 1) / len(ms), where="post", ls=ls,
                label=f"{r.config.distance.metric} (median {np.median(ms):.2g} ms)")
    ax.set_xscale("log")
    ax.set_xlabel("solve time [ms]")
    ax.set_ylabel("fraction of steps")
    ax.set_title("NMPC solve times")
    ax.legend(loc="lower right", fontsize="small")
    ax.grid(alpha=0.3, which="both")
    return fig


def plot_input_spectrum(results, cutoff_hz: float = metrics.DEFAULT_CUTOFF_HZ, ax=None):
    """Power spectrum of the thrusts (:func:`~paper_repro.metrics.input_spectrum`, summed over
    the rotors) with the cut-off marked: ``hf_energy_fraction`` is the share of the power to
    the right of the dashed line."""
    fig, ax = _axes(ax, figsize=(6, 3.5))
    for r, ls in zip(results, _LINESTYLES):
        freqs, psd = metrics.input_spectrum(r.u, r.config.nmpc.ts)
        if len(freqs) < 2:
            continue
        ax.loglog(freqs[1:], psd[1:] + 1e-30, lw=0.9, ls=ls, label=r.config.distance.metric)
    ax.axvline(cutoff_hz, ls="--", color="gray", label=f"cut-off {cutoff_hz:g} Hz")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("power [N²/Hz]")
    ax.set_title("spectrum of the thrusts")
    ax.legend(loc="lower left", fontsize="small")
    ax.grid(alpha=0.3, which="both")
    return fig


# --- tutorial: the smoothed distance on a 2-D slice (eq. 8-13) ------------------------------

def slice_grid(extent, z: float, n: int):
    """Query points on the plane z = const: X, Y (n, n) and the points (n·n, 3), m.

    ``extent`` : (x_min, x_max, y_min, y_max), m.
    """
    x0, x1, y0, y1 = extent
    X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    return X, Y, np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, float(z))])


def plot_distance_slice(cloud, z: float, extent, eta: float, sigma: float, n: int = 200,
                        axes=None, levels=None):
    """D_{η,σ} (eq. 8) beside ½·d² on the plane z = const, same contour levels (m²).

    The Euclidean level sets have kinks where two parts of the cloud are equally near (the
    inside of a concave corner); those of D are smooth.
    """
    fig, axes = _axes_row(axes, 2, figsize=(10, 4.2))
    X, Y, q = slice_grid(extent, z, n)
    values = (smooth_distance(q, cloud, eta, sigma).reshape(X.shape),
              euclidean_distance(q, cloud).reshape(X.shape))
    levels = levels if levels is not None else [0.125, 0.5, 1.0, 2.0, 4.0, 8.0]
    titles = (f"smoothed $D_{{\\eta,\\sigma}}$ (η = {eta:g} m, σ = {sigma:g} m)",
              "Euclidean $\\frac{1}{2}d^2$")
    for ax, v, title in zip(axes, values, titles):
        filled = ax.contourf(X, Y, v, levels=[0, *levels, v.max() + 1], cmap="Blues_r",
                             extend="neither")
        lines = ax.contour(X, Y, v, levels=levels, colors="black", linewidths=0.8)
        ax.clabel(lines, fmt="%g", fontsize="x-small")
        _slice_points(ax, cloud, z)
        ax.set_title(title, fontsize="medium")
        _slice_axes(ax, extent)
    fig.colorbar(filled, ax=list(axes), label="m²", shrink=0.9)
    return fig


def plot_eta_sigma(cloud, z: float, extent, etas=(0.1, 0.3, 0.6), sigmas=(0.8, 2.0, 100.0),
                   eta: float = 0.3, sigma: float = 0.8, n: int = 120, level: float = 1.0):
    """The level set D = ``level`` (m²) for several η (top row, σ fixed) and σ (bottom row,
    η fixed), each against the Euclidean ½d² = ``level`` (dashed).

    η (eq. 8) smooths the corners and, for a fixed level, pulls the set slightly outwards;
    σ (eq. 9) weights the points near the centroid: a small σ lowers the weight of the
    cloud's extremities, raising D there by up to η²·ln(V/W_j).
    """
    cols = max(len(etas), len(sigmas))
    fig, axes = plt.subplots(2, cols, figsize=(3.3 * cols, 6.2), squeeze=False,
                             constrained_layout=True)
    X, Y, q = slice_grid(extent, z, n)
    half_sq = euclidean_distance(q, cloud).reshape(X.shape)
    rows = ([(e, sigma) for e in etas], [(eta, s) for s in sigmas])
    for r, pairs in enumerate(rows):
        for c in range(cols):
            ax = axes[r, c]
            if c >= len(pairs):
                ax.set_visible(False)
                continue
            e, s = pairs[c]
            d = smooth_distance(q, cloud, e, s).reshape(X.shape)
            ax.contour(X, Y, half_sq, levels=[level], colors="gray", linestyles="--",
                       linewidths=1.0)
            ax.contourf(X, Y, d, levels=[0, level], colors=["tab:blue"], alpha=0.25)
            ax.contour(X, Y, d, levels=[level], colors="tab:blue", linewidths=1.4)
            _slice_points(ax, cloud, z)
            ax.set_title(f"η = {e:g} m, σ = {s:g} m", fontsize="medium")
            _slice_axes(ax, extent)
    fig.suptitle(f"level set D = {level:g} m² (blue) against ½d² = {level:g} m² (dashed)")
    return fig


def plot_gradient_field(cloud, z: float, extent, eta: float, sigma: float, n: int = 25,
                        axes=None):
    """Directions of ∇D = y − Π (eq. 13, smooth) and of ∇(½d²) = y − a* (nearest point a*).

    Arrows are unit vectors (in-plane part), coloured by the angle between the smooth and the
    Euclidean directions; the Euclidean field flips across the line where two parts of the
    cloud are equally near, the smooth one turns continuously.
    """
    fig, axes = _axes_row(axes, 2, figsize=(10, 4.2))
    X, Y, q = slice_grid(extent, z, n)
    smooth = q - smooth_projection(q, cloud, eta, sigma)
    nearest = np.asarray(cloud)[cKDTree(cloud).query(q)[1]]
    euclid = q - nearest
    for ax, g, title in zip(axes, (smooth, euclid),
                            (f"$y - \\Pi_{{\\eta,\\sigma}}(y)$ (η = {eta:g} m, σ = {sigma:g} m)",
                             "$y - a^*(y)$, nearest point")):
        u = g[:, :2] / np.maximum(np.linalg.norm(g[:, :2], axis=1, keepdims=True), 1e-12)
        ax.quiver(X, Y, u[:, 0].reshape(X.shape), u[:, 1].reshape(X.shape), angles="xy",
                  scale_units="xy", scale=n / (extent[1] - extent[0]) * 1.3, width=0.004,
                  color="tab:blue")
        _slice_points(ax, cloud, z)
        ax.set_title(title, fontsize="medium")
        _slice_axes(ax, extent)
    return fig


def plot_half_squared_limit(cloud, z: float, extent, etas=None, sigma: float = 0.8,
                            n: int = 60, ax=None):
    """Why D → ½d² as η → 0: the gap D − ½d² on the slice against η, with its bound.

    D is a weighted soft-min of ½‖y − a_j‖², so  ½d² ≤ D ≤ ½d² + η²·ln(V/W_*)  (W_* the weight
    of the nearest point): the gap vanishes like η². The plot shows the largest and the
    median gap on the slice, and the bound η²·max_j ln(V/W_j).
    """
    fig, ax = _axes(ax, figsize=(6, 3.8))
    etas = np.asarray(etas if etas is not None else np.geomspace(0.03, 1.0, 12), float)
    X, Y, q = slice_grid(extent, z, n)
    half_sq = euclidean_distance(q, cloud)
    weights = CloudWeights.from_cloud(cloud, sigma)
    worst_log_ratio = float(weights.log_volume - weights.log_weights.min())
    gaps = np.array([smooth_distance(q, weights, e, sigma) - half_sq for e in etas])
    ax.loglog(etas, gaps.max(axis=1), "o-", label="max over the slice")
    ax.loglog(etas, np.median(gaps, axis=1), "s-", label="median over the slice")
    ax.loglog(etas, etas**2 * worst_log_ratio, "k--",
              label="bound $\\eta^2 \\max_j \\ln(V/W_j)$")
    ax.set_xlabel("η [m]")
    ax.set_ylabel("$D_{\\eta,\\sigma} - \\frac{1}{2}d^2$ [m²]")
    ax.set_title(f"D tends to ½d² like η² (σ = {sigma:g} m)")
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3, which="both")
    return fig


# --- animation ------------------------------------------------------------------------------

def animate_flight(result, scene, path, frames: int = 100, fps: int = 12, dpi: int = 72,
                   close_up: float = 5.0):
    """GIF of the flight: whole workspace (left) and a close-up around the UAV (right), with
    the LiDAR sphere and the points it sees highlighted.

    Parameters
    ----------
    path : output file (``.gif``).  frames : number of frames, evenly spaced in time.
    fps : frames per second of the GIF.  dpi : resolution (the GIF is 9 × 4.5 in).
    close_up : half-width of the close-up view, m.

    Returns the path written.
    """
    if not (isinstance(frames, int) and frames >= 1):
        raise ValueError(f"frames must be an integer >= 1, got {frames!r}")
    pos = result.x[:, :3]
    r_s = result.config.simulation.lidar_range
    lidar = Lidar(scene.clouds, r_s)
    steps = np.unique(np.linspace(0, len(pos) - 1, frames).round().astype(int))
    fig = plt.figure(figsize=(9, 4.5), dpi=dpi)
    axes = [fig.add_subplot(1, 2, i + 1, projection="3d") for i in range(2)]
    fig.subplots_adjust(left=0.0, right=0.97, bottom=0.05, top=0.92, wspace=0.05)
    trail_idx = stride_indices(len(pos), MAX_POINTS)
    artists = {"dynamic": []}
    lines = []
    for ax in axes:
        for cloud in scene.clouds:
            ax.scatter(*cloud.T, s=1, color=CLOUD_COLOR, alpha=0.25, depthshade=False)
        (line,) = ax.plot([], [], [], color="black", lw=1.0)
        lines.append(line)
    _mark_start_and_targets(axes[0], scene, three_d=True)
    _workspace_limits(axes[0], three_d=True)
    axes[0].set_title("workspace", fontsize="small")

    def update(k):
        for a in artists["dynamic"]:
            a.remove()
        artists["dynamic"] = []
        p = pos[k]
        trail = trail_idx[trail_idx <= k]
        trail = np.append(trail, k)
        for ax, line in zip(axes, lines):
            line.set_data_3d(*pos[trail].T)
            artists["dynamic"].append(_draw_sphere(ax, p, r_s, alpha=0.15))
            artists["dynamic"].append(ax.scatter(*p, s=18, color="black", depthshade=False))
        seen = [v for v in lidar.scan(p) if len(v)]
        if seen:
            pts = np.concatenate(seen)
            for ax in axes:
                artists["dynamic"].append(ax.scatter(*pts.T, s=14, color="orange",
                                                     edgecolor="darkred", lw=0.4,
                                                     depthshade=False))
        ax = axes[1]
        for i, set_lim in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            set_lim(p[i] - close_up, p[i] + close_up)
        ax.set_box_aspect((1, 1, 1))
        n_seen = sum(len(v) for v in seen)
        k_log = min(k, len(result.t) - 1)
        ax.set_title(f"t = {k * result.config.nmpc.ts:6.1f} s, {n_seen} points in view, "
                     f"clearance {result.clearance[k_log]:.2f} m", fontsize="small")
        return []

    return _save_animation(fig, update, steps, path, fps, dpi)


# --- saving ---------------------------------------------------------------------------------

def save_figure(fig, stem: str, directory, formats=("pdf", "png"), dpi: int = 150,
                close: bool = False) -> list[Path]:
    """Write ``directory/stem.pdf`` and ``directory/stem.png``; returns the paths.

    The PDF carries no creation date (``CreationDate: None``), so saving the same figure twice
    gives the same bytes and regenerated figures only show up in git when they change.
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = out / f"{stem}.{fmt}"
        if fmt == "pdf":
            fig.savefig(path, format="pdf", metadata={"CreationDate": None}, bbox_inches="tight")
        elif fmt == "png":
            fig.savefig(path, format="png", dpi=dpi, bbox_inches="tight")
        else:
            raise ValueError(f"format must be 'pdf' or 'png', got {fmt!r}")
        paths.append(path)
    if close:
        plt.close(fig)
    return paths


# --- studies (tables of many runs, paper_repro.study) ---------------------------------------

METRIC_COLOURS = {"smooth": "tab:blue", "euclidean": "tab:red"}


def plot_rates(rates, ax=None):
    """Outcome rates per metric with their 95 % intervals (:func:`paper_repro.analysis.rates`).
    """
    fig, ax = _axes(ax, (7.0, 3.2))
    events = list(dict.fromkeys(rates["event"]))
    metrics_ = list(dict.fromkeys(rates["metric"]))
    width = 0.8 / len(metrics_)
    for i, m in enumerate(metrics_):
        r = rates[rates["metric"] == m].set_index("event").loc[events]
        x = np.arange(len(events)) + (i - (len(metrics_) - 1) / 2) * width
        ax.bar(x, r["rate"], width, color=METRIC_COLOURS.get(m), alpha=0.8,
               label=f"{m} (n = {int(r['n'].iloc[0])})")
        ax.errorbar(x, r["rate"], yerr=[r["rate"] - r["low"], r["high"] - r["rate"]],
                    fmt="none", ecolor="k", capsize=3, lw=1)
    ax.set_xticks(np.arange(len(events)), events)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share of runs")
    ax.legend(frameon=False)
    return fig


def plot_paired(table, a: str = "smooth", b: str = "euclidean", pair_on: str = "scene_seed",
                columns=("tv_u_rate_N_per_s", "hf_energy_fraction", "max_abs_du_N",
                         "min_clearance_m")):
    """One panel per measure: each scene's run ``b`` against its run ``a`` (log axes for the
    chattering measures), with the diagonal y = x."""
    from .analysis import PAIRED_COLUMNS

    ok = table[table["status"] == "ok"]
    wide = ok.pivot_table(index=pair_on, columns="metric", values=list(columns),
                          aggfunc="first")
    fig, axes = plt.subplots(1, len(columns), figsize=(3.3 * len(columns), 3.3),
                             constrained_layout=True)
    for ax, col in zip(np.atleast_1d(axes), columns, strict=True):
        pair = wide[[(col, a), (col, b)]].dropna()
        va, vb = pair[(col, a)].to_numpy(float), pair[(col, b)].to_numpy(float)
        ax.scatter(va, vb, s=12, alpha=0.7, color="k")
        both = np.r_[va, vb]
        positive = both[both > 0]
        if col != "min_clearance_m" and len(positive):
            ax.set_xscale("log")
            ax.set_yscale("log")
            lo, hi = positive.min() / 1.5, positive.max() * 1.5
        else:
            lo, hi = (both.min() - 0.05, both.max() + 0.05) if len(both) else (0, 1)
        ax.plot([lo, hi], [lo, hi], color="0.6", lw=1, ls="--")
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_xlabel(f"{a}")
        ax.set_ylabel(f"{b}")
        ax.set_title(PAIRED_COLUMNS.get(col, col), fontsize=9)
    return fig


def plot_paired_by(paired, by: str):
    """The paired effects of :func:`paper_repro.analysis.paired` (median and 95 % interval)
    for each value of ``by`` side by side, one panel per measure; ratios on a log axis with the
    line of no difference."""
    measures = list(dict.fromkeys(paired["measure"]))
    groups = list(dict.fromkeys(paired[by]))
    fig, axes = plt.subplots(1, len(measures), figsize=(3.0 * len(measures), 3.0),
                             constrained_layout=True)
    for ax, m in zip(np.atleast_1d(axes), measures, strict=True):
        rows = paired[paired["measure"] == m].set_index(by).loc[groups]
        x = np.arange(len(groups))
        y = rows["median_effect"].to_numpy(float)
        err = np.vstack([y - rows["low"].to_numpy(float), rows["high"].to_numpy(float) - y])
        ax.errorbar(x, y, yerr=np.abs(err), fmt="o", color="k", capsize=4)
        ratio = rows["effect"].iloc[0].startswith("ratio")
        ax.axhline(1.0 if ratio else 0.0, color="0.6", ls="--", lw=1)
        if ratio and np.all(np.r_[y, rows["low"]] > 0):
            ax.set_yscale("log")
        ax.set_xticks(x, groups)
        ax.set_xlim(-0.6, len(groups) - 0.4)
        ax.set_title(f"{rows['label'].iloc[0]}\n({rows['effect'].iloc[0]})", fontsize=8)
    return fig


def plot_clearance_ecdf(table, ax=None, collision: float = metrics.COLLISION_CLEARANCE):
    """ECDF of each run's minimum clearance, per metric, with the collision threshold."""
    from .analysis import ecdf

    fig, ax = _axes(ax, (5.5, 3.4))
    ok = table[table["status"] == "ok"]
    for m, group in ok.groupby("metric", sort=False):
        x, f = ecdf(group["min_clearance_m"])
        ax.step(x, f, where="post", color=METRIC_COLOURS.get(m), label=f"{m} ({len(x)} runs)")
    ax.axvline(collision, color="k", ls=":", lw=1, label=f"collision < {collision} m")
    ax.set_xlabel("minimum clearance over the run, m")
    ax.set_ylabel("share of runs ≤ x")
    ax.legend(frameon=False)
    return fig


def plot_study_solve_times(table, ts_ms: float = 10.0):
    """ECDFs of each run's median and 99th-percentile solve time, per metric, against T_s."""
    from .analysis import ecdf

    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2), constrained_layout=True, sharey=True)
    ok = table[table["status"] == "ok"]
    for ax, col, title in zip(axes, ("solve_median_ms", "solve_p99_ms"),
                              ("median per run", "99th percentile per run"), strict=True):
        for m, group in ok.groupby("metric", sort=False):
            x, f = ecdf(group[col])
            ax.step(x, f, where="post", color=METRIC_COLOURS.get(m), label=m)
        ax.axvline(ts_ms, color="k", ls=":", lw=1, label=f"T_s = {ts_ms:g} ms")
        ax.set_xscale("log")
        ax.set_xlabel("solve time, ms")
        ax.set_title(title, fontsize=9)
    axes[0].set_ylabel("share of runs ≤ x")
    axes[0].legend(frameon=False)
    return fig


def plot_sweep(settings, x: str, fixed: dict, columns=(
        ("tv_u_rate_N_per_s", "TV of u per second, N/s", True),
        ("hf_energy_fraction", "thrust power above 5 Hz", False),
        ("min_clearance_m", "min clearance, m", False),
        ("time_to_complete_s", "passage time, s", False),
        ("stalled_rate", "stall rate", False),
        ("completed_rate", "completion rate", False))):
    """Medians over scenes (bands: their 95 % intervals) of the smooth runs against ``x``
    (``"eta"`` or ``"sigma"``) with the other parameter held at ``fixed``; the Euclidean
    baseline as a dashed line (:func:`paper_repro.analysis.by_setting`)."""
    smooth = settings[settings["metric"] == "smooth"]
    for name, value in fixed.items():
        smooth = smooth[np.isclose(smooth[name], value)]
    smooth = smooth.sort_values(x)
    base = settings[settings["metric"] == "euclidean"]
    fig, axes = plt.subplots(2, 3, figsize=(11.0, 5.6), constrained_layout=True)
    for ax, (col, label, log) in zip(axes.ravel(), columns, strict=True):
        stem = col.removesuffix("_rate")  # rates' intervals are <event>_low, _high
        lo_col, hi_col = f"{stem}_low", f"{stem}_high"
        xs = smooth[x].to_numpy(float)
        ax.plot(xs, smooth[col], "o-", color=METRIC_COLOURS["smooth"], label="smoothed D")
        if lo_col in smooth and hi_col in smooth:
            ax.fill_between(xs, smooth[lo_col], smooth[hi_col], color=METRIC_COLOURS["smooth"],
                            alpha=0.2, lw=0)
        if len(base):
            ax.axhline(float(base[col].iloc[0]), color=METRIC_COLOURS["euclidean"], ls="--",
                       label="Euclidean (η → 0)")
        values = np.r_[smooth[col].to_numpy(float), base[col].to_numpy(float)]
        if not np.isfinite(values).any():  # e.g. no run completed: nothing to draw
            ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", color="0.5")
        else:
            ax.set_xscale("log")
            ax.set_xticks(xs, [f"{v:g}" for v in xs])  # the swept values, not log decades
            ax.minorticks_off()
            if log and np.nanmin(values) > 0:
                ax.set_yscale("log")
        ax.set_xlabel(f"{'η' if x == 'eta' else 'σ'}, m  ("
                      + ", ".join(f"{'σ' if k == 'sigma' else 'η'} = {v:g} m"
                                  for k, v in fixed.items()) + ")")
        ax.set_title(label, fontsize=9)
    axes[0, 0].legend(frameon=False, fontsize=8)
    return fig


# --- the mission's clock (paper_repro.timeline, issue 12) -----------------------------------

def plot_clock_levers(sweeps, paper_time: float = 500.0, tolerance: float = 0.10,
                      printed: dict | None = None):
    """Mission time of the linear loop against each lever, beside the paper's clock.

    Parameters
    ----------
    sweeps : DataFrame of :func:`paper_repro.timeline.lever_sweep` rows (several levers).
    paper_time : s, the paper's mission (a band of ± ``tolerance`` around it is shaded).
    printed : lever → printed value, marked with a dotted line.
    """
    from .timeline import LEVERS

    levers = list(dict.fromkeys(sweeps["lever"]))
    fig, axes = plt.subplots(1, len(levers), figsize=(2.6 * len(levers), 3.0), sharey=True,
                             squeeze=False)
    for ax, lever in zip(axes[0], levers):
        rows = sweeps[sweeps["lever"] == lever].sort_values("value")
        ax.plot(rows["value"], rows["mission_time_s"], "o-", ms=3, lw=1.0, color="black")
        ax.axhspan(paper_time * (1 - tolerance), paper_time * (1 + tolerance),
                   color="tab:green", alpha=0.2, lw=0)
        ax.axhline(paper_time, color="tab:green", lw=0.8)
        if printed and lever in printed:
            ax.axvline(printed[lever], color="0.4", ls=":", lw=1.0)
        if lever in ("T", "R", "rate weights"):
            ax.set_xscale("log")
        ax.set_xlabel(LEVERS[lever][0] if lever in LEVERS else lever, fontsize=8)
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("mission time, linear loop [s]")
    fig.suptitle(f"the clock under one changed parameter (band: {paper_time:g} s "
                 f"± {tolerance:.0%})", fontsize=10)
    fig.tight_layout()
    return fig


def plot_flight_clocks(results, labels, paper_time: float = 500.0,
                       paper_avoidance=(50.0, 120.0), merge_gap_s: float = 5.0):
    """Distance to the active target against time for each flight, with its avoidance
    windows (a cloud within the LiDAR's range) as bars, beside the paper's clock.

    Parameters
    ----------
    results : SimulationResults.   labels : one legend entry each.
    paper_time : s, end of the paper's time axes (dashed line).
    paper_avoidance : (t0, t1) s, the paper's avoidance phases (shaded).
    """
    from .timeline import avoidance_windows

    fig, (ax, bars) = plt.subplots(2, 1, figsize=(7.5, 5.0), sharex=True,
                                   gridspec_kw={"height_ratios": (3, 1.3)})
    for i, (r, label) in enumerate(zip(results, labels, strict=True)):
        dist = np.linalg.norm(metrics.tracking_error(r), axis=1)
        idx = stride_indices(len(dist), MAX_POINTS)
        line, = ax.plot(r.t[idx], dist[idx], _LINESTYLES[i], lw=1.0, label=label)
        for a, b in avoidance_windows(r, merge_gap_s):
            bars.plot([a, b], [i, i], color=line.get_color(), lw=5, solid_capstyle="butt")
    for a in (ax, bars):
        a.axvspan(*paper_avoidance, color="tab:orange", alpha=0.15, lw=0)
        a.axvline(paper_time, color="tab:green", ls="--", lw=1.0)
        a.grid(alpha=0.3)
    ax.set_ylabel("‖y − y_t‖ [m]")
    ax.set_title(f"the paper mission's clock (dashed: the paper's {paper_time:g} s; shaded: "
                 f"its avoidance, {paper_avoidance[0]:g}–{paper_avoidance[1]:g} s)",
                 fontsize=9)
    ax.legend(fontsize="small", loc="upper right")
    bars.set_yticks(range(len(labels)), labels, fontsize=7)
    bars.set_ylim(-0.7, len(labels) - 0.3)
    bars.invert_yaxis()
    bars.set_xlabel("t [s]")
    bars.set_ylabel("cloud in view", fontsize=8)
    fig.tight_layout()
    return fig


# --- helpers --------------------------------------------------------------------------------

def slice_through(cloud, pad: float = 3.0):
    """A horizontal slice through the middle of a cloud: (z, extent), m.

    z is the mid-height of the cloud's bounding box; extent = (x_min, x_max, y_min, y_max) is
    its horizontal bounding box widened by ``pad``.
    """
    cloud = np.asarray(cloud, float)
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    extent = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
    return float((lo[2] + hi[2]) / 2), tuple(float(v) for v in extent)


def lidar_instants(result, scene, n: int = 4) -> list[int]:
    """Steps at which to draw the LiDAR sphere: the closest approach to each region the UAV
    comes within range of, then evenly spaced steps at least r_s apart, ``n`` at most."""
    pos = result.x[:, :3]
    r_s = result.config.simulation.lidar_range
    chosen = []
    for cloud in scene.clouds:
        d = cKDTree(cloud).query(pos)[0]
        k = int(np.argmin(d))
        if d[k] <= r_s:
            chosen.append(k)
    # Fill up with evenly spaced instants, skipping any whose sphere would overlap another's
    # centre (a short run gets a single sphere rather than a stack of them).
    for k in np.linspace(0, len(pos) - 1, n).round().astype(int):
        if len(chosen) >= n:
            break
        if all(np.linalg.norm(pos[k] - pos[c]) >= r_s for c in chosen):
            chosen.append(int(k))
    return sorted(chosen[:n])


def stride_indices(n: int, max_points: int = MAX_POINTS) -> np.ndarray:
    """Evenly spaced indices into a length-n sequence, at most ``max_points``, first and last
    included (for smooth curves such as the trajectory)."""
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max(2, max_points)).round().astype(int))


def envelope_indices(y, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices keeping the min and the max of y in each of ``max_points``/2 buckets.

    Unlike a stride, this keeps the envelope of a chattering signal: a 40 Hz oscillation
    stays visible at full amplitude after decimation.
    """
    y = np.asarray(y, float).ravel()
    n = len(y)
    if n <= max_points:
        return np.arange(n)
    buckets = max(1, max_points // 2)
    edges = np.linspace(0, n, buckets + 1).round().astype(int)
    keep = [0, n - 1]
    for a, b in zip(edges[:-1], edges[1:]):
        if b > a:
            seg = y[a:b]
            keep += [a + int(np.argmin(seg)), a + int(np.argmax(seg))]
    return np.unique(keep)


def _axes(ax, figsize):
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, constrained_layout=True)
        return fig, ax
    return ax.figure, ax


def _axes3d(ax):
    if ax is None:
        fig = plt.figure(figsize=(7.5, 6), constrained_layout=True)
        ax = fig.add_subplot(projection="3d")
        return fig, ax
    return ax.figure, ax


def _axes_column(axes, n, figsize):
    if axes is None:
        fig, axes = plt.subplots(n, 1, figsize=figsize, sharex=True, constrained_layout=True)
        return fig, list(np.atleast_1d(axes))
    axes = list(np.atleast_1d(axes))
    if len(axes) != n:
        raise ValueError(f"axes must hold {n} Axes, got {len(axes)}")
    return axes[0].figure, axes


def _axes_row(axes, n, figsize):
    if axes is None:
        fig, axes = plt.subplots(1, n, figsize=figsize, constrained_layout=True)
        return fig, list(np.atleast_1d(axes))
    axes = list(np.atleast_1d(axes))
    if len(axes) != n:
        raise ValueError(f"axes must hold {n} Axes, got {len(axes)}")
    return axes[0].figure, axes


def _draw_sphere(ax, center, radius, alpha: float = 0.12, label=None):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, np.pi, 13))
    xs = center[0] + radius * np.cos(u) * np.sin(v)
    ys = center[1] + radius * np.sin(u) * np.sin(v)
    zs = center[2] + radius * np.cos(v)
    return ax.plot_surface(xs, ys, zs, color=SPHERE_COLOR, alpha=alpha, linewidth=0,
                           shade=False, label=label)


def _mark_start_and_targets(ax, scene, three_d: bool):
    start = np.asarray(scene.start, float)
    targets = np.atleast_2d(np.asarray(scene.targets, float))
    kw = {"depthshade": False} if three_d else {}
    ax.scatter(*start, s=40, marker="o", color="tab:green", label="start", **kw)
    ax.scatter(*targets.T, s=90, marker="*", color="tab:purple", label="targets", **kw)


def _workspace_limits(ax, three_d: bool):
    lo, hi = WORKSPACE_LOWER, WORKSPACE_UPPER
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xlabel(AXIS_LABELS[0])
    ax.set_ylabel(AXIS_LABELS[1])
    if three_d:
        ax.set_zlim(lo[2], hi[2])
        ax.set_zlabel(AXIS_LABELS[2])
        ax.set_box_aspect(tuple(hi - lo))


def _mark_target_switches(ax, result, t):
    """Dotted lines at the target switches that fall inside the drawn times ``t``."""
    ts = result.config.nmpc.ts
    for k in np.asarray(result.reached)[:-1]:
        if k >= 0 and len(t) and t[0] <= k * ts <= t[-1]:
            ax.axvline(k * ts, ls=":", color="gray", lw=1.0)


def _steps_in(result, t_range) -> np.ndarray:
    """Indices of the steps with t in ``t_range`` (all steps when None)."""
    t = np.asarray(result.t, float)
    if t_range is None:
        return np.arange(len(t))
    t0, t1 = t_range
    k = np.flatnonzero((t >= t0) & (t <= t1))
    if len(k) == 0:
        raise ValueError(f"t_range {t_range!r} holds no step of the run ({t[0]:g}-{t[-1]:g} s)")
    return k


def _slice_points(ax, cloud, z: float, slab: float = 0.5):
    """Cloud points within ``slab`` (m) of the plane, drawn as red dots."""
    cloud = np.asarray(cloud)
    near = np.abs(cloud[:, 2] - z) <= slab
    ax.scatter(cloud[near, 0], cloud[near, 1], s=6, color=CLOUD_COLOR, zorder=3, lw=0)


def _slice_axes(ax, extent):
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel(AXIS_LABELS[0])
    ax.set_ylabel(AXIS_LABELS[1])


# --- the smooth sensing window (issue 13, part 2) ---------------------------------------------

def scan_change_times(result) -> np.ndarray:
    """Times (s) of the steps whose scan holds a different number of points from the scan
    before: the changes of the visible set of :func:`paper_repro.metrics.scan_change_steps`.
    """
    change = np.flatnonzero(np.diff(np.asarray(result.visible_points)) != 0) + 1
    return np.asarray(result.t, float)[change]


def plot_sensing_window(sensor_range: float = 3.0, widths=(0.25, 0.5, 1.0), ax=None,
                        n: int = 400):
    """The weight ψ(r) of a visible point against its range r, for each window width w.

    The hard cut-off (w = 0, the paper's LiDAR) is the grey step; each width is the C∞ step of
    :func:`paper_repro.distance.sensing_window`, with a dot where full weight ends (r_s − w)
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
    from .distance import sensing_window

    widths = tuple(float(w) for w in widths)
    if not widths or not all(0 < w < sensor_range for w in widths):
        raise ValueError(f"widths must be non-empty, each in (0, {sensor_range}) m, got "
                         f"{widths!r}")
    fig, ax = _axes(ax, (6.0, 3.2))
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
                             threshold: float = metrics.SCAN_STEP_THRESHOLD):
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

    Returns
    -------
    matplotlib Figure; its Axes form a (5, len(results)) grid.
    """
    results, labels = list(results), list(labels)
    if not results or len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    fig, axes = plt.subplots(5, len(results), figsize=(4.2 * len(results) + 0.8, 8.0),
                             sharex="col", sharey="row", squeeze=False,
                             constrained_layout=True)
    for j, (result, label) in enumerate(zip(results, labels, strict=True)):
        k = _steps_in(result, t_range)
        t, u = result.t[k], result.u[k]
        col = axes[:, j]
        changes = scan_change_times(result)
        changes = changes[(changes >= t[0]) & (changes <= t[-1])]
        for i in range(4):
            idx = envelope_indices(u[:, i], max_points)
            col[i].plot(t[idx], u[idx, i], color="tab:blue", lw=0.8)
            if j == 0:
                col[i].set_ylabel(f"$f_{i + 1}$ [N]")
        du = np.abs(np.diff(np.asarray(result.u, float), axis=0)).max(axis=1)
        kd = k[k >= 1]  # step k: the change from u_{k-1} to u_k
        du_k = du[kd - 1]
        idx = envelope_indices(du_k, max_points)
        col[4].plot(result.t[kd][idx], du_k[idx], color="tab:blue", lw=0.6)
        at = np.isin(result.t[kd], changes)
        col[4].plot(result.t[kd][at], du_k[at], "o", color="tab:orange", ms=3,
                    label="change of the visible set")
        col[4].axhline(threshold, color="k", ls=":", lw=1, label=f"{threshold * 1e3:g} mN")
        col[4].set_yscale("log")
        col[4].set_xlabel("t [s]")
        if j == 0:
            col[4].set_ylabel("max$_i$ |Δf$_i$| [N]")
            col[4].legend(loc="lower right", fontsize="x-small", frameon=False)
        for ax in col:
            for tc in changes:
                ax.axvline(tc, color="tab:orange", lw=0.5, alpha=0.5)
            ax.grid(alpha=0.3)
        jumps = int(np.sum(du_k[at] > threshold))
        col[0].set_title(f"{label}\n{len(changes)} changes of the visible set, {jumps} with a "
                         f"step > {threshold * 1e3:g} mN", fontsize=9)
    return fig


def plot_scan_change_du(results, labels, ax=None, floor: float = 1e-7,
                        threshold: float = metrics.SCAN_STEP_THRESHOLD,
                        neighbourhood: int | None = metrics.SCAN_NEIGHBOURHOOD):
    """ECDFs of the thrust steps max_i |Δf_i| (N, log axis) at changes of the visible set
    (solid) and at the steps around them (dashed), one colour per run
    (:func:`paper_repro.metrics.scan_change_steps`).

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
    from .analysis import ecdf

    results, labels = list(results), list(labels)
    if len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    fig, ax = _axes(ax, (6.0, 3.6))
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

    1. outcome rates with 95 % Clopper–Pearson intervals (:func:`paper_repro.analysis.rates`);
    2. per run, the share of changes of the visible set with a thrust step above
       ``threshold`` (``scan_change_jump_share``), the median as a bar;
    3. per run, the median thrust step at changes (filled) and around them (open), N, log
       axis (the two columns ``steps``);
    4. per run, the minimum clearance, m, with the collision threshold.

    Runs that failed are left out of panels 2-4 (they count in panel 1); runs without a change
    of the visible set have no value in panels 2-3 (a note says how many).

    Parameters
    ----------
    table : a study table (:func:`paper_repro.study.run_study`) with a column ``by`` and the
        columns of :func:`paper_repro.metrics.summary_row`.
    by : the setting, one group of runs per value.   label : its axis label.
    events : the outcomes of panel 1 (:data:`paper_repro.analysis.EVENTS`).
    steps : the columns of panel 3, medians over each run of |Δu| (N) at changes and around.
    threshold : N, a jump (dotted line in panel 3).   collision : m (dotted line in panel 4).

    Returns
    -------
    matplotlib Figure with four Axes.
    """
    from .analysis import rates as outcome_rates

    settings = sorted(table[by].dropna().unique())
    colours = dict(zip(settings, plt.cm.viridis(np.linspace(0.15, 0.85, len(settings))),
                       strict=True))
    fig, axes = plt.subplots(1, 4, figsize=(14.0, 3.4), constrained_layout=True)
    rates = outcome_rates(table, by=[by])
    width = 0.8 / max(len(settings), 1)
    for i, s in enumerate(settings):
        r = rates[rates[by] == s].set_index("event").loc[list(events)]
        x = np.arange(len(events)) + (i - (len(settings) - 1) / 2) * width
        axes[0].bar(x, r["rate"], width, color=colours[s], alpha=0.85,
                    label=f"{s:g} (n = {int(r['n'].iloc[0])})")
        axes[0].errorbar(x, r["rate"], yerr=[r["rate"] - r["low"], r["high"] - r["rate"]],
                         fmt="none", ecolor="k", capsize=3, lw=1)
    axes[0].set_xticks(np.arange(len(events)), events)
    axes[0].set_ylim(0, 1.05)
    axes[0].set_ylabel("share of runs")
    axes[0].legend(title=label, fontsize="x-small", title_fontsize="x-small", frameon=False)
    ok = table[table["status"] == "ok"]
    jitter = np.random.default_rng(0)
    x = np.arange(len(settings))
    panels = ((axes[1], ("scan_change_jump_share",), f"share of changes with a step "
               f"> {threshold * 1e3:g} mN", False),
              (axes[2], tuple(steps), "median thrust step [N]: at changes (●), around (○)",
               True),
              (axes[3], ("min_clearance_m",), "minimum clearance [m]", False))
    for ax, columns, title, log in panels:
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
        ax.set_xticks(x, [f"{s:g}" for s in settings])
        ax.set_xlim(-0.6, len(settings) - 0.4)
        ax.set_xlabel(label)
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
    axes[1].axhline(0.0, color="0.6", lw=0.8)
    axes[2].axhline(threshold, color="k", ls=":", lw=1)
    axes[3].axhline(collision, color="k", ls=":", lw=1)
    return fig


# --- moving obstacles (simulation.prediction: static, oracle, kalman) ------------------------

PREDICTION_COLOURS = {"static": "tab:gray", "oracle": "tab:green", "kalman": "tab:orange"}
"""Colour of each way of predicting a moving region (``SimulationParams.prediction``)."""

GHOST_COLOR = "tab:blue"


def prediction_velocities(result) -> np.ndarray:
    """The velocity of each region that the controller was given at each step of ``result``.

    * ``"static"`` (the paper): zeros, the regions are taken to stay where they are seen;
    * ``"oracle"``: the regions' true velocities at t_k (:meth:`Lidar.velocities`);
    * ``"kalman"``: the estimates of a :class:`~paper_repro.tracking.RegionTracker` replayed
      along the saved trajectory. The LiDAR is deterministic (a perfect one; a noisy one
      draws its noise from its seed, scan after scan), so scanning again from each saved
      state x_k at t_k and updating a new tracker gives the velocities the controller used,
      bit for bit, for a run flown by :func:`~paper_repro.simulation.simulate` without
      injected faults.

    Parameters
    ----------
    result : a :class:`~paper_repro.simulation.SimulationResult`.

    Returns
    -------
    (K, n_regions, 3) array, m/s, K = ``result.steps``.
    """
    from .tracking import RegionTracker

    cfg, scene = result.config, result.scene
    t = np.asarray(result.t, float)
    n = len(scene.clouds)
    prediction = cfg.simulation.prediction
    out = np.zeros((len(t), n, 3))
    if prediction == "static":
        return out
    lidar = Lidar(scene.clouds, cfg.simulation.lidar_range, noise=cfg.sensor,
                  motions=scene.motions)
    if prediction == "oracle":
        for k, tk in enumerate(t):
            out[k] = lidar.velocities(float(tk))
        return out
    tracker = RegionTracker(cfg.nmpc.ts)
    for k, tk in enumerate(t):
        scan = lidar.scan(result.x[k, :3], float(tk))
        scan = [v[np.all(np.isfinite(v), axis=1)] for v in scan]  # as the closed loop does
        out[k] = tracker.update(scan, float(tk))
    return out


def plot_clearance_time(results, labels, ax=None, t_range=None,
                        collision: float = metrics.COLLISION_CLEARANCE,
                        max_points: int = MAX_POINTS):
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

    Returns
    -------
    matplotlib Figure.
    """
    results, labels = list(results), list(labels)
    if not results or len(labels) != len(results):
        raise ValueError(f"need one label per run, got {len(results)} runs and {len(labels)} "
                         "labels")
    fig, ax = _axes(ax, (7.0, 3.4))
    for i, (result, label) in enumerate(zip(results, labels, strict=True)):
        k = _steps_in(result, t_range)
        t, c = np.asarray(result.t, float)[k], np.asarray(result.clearance, float)[k]
        colour = PREDICTION_COLOURS.get(label, f"C{i}")
        idx = envelope_indices(c, max_points)
        j = int(np.argmin(c))
        ax.plot(t[idx], c[idx], color=colour, lw=1.3, ls=_LINESTYLES[i],
                label=f"{label}: min {c[j]:.3f} m at {t[j]:.2f} s")
        ax.plot(t[j], c[j], "o", color=colour, ms=5)
    ax.axhline(collision, color="k", ls=":", lw=1, label=f"collision < {collision:g} m")
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("clearance [m]")
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
    circle), each region's cloud where it is at t_k (red, faint), the points in view (orange)
    and, with ``velocities`` ((n_regions, 3) m/s at step k), the scanned points moved by
    v_i·τ_j for each stage j of ``stages``, τ_j = j·h: where the controller predicted them
    (blue rings, fainter with j)."""
    i0, i1 = _plane_index(plane)
    cfg = result.config
    r_s = cfg.simulation.lidar_range
    t = float(result.t[min(k, len(result.t) - 1)])
    pos = result.x[:, :3]
    artists = []
    clouds = result.scene.clouds_at(t)
    for c in clouds:
        artists.append(ax.scatter(c[:, i0], c[:, i1], s=6, color=CLOUD_COLOR, alpha=0.35, lw=0,
                                  zorder=2))
    lidar = Lidar(clouds, r_s)  # the clouds where they are at t: a static scan of them
    seen = lidar.scan(pos[k])
    if any(len(v) for v in seen):
        pts = np.concatenate([v for v in seen if len(v)])
        artists.append(ax.scatter(pts[:, i0], pts[:, i1], s=12, color="orange",
                                  edgecolor="darkred", lw=0.4, zorder=3))
    if velocities is not None and stages:
        h = cfg.nmpc.prediction_step
        stages = sorted(stages)
        alphas = np.linspace(0.8, 0.3, len(stages))
        for j, alpha in zip(stages, alphas, strict=True):
            moved = [v + np.asarray(velocities[i], float) * j * h
                     for i, v in enumerate(seen) if len(v)]
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
    p = result.x[np.asarray(steps, int), :3][:, [i0, i1]]
    lo = np.maximum(p.min(axis=0) - pad, WORKSPACE_LOWER[[i0, i1]])
    hi = np.minimum(p.max(axis=0) + pad, WORKSPACE_UPPER[[i0, i1]])
    return lo, hi


def _crossing_handles(stages, h: float) -> list:
    """Legend entries of :func:`_draw_crossing`."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="black", lw=1.0, marker="o", ms=4, label="UAV path"),
               Line2D([], [], ls="", marker="o", ms=4, color=CLOUD_COLOR, alpha=0.5,
                      label="cloud at t"),
               Line2D([], [], ls="", marker="o", ms=5, color="orange", mec="darkred",
                      label="in view"),
               Line2D([], [], color=SPHERE_COLOR, lw=0.8, label="LiDAR range")]
    if stages:
        taus = ", ".join(f"{j * h:g}" for j in sorted(stages))
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
            pos = result.x[:, :3]
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
    h = results[0].config.nmpc.prediction_step
    handles = _crossing_handles(stages if any(v is not None for v in velocities) else (), h)
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
    result : a :class:`~paper_repro.simulation.SimulationResult` (its scene's motions place
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
    window = _steps_in(result, t_range)
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
    handles = _crossing_handles(stages, result.config.nmpc.prediction_step)
    fig.legend(handles=handles, loc="lower center", ncols=3, fontsize="small", frameon=False)
    title = fig.suptitle("", fontsize="medium")
    prediction = result.config.simulation.prediction
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

    return _save_animation(fig, update, steps, path, fps, dpi)


def plot_prediction_study(table, events=("completed", "collision", "stalled", "step_limit"),
                          collision: float = metrics.COLLISION_CLEARANCE):
    """A moving-obstacle study per prediction (x axis) and metric (colour).

    One panel per event of ``events``: its rate with the 95 % Clopper–Pearson interval
    (:func:`paper_repro.analysis.rates` by prediction and metric); then, per run, the minimum
    clearance (m, with the collision threshold) and the total variation of u per second
    (N/s, log axis), the median of each group as a black bar. Runs that failed count in the
    rates and are left out of the per-run panels.

    Parameters
    ----------
    table : a study table with the columns ``prediction`` and ``metric`` and those of
        :func:`paper_repro.metrics.summary_row` (``moving_obstacles``).
    events : outcomes of :data:`paper_repro.analysis.EVENTS`, one panel each.
    collision : m, the collision threshold (dotted line).

    Returns
    -------
    matplotlib Figure with ``len(events) + 2`` Axes (in rows of three).
    """
    from .analysis import rates as outcome_rates

    order = ("static", "oracle", "kalman")
    present = list(dict.fromkeys(table["prediction"]))
    predictions = [p for p in order if p in present] + [p for p in present if p not in order]
    metrics_ = list(dict.fromkeys(table["metric"]))
    n_panels = len(events) + 2
    rows = int(np.ceil(n_panels / 3))
    fig, grid = plt.subplots(rows, 3, figsize=(12.0, 3.3 * rows), constrained_layout=True,
                             squeeze=False)
    axes = grid.ravel()
    for ax in axes[n_panels:]:
        ax.remove()
    rates = outcome_rates(table, by=["prediction", "metric"])
    width = 0.8 / max(len(metrics_), 1)
    x = np.arange(len(predictions))
    for ax, event in zip(axes, events):
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
    axes[0].set_ylabel("share of runs")
    axes[0].legend(fontsize="x-small", frameon=False)
    ok = table[table["status"] == "ok"]
    jitter = np.random.default_rng(0)
    per_run = ((axes[len(events)], "min_clearance_m", "minimum clearance [m]", False),
               (axes[len(events) + 1], "tv_u_rate_N_per_s", "total variation of u per s [N/s]",
                True))
    for ax, column, title, log in per_run:
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


def _save_animation(fig, update, frames, path, fps: int, dpi: int) -> Path:
    """Render ``update`` over ``frames`` into a GIF at ``path`` (folders made), close ``fig``."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    anim = FuncAnimation(fig, update, frames=frames, blit=False)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(path, writer=PillowWriter(fps=fps), dpi=dpi)
    plt.close(fig)
    return path

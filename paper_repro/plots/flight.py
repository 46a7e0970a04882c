"""The paper's figures of one flight: the 3-D flight, projections, thrusts, tracking errors,
states, and the summary figures of several flights."""

from __future__ import annotations

import dataclasses

import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial import cKDTree

from paper_repro.analysis import metrics
from paper_repro.plots.common import (
    AXIS_LABELS,
    CLOUD_COLOR,
    LINESTYLES,
    MAX_POINTS,
    axes3d_or_new,
    axes_column,
    axes_or_new,
    draw_sphere,
    envelope_indices,
    stride_indices,
)
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER

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
    fig, ax = axes3d_or_new(ax)
    pos = result.positions
    for i, cloud in enumerate(scene.clouds):
        ax.scatter(*cloud.T, s=2, color=CLOUD_COLOR, alpha=0.6, depthshade=False,
                   label="point clouds" if i == 0 else None)
    idx = stride_indices(len(pos), max_points)
    ax.plot(*pos[idx].T, color="black", lw=1.2, label="trajectory")
    if sphere_steps is None:
        sphere_steps = lidar_instants(result, scene, n_spheres)
    r_s = result.config.sensor.range
    for j, k in enumerate(sphere_steps):
        draw_sphere(ax, pos[k], r_s, label=f"LiDAR range ($r_s$ = {r_s:g} m)" if j == 0 else None)
    mark_start_and_targets(ax, scene, three_d=True)
    workspace_limits(ax, three_d=True)
    ax.set_title(f"3-D flight ({result.config.distance.metric} distance)\n"
                 f"{setup_label(result)}", fontsize="medium")
    ax.legend(loc="upper left", fontsize="small")
    return fig


def plot_projection(result, scene, plane: str = "xz", ax=None, max_points: int = MAX_POINTS):
    """Figs. 2 and 3: the trajectory and the clouds projected onto the XZ or XY plane."""
    if plane not in ("xz", "xy", "yz"):
        raise ValueError(f"plane must be 'xz', 'xy' or 'yz', got {plane!r}")
    axes_idx = ["xyz".index(c) for c in plane]
    fig, ax = axes_or_new(ax, figsize=(7, 4.5 if plane == "xy" else 3.5))
    for i, cloud in enumerate(scene.clouds):
        ax.scatter(cloud[:, axes_idx[0]], cloud[:, axes_idx[1]], s=3, color=CLOUD_COLOR,
                   alpha=0.6, lw=0, label="point clouds" if i == 0 else None)
    pos = result.positions
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
    ax.set_title(f"projection onto the {plane.upper()}-plane ({result.config.distance.metric} "
                 f"distance)\n{setup_label(result)}", fontsize="medium")
    ax.legend(loc="best", fontsize="small")
    ax.grid(alpha=0.3)
    return fig


def plot_thrusts(result, axes=None, max_points: int = MAX_POINTS, t_range=None,
                 full_range: bool = False):
    """Figs. 4 and 8: thrusts f1..f4 (N) against time, with the artificial input u_a (dashed).

    ``axes`` : four Axes (a new 4×1 figure if omitted). ``t_range`` : (t0, t1) s to draw only
    part of the run, e.g. :func:`view_window` (the title then says "zoom"). ``full_range`` :
    every panel spans the input box 𝒰 (0–12 N for the quadrotor), so that the two metrics'
    zooms share their axes and compare at a glance.
    """
    fig, axes = axes_column(axes, 4, figsize=(7, 6.5))
    k = steps_in(result, t_range)
    t, u, u_a = result.t[k], result.u[k], result.u_a[k]
    lower, upper = (np.asarray(result.config.quadrotor.input_lower, float),
                    np.asarray(result.config.quadrotor.input_upper, float))
    for i, ax in enumerate(axes):
        idx = envelope_indices(u[:, i], max_points)
        ax.plot(t[idx], u[idx, i], color="tab:blue", lw=0.8, label=f"$f_{i + 1}$")
        idx = envelope_indices(u_a[:, i], max_points)
        ax.plot(t[idx], u_a[idx, i], "--", color="tab:orange", lw=1.0,
                label=f"$u_{{a,{i + 1}}}$")
        if full_range:
            pad = 0.04 * (upper[i] - lower[i])
            ax.set_ylim(lower[i] - pad, upper[i] + pad)
        ax.set_ylabel(f"$f_{i + 1}$ [N]")
        ax.grid(alpha=0.3)
        _mark_target_switches(ax, result, t)
        ax.legend(loc="upper right", fontsize="small", ncol=3)
    axes[-1].set_xlabel("t [s]")
    _title(axes[0], "rotor thrusts", result, t, t_range)
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
    fig, ax = axes_or_new(ax, figsize=(7, 3.5))
    k = steps_in(result, t_range)
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
    _title(ax, "absolute output tracking error" if not signed else "output tracking error",
           result, t, t_range)
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(alpha=0.3)
    return fig


def plot_states(result, axes=None, max_points: int = MAX_POINTS, t_range=None):
    """Fig. 6: position x, y, z (m) against time with the artificial state y_a and the target.

    ``t_range`` : (t0, t1) s to draw only part of the run.
    """
    fig, axes = axes_column(axes, 3, figsize=(7, 5.5))
    k = steps_in(result, t_range)
    t, pos, pos_a = result.t[k], result.positions[k], result.x_a[k, :3]
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
    _title(axes[0], "UAV position", result, t, t_range)
    return fig


def avoidance_window(result, half_width: float = 10.0) -> tuple[float, float]:
    """(t0, t1) s: ``half_width`` seconds either side of the closest approach to a cloud (the
    step of minimum clearance), clipped to the run; for a zoomed view of the avoidance."""
    t = np.asarray(result.t, float)
    tc = t[int(np.argmin(result.clearance))]
    return float(max(t[0], tc - half_width)), float(min(t[-1], tc + half_width))


def view_window(result, width: float = 20.0, before: float = 1.0) -> tuple[float, float]:
    """(t0, t1) s: ``width`` seconds from ``before`` seconds ahead of the first step with a
    region in view, clipped to the run. Both metrics fly the same path until then (the
    controller is the same without a cloud in view), so their windows coincide: the zooms
    of Figs. 4 and 8 show the same seconds. A run that never sees a region: its first
    ``width`` seconds."""
    t = np.asarray(result.t, float)
    seen = np.flatnonzero(np.asarray(result.visible_points) > 0)
    t0 = max(t[0], t[seen[0]] - before) if len(seen) else t[0]
    return float(t0), float(min(t[-1], t0 + width))


# --- summary figures ------------------------------------------------------------------------

def plot_regions(clouds, names=None, start=None, targets=None, ax=None):
    """A scene's regions in 3-D, one colour each (as ``python -m paper_repro scene`` draws a
    scan split into regions), with the start and targets when given.

    Parameters
    ----------
    clouds : sequence of (m_i, 3) arrays, m.  names : one label per region (default its index).
    start : (3,) m, or None.  targets : (k, 3) m, or None.
    ax : a 3-D Axes to draw into (a new figure if omitted).
    """
    fig, ax = axes3d_or_new(ax)
    names = names if names is not None else [str(i) for i in range(len(clouds))]
    colours = plt.get_cmap("tab10")
    for i, (cloud, name) in enumerate(zip(clouds, names, strict=True)):
        ax.scatter(*np.asarray(cloud).T, s=3, color=colours(i % 10), depthshade=False,
                   label=f"{name} ({len(cloud)} points)" if i < 10 else None)
    drawn = [np.asarray(c, float) for c in clouds]
    if start is not None:
        ax.scatter(*np.asarray(start, float), s=40, marker="o", color="tab:green",
                   label="start", depthshade=False)
        drawn.append(np.atleast_2d(np.asarray(start, float)))
    if targets is not None:
        targets = np.atleast_2d(np.asarray(targets, float))
        ax.scatter(*targets.T, s=90, marker="*", color="tab:purple", label="targets",
                   depthshade=False)
        drawn.append(targets)
    every = np.concatenate(drawn)
    # Each axis spans at least a quarter of the longest, so a flat scan keeps some depth.
    mid = (every.min(axis=0) + every.max(axis=0)) / 2
    half = np.maximum(np.ptp(every, axis=0) / 2 + 0.5, np.ptp(every, axis=0).max() / 8)
    lo, hi = mid - half, mid + half
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(hi - lo))
    for set_label, label in zip((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), AXIS_LABELS,
                                strict=True):
        set_label(label)
    ax.set_title(f"{len(clouds)} region(s)", fontsize="medium")
    ax.legend(loc="upper left", fontsize="small")
    return fig


def plot_solve_times(results, ax=None, max_points: int = MAX_POINTS):
    """The tail of the solve times: the share of the steps whose controller call took at
    least t (ms), both axes logarithmic, with the sampling period T_s marked (a call longer
    than T_s misses the real-time deadline)."""
    fig, ax = axes_or_new(ax, figsize=(6, 3.5))
    for r, ls in zip(results, LINESTYLES):
        ms = np.sort(np.asarray(r.solve_time) * 1e3)
        idx = stride_indices(len(ms), max_points)
        ax.step(ms[idx], (len(ms) - idx) / len(ms), where="post", ls=ls,
                label=f"{r.config.distance.metric} (median {np.median(ms):.2g} ms, "
                      f"max {ms[-1]:.2g} ms)")
    if results:
        ts_ms = 1e3 * results[0].config.nmpc.ts
        ax.axvline(ts_ms, color="tab:red", lw=1.0, label=f"$T_s$ = {ts_ms:g} ms")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("solve time t [ms]")
    ax.set_ylabel("share of steps taking ≥ t")
    ax.set_title("NMPC solve times: the tail against $T_s$")
    ax.legend(loc="lower left", fontsize="small")
    ax.grid(alpha=0.3, which="both")
    return fig


def plot_input_spectrum(results, cutoff_hz: float = metrics.DEFAULT_CUTOFF_HZ, ax=None):
    """Power spectrum of the thrusts (:func:`~paper_repro.analysis.metrics.input_spectrum`, summed
    over
    the rotors) with the cut-off marked: ``hf_energy_fraction`` is the share of the power to
    the right of the dashed line."""
    fig, ax = axes_or_new(ax, figsize=(6, 3.5))
    for r, ls in zip(results, LINESTYLES):
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


def lidar_instants(result, scene, n: int = 4) -> list[int]:
    """Steps k at which to draw the LiDAR sphere: the closest approach to each region the UAV
    comes within range of, then evenly spaced steps at least r_s apart, ``n`` at most. Each k
    indexes the per-step arrays (``result.t[k]``, ``result.visible_points[k]``): the state
    after the last step, which has no time of its own, is never chosen."""
    pos = result.positions[:len(result.t)]
    r_s = result.config.sensor.range
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


def mark_start_and_targets(ax, scene, three_d: bool):
    start = np.asarray(scene.start, float)
    targets = np.atleast_2d(np.asarray(scene.targets, float))
    kw = {"depthshade": False} if three_d else {}
    ax.scatter(*start, s=40, marker="o", color="tab:green", label="start", **kw)
    ax.scatter(*targets.T, s=90, marker="*", color="tab:purple", label="targets", **kw)


def workspace_limits(ax, three_d: bool):
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
    """Dotted lines, labelled "target switch", at the switches inside the drawn times ``t``."""
    ts = result.config.nmpc.ts
    for n, k in enumerate(np.asarray(result.reached)[:-1]):
        if k >= 0 and len(t) and t[0] <= k * ts <= t[-1]:
            ax.axvline(k * ts, ls=":", color="gray", lw=1.0,
                       label="target switch" if n == 0 else None)


def _title(ax, what: str, result, t, t_range) -> None:
    """``what (metric distance[, zoom t0–t1 s])`` over the set-up (:func:`setup_label`)."""
    zoom = f", zoom {t[0]:.0f}–{t[-1]:.0f} s" if t_range is not None and len(t) else ""
    ax.set_title(f"{what} ({result.config.distance.metric} distance{zoom})\n"
                 f"{setup_label(result)}", fontsize="medium")


def setup_label(result) -> str:
    """The set-up a run flew, for a figure's title: the preset (``paper``, the printed one, or
    ``paper-timeline``) whose controller and avoidance parameters it flew, with its horizon;
    else just "N = …"."""
    from paper_repro.config import Config
    from paper_repro.presets import PRESETS

    cfg = result.config
    for name, preset in PRESETS.items():
        ref = preset.apply(Config())
        ref = dataclasses.replace(ref, distance=dataclasses.replace(
            ref.distance, metric=cfg.distance.metric))
        if (ref.nmpc, ref.barrier, ref.distance) == (cfg.nmpc, cfg.barrier, cfg.distance):
            printed = ", the printed set-up" if name == "paper" else ""
            return f"preset {name}{printed}, N = {cfg.nmpc.horizon}"
    return f"N = {cfg.nmpc.horizon}"


def steps_in(result, t_range) -> np.ndarray:
    """Indices of the steps with t in ``t_range`` (all steps when None)."""
    t = np.asarray(result.t, float)
    if t_range is None:
        return np.arange(len(t))
    t0, t1 = t_range
    k = np.flatnonzero((t >= t0) & (t <= t1))
    if len(k) == 0:
        raise ValueError(f"t_range {t_range!r} holds no step of the run ({t[0]:g}-{t[-1]:g} s)")
    return k

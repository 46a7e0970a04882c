"""Figures of the local map and the guide: one passage flown with and without them."""

from __future__ import annotations

import numpy as np

from paper_repro.plots.common import (
    AXIS_LABELS,
    CLOUD_COLOR,
    axes_column,
    axes_or_new,
    stride_indices,
)

ARM_COLOURS = {"paper": "tab:red", "map": "tab:orange", "map+guide": "tab:blue"}
"""A colour per arm of the ``guidance`` study."""


def plot_guided_passage(runs: dict, ax=None):
    """The passage seen from above: the clouds, each run's trajectory (``runs``: arm ->
    :class:`~paper_repro.sim.result.SimulationResult` of the same scene), where it ended
    (a cross when it did not complete), and, for a guided run, the set-points it was handed
    where they lie within the view (the others, tens of metres ahead, as arrows from the
    vehicle at the instant they were handed over)."""
    fig, ax = axes_or_new(ax, (7.0, 6.0))
    scene = next(iter(runs.values())).scene
    points = scene.all_points
    ax.scatter(points[:, 0], points[:, 1], s=3, color=CLOUD_COLOR, alpha=0.5, lw=0,
               label="point clouds")
    span = [points[:, :2].min(0) - 6.0, points[:, :2].max(0) + 6.0]
    for arm, r in runs.items():
        pos = r.positions[:, :2]
        idx = stride_indices(len(pos))
        colour = ARM_COLOURS.get(arm)
        ax.plot(pos[idx, 0], pos[idx, 1], color=colour, lw=1.4,
                label=f"{arm}: {r.outcome} after {r.steps * r.config.nmpc.ts:.0f} s")
        if not r.completed:
            ax.plot(*pos[-1], "x", color=colour, ms=10, mew=2)
        if r.set_points is not None:
            moved = np.flatnonzero(np.r_[True, np.any(np.diff(r.set_points, axis=0) != 0,
                                                      axis=1)])
            moved = moved[:: max(1, len(moved) // 40)]
            step = r.set_points[moved, :2] - r.x[moved, :2]
            ahead = step / np.maximum(np.linalg.norm(step, axis=1, keepdims=True), 1e-9)
            ax.quiver(r.x[moved, 0], r.x[moved, 1], ahead[:, 0], ahead[:, 1], color=colour,
                      alpha=0.6, scale=25, width=0.003,
                      label=f"{arm}: direction of the set-point handed over")
    ax.plot(*scene.start[:2], "o", color="tab:green", label="start")
    ax.set_xlim(span[0][0], span[1][0])
    ax.set_ylim(span[0][1], span[1][1])
    ax.set_aspect("equal")
    ax.set_xlabel(AXIS_LABELS[0])
    ax.set_ylabel(AXIS_LABELS[1])
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    return fig


def plot_guided_thrusts(runs: dict, axes=None):
    """Rotor 1's thrust (N) and the distance from the vehicle to its set-point (m), against
    time, for each run of ``runs`` (arm -> result); the set-point of an unguided run is the
    scene's target."""
    fig, (top, bottom) = axes_column(axes, 2, (8.0, 5.0))
    for arm, r in runs.items():
        colour = ARM_COLOURS.get(arm)
        idx = stride_indices(r.steps)
        top.plot(r.t[idx], r.u[idx, 0], color=colour, lw=0.9, label=arm)
        set_points = (r.set_points if r.set_points is not None
                      else np.asarray(r.targets)[r.target_index])
        gap = np.linalg.norm(set_points - r.positions[:-1], axis=1)
        bottom.plot(r.t[idx], gap[idx], color=colour, lw=0.9, label=arm)
    top.set_ylabel("f1 [N]")
    bottom.set_ylabel("‖y_t − y‖ [m]")
    bottom.set_xlabel("t [s]")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    top.legend(fontsize="small", frameon=False)
    return fig

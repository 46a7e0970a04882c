"""Animations of a flight."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from paper_repro.plots.common import CLOUD_COLOR, MAX_POINTS, draw_sphere, stride_indices
from paper_repro.plots.flight import mark_start_and_targets, workspace_limits

# --- animation ------------------------------------------------------------------------------

def animate_flight(result, scene, path, frames: int = 100, fps: int = 12, dpi: int = 72,
                   close_up: float = 5.0):
    """GIF of the flight: whole workspace (left) and a close-up around the UAV (right), with
    the LiDAR sphere and the points the controller was handed highlighted
    (:meth:`~paper_repro.sim.result.SimulationResult.scan`).

    Parameters
    ----------
    path : output file (``.gif``).  frames : number of frames, evenly spaced in time.
    fps : frames per second of the GIF.  dpi : resolution (the GIF is 9 × 4.5 in).
    close_up : half-width of the close-up view, m.

    Returns the path written.
    """
    if not (isinstance(frames, int) and frames >= 1):
        raise ValueError(f"frames must be an integer >= 1, got {frames!r}")
    pos = result.positions
    r_s = result.config.sensor.range
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
    mark_start_and_targets(axes[0], scene, three_d=True)
    workspace_limits(axes[0], three_d=True)
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
            artists["dynamic"].append(draw_sphere(ax, p, r_s, alpha=0.15))
            artists["dynamic"].append(ax.scatter(*p, s=18, color="black", depthshade=False))
        k_log = min(k, len(result.t) - 1)  # the state after the last step has no scan
        seen = [v for v in result.scan(k_log) if len(v)]
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
        ax.set_title(f"t = {k * result.config.nmpc.ts:6.1f} s, {n_seen} points in view, "
                     f"clearance {result.clearance[k_log]:.2f} m", fontsize="small")
        return []

    return save_animation(fig, update, steps, path, fps, dpi)


def save_animation(fig, update, frames, path, fps: int, dpi: int) -> Path:
    """Render ``update`` over ``frames`` into a GIF at ``path`` (folders made), close ``fig``."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    anim = FuncAnimation(fig, update, frames=frames, blit=False)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(path, writer=PillowWriter(fps=fps), dpi=dpi)
    plt.close(fig)
    return path

"""What the world knows and no sensor does: where each region is at time t, how fast it
moves, and how far the vehicle truly is from the nearest point.

The closed loop measures its clearance here, and the ``oracle`` prediction reads the regions'
true velocities here. The LiDAR (:mod:`paper_repro.world.lidar`) sees only the points within
its range, where :func:`region_offsets` puts them.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from paper_repro.validation import require_time
from paper_repro.world.scene import Scene


def region_offsets(motions, count: int, dim: int, t: float = 0.0) -> np.ndarray:
    """(count, p) m: each region's offset c_i(t) from its stored cloud at time ``t`` (s),
    zero for a static region. ``motions``: ``None`` or one
    :class:`~paper_repro.world.motion.Motion` or ``None`` per region (as
    :attr:`Scene.motions`)."""
    shifts = np.zeros((count, dim))
    if motions is not None:
        for i, m in enumerate(motions):
            if m is not None:
                shifts[i] = m.offset(t)
    return shifts


def region_velocities(motions, count: int, dim: int, t: float = 0.0) -> list[np.ndarray]:
    """The regions' true velocities at time ``t`` (s): one (p,) array per region, m/s (zeros
    for a static region). What the ``oracle`` prediction hands the controller."""
    require_time(t)
    if motions is None:
        return [np.zeros(dim) for _ in range(count)]
    return [np.zeros(dim) if m is None else m.velocity(t) for m in motions]


def scene_velocities(scene: Scene, t: float = 0.0) -> list[np.ndarray]:
    """:func:`region_velocities` of a scene's regions."""
    return region_velocities(scene.motions, len(scene.clouds), scene.dim, t)


class TrueClearance:
    """Distance (m) from a position to the nearest cloud point where it is at time t: one
    KD-tree over every point for a static scene, one per region queried at y − c_i(t) for a
    moving one; ``inf`` for a scene without points."""

    def __init__(self, scene: Scene):
        self.motions = scene.motions
        if self.motions is None:
            points = scene.all_points
            self.trees = [cKDTree(points)] if len(points) else []
        else:
            self.trees = [cKDTree(c) if len(c) else None for c in scene.clouds]

    def along(self, y: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The distances of a flight, (K,) m: positions ``y`` (K, p) at times ``t`` (K,) s,
        in one query per tree; NaN where the position is not finite (a diverged plant)."""
        out = np.full(len(y), np.inf)
        finite = np.isfinite(y).all(axis=1)
        y, t = y[finite], np.asarray(t)[finite]
        if len(y) and self.motions is None and self.trees:
            out[finite] = self.trees[0].query(y)[0]
        elif len(y) and self.motions is not None:
            near = out[finite]
            for tree, m in zip(self.trees, self.motions, strict=True):
                if tree is not None:
                    at = y if m is None else y - np.array([m.offset(tk) for tk in t])
                    np.minimum(near, tree.query(at)[0], out=near)
            out[finite] = near
        out[~finite] = np.nan
        return out

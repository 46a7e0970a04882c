"""A planar scene for a ground robot: an L-shaped wall of points, seen through a 2-D LiDAR.

The scene is a :class:`~paper_repro.world.scene.Scene` whose positions are 2-D (p = 2): its
one region holds given points (no solid shape), and :func:`~paper_repro.sim.loop.simulate`
flies a planar vehicle through it with the same closed loop as the quadrotor.
"""

from __future__ import annotations

import numpy as np

from paper_repro.world.scene import Region, Scene


def planar_scene(spacing: float = 0.1) -> Scene:
    """An L-shaped wall between start (0, −0.9) m and target (9, −0.9) m: one arm (0.3 m
    thick) crosses the straight line 0.6 m from its lower end, the other runs along the far
    side, so the way round is below. The Euclidean distance's gradient points straight back
    along the line, and the robot stops in front of the wall; the smoothed one leans towards
    the cloud's centroid and leads round. Points lie every ``spacing`` m."""
    if not (isinstance(spacing, (int, float)) and np.isfinite(spacing) and 0 < spacing <= 1):
        raise ValueError(f"spacing must be a finite number in (0, 1] (m), got {spacing!r}")
    arm_across = _segment((4.0, -1.5), (4.0, 1.2), spacing)
    arm_along = _segment((4.0, 1.2), (6.5, 1.2), spacing)
    inner = _segment((4.3, -1.5), (4.3, 0.9), spacing)  # a 0.3 m thick wall
    cloud = np.unique(np.round(np.vstack([arm_across, arm_along, inner]), 9), axis=0)
    return Scene("planar", (Region("L-wall", None),), start=(0.0, -0.9),
                 targets=((9.0, -0.9),), clouds=(cloud,))


def _segment(a, b, spacing: float) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1)
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)

"""A planar scene for a ground robot: an L-shaped wall of points, and a 2-D LiDAR."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from paper_repro.problem.ocp import Controller, NMPCSolution
from paper_repro.vehicles.base import rk4


@dataclass(frozen=True)
class PlanarScene:
    """A planar scene: ``cloud`` (m, 2) points, m; ``start`` (3,) state; ``target`` (2,) m."""

    cloud: np.ndarray
    start: np.ndarray
    target: np.ndarray


def planar_scene(spacing: float = 0.1) -> PlanarScene:
    """An L-shaped wall between start and target: one arm (0.3 m thick) crosses the straight
    line 0.6 m from its lower end, the other runs along the far side, so the way round is
    below. The Euclidean distance's gradient points straight back along the line, and the
    robot stops in front of the wall; the smoothed one leans towards the cloud's centroid and
    leads round. Points lie every ``spacing`` m."""
    arm_across = _segment((4.0, -1.5), (4.0, 1.2), spacing)
    arm_along = _segment((4.0, 1.2), (6.5, 1.2), spacing)
    inner = _segment((4.3, -1.5), (4.3, 0.9), spacing)  # a 0.3 m thick wall
    cloud = np.unique(np.round(np.vstack([arm_across, arm_along, inner]), 9), axis=0)
    return PlanarScene(cloud, np.array([0.0, -0.9, 0.0]), np.array([9.0, -0.9]))


def planar_scan(tree: cKDTree, cloud: np.ndarray, position, lidar_range: float = 3.0):
    """What a 2-D LiDAR at ``position`` (2,) sees: ``[points within lidar_range]`` (one
    region)."""
    idx = tree.query_ball_point(np.asarray(position, float), lidar_range)
    return [cloud[np.sort(np.asarray(idx, dtype=int))]]


@dataclass
class PlanarRun:
    """A closed loop of the ground robot.

    Attributes
    ----------
    t : (K+1,) s.  x : (K+1, 3) states.  u : (K, 2) applied inputs.
    solve_time : (K,) s.  success : (K,) bool.  clearance : (K+1,) m, to the nearest point.
    visible : (K,) points in view.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    solve_time: np.ndarray
    success: np.ndarray
    clearance: np.ndarray
    visible: np.ndarray


def fly(controller: Controller, scene: PlanarScene | None = None, steps: int = 500,
        lidar_range: float = 3.0, substeps: int = 10) -> PlanarRun:
    """The closed loop: scan, solve, apply the first input for T_s, integrate the unicycle
    (RK4, ``substeps`` per T_s). A failed solve applies the previous plan, shifted."""
    for name, value in (("steps", steps), ("substeps", substeps)):
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    if not (isinstance(lidar_range, (int, float)) and np.isfinite(lidar_range)
            and lidar_range > 0):
        raise ValueError(f"lidar_range must be a finite number > 0 (m), got {lidar_range!r}")
    scene = scene or planar_scene()
    ocp = controller.ocp
    ts = ocp.config.nmpc.ts
    plant = rk4(ocp.model.dynamics, ts, substeps)
    tree = cKDTree(scene.cloud)
    x = np.array(scene.start, float)
    xs, us, times, oks, seen = [x], [], [], [], []
    controller.reset()
    plan: NMPCSolution | None = None
    for _ in range(steps):
        visible = planar_scan(tree, scene.cloud, x[:2], lidar_range)
        start = time.perf_counter()
        sol = controller.solve(x, scene.target, visible, previous=plan)
        times.append(time.perf_counter() - start)
        oks.append(sol.success)
        plan = sol if sol.success else (plan.shifted() if plan is not None else sol)
        u = plan.u[0]
        x = np.asarray(plant(x, u), float).ravel()
        xs.append(x)
        us.append(u)
        seen.append(len(visible[0]))
    x = np.array(xs)
    clear, _ = tree.query(x[:, :2])
    return PlanarRun(np.arange(len(x)) * ts, x, np.array(us), np.array(times), np.array(oks),
                     clear, np.array(seen))


def _segment(a, b, spacing: float) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1)
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)

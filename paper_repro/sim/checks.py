"""Checks of a mission before anything is built or flown, and the unsafe set-ups it reports.

Two kinds of problem, kept apart:

* **Inconsistent** (:func:`check_setup` raises ``ValueError``): the mission cannot be flown as
  posed. The start lies outside the admissible state set 𝒳 (the UAV starts at rest, so its
  position must lie in the position bounds ``quadrotor.state_lower[:3]``,
  ``quadrotor.state_upper[:3]``; outside them every QP is infeasible), or a target lies outside
  the workspace (the same position bounds). A target outside the workspace is an error, not
  clamped: a clamped target is a different mission, and one the UAV may still never reach within
  the tolerance, so the run would silently spend ``max_steps`` and report a target as missed.
* **Hazardous** (:func:`setup_hazards` reports, nothing raises): the mission can be flown but
  starts or ends somewhere unsafe: inside the unsafe set of the barrier (D < d_min for the
  configured metric, eq. 17, computed as the controller would see it: per region, from the
  points within the LiDAR range), or within the rotor radius (``quadrotor.arm``) of a cloud
  point, or at a target that the artificial equilibrium cannot bring within ``tolerance``
  (a target farther than that from λ(𝒳)). Such set-ups are legitimate studies (what does the
  barrier do when it starts violated?), so they are allowed, and must be reported.

:func:`paper_repro.sim.loop.simulate` calls :func:`check_setup` first, before building the
scene's LiDAR or a controller, then stores :func:`setup_hazards` in the result and warns with
:class:`SetupHazardWarning` for each entry of its ``warnings``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from paper_repro.config import Config, relaxed_box
from paper_repro.problem import distance as dist
from paper_repro.vehicles.base import VehicleModel
from paper_repro.world.lidar import Lidar
from paper_repro.world.scene import Scene

_AXES = "xyz"


class SetupHazardWarning(UserWarning):
    """A mission flown from or to an unsafe set-up (see :func:`setup_hazards`)."""


def check_setup(config: Config, scene: Scene, model: VehicleModel | None = None) -> None:
    """Raise ``ValueError`` (one line naming the offending field and its accepted range) when
    the mission is inconsistent: the start outside the admissible state set, or a target
    outside the workspace, or a passage without a finish line.

    Parameters
    ----------
    config : the run's :class:`~paper_repro.config.Config`; the admissible positions are
        ``[quadrotor.state_lower[:3], quadrotor.state_upper[:3]]``, m (closed box).
    scene : the :class:`~paper_repro.world.scene.Scene` to fly.
    model : the vehicle flown (default: the quadrotor): the admissible positions are its box
        𝒳 at its ``position`` states.
    """
    if not isinstance(config, Config):
        raise ValueError(f"config must be a Config, got {type(config).__name__}")
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a Scene, got {type(scene).__name__}")
    lower, upper, label = _position_box(config, model)
    if len(lower) != scene.dim:
        raise ValueError(f"scene {scene.name!r} is {scene.dim}-D and the vehicle has "
                         f"{len(lower)} position states")
    _require_inside("scene.start", np.asarray(scene.start, float), lower, upper,
                    "the admissible state set", label)
    for k, target in enumerate(_targets(scene)):
        _require_inside(f"scene.targets[{k}]", target, lower, upper, "the workspace", label)
    if getattr(config.simulation, "kind", "mission") == "passage" and scene.finish is None:
        raise ValueError(f"simulation.kind 'passage' needs a scene with a finish line, and "
                         f"scene {scene.name!r} has none (use kind 'mission')")


def setup_hazards(config: Config, scene: Scene, model: VehicleModel | None = None) -> dict:
    """Unsafe set-ups that are allowed but must be reported (see the module docstring).

    A point y is *unsafe* when, for some region, the barrier distance D(y) (the smoothed
    D_{η,σ} or ½·d², as ``distance.metric``) computed from that region's points within
    ``sensor.range`` is below ``barrier.d_min``, or when its clearance to the nearest
    cloud point is below the rotor radius ``quadrotor.arm``.

    Returns
    -------
    dict, JSON-able:
        ``start_unsafe`` : bool.
        ``start_clearance_m`` : m, distance from the start to the nearest cloud point
        (``None`` for a scene without points).
        ``start_distance_m2`` : m², the smallest D over the regions in range (``None`` when
        none is in range).
        ``targets_unsafe``, ``target_clearance_m``, ``target_distance_m2`` : the same, one
        entry per target.
        ``targets_unreachable`` : per target, True when it lies farther than
        ``simulation.tolerance`` from λ(𝒳), where the artificial equilibrium must rest.
        ``warnings`` : list of one-line messages, one per hazard (empty when none).
    """
    check_setup(config, scene, model)
    points = scene.all_points
    tree = cKDTree(points) if len(points) else None
    lidar = Lidar(list(scene.clouds), config.sensor.range, dim=scene.dim)
    arm, d_min = config.quadrotor.arm, config.barrier.d_min

    def assess(y):
        clear = None if tree is None else float(tree.query(y)[0])
        values = [_barrier_distance(y, v, config) for v in lidar.scan(y) if len(v)]
        d = min(values) if values else None
        unsafe = (d is not None and d < d_min) or (clear is not None and clear < arm)
        return bool(unsafe), clear, d

    warnings = []
    start = np.asarray(scene.start, float)
    start_unsafe, start_clear, start_d = assess(start)
    if start_unsafe:
        warnings.append(f"start {start.tolist()} is unsafe: " + _why(start_clear, start_d,
                                                                      config))
    lower, upper, _ = _position_box(config, model)
    xl, xu = relaxed_box(lower, upper, config.nmpc.lam)
    targets_unsafe, target_clear, target_d, unreachable = [], [], [], []
    for k, target in enumerate(_targets(scene)):
        unsafe, clear, d = assess(target)
        gap = float(np.linalg.norm(target - np.clip(target, xl, xu)))
        far = gap > config.simulation.tolerance
        targets_unsafe.append(unsafe)
        target_clear.append(clear)
        target_d.append(d)
        unreachable.append(bool(far))
        if unsafe:
            warnings.append(f"target {k} {target.tolist()} is unsafe: "
                            + _why(clear, d, config))
        if far:
            warnings.append(
                f"target {k} {target.tolist()} lies {gap:.3g} m from λ(𝒳) (nmpc.lam = "
                f"{config.nmpc.lam}), more than the tolerance {config.simulation.tolerance} m: "
                "it cannot be reached")
    return {"start_unsafe": start_unsafe, "start_clearance_m": start_clear,
            "start_distance_m2": start_d, "targets_unsafe": targets_unsafe,
            "target_clearance_m": target_clear, "target_distance_m2": target_d,
            "targets_unreachable": unreachable, "warnings": warnings}


def _require_inside(name: str, point: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    what: str, label: str) -> None:
    for i in range(len(point)):
        if not lower[i] <= point[i] <= upper[i]:
            raise ValueError(
                f"{name}[{i}] ({_AXES[i]}) must lie in [{lower[i]:g}, {upper[i]:g}] m "
                f"({label}_lower[{i}], {label}_upper[{i}]: {what}), got {point[i]:g}")


def _position_box(config: Config, model: VehicleModel | None):
    """(lower, upper, name) of the admissible positions: the quadrotor's box 𝒳 at
    (x, y, z), or a model's box 𝒳 at its ``position`` states."""
    if model is None or model.name == "quadrotor":
        return (np.asarray(config.quadrotor.state_lower[:3], float),
                np.asarray(config.quadrotor.state_upper[:3], float), "quadrotor.state")
    index = list(model.position)
    return (np.asarray(model.state_lower, float)[index],
            np.asarray(model.state_upper, float)[index], f"{model.name}.state")


def _targets(scene: Scene) -> np.ndarray:
    return np.atleast_2d(np.asarray(scene.targets, float))


def _barrier_distance(y: np.ndarray, cloud: np.ndarray, config: Config) -> float:
    """D(y) of one region's visible points, in the configured metric (m²)."""
    d = config.distance
    if d.metric == "smooth":
        return float(dist.smooth_distance(y, cloud, d.eta, d.sigma))
    return float(dist.euclidean_distance(y, cloud))


def _why(clearance, d, config: Config) -> str:
    reasons = []
    if d is not None and d < config.barrier.d_min:
        reasons.append(f"D = {d:.3g} m² < d_min = {config.barrier.d_min:g} m² "
                       f"({config.distance.metric} metric)")
    if clearance is not None and clearance < config.quadrotor.arm:
        reasons.append(f"clearance {clearance:.3g} m < rotor radius "
                       f"{config.quadrotor.arm:g} m")
    return "; ".join(reasons)

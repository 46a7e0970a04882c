"""Perception: what the controller is given of the world at each instant.

At step k (time t = k·T_s), in this order:

1. the LiDAR scans the regions where they are at t (:class:`~paper_repro.world.lidar.Lidar`);
2. a scan fault, if one is injected, acts on the scan;
3. non-finite returns are dropped and counted (:func:`~paper_repro.problem.scan.drop_non_finite`);
4. the predictor tells the regions' velocities: none with the paper's ``static`` prediction,
   the true ones (``oracle``, :mod:`paper_repro.world.truth`), or a Kalman filter's estimates
   from the scans (``kalman``, :class:`~paper_repro.world.tracking.RegionTracker`);
5. with a local map (``sensor.map_voxel`` > 0), the map takes the scan and the controller
   reads the map's points within range instead; a region predicted to move faster than
   :data:`~paper_repro.world.local_map.MAPPED_SPEED` stays out of the map and is read from
   the scan.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from paper_repro.config import Config
from paper_repro.problem.scan import drop_non_finite
from paper_repro.world.lidar import Lidar
from paper_repro.world.local_map import MAPPED_SPEED, VoxelMap
from paper_repro.world.scene import Scene
from paper_repro.world.tracking import RegionTracker
from paper_repro.world.truth import region_velocities


class Percept(NamedTuple):
    """What the controller is given at one instant.

    Attributes
    ----------
    visible : one (k_i, p) array per region, m: the points the controller is handed.
    velocities : one (p,) array per region, m/s, or ``None`` (the ``static`` prediction).
    dropped : the non-finite returns dropped from the scan.
    """

    visible: Sequence[np.ndarray]
    velocities: list | None
    dropped: int


class ScanLog:
    """Every scan the controller was handed, in a compact form: each distinct scan once, and
    for each step the index of its scan. A vehicle among static regions mostly sees the same
    points from one step to the next, so most steps add one integer.

    :meth:`arrays` gives what a :class:`~paper_repro.sim.result.SimulationResult` stores:
    ``scan_points`` (M, p) m, the points of the distinct scans one after the other, region by
    region; ``scan_sizes`` (S, n_regions) the number of points of each region in each distinct
    scan; ``scan_index`` (K,) the distinct scan of each step.
    """

    def __init__(self, regions: int, dim: int):
        self.regions, self.dim = regions, dim
        self._points: list[np.ndarray] = []
        self._sizes: list[list[int]] = []
        self._index: list[int] = []
        self._last: tuple | None = None

    def add(self, visible: Sequence[np.ndarray]) -> None:
        """Log the scan of the next step: one (k_i, p) array per region."""
        key = tuple(np.ascontiguousarray(v, float).tobytes() for v in visible)
        if key != self._last:
            self._last = key
            self._sizes.append([len(v) for v in visible])
            # copies: a sensor or a map may hand out the same arrays again, changed
            self._points.extend(np.array(v, float).reshape(-1, self.dim) for v in visible)
        self._index.append(len(self._sizes) - 1)

    def arrays(self) -> dict:
        """``scan_points``, ``scan_sizes`` and ``scan_index`` (class docstring)."""
        points = (np.concatenate(self._points) if self._points
                  else np.empty((0, self.dim)))
        sizes = np.array(self._sizes, dtype=np.int32).reshape(len(self._sizes), self.regions)
        return {"scan_points": points, "scan_sizes": sizes,
                "scan_index": np.asarray(self._index, dtype=np.int32)}


class Perception:
    """The sensor, the predictor and the local map of one flight (module docstring).

    Parameters
    ----------
    config : the run's configuration: ``sensor`` (range, noise, map), ``nmpc.prediction``,
        ``tracker`` and ``nmpc.ts``.
    scene : the scene flown.
    scan_fault : ``(k, visible) -> visible``, applied to the scan of step k, or ``None``.

    Attributes
    ----------
    local_map : the :class:`~paper_repro.world.local_map.VoxelMap`, or ``None`` (the paper).
    scans : the :class:`ScanLog` of every scan handed to the controller, one per call of
        :meth:`sense`.
    """

    def __init__(self, config: Config, scene: Scene, scan_fault: Callable | None = None):
        self.dim = scene.dim
        self.lidar = Lidar(scene.clouds, config.sensor.range, noise=config.sensor,
                           motions=scene.motions, dim=scene.dim)
        self.scan_fault = scan_fault
        self.predict = _predictor(config, scene)
        self.read_map, self.local_map = _map_reader(config, scene)
        self.scans = ScanLog(len(scene.clouds), scene.dim)

    def sense(self, k: int, t: float, y: np.ndarray) -> Percept:
        """What the controller is given at step ``k``, time ``t`` (s), with the vehicle's
        output at ``y`` (p,) m."""
        visible = self.lidar.scan(y, t)
        if self.scan_fault is not None:
            visible = self.scan_fault(k, visible)
        visible, dropped = drop_non_finite(visible, self.dim)
        velocities = self.predict(visible, t)  # the tracker reads the raw scan
        if self.read_map is not None:
            visible = self.read_map(visible, y, t, velocities)
        self.scans.add(visible)
        return Percept(visible, velocities, dropped)


def _predictor(config: Config, scene: Scene):
    """``(visible, t) -> velocities``: what the controller is told of the regions' motion,
    one (p,) m/s per region, or ``None`` for ``"static"`` (the paper)."""
    prediction = config.nmpc.prediction
    if prediction == "static":
        return lambda visible, t: None
    if prediction == "oracle":
        motions, count, dim = scene.motions, len(scene.clouds), scene.dim
        return lambda visible, t: region_velocities(motions, count, dim, t)
    tracker = config.tracker
    return RegionTracker(config.nmpc.ts, scene.dim, tracker.accel_noise,
                         tracker.centroid_noise, tracker.forget_after,
                         velocity_prior=tracker.velocity_prior,
                         gate_probability=tracker.gate_probability,
                         subset_jump=tracker.subset_jump).update


def _map_reader(config: Config, scene: Scene):
    """What the controller reads instead of the raw scan when ``sensor.map_voxel`` > 0: a
    function (visible, y, t, velocities) -> visible that updates a
    :class:`~paper_repro.world.local_map.VoxelMap` with the scan and returns its points within
    r_s, and the map. (None, None) when the map is off (the paper)."""
    if config.sensor.map_voxel == 0:
        return None, None
    if scene.dim != 3:
        raise ValueError(f"sensor.map_voxel needs a 3-D scene; {scene.name!r} is planar "
                         f"(p = {scene.dim}): set map_voxel = 0")
    local_map = VoxelMap(voxel=config.sensor.map_voxel, sensing_range=config.sensor.range)
    n = len(scene.clouds)

    def read(visible, y, t, velocities):
        moving = ([False] * n if velocities is None
                  else [float(np.linalg.norm(v)) > MAPPED_SPEED for v in velocities])
        local_map.update(visible, y, t, exclude=moving)
        mapped = local_map.regions(y, config.sensor.range, n)
        return [visible[i] if moving[i] else mapped[i] for i in range(n)]

    return read, local_map

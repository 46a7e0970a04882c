"""Workspace, obstacle regions sampled as Halton point clouds, and the virtual LiDAR.

A region is a solid shape (boxes, cylinders, and their unions and differences, so nonconvex
shapes such as an L-wall or a U-channel are easy) filled with a scrambled, seeded Halton
sequence (``scipy.stats.qmc.Halton``) at a given density, as in Section V. A
:class:`Scene` holds the regions' clouds, the start and the sequence of targets; a
:class:`Lidar` returns, per region, the points inside a sphere of radius r_s around the UAV.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import qmc

from .config import SensorParams

WORKSPACE_LOWER = np.array([-25.0, -25.0, 0.0])
WORKSPACE_UPPER = np.array([25.0, 25.0, 25.0])


# --- shapes ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Box:
    """Axis-aligned box. ``center`` (3,) and ``size`` (3,) edge lengths, m."""

    center: tuple[float, float, float]
    size: tuple[float, float, float]

    def __post_init__(self):
        _require_point("Box.center", self.center)
        _require_point("Box.size", self.size, positive=True)

    def contains(self, p: np.ndarray) -> np.ndarray:
        half = np.asarray(self.size) / 2
        return np.all(np.abs(p - np.asarray(self.center)) <= half, axis=-1)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        c, half = np.asarray(self.center, float), np.asarray(self.size, float) / 2
        return c - half, c + half


@dataclass(frozen=True)
class Cylinder:
    """Vertical cylinder: ``base`` (3,) centre of the bottom disc, ``radius`` and ``height``, m."""

    base: tuple[float, float, float]
    radius: float
    height: float

    def __post_init__(self):
        _require_point("Cylinder.base", self.base)
        for name in ("radius", "height"):
            value = getattr(self, name)
            if not (_is_number(value) and math.isfinite(value) and value > 0):
                raise ValueError(f"Cylinder.{name} must be a finite number > 0 (m), got "
                                 f"{value!r}")

    def contains(self, p: np.ndarray) -> np.ndarray:
        b = np.asarray(self.base)
        radial = np.sum((p[..., :2] - b[:2]) ** 2, axis=-1) <= self.radius**2
        return radial & (p[..., 2] >= b[2]) & (p[..., 2] <= b[2] + self.height)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        b = np.asarray(self.base, float)
        r = self.radius
        return b - [r, r, 0.0], b + [r, r, self.height]


@dataclass(frozen=True)
class Union:
    """Points in any of ``parts`` (a non-empty tuple of shapes)."""

    parts: tuple

    def __post_init__(self):
        if not (isinstance(self.parts, (tuple, list)) and len(self.parts) > 0):
            raise ValueError(f"Union.parts must be a non-empty tuple of shapes, got "
                             f"{self.parts!r}")
        for i, part in enumerate(self.parts):
            _require_shape(f"Union.parts[{i}]", part)

    def contains(self, p: np.ndarray) -> np.ndarray:
        return np.any([s.contains(p) for s in self.parts], axis=0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = zip(*(s.bounds() for s in self.parts))
        return np.min(lo, axis=0), np.max(hi, axis=0)


@dataclass(frozen=True)
class Difference:
    """Points in ``outer`` but not in ``inner`` (e.g. a U-channel = box minus box)."""

    outer: object
    inner: object

    def __post_init__(self):
        _require_shape("Difference.outer", self.outer)
        _require_shape("Difference.inner", self.inner)

    def contains(self, p: np.ndarray) -> np.ndarray:
        return self.outer.contains(p) & ~self.inner.contains(p)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.outer.bounds()


# --- regions and scenes ---------------------------------------------------------------------

@dataclass(frozen=True)
class Region:
    """A nonfeasible region: a ``shape`` sampled at ``density`` points per m³."""

    name: str
    shape: object
    density: float = 3.0

    def __post_init__(self):
        if not (isinstance(self.name, str) and self.name):
            raise ValueError(f"Region.name must be a non-empty str, got {self.name!r}")
        _require_shape(f"Region {self.name!r} shape", self.shape)
        if not (_is_number(self.density) and math.isfinite(self.density) and self.density > 0):
            raise ValueError(
                f"density must be a finite number > 0 (points/m³), got {self.density!r}")


def halton_cloud(shape, density: float, seed: int) -> np.ndarray:
    """Fill ``shape`` with scrambled Halton points (seeded, reproducible).

    The sequence is drawn in the shape's bounding box, ``density``·volume(box) points, and
    the points outside the shape are dropped, so the density inside is ``density`` for any
    shape. Returns (m, 3), m.
    """
    if not (_is_number(density) and math.isfinite(density) and density > 0):
        raise ValueError(f"density must be a finite number > 0 (points/m³), got {density!r}")
    _require_seed("seed", seed)
    lo, hi = shape.bounds()
    n = max(1, int(round(density * float(np.prod(hi - lo)))))
    sample = qmc.Halton(d=3, scramble=True, seed=seed).random(n)
    points = qmc.scale(sample, lo, hi)
    return points[shape.contains(points)]


@dataclass(frozen=True)
class Scene:
    """Regions with their clouds, a start position and targets to visit in order.

    Attributes
    ----------
    name : str.
    regions : tuple of :class:`Region`.
    start : (3,) initial position, m.
    targets : (k, 3) set-points y_t, m, visited in sequence.
    seed : base seed of the Halton clouds (region i uses ``seed + i``).
    finish : ``None``, or a finish line ``(point, direction)`` (each (3,), m and unit vector)
        for a *passage*: the run ends once ``(y − point)·direction ≥ 0``.
    clouds : tuple of (m_i, 3) arrays, m. Sampled from the regions when omitted; given when a
        scene is rebuilt from a saved result, so that a run redraws against its own points
        whatever the generators do later.
    """

    name: str
    regions: tuple
    start: tuple
    targets: tuple
    seed: int = 7
    finish: tuple | None = None
    clouds: tuple | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if not (isinstance(self.name, str) and self.name):
            raise ValueError(f"Scene.name must be a non-empty str, got {self.name!r}")
        if not (isinstance(self.regions, (tuple, list))
                and all(isinstance(r, Region) for r in self.regions)):
            raise ValueError(f"regions must be a tuple of Region, got {self.regions!r}")
        _require_seed("seed", self.seed)
        start = np.asarray(self.start, float)
        targets = np.asarray(self.targets, float)
        if targets.ndim == 1:
            targets = targets[None]
        for label, pts in (("start", start[None]), ("targets", targets)):
            if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
                raise ValueError(f"{label} must be finite 3-D positions, got shape {pts.shape}")
        if len(targets) == 0:
            raise ValueError("targets must hold at least one 3-D position")
        if self.finish is not None:
            point, direction = (np.asarray(v, float) for v in self.finish)
            if point.shape != (3,) or direction.shape != (3,) or not (
                    np.all(np.isfinite(point)) and np.isclose(np.linalg.norm(direction), 1.0)):
                raise ValueError("finish must be (point (3,), unit direction (3,)), got "
                                 f"{self.finish!r}")
        if self.clouds is None:
            clouds = tuple(halton_cloud(r.shape, r.density, self.seed + i)
                           for i, r in enumerate(self.regions))
        else:
            if len(self.clouds) != len(self.regions):
                raise ValueError(f"clouds must hold one (m, 3) array per region "
                                 f"({len(self.regions)}), got {len(self.clouds)}")
            clouds = tuple(_cloud_array(f"clouds[{i}]", c) for i, c in enumerate(self.clouds))
        for r, c in zip(self.regions, clouds, strict=True):
            if len(c) == 0:
                raise ValueError(f"region {r.name!r} holds no point at density {r.density}")
        object.__setattr__(self, "clouds", clouds)

    @property
    def all_points(self) -> np.ndarray:
        """(Σm_i, 3) every point of every region."""
        return np.concatenate(self.clouds) if self.clouds else np.zeros((0, 3))

    def fingerprint(self) -> str:
        """SHA-256 (hex) of the start, the targets, the finish line and every cloud point:
        two scenes with the same fingerprint are flown identically."""
        digest = hashlib.sha256()
        finish = np.zeros((0, 3)) if self.finish is None else np.asarray(self.finish, float)
        for block in (self.start, self.targets, finish, *self.clouds):
            digest.update(np.ascontiguousarray(block, dtype=np.float64).tobytes())
        return digest.hexdigest()

    def to_dict(self) -> dict:
        """JSON-able description (regions as shape trees); the clouds are stored apart, as
        arrays (see :meth:`from_dict`)."""
        return {"name": self.name, "seed": int(self.seed),
                "start": [float(v) for v in self.start],
                "targets": np.atleast_2d(np.asarray(self.targets, float)).tolist(),
                "finish": None if self.finish is None else
                [np.asarray(v, float).tolist() for v in self.finish],
                "regions": [{"name": r.name, "density": r.density,
                             "shape": shape_to_dict(r.shape)} for r in self.regions],
                "fingerprint": self.fingerprint()}

    @classmethod
    def from_dict(cls, data: dict, clouds=None) -> Scene:
        """Rebuild a scene from :meth:`to_dict`; with ``clouds`` (one (m_i, 3) array per
        region) the points are taken as stored, and the stored fingerprint must match."""
        regions = tuple(Region(r["name"], shape_from_dict(r["shape"]), r["density"])
                        for r in data["regions"])
        finish = None if data.get("finish") is None else tuple(
            tuple(v) for v in data["finish"])
        scene = cls(data["name"], regions, tuple(data["start"]),
                    tuple(tuple(t) for t in data["targets"]), int(data["seed"]), finish,
                    None if clouds is None else tuple(clouds))
        stored = data.get("fingerprint")
        if stored is not None and clouds is not None and scene.fingerprint() != stored:
            raise ValueError(f"scene {scene.name!r}: the stored clouds do not match the stored "
                             "fingerprint (the result files are inconsistent)")
        return scene


def shape_to_dict(shape) -> dict:
    """A shape tree (Box, Cylinder, Union, Difference) as nested JSON-able dicts."""
    if isinstance(shape, Union):
        return {"type": "Union", "parts": [shape_to_dict(s) for s in shape.parts]}
    if isinstance(shape, Difference):
        return {"type": "Difference", "outer": shape_to_dict(shape.outer),
                "inner": shape_to_dict(shape.inner)}
    if isinstance(shape, (Box, Cylinder)):
        return {"type": type(shape).__name__,
                **{k: (list(v) if isinstance(v, tuple) else v)
                   for k, v in dataclasses.asdict(shape).items()}}
    raise TypeError(f"shape must be a Box, Cylinder, Union or Difference, got {shape!r}")


def shape_from_dict(data: dict):
    """Inverse of :func:`shape_to_dict`."""
    kind = data.get("type")
    if kind == "Union":
        return Union(tuple(shape_from_dict(s) for s in data["parts"]))
    if kind == "Difference":
        return Difference(shape_from_dict(data["outer"]), shape_from_dict(data["inner"]))
    if kind == "Box":
        return Box(tuple(data["center"]), tuple(data["size"]))
    if kind == "Cylinder":
        return Cylinder(tuple(data["base"]), data["radius"], data["height"])
    raise ValueError(f"shape type must be Box, Cylinder, Union or Difference, got {kind!r}")


def _is_number(value) -> bool:
    return (isinstance(value, (int, float, np.floating, np.integer))
            and not isinstance(value, (bool, np.bool_)))


def _require_point(name: str, value, positive: bool = False) -> None:
    """Three finite numbers (each > 0 when ``positive``), given as a tuple or list."""
    ok = (isinstance(value, (tuple, list, np.ndarray)) and np.shape(value) == (3,)
          and all(_is_number(v) and math.isfinite(v) and (v > 0 or not positive)
                  for v in value))
    if not ok:
        what = "finite numbers > 0 (m)" if positive else "finite numbers (m)"
        raise ValueError(f"{name} must be 3 {what}, got {value!r}")


def _require_shape(name: str, shape) -> None:
    if not isinstance(shape, (Box, Cylinder, Union, Difference)):
        raise ValueError(f"{name} must be a Box, Cylinder, Union or Difference, got {shape!r}")


def _require_seed(name: str, seed) -> None:
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_))
            and seed >= 0):
        raise ValueError(f"{name} must be an integer >= 0, got {seed!r}")


def _cloud_array(name: str, cloud, allow_empty: bool = False) -> np.ndarray:
    """``cloud`` as a float (m, 3) array, checked (never reshaped)."""
    try:
        arr = np.asarray(cloud, float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (m, 3) array of points, got "
                         f"{type(cloud).__name__}") from None
    if arr.ndim != 2 or arr.shape[1] != 3 or (arr.shape[0] == 0 and not allow_empty):
        raise ValueError(f"{name} must be an (m, 3) array of points (m ≥ "
                         f"{0 if allow_empty else 1}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        raise ValueError(f"{name} must hold finite coordinates only, got {len(bad)} "
                         f"non-finite row(s), the first at row {bad[0]}")
    return arr


def make_scene(name: str, seed: int = 7) -> Scene:
    """The named scene: ``"paper"`` (Section V mission), ``"encounter"`` (one region, short)
    or ``"random"`` (:func:`paper_repro.random_scenes.random_scene` of ``seed``: a seeded field
    of regions across a straight flight, with a finish line for passages)."""
    from .random_scenes import random_scene

    builders = {"paper": paper_scene, "encounter": encounter_scene, "random": random_scene}
    if name not in builders:
        raise ValueError(f"scenario must be one of {tuple(builders)}, got {name!r}")
    return builders[name](seed)


def paper_scene(seed: int = 7) -> Scene:
    """Section V: start [22, −22, 0], targets [−12, 18, 11] then [−21, 18, 0].

    The paper does not give its regions, only that they lie across the flight (Figs. 1-3).
    Under the printed weights the UAV first climbs to the target height and then flies the
    straight line in the horizontal plane, so the regions straddle that path at flight level,
    each offset so that the straight path cuts its edge by about half a metre:

    * ``tower``: a 16 m tall box a quarter of the way along the first leg;
    * ``L-wall``: a nonconvex L of two 1 m thick walls, half-way along the first leg;
    * ``U-channel``: a floating box with a channel cut into its far side (nonconvex);
    * ``column``: a cylinder on the descent of the second leg.
    """
    regions = (
        Region("tower", Box((14.0, -11.55, 8.0), (2.0, 2.0, 16.0))),
        Region("L-wall", Union((Box((5.5, -1.0, 11.0), (5.0, 1.0, 5.0)),
                                Box((3.5, 1.0, 11.0), (1.0, 5.0, 5.0))))),
        Region("U-channel", Difference(Box((-3.83, 9.78, 11.0), (3.0, 3.0, 4.0)),
                                        Box((-3.83, 10.55, 11.0), (1.6, 1.5, 2.4)))),
        Region("column", Cylinder((-16.5, 19.5, 0.0), 1.2, 12.0)),
    )
    return Scene("paper", regions, (22.0, -22.0, 0.0), ((-12.0, 18.0, 11.0), (-21.0, 18.0, 0.0)),
                 seed)


def encounter_scene(seed: int = 7) -> Scene:
    """A short flight past one nonconvex region (an L-shaped corner) for tests and benchmarks.

    The UAV starts at [−20, 0, 2], about 3 m before the corner, with its target 40 m away so
    that it cruises at the speed of the paper's mission (≈0.27 m/s: under the printed weights
    the speed is about the distance to the target over 150 s). The straight line to the target
    passes 0.9 m from the corner, inside the safety margin, so the barrier must bend the path
    around the near arm and then along the second arm; the near arm is passed in about 1,500
    steps and the whole region in about 2,500.
    """
    x0 = -20.0
    regions = (
        Region("corner", Union((Box((x0 + 3.5, 2.15, 2.0), (1.0, 2.5, 3.0)),
                                Box((x0 + 5.0, 1.4, 2.0), (2.0, 1.0, 3.0))))),
    )
    return Scene("encounter", regions, (x0, 0.0, 2.0), ((x0 + 40.0, 0.0, 2.0),), seed)


# --- LiDAR ----------------------------------------------------------------------------------

class Lidar:
    """Virtual spherical LiDAR of range r_s (m) over a scene's clouds, perfect or imperfect.

    Parameters
    ----------
    clouds : sequence with one (m_i, 3) finite array per region, m (m_i ≥ 0). Shapes are
        checked, never reshaped: a bare (m, 3) array is rejected (wrap it in a list).
    range_ : r_s > 0, m.
    noise : :class:`~paper_repro.config.SensorParams`, or ``None`` for a perfect sensor (as
        is a ``SensorParams`` with its defaults). See :meth:`scan` for the model.

    One KD-tree over all points is built at construction; :meth:`scan` is a ball query.
    """

    def __init__(self, clouds, range_: float = 3.0, noise: SensorParams | None = None):
        if not (_is_number(range_) and math.isfinite(range_) and range_ > 0):
            raise ValueError(f"lidar range must be a finite number > 0 (m), got {range_!r}")
        if isinstance(clouds, np.ndarray) or not isinstance(clouds, (tuple, list)):
            raise ValueError("clouds must be a sequence (list or tuple) with one (m, 3) array "
                             f"per region, got {type(clouds).__name__}"
                             + (f" of shape {clouds.shape}; wrap a single cloud in a list"
                                if isinstance(clouds, np.ndarray) else ""))
        if noise is not None and not isinstance(noise, SensorParams):
            raise ValueError(f"noise must be a SensorParams or None, got {noise!r}")
        self.range = float(range_)
        self.clouds = tuple(_cloud_array(f"clouds[{i}]", c, allow_empty=True)
                            for i, c in enumerate(clouds))
        self.noise = noise if noise is not None else SensorParams()
        self._labels = np.concatenate(
            [np.full(len(c), i) for i, c in enumerate(self.clouds)] or [np.zeros(0, int)])
        points = np.concatenate(self.clouds) if self.clouds else np.zeros((0, 3))
        self._points = points
        self._tree = cKDTree(points) if len(points) else None
        self.reset()

    def reset(self) -> None:
        """Reseed the noise generator with ``noise.seed``: the next scans replay the same
        noise as after construction (a clean slate for a rerun)."""
        self._rng = np.random.default_rng(self.noise.seed)

    def scan(self, position) -> list[np.ndarray]:
        """Visible points of each region: a list (one entry per region) of (k_i, 3) arrays,
        k_i = 0 for a region out of range.

        A perfect sensor (the default) returns exactly the points within r_s, in their cloud
        order, and never draws from the generator. With ``noise``, per scan, in this order:

        * **dropout**: each point within r_s is lost with probability ``dropout``;
        * **range noise**: each kept point p is moved along its ray from the sensor s to
          s + max(0, ‖p − s‖ + ε)·(p − s)/‖p − s‖, ε ~ 𝒩(0, ``range_noise``²) (so a
          noisy point may lie slightly beyond r_s, as a real return would);
        * **spurious returns**: K ~ Poisson(``spurious_rate``) points uniform in the ball of
          radius r_s about s, each appended to the region whose cloud holds the point
          nearest to it (the region a segmentation by nearest obstacle would give it). A
          scene without any point has no region to give them to, and they are dropped.
        """
        p = np.asarray(position, float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"position must be a finite (3,) array, got {p!r}")
        if self._tree is None:
            return [np.zeros((0, 3)) for _ in self.clouds]
        idx = np.sort(np.asarray(self._tree.query_ball_point(p, self.range), dtype=int))
        if not self.noise.perfect:
            return self._noisy_scan(p, idx)
        labels = self._labels[idx]
        return [self._points[idx[labels == i]] for i in range(len(self.clouds))]

    def _noisy_scan(self, p: np.ndarray, idx: np.ndarray) -> list[np.ndarray]:
        noise, rng = self.noise, self._rng
        # Every draw is made whatever the parameters, so that the stream a given seed produces
        # does not depend on which imperfections are switched on.
        kept = rng.random(len(idx)) >= noise.dropout
        eps = rng.standard_normal(len(idx)) * noise.range_noise
        idx, eps = idx[kept], eps[kept]
        ray = self._points[idx] - p
        dist = np.linalg.norm(ray, axis=1)
        scale = np.divide(np.maximum(dist + eps, 0.0), dist, out=np.ones_like(dist),
                          where=dist > 0)
        points = p + ray * scale[:, None]
        labels = self._labels[idx]

        k = int(rng.poisson(noise.spurious_rate))
        direction = rng.standard_normal((k, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = self.range * rng.random(k) ** (1.0 / 3.0)  # uniform in volume
        spurious = p + direction * radius[:, None]
        if k:
            _, nearest = self._tree.query(spurious)
            points = np.vstack([points, spurious])
            labels = np.concatenate([labels, self._labels[nearest]])
        return [points[labels == i] for i in range(len(self.clouds))]

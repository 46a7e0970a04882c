"""Workspace, obstacle regions sampled as Halton point clouds, and the virtual LiDAR.

A region is a solid shape (boxes, cylinders, and their unions and differences, so nonconvex
shapes such as an L-wall or a U-channel are easy) filled with a scrambled, seeded Halton
sequence (``scipy.stats.qmc.Halton``) at a given density, as in Section V. A
:class:`Scene` holds the regions' clouds, the start and the sequence of targets; a
:class:`Lidar` returns, per region, the points inside a sphere of radius r_s around the UAV.

Regions are static, as in the paper, unless the scene gives them a :class:`Motion`: a rigid
translation c(t) of the region's stored points, so that at time t region i is the cloud
``clouds[i] + c_i(t)`` (:meth:`Scene.clouds_at`); the LiDAR then sees each region where it is
at the time of the scan.
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


# --- motion ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Motion:
    """A rigid translation of a region over time: a piecewise-linear offset c(t) ∈ R³.

    At time t (s) the region's points are its stored points + c(t) (m); the region does not
    rotate or deform.

    Attributes
    ----------
    times : (n,) s, strictly increasing finite times, n ≥ 1 (stored as a tuple of floats).
    offsets : (n, 3) m, c at each of ``times`` (stored as a tuple of 3-tuples of floats).

    Between two times c is linear. Before the first time c is the first offset (at rest);
    after the last it goes on with the last segment's velocity (at rest when n = 1), so
    ``Motion.constant(v)`` moves for ever.
    """

    times: tuple
    offsets: tuple

    def __post_init__(self):
        times = self.times
        if not (isinstance(times, (tuple, list, np.ndarray)) and np.ndim(times) == 1
                and len(times) >= 1 and all(_is_number(t) and math.isfinite(t) for t in times)):
            raise ValueError(f"Motion.times must be a non-empty sequence of finite numbers (s), "
                             f"got {times!r}")
        t = np.asarray(times, float)
        if np.any(np.diff(t) <= 0):
            raise ValueError(f"Motion.times must be strictly increasing (s), got {times!r}")
        offsets = self.offsets
        if not (isinstance(offsets, (tuple, list, np.ndarray)) and len(offsets) == len(t)):
            raise ValueError(f"Motion.offsets must hold one (3,) offset (m) per time "
                             f"({len(t)}), got {offsets!r}")
        for i, c in enumerate(offsets):
            _require_point(f"Motion.offsets[{i}]", c)
        c = np.asarray(offsets, float).reshape(len(t), 3)
        object.__setattr__(self, "times", tuple(float(v) for v in t))
        object.__setattr__(self, "offsets", tuple(tuple(float(v) for v in row) for row in c))
        # Velocity of the segment that starts at each time (the last one goes on for ever).
        v = np.zeros((len(t), 3))
        if len(t) > 1:
            v[:-1] = np.diff(c, axis=0) / np.diff(t)[:, None]
            v[-1] = v[-2]
        object.__setattr__(self, "_t", t)
        object.__setattr__(self, "_c", c)
        object.__setattr__(self, "_v", v)

    @classmethod
    def constant(cls, velocity, start_offset=(0.0, 0.0, 0.0)) -> Motion:
        """Constant ``velocity`` (3,) m/s for all t ≥ 0, from ``start_offset`` (3,) m at t = 0:
        c(t) = start_offset + velocity·t (at rest at ``start_offset`` before t = 0)."""
        _require_point("Motion.constant velocity", velocity)
        _require_point("Motion.constant start_offset", start_offset)
        start = np.asarray(start_offset, float)
        return cls((0.0, 1.0), (start, start + np.asarray(velocity, float)))

    def _segment(self, t) -> int:
        if not (_is_number(t) and math.isfinite(t)):
            raise ValueError(f"time t must be a finite number (s), got {t!r}")
        return int(np.searchsorted(self._t, float(t), side="right")) - 1

    def offset(self, t: float) -> np.ndarray:
        """c(t), (3,) m."""
        i = self._segment(t)
        if i < 0:
            return self._c[0].copy()
        return self._c[i] + self._v[i] * (float(t) - self._t[i])

    def velocity(self, t: float) -> np.ndarray:
        """dc/dt at t, (3,) m/s: the velocity of the segment t lies in (of the segment that
        starts at t, at a breakpoint); zero before the first time."""
        i = self._segment(t)
        return np.zeros(3) if i < 0 else self._v[i].copy()

    def to_dict(self) -> dict:
        """JSON-able: ``{"times": [...], "offsets": [[x, y, z], ...]}``."""
        return {"times": list(self.times), "offsets": [list(c) for c in self.offsets]}

    @classmethod
    def from_dict(cls, data: dict) -> Motion:
        """Inverse of :meth:`to_dict`."""
        return cls(tuple(data["times"]), tuple(tuple(c) for c in data["offsets"]))


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
        whatever the generators do later. For a moving region, the points where its offset
        is zero (each scene's builder says when that is).
    motions : ``None`` (every region static, the paper), or one :class:`Motion` or ``None``
        per region: region i is at ``clouds[i] + motions[i].offset(t)`` at time t. A tuple of
        ``None`` only is stored as ``None``.
    """

    name: str
    regions: tuple
    start: tuple
    targets: tuple
    seed: int = 7
    finish: tuple | None = None
    clouds: tuple | None = field(default=None, repr=False, compare=False)
    motions: tuple | None = None

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
        object.__setattr__(self, "motions", _motions("motions", self.motions, len(self.regions)))

    @property
    def is_moving(self) -> bool:
        """True when some region has a :class:`Motion`."""
        return self.motions is not None

    def clouds_at(self, t: float) -> tuple:
        """The regions' clouds at time ``t`` (s): tuple of (m_i, 3) arrays, m (the stored
        clouds themselves for static regions)."""
        if not self.is_moving:
            return self.clouds
        return tuple(c if m is None else c + m.offset(t)
                     for c, m in zip(self.clouds, self.motions, strict=True))

    @property
    def all_points(self) -> np.ndarray:
        """(Σm_i, 3) every point of every region."""
        return np.concatenate(self.clouds) if self.clouds else np.zeros((0, 3))

    def fingerprint(self) -> str:
        """SHA-256 (hex) of the start, the targets, the finish line, every cloud point and, for
        a moving scene only, the motions: two scenes with the same fingerprint are flown
        identically (and a static scene's fingerprint is the one it had before motions)."""
        digest = hashlib.sha256()
        finish = np.zeros((0, 3)) if self.finish is None else np.asarray(self.finish, float)
        for block in (self.start, self.targets, finish, *self.clouds):
            digest.update(np.ascontiguousarray(block, dtype=np.float64).tobytes())
        if self.is_moving:
            digest.update(b"motions")
            for m in self.motions:
                if m is None:
                    digest.update(b"static")
                else:
                    digest.update(b"motion")
                    digest.update(np.asarray(m.times, np.float64).tobytes())
                    digest.update(np.asarray(m.offsets, np.float64).tobytes())
        return digest.hexdigest()

    def to_dict(self) -> dict:
        """JSON-able description (regions as shape trees); the clouds are stored apart, as
        arrays (see :meth:`from_dict`). A moving scene adds ``"motions"`` (one
        :meth:`Motion.to_dict` or ``None`` per region); a static one has no such key, so its
        description is the one it had before motions."""
        data = {"name": self.name, "seed": int(self.seed),
                "start": [float(v) for v in self.start],
                "targets": np.atleast_2d(np.asarray(self.targets, float)).tolist(),
                "finish": None if self.finish is None else
                [np.asarray(v, float).tolist() for v in self.finish],
                "regions": [{"name": r.name, "density": r.density,
                             "shape": shape_to_dict(r.shape)} for r in self.regions]}
        if self.is_moving:
            data["motions"] = [None if m is None else m.to_dict() for m in self.motions]
        data["fingerprint"] = self.fingerprint()
        return data

    @classmethod
    def from_dict(cls, data: dict, clouds=None) -> Scene:
        """Rebuild a scene from :meth:`to_dict`; with ``clouds`` (one (m_i, 3) array per
        region) the points are taken as stored, and the stored fingerprint must match."""
        regions = tuple(Region(r["name"], shape_from_dict(r["shape"]), r["density"])
                        for r in data["regions"])
        finish = None if data.get("finish") is None else tuple(
            tuple(v) for v in data["finish"])
        motions = None if data.get("motions") is None else tuple(
            None if m is None else Motion.from_dict(m) for m in data["motions"])
        scene = cls(data["name"], regions, tuple(data["start"]),
                    tuple(tuple(t) for t in data["targets"]), int(data["seed"]), finish,
                    None if clouds is None else tuple(clouds), motions)
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


def _motions(name: str, motions, count: int) -> tuple | None:
    """``motions`` checked: ``None``, or a tuple of ``count`` entries, each a :class:`Motion`
    or ``None``; all ``None`` becomes ``None`` (a static scene)."""
    if motions is None:
        return None
    if not (isinstance(motions, (tuple, list)) and len(motions) == count
            and all(m is None or isinstance(m, Motion) for m in motions)):
        raise ValueError(f"{name} must be None or hold one Motion or None per region "
                         f"({count}), got {motions!r}")
    return None if all(m is None for m in motions) else tuple(motions)


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
    """The named scene: ``"paper"`` (Section V mission), ``"encounter"`` (one region, short),
    ``"random"`` (:func:`paper_repro.random_scenes.random_scene` of ``seed``: a seeded field
    of regions across a straight flight, with a finish line for passages), or a scene whose
    regions move: ``"crossing"`` (:func:`crossing_scene`), ``"oncoming"``
    (:func:`oncoming_scene`) and ``"random-crossing"`` (the ``"random"`` field of ``seed``,
    each region crossing the flight line, ``random_scene(seed, moving=True)``)."""
    from .random_scenes import random_scene

    builders = {"paper": paper_scene, "encounter": encounter_scene, "random": random_scene,
                "crossing": crossing_scene, "oncoming": oncoming_scene,
                "random-crossing": lambda s: random_scene(s, moving=True)}
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


CROSSING_SPEED = 1.0
"""m/s, speed of the region of the ``crossing`` scene across the flight line."""

ONCOMING_SPEED = 0.5
"""m/s, speed of the region of the ``oncoming`` scene along the flight line, towards the UAV."""

MEETING_TIME = 8.0
"""s, when the UAV, flying straight, meets the moving region of ``crossing`` and ``oncoming``."""


def crossing_scene(seed: int = 7) -> Scene:
    """A 2 × 2 × 3 m box that crosses the UAV's straight path at 1.0 m/s, for moving obstacles.

    The UAV starts at rest at [−20, 0, 2] with its target 40 m ahead, [20, 0, 2], as in the
    encounter: it cruises at ≈0.25 m/s (about the distance to the target over 150 s; flying
    straight it is at x ≈ −18.0 m at t = 8 s, after dipping to z ≈ 1.3 m). The box (its
    points at t = 0 are the stored cloud) is centred at [−18, −8, 2] at t = 0 and moves along
    +y at ``CROSSING_SPEED``, so that its centre is on the path at x = −18 at t =
    ``MEETING_TIME`` = 8 s, just when the UAV gets there: flown straight (no avoidance, or an
    avoidance that takes the box as static) the two meet. The box covers the path between
    t = 7 and 9 s; it comes within the 3 m LiDAR range of the UAV at t ≈ 4 s. The finish line
    of a passage is 2 m past the box's far face, at x = −15.
    """
    x0, xc = -20.0, -18.0
    t_meet = MEETING_TIME
    region = Region("crossing-box", Box((xc, -CROSSING_SPEED * t_meet, 2.0), (2.0, 2.0, 3.0)))
    return Scene("crossing", (region,), (x0, 0.0, 2.0), ((x0 + 40.0, 0.0, 2.0),), seed,
                 ((xc + 3.0, 0.0, 2.0), (1.0, 0.0, 0.0)),
                 motions=(Motion.constant((0.0, CROSSING_SPEED, 0.0)),))


def oncoming_scene(seed: int = 7) -> Scene:
    """A 2 × 2 × 3 m box on the UAV's path that comes towards it at 0.5 m/s.

    Start [−20, 0, 2] and target [20, 0, 2], as :func:`crossing_scene`. The box (its points
    at t = 0 are the stored cloud) is centred at [−13, 0, 2] at t = 0, its near face 6 m ahead
    of the UAV, and moves along −x at ``ONCOMING_SPEED`` for ever; with the UAV at ≈0.25 m/s
    they close at ≈0.75 m/s: the box comes within the 3 m LiDAR range at t ≈ 4 s and, flown
    straight, meets the UAV at t ≈ ``MEETING_TIME`` = 8 s, at x ≈ −18 m. The finish line of a
    passage is 2 m past the box's far face at that time, at x = −14: the UAV has to get round
    or over the box.
    """
    x0 = -20.0
    region = Region("oncoming-box", Box((-13.0, 0.0, 2.0), (2.0, 2.0, 3.0)))
    return Scene("oncoming", (region,), (x0, 0.0, 2.0), ((x0 + 40.0, 0.0, 2.0),), seed,
                 ((-14.0, 0.0, 2.0), (1.0, 0.0, 0.0)),
                 motions=(Motion.constant((-ONCOMING_SPEED, 0.0, 0.0)),))


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
    motions : ``None`` (static regions), or one :class:`Motion` or ``None`` per region (as
        :attr:`Scene.motions`): region i is seen at ``clouds[i] + motions[i].offset(t)``.

    Static regions: one KD-tree over all points is built at construction and :meth:`scan` is
    one ball query. With motions: one KD-tree per region, each queried at the sensor's
    position less the region's offset, so a moving region costs what a static one does.
    """

    def __init__(self, clouds, range_: float = 3.0, noise: SensorParams | None = None,
                 motions=None):
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
        self.motions = _motions("lidar motions", motions, len(self.clouds))
        self.noise = noise if noise is not None else SensorParams()
        self._labels = np.concatenate(
            [np.full(len(c), i) for i, c in enumerate(self.clouds)] or [np.zeros(0, int)])
        points = np.concatenate(self.clouds) if self.clouds else np.zeros((0, 3))
        self._points = points
        self._tree = cKDTree(points) if len(points) else None
        if self.motions is not None:
            self._first = np.cumsum([0] + [len(c) for c in self.clouds])[:-1]
            self._trees = [cKDTree(c) if len(c) else None for c in self.clouds]
        self.reset()

    def reset(self) -> None:
        """Reseed the noise generator with ``noise.seed``: the next scans replay the same
        noise as after construction (a clean slate for a rerun)."""
        self._rng = np.random.default_rng(self.noise.seed)

    def offsets(self, t: float = 0.0) -> np.ndarray:
        """(n_regions, 3) m, each region's offset c_i(t) from its stored cloud (zero when
        static)."""
        shifts = np.zeros((len(self.clouds), 3))
        if self.motions is not None:
            for i, m in enumerate(self.motions):
                if m is not None:
                    shifts[i] = m.offset(t)
        return shifts

    def velocities(self, t: float = 0.0) -> list[np.ndarray]:
        """The regions' true velocities at time ``t`` (s): a list with one (3,) array per
        region, m/s (zeros for a static region). The oracle a predictor can be given."""
        _require_time(t)
        if self.motions is None:
            return [np.zeros(3) for _ in self.clouds]
        return [np.zeros(3) if m is None else m.velocity(t) for m in self.motions]

    def scan(self, position, t: float = 0.0) -> list[np.ndarray]:
        """Visible points of each region at time ``t`` (s; only moving regions depend on it):
        a list (one entry per region) of (k_i, 3) arrays, k_i = 0 for a region out of range.

        A perfect sensor (the default) returns exactly the points within r_s, in their cloud
        order, and never draws from the generator; a moving region's points are returned
        where they are at ``t`` (stored points + c_i(t)). With ``noise``, per scan, in this
        order:

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
        _require_time(t)
        if self._tree is None:
            return [np.zeros((0, 3)) for _ in self.clouds]
        if self.motions is not None:
            return self._moving_scan(p, t)
        idx = np.sort(np.asarray(self._tree.query_ball_point(p, self.range), dtype=int))
        if not self.noise.perfect:
            return self._noisy_scan(p, idx)
        labels = self._labels[idx]
        return [self._points[idx[labels == i]] for i in range(len(self.clouds))]

    def _moving_scan(self, p: np.ndarray, t: float) -> list[np.ndarray]:
        """:meth:`scan` with motions: region i's tree is queried at p − c_i(t) and its points
        are shifted by + c_i(t)."""
        shifts = self.offsets(t)
        local = [np.zeros(0, int) if tree is None else
                 np.sort(np.asarray(tree.query_ball_point(p - shifts[i], self.range),
                                    dtype=int))
                 for i, tree in enumerate(self._trees)]
        if not self.noise.perfect:
            idx = np.concatenate([self._first[i] + li for i, li in enumerate(local)])
            return self._noisy_scan(p, idx, shifts)
        return [c[li] + shifts[i] if len(li) else np.zeros((0, 3))
                for i, (c, li) in enumerate(zip(self.clouds, local, strict=True))]

    def _nearest_region(self, points: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """Region holding the nearest point (where it is now) to each of ``points``."""
        best = np.full(len(points), np.inf)
        label = np.zeros(len(points), int)
        for i, tree in enumerate(self._trees):
            if tree is None:
                continue
            d, _ = tree.query(points - shifts[i])
            closer = d < best
            best[closer], label[closer] = d[closer], i
        return label

    def _noisy_scan(self, p: np.ndarray, idx: np.ndarray,
                    shifts: np.ndarray | None = None) -> list[np.ndarray]:
        noise, rng = self.noise, self._rng
        # Every draw is made whatever the parameters, so that the stream a given seed produces
        # does not depend on which imperfections are switched on.
        kept = rng.random(len(idx)) >= noise.dropout
        eps = rng.standard_normal(len(idx)) * noise.range_noise
        idx, eps = idx[kept], eps[kept]
        labels = self._labels[idx]
        where = self._points[idx] if shifts is None else self._points[idx] + shifts[labels]
        ray = where - p
        dist = np.linalg.norm(ray, axis=1)
        scale = np.divide(np.maximum(dist + eps, 0.0), dist, out=np.ones_like(dist),
                          where=dist > 0)
        points = p + ray * scale[:, None]

        k = int(rng.poisson(noise.spurious_rate))
        direction = rng.standard_normal((k, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = self.range * rng.random(k) ** (1.0 / 3.0)  # uniform in volume
        spurious = p + direction * radius[:, None]
        if k:
            if shifts is None:
                _, nearest = self._tree.query(spurious)
                spurious_labels = self._labels[nearest]
            else:
                spurious_labels = self._nearest_region(spurious, shifts)
            points = np.vstack([points, spurious])
            labels = np.concatenate([labels, spurious_labels])
        return [points[labels == i] for i in range(len(self.clouds))]


def _require_time(t) -> None:
    if not (_is_number(t) and math.isfinite(t)):
        raise ValueError(f"time t must be a finite number (s), got {t!r}")

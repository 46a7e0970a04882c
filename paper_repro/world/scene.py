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

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from paper_repro.validation import is_number, require_int
from paper_repro.world.motion import Motion
from paper_repro.world.shapes import (
    halton_cloud,
    require_shape,
    shape_from_dict,
    shape_to_dict,
)

WORKSPACE_LOWER = np.array([-25.0, -25.0, 0.0])
WORKSPACE_UPPER = np.array([25.0, 25.0, 25.0])


# --- regions and scenes ---------------------------------------------------------------------

@dataclass(frozen=True)
class Region:
    """A nonfeasible region: a ``shape`` sampled at ``density`` points per m³, or (``shape``
    ``None``) points given by the scene's ``clouds``, as a planar scene's are."""

    name: str
    shape: object
    density: float = 3.0

    def __post_init__(self):
        if not (isinstance(self.name, str) and self.name):
            raise ValueError(f"Region.name must be a non-empty str, got {self.name!r}")
        if self.shape is not None:
            require_shape(f"Region {self.name!r} shape", self.shape)
        if not (is_number(self.density) and math.isfinite(self.density) and self.density > 0):
            raise ValueError(
                f"density must be a finite number > 0 (points/m³), got {self.density!r}")


@dataclass(frozen=True)
class Scene:
    """Regions with their clouds, a start position and targets to visit in order.

    Attributes
    ----------
    name : str.
    regions : tuple of :class:`Region`.
    start : (p,) initial position, m: p = 3 in the workspace of the paper, p = 2 for a planar
        scene (a ground robot's); every other position and cloud of the scene has p entries.
    targets : (k, p) set-points y_t, m, visited in sequence.
    seed : base seed of the Halton clouds (region i uses ``seed + i``).
    finish : ``None``, or a finish line ``(point, direction)`` (each (3,), m and unit vector)
        for a *passage*: the run ends once ``(y − point)·direction ≥ 0``.
    clouds : tuple of (m_i, p) arrays, m. Sampled from the regions when omitted; given when a
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
        require_int("seed", self.seed, 0)
        start = np.asarray(self.start, float)
        targets = np.asarray(self.targets, float)
        if targets.ndim == 1:
            targets = targets[None]
        if start.shape not in ((2,), (3,)) or not np.all(np.isfinite(start)):
            raise ValueError(f"start must be a finite 3-D (or planar 2-D) position, got shape "
                             f"{start.shape}")
        dim = len(start)
        if targets.ndim != 2 or targets.shape[1] != dim or not np.all(np.isfinite(targets)):
            raise ValueError(f"targets must be finite {dim}-D positions (as the start), got "
                             f"shape {targets.shape}")
        if len(targets) == 0:
            raise ValueError(f"targets must hold at least one {dim}-D position")
        if self.finish is not None:
            point, direction = (np.asarray(v, float) for v in self.finish)
            if point.shape != (dim,) or direction.shape != (dim,) or not (
                    np.all(np.isfinite(point)) and np.isclose(np.linalg.norm(direction), 1.0)):
                raise ValueError(f"finish must be (point ({dim},), unit direction ({dim},)), "
                                 f"got {self.finish!r}")
        if self.clouds is None:
            unsampled = [r.name for r in self.regions if r.shape is None]
            if unsampled or dim != 3:
                raise ValueError(f"clouds must be given for a planar scene or a region without "
                                 f"a shape ({unsampled or 'planar'})")
            clouds = tuple(halton_cloud(r.shape, r.density, self.seed + i)
                           for i, r in enumerate(self.regions))
        else:
            if len(self.clouds) != len(self.regions):
                raise ValueError(f"clouds must hold one (m, {dim}) array per region "
                                 f"({len(self.regions)}), got {len(self.clouds)}")
            clouds = tuple(cloud_array(f"clouds[{i}]", c, dim=dim)
                           for i, c in enumerate(self.clouds))
        for r, c in zip(self.regions, clouds, strict=True):
            if len(c) == 0:
                raise ValueError(f"region {r.name!r} holds no point at density {r.density}")
        object.__setattr__(self, "clouds", clouds)
        object.__setattr__(self, "motions",
                           checked_motions("motions", self.motions, len(self.regions)))

    @property
    def dim(self) -> int:
        """p, the dimension of the scene's positions: 3, or 2 for a planar scene."""
        return len(self.start)

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
        """(Σm_i, p) every point of every region."""
        return np.concatenate(self.clouds) if self.clouds else np.zeros((0, self.dim))

    def fingerprint(self) -> str:
        """SHA-256 (hex) of the start, the targets, the finish line, every cloud point and, for
        a moving scene only, the motions: two scenes with the same fingerprint are flown
        identically (and a static scene's fingerprint is the one it had before motions)."""
        digest = hashlib.sha256()
        finish = np.zeros((0, self.dim)) if self.finish is None else np.asarray(self.finish, float)
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
                             "shape": None if r.shape is None else shape_to_dict(r.shape)}
                            for r in self.regions]}
        if self.is_moving:
            data["motions"] = [None if m is None else m.to_dict() for m in self.motions]
        data["fingerprint"] = self.fingerprint()
        return data

    @classmethod
    def from_dict(cls, data: dict, clouds=None) -> Scene:
        """Rebuild a scene from :meth:`to_dict`; with ``clouds`` (one (m_i, 3) array per
        region) the points are taken as stored, and the stored fingerprint must match."""
        regions = tuple(Region(r["name"], None if r["shape"] is None
                               else shape_from_dict(r["shape"]), r["density"])
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



def checked_motions(name: str, motions, count: int) -> tuple | None:
    """``motions`` checked: ``None``, or a tuple of ``count`` entries, each a :class:`Motion`
    or ``None``; all ``None`` becomes ``None`` (a static scene)."""
    if motions is None:
        return None
    if not (isinstance(motions, (tuple, list)) and len(motions) == count
            and all(m is None or isinstance(m, Motion) for m in motions)):
        raise ValueError(f"{name} must be None or hold one Motion or None per region "
                         f"({count}), got {motions!r}")
    return None if all(m is None for m in motions) else tuple(motions)


def cloud_array(name: str, cloud, allow_empty: bool = False, dim: int = 3) -> np.ndarray:
    """``cloud`` as a float (m, dim) array, checked (never reshaped); dim = 3, or 2 in a
    planar scene."""
    try:
        arr = np.asarray(cloud, float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an (m, {dim}) array of points, got "
                         f"{type(cloud).__name__}") from None
    if arr.ndim != 2 or arr.shape[1] != dim or (arr.shape[0] == 0 and not allow_empty):
        raise ValueError(f"{name} must be an (m, {dim}) array of points (m ≥ "
                         f"{0 if allow_empty else 1}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        raise ValueError(f"{name} must hold finite coordinates only, got {len(bad)} "
                         f"non-finite row(s), the first at row {bad[0]}")
    return arr

"""Solid shapes of the obstacle regions (boxes, cylinders, their unions and differences), and the
Halton clouds sampled inside them (the paper's point clouds)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from paper_repro.validation import is_number, require_int, require_point

# --- shapes ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Box:
    """Axis-aligned box. ``center`` (3,) and ``size`` (3,) edge lengths, m."""

    center: tuple[float, float, float]
    size: tuple[float, float, float]

    def __post_init__(self):
        require_point("Box.center", self.center)
        require_point("Box.size", self.size, positive=True)

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
        require_point("Cylinder.base", self.base)
        for name in ("radius", "height"):
            value = getattr(self, name)
            if not (is_number(value) and math.isfinite(value) and value > 0):
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
            require_shape(f"Union.parts[{i}]", part)

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
        require_shape("Difference.outer", self.outer)
        require_shape("Difference.inner", self.inner)

    def contains(self, p: np.ndarray) -> np.ndarray:
        return self.outer.contains(p) & ~self.inner.contains(p)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.outer.bounds()


def halton_cloud(shape, density: float, seed: int) -> np.ndarray:
    """Fill ``shape`` with scrambled Halton points (seeded, reproducible).

    The sequence is drawn in the shape's bounding box, ``density``·volume(box) points, and
    the points outside the shape are dropped, so the density inside is ``density`` for any
    shape. Returns (m, 3), m.
    """
    if not (is_number(density) and math.isfinite(density) and density > 0):
        raise ValueError(f"density must be a finite number > 0 (points/m³), got {density!r}")
    require_int("seed", seed, 0)
    lo, hi = shape.bounds()
    n = max(1, int(round(density * float(np.prod(hi - lo)))))
    sample = qmc.Halton(d=3, scramble=True, seed=seed).random(n)
    points = qmc.scale(sample, lo, hi)
    return points[shape.contains(points)]


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

def require_shape(name: str, shape) -> None:
    if not isinstance(shape, (Box, Cylinder, Union, Difference)):
        raise ValueError(f"{name} must be a Box, Cylinder, Union or Difference, got {shape!r}")

"""How a region moves: a piecewise-constant velocity, offsets and velocities at time t."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from paper_repro.validation import is_number, require_point

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
                and len(times) >= 1 and all(is_number(t) and math.isfinite(t) for t in times)):
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
            require_point(f"Motion.offsets[{i}]", c)
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
        require_point("Motion.constant velocity", velocity)
        require_point("Motion.constant start_offset", start_offset)
        start = np.asarray(start_offset, float)
        return cls((0.0, 1.0), (start, start + np.asarray(velocity, float)))

    def _segment(self, t) -> int:
        if not (is_number(t) and math.isfinite(t)):
            raise ValueError(f"time t must be a finite number (s), got {t!r}")
        return int(np.searchsorted(self._t, float(t), side="right")) - 1

    def offset(self, t: float) -> np.ndarray:
        """c(t), (3,) m."""
        i = self._segment(t)
        if i < 0:
            return self._c[0].copy()
        return self._c[i] + self._v[i] * (float(t) - self._t[i])

    def offsets_at(self, t) -> np.ndarray:
        """c(t) for many times at once: ``t`` (n,) s → (n, 3) m, each row :meth:`offset` of
        that time (the same arithmetic, without a Python loop)."""
        t = np.asarray(t, float)
        if t.ndim != 1 or not np.all(np.isfinite(t)):
            raise ValueError(f"times t must be a 1-D array of finite numbers (s), got shape "
                             f"{t.shape}")
        i = np.searchsorted(self._t, t, side="right") - 1
        before = i < 0
        i = np.maximum(i, 0)
        out = self._c[i] + self._v[i] * (t - self._t[i])[:, None]
        out[before] = self._c[0]
        return out

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

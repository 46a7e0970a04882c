"""The checks of every input, in one place: each raises a ``ValueError`` that names the
parameter and the accepted range, before anything is built or solved.

Every module that takes user input calls these; none writes its own. A ``bool`` is never a
number here (``True`` is an ``int`` in Python, but never a meaningful setting).
"""

from __future__ import annotations

import math

import numpy as np


def is_number(value) -> bool:
    """A real scalar, not a bool."""
    return (isinstance(value, (int, float, np.floating, np.integer))
            and not isinstance(value, (bool, np.bool_)))


def require_positive(name: str, value) -> None:
    """A finite number > 0."""
    if not (is_number(value) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def require_range(name: str, value, lower: float, upper: float,
                  closed_upper: bool = False) -> None:
    """``lower <= value < upper`` (``<= upper`` when ``closed_upper``), finite."""
    inside = is_number(value) and math.isfinite(value) and lower <= value and (
        value <= upper if closed_upper else value < upper)
    if not inside:
        bracket = "]" if closed_upper else ")"
        raise ValueError(f"{name} must be a finite number in [{lower}, {upper}{bracket}, "
                         f"got {value!r}")


def require_int(name: str, value, minimum: int) -> None:
    """An integer (Python or NumPy, not a bool) >= ``minimum``."""
    if not (isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
            and value >= minimum):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def require_vector(name: str, value, n: int | None) -> None:
    """A tuple or list of ``n`` finite numbers (``None``: at least one)."""
    if not (isinstance(value, (tuple, list)) and (len(value) == n if n else len(value) >= 1)
            and all(is_number(x) and math.isfinite(x) for x in value)):
        raise ValueError(f"{name} must be {n or 'one or more'} finite numbers, got {value!r}")


def require_point(name: str, value, positive: bool = False) -> None:
    """Three finite numbers (each > 0 when ``positive``), m, as a tuple, list or array."""
    ok = (isinstance(value, (tuple, list, np.ndarray)) and np.shape(value) == (3,)
          and all(is_number(v) and math.isfinite(v) and (v > 0 or not positive)
                  for v in value))
    if not ok:
        what = "finite numbers > 0 (m)" if positive else "finite numbers (m)"
        raise ValueError(f"{name} must be 3 {what}, got {value!r}")


def require_ordered(lower_name: str, lower, upper_name: str, upper) -> None:
    """Bounds of a box: lower[i] < upper[i] for every i, naming the first bad index."""
    for i, (lo, hi) in enumerate(zip(lower, upper, strict=True)):
        if not lo < hi:
            raise ValueError(f"{lower_name}[{i}] must be < {upper_name}[{i}], got {lo!r} >= "
                             f"{hi!r}")


def require_choice(name: str, value, choices: tuple[str, ...]) -> None:
    """One of ``choices``."""
    if not (isinstance(value, str) and value in choices):
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")


def require_time(t) -> None:
    """A time t, s: a finite number."""
    if not (is_number(t) and math.isfinite(t)):
        raise ValueError(f"time t must be a finite number (s), got {t!r}")


def as_vector(name: str, value, n: int) -> np.ndarray:
    """``value`` as a finite float array of shape (n,), or a ``ValueError`` naming it."""
    arr = np.asarray(value, dtype=float)
    # The array's own .all(): np.all's dispatch costs more than the check of a short vector.
    if arr.shape != (n,) or not np.isfinite(arr).all():
        raise ValueError(f"{name} must be a finite array of shape ({n},), got {arr!r}")
    return arr

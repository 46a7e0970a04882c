"""Flights flown more than once, for timing: each call's least time over the passes.

The closed loop is deterministic (a reset controller flies bit for bit as a new one), so every
pass of a flight makes the same controller calls. A call slow in one pass only was slowed by
the machine (another process, or the host of this virtual machine, held the core; the thread's
CPU time counts that too, so it cannot tell them apart); the least of its times is its own
cost."""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import numpy as np

PASSES = 2
"""Flights of each scene."""


def fly_passes(fly, passes: int = PASSES, name: str = "the flight"):
    """``fly()`` (one flight from a reset controller, a
    :class:`~paper_repro.sim.result.SimulationResult`) ``passes`` times: the results, and each
    call's least ``solve_time`` over them (ms, one entry per step). ``RuntimeError`` when the
    passes fly different states: their calls could not be compared."""
    results = [fly() for _ in range(passes)]
    if any(not np.array_equal(r.x, results[0].x) for r in results[1:]):
        raise RuntimeError(f"{name}: the passes flew differently; their calls cannot be "
                           "compared")
    least = np.minimum.reduce([1e3 * np.asarray(r.solve_time, float) for r in results])
    return results, least

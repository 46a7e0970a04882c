"""Shared fixtures for the unit tests."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh, seeded generator per test (tests do not depend on each other's draws)."""
    return np.random.default_rng(20240611)


@pytest.fixture(scope="session")
def l_cloud() -> np.ndarray:
    """A nonconvex (L-shaped) cloud of 3-D points with irregular spacing, about 2 m x 2 m.

    Built on a jittered grid so that it does not depend on ``paper_repro.world.scene``.
    """
    gen = np.random.default_rng(11)
    g = np.arange(0.0, 2.01, 0.4)
    pts = np.array([(x, y, z) for x in g for y in g for z in (0.0, 0.5, 1.0)
                    if x <= 0.4 or y <= 0.4])
    pts = pts + gen.normal(scale=0.05, size=pts.shape)
    return pts + np.array([1.0, -2.0, 3.0])

"""Shared fixtures for the unit tests."""

from __future__ import annotations

import os

import numpy as np
import pytest

# A controller made in a test flies a few steps: it compiles only the rungs its scans need
# (solvers.linearisation.RUNGS_ENV), and the steps are the same. A fresh machine compiles
# less; a caller's own choice stands.
os.environ.setdefault("PAPER_REPRO_RUNGS", "needed")


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


@pytest.fixture(scope="session")
def site_check():
    """``docs/check_site.py`` as a module, when the browser it drives is installed (it installs
    Chromium and Playwright itself: ``python docs/check_site.py``); else the test is skipped."""
    import importlib.util
    from pathlib import Path

    pytest.importorskip("playwright", reason="no Playwright: python docs/check_site.py installs it")
    path = Path(__file__).resolve().parents[1] / "docs" / "check_site.py"
    spec = importlib.util.spec_from_file_location("check_site", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if not Path(module.CHROMIUM).exists():
        pytest.skip(f"no Chromium at {module.CHROMIUM}: python docs/check_site.py installs it")
    return module

"""Properties of the seeded random scenes: reproducible, blocked, clear at both ends, inside
the workspace, with a finish line 2 m past the field, and varied in their regions."""

from __future__ import annotations

import collections
import dataclasses

import numpy as np
import pytest

from paper_repro.world.random_scenes import (
    NONCONVEX_KINDS,
    REGION_KINDS,
    RandomSceneParams,
    passage_progress,
    random_scene,
)
from paper_repro.world.scenarios import make_scene
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER, Scene

SEEDS = range(50)
PARAMS = RandomSceneParams()


@pytest.fixture(scope="module")
def scenes() -> dict[int, Scene]:
    return {seed: random_scene(seed) for seed in SEEDS}


def _kind(region) -> str:
    return region.name.rsplit("-", 1)[0]


def _segment_distances(points: np.ndarray, a, b) -> np.ndarray:
    """Distance (m) of each point (n, 3) to the segment a → b."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    s = np.clip((points - a) @ (b - a) / np.sum((b - a) ** 2), 0.0, 1.0)
    return np.linalg.norm(points - (a + s[:, None] * (b - a)), axis=1)


def _midpoints_outside(shape, cloud) -> int:
    mids = (cloud[:, None, :] + cloud[None, :, :]) / 2
    return int(np.sum(~shape.contains(mids.reshape(-1, 3))))


# --- reproducibility ------------------------------------------------------------------------

def test_scene_is_rebuilt_from_its_seed(scenes):
    """Same seed → same fingerprint, through random_scene, make_scene("random") and a
    to_dict/from_dict round trip that resamples the clouds (region i uses seed + i); other
    seeds give other scenes."""
    for seed in (0, 17, 42):
        scene = scenes[seed]
        assert scene.name == f"random-{seed}" and scene.seed == seed
        assert random_scene(seed).fingerprint() == scene.fingerprint()
        assert make_scene("random", seed).fingerprint() == scene.fingerprint()
        assert Scene.from_dict(scene.to_dict()).fingerprint() == scene.fingerprint()
    assert len({s.fingerprint() for s in scenes.values()}) == len(scenes)


# --- geometry -------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", SEEDS)
def test_scene_geometry(scenes, seed):
    """One target; the straight segment is blocked (within 0.5 m of a cloud point); start and
    target ≥ 3 m from every point; every point in its region and the workspace; the start,
    the target and the finish point 1 m inside the side walls; 2-6 regions."""
    scene = scenes[seed]
    start, targets = np.asarray(scene.start), np.atleast_2d(scene.targets)
    assert targets.shape == (1, 3)
    target = targets[0]
    points = scene.all_points
    assert PARAMS.regions[0] <= len(scene.regions) <= PARAMS.regions[1]
    assert _segment_distances(points, start, target).min() <= PARAMS.blocking_distance
    assert np.linalg.norm(points - start, axis=1).min() >= PARAMS.clearance
    assert np.linalg.norm(points - target, axis=1).min() >= PARAMS.clearance
    for region, cloud in zip(scene.regions, scene.clouds, strict=True):
        assert _kind(region) in REGION_KINDS
        assert np.all(region.shape.contains(cloud))
        assert np.all(cloud >= WORKSPACE_LOWER) and np.all(cloud <= WORKSPACE_UPPER)
    margin = PARAMS.workspace_margin
    for p in (start, target, np.asarray(scene.finish[0])):
        assert np.all(p[:2] >= WORKSPACE_LOWER[:2] + margin - 1e-9)
        assert np.all(p[:2] <= WORKSPACE_UPPER[:2] - margin + 1e-9)
        assert PARAMS.altitude[0] <= p[2] <= PARAMS.altitude[1]


@pytest.mark.parametrize("seed", SEEDS)
def test_finish_line_is_two_metres_past_the_field(scenes, seed):
    """The finish direction is the unit heading start → target; the finish point lies on the
    segment, 2 m past the farthest cloud point along the line; the start is at least the
    lead-in before the nearest one; the field is at most the deepest field deep; the target
    is the run-out beyond the field."""
    scene = scenes[seed]
    start, target = np.asarray(scene.start), np.asarray(scene.targets[0])
    point, direction = (np.asarray(v) for v in scene.finish)
    length = np.linalg.norm(target - start)
    np.testing.assert_allclose(direction, (target - start) / length, atol=1e-12)
    along = (scene.all_points - start) @ direction
    finish_along = (point - start) @ direction
    np.testing.assert_allclose(point, start + finish_along * direction, atol=1e-9)
    assert finish_along == pytest.approx(along.max() + PARAMS.finish_margin)
    assert 0 < finish_along < length
    assert length == pytest.approx(along.max() + PARAMS.run_out)
    assert along.min() >= PARAMS.lead_in - 1e-9
    assert along.max() - along.min() <= PARAMS.depth[1]


def test_passage_progress(scenes):
    """Signed distance past the finish line: −(finish distance) at the start, 0 on the line,
    run-out − finish margin at the target; vectorised over (n, 3)."""
    scene = scenes[3]
    start, target = np.asarray(scene.start), np.asarray(scene.targets[0])
    point = np.asarray(scene.finish[0])
    assert passage_progress(scene, start) == pytest.approx(-np.linalg.norm(point - start))
    assert passage_progress(scene, point) == pytest.approx(0.0, abs=1e-9)
    assert passage_progress(scene, target) == pytest.approx(
        PARAMS.run_out - PARAMS.finish_margin)
    both = passage_progress(scene, np.stack([start, target]))
    assert both.shape == (2,) and both[0] < 0 < both[1]
    with pytest.raises(ValueError, match="no finish line"):
        passage_progress(make_scene("paper"), start)


# --- variety --------------------------------------------------------------------------------

def test_region_counts_and_kinds_vary(scenes):
    """Over 50 seeds every region count 2-6 and every kind appears, and the regions of the
    nonconvex kinds are nonconvex (some midpoints of their clouds fall outside them) while
    boxes and cylinders are not."""
    counts = collections.Counter(len(s.regions) for s in scenes.values())
    assert set(counts) == set(range(PARAMS.regions[0], PARAMS.regions[1] + 1))
    kinds = collections.Counter(_kind(r) for s in scenes.values() for r in s.regions)
    assert set(kinds) == set(REGION_KINDS)
    for scene in list(scenes.values())[:15]:
        for region, cloud in zip(scene.regions, scene.clouds, strict=True):
            nonconvex = _midpoints_outside(region.shape, cloud) > 0
            assert nonconvex == (_kind(region) in NONCONVEX_KINDS), region


def test_kinds_and_counts_follow_the_parameters():
    params = dataclasses.replace(PARAMS, regions=(3, 3), kinds=("cylinder", "L-wall"))
    for seed in range(5):
        scene = random_scene(seed, params)
        assert len(scene.regions) == 3
        assert {_kind(r) for r in scene.regions} <= {"cylinder", "L-wall"}


# --- validation -----------------------------------------------------------------------------

@pytest.mark.parametrize("field, value", [
    ("regions", (0, 3)), ("regions", (4, 2)), ("regions", (2.0, 6.0)),
    ("depth", (12.0, 4.0)), ("depth", (4.0, float("nan"))), ("width", 5.0),
    ("height", (3.0, 30.0)), ("altitude", (2.0, 19.0)), ("radius", (0.0, 1.0)),
    ("density", 0.0), ("lead_in", 2.0), ("run_out", 1.0), ("run_out", 70.0),
    ("finish_margin", -1.0), ("blocking_distance", 0.0), ("lateral_spread", -1.0),
    ("workspace_margin", float("inf")), ("kinds", ()), ("kinds", ("pyramid",)),
    ("max_attempts", 0),
])
def test_bad_params_rejected_with_field_named(field, value):
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(PARAMS, **{field: value})


@pytest.mark.parametrize("seed", [-1, 1.5, True, "3"])
def test_bad_seed_rejected(seed):
    with pytest.raises(ValueError, match="seed"):
        random_scene(seed)


def test_impossible_layout_raises_clear_error():
    """Six regions that must not touch in a 1 m deep field, offset at most 0.5 m across the
    line, cannot be laid out: a clear error after max_attempts tries."""
    params = dataclasses.replace(PARAMS, regions=(6, 6), depth=(1.0, 1.0), lateral_spread=0.5,
                                 max_attempts=5)
    with pytest.raises(ValueError, match="no valid layout in 5 attempts"):
        random_scene(0, params)

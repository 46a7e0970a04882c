"""Properties of the scenes, the Halton point clouds and the virtual LiDAR."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from paper_repro.problem.distance import clearance
from paper_repro.world.lidar import Lidar
from paper_repro.world.scenarios import encounter_scene, make_scene, paper_scene
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER, Region
from paper_repro.world.shapes import Box, Cylinder, Difference, Union, halton_cloud

SHAPES = {
    "box": Box((1.0, 2.0, 3.0), (2.0, 3.0, 4.0)),
    "cylinder": Cylinder((-3.0, 4.0, 0.0), 1.5, 5.0),
    "union": Union((Box((0.0, 0.0, 2.0), (4.0, 1.0, 2.0)), Box((1.5, 1.5, 2.0), (1.0, 4.0, 2.0)))),
    "difference": Difference(Box((0.0, 0.0, 5.0), (4.0, 4.0, 4.0)),
                             Box((0.0, 1.0, 5.5), (2.0, 3.0, 4.0))),
}


@pytest.fixture(scope="module")
def paper():
    return paper_scene()


@pytest.fixture(scope="module")
def encounter():
    return encounter_scene()


def _segment(a, b, n=4001) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def _midpoints_outside(shape, cloud) -> int:
    """Number of pairs of cloud points whose midpoint is not in the shape."""
    mids = (cloud[:, None, :] + cloud[None, :, :]) / 2
    return int(np.sum(~shape.contains(mids.reshape(-1, 3))))


# --- Halton clouds --------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(SHAPES))
def test_halton_cloud_reproducible_and_inside_shape(name):
    """Same seed → identical cloud; another seed → a different cloud; every point lies in
    the shape and in its bounding box."""
    shape = SHAPES[name]
    a = halton_cloud(shape, 3.0, seed=5)
    b = halton_cloud(shape, 3.0, seed=5)
    c = halton_cloud(shape, 3.0, seed=6)
    assert a.ndim == 2 and a.shape[1] == 3 and len(a) > 10
    np.testing.assert_array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)
    assert np.all(shape.contains(a)) and np.all(shape.contains(c))
    lo, hi = shape.bounds()
    assert np.all(a >= lo) and np.all(a <= hi)


def test_halton_box_count_matches_density():
    """A box keeps every point of its bounding box: exactly round(density · volume) points."""
    box = SHAPES["box"]
    for density in (0.5, 3.0, 10.0):
        assert len(halton_cloud(box, density, seed=1)) == round(density * 2 * 3 * 4)


def test_halton_cylinder_density_is_uniform():
    """Dropping the points outside the shape keeps the density: a cylinder holds about
    density · πr²h points (low-discrepancy sampling: within 5 %)."""
    cyl = SHAPES["cylinder"]
    n = len(halton_cloud(cyl, 10.0, seed=3))
    assert n == pytest.approx(10.0 * np.pi * 1.5**2 * 5.0, rel=0.05)


@pytest.mark.parametrize("factory", [paper_scene, encounter_scene])
def test_scene_clouds_inside_regions_and_workspace(factory):
    """Every cloud point lies in its region's shape and in [-25, 25]² × [0, 25]; start and
    targets are in the workspace; make_scene reproduces the scene for a seed and region i
    uses the Halton seed ``seed + i``."""
    scene = factory(seed=3)
    assert len(scene.clouds) == len(scene.regions) > 0
    for i, (region, cloud) in enumerate(zip(scene.regions, scene.clouds, strict=True)):
        assert len(cloud) > 0
        assert np.all(region.shape.contains(cloud))
        assert np.all(cloud >= WORKSPACE_LOWER) and np.all(cloud <= WORKSPACE_UPPER)
        np.testing.assert_array_equal(cloud, halton_cloud(region.shape, region.density, 3 + i))
    for p in [scene.start, *scene.targets]:
        assert np.all(np.asarray(p) >= WORKSPACE_LOWER) and np.all(np.asarray(p) <= WORKSPACE_UPPER)
    again = make_scene(scene.name, seed=3)
    for c1, c2 in zip(scene.clouds, again.clouds, strict=True):
        np.testing.assert_array_equal(c1, c2)
    other = factory(seed=4)
    assert not all(c1.shape == c2.shape and np.array_equal(c1, c2)
                   for c1, c2 in zip(scene.clouds, other.clouds, strict=True))
    np.testing.assert_array_equal(scene.all_points, np.concatenate(scene.clouds))


# --- geometry of the scenes -----------------------------------------------------------------

def test_paper_scene_has_nonconvex_regions(paper):
    """At least one region is nonconvex: two of its points have their midpoint outside it.
    The L-wall and the U-channel are; the box tower and the cylinder, being convex, are not."""
    outside = {r.name: _midpoints_outside(r.shape, c)
               for r, c in zip(paper.regions, paper.clouds, strict=True)}
    assert sum(n > 0 for n in outside.values()) >= 1
    assert outside["L-wall"] > 0 and outside["U-channel"] > 0
    assert outside["tower"] == 0 and outside["column"] == 0


def test_encounter_region_is_nonconvex(encounter):
    """The encounter corner is an L: some midpoints of its cloud fall outside it."""
    assert _midpoints_outside(encounter.regions[0].shape, encounter.clouds[0]) > 0


def test_paper_scene_regions_lie_across_the_path(paper):
    """Each straight leg (start → target 1, target 1 → target 2) passes within 1 m of some
    region's cloud, so flying straight is not safe."""
    waypoints = [paper.start, *paper.targets]
    assert len(waypoints) == 3
    for a, b in pairwise(waypoints):
        seg = _segment(a, b)
        closest = min(float(clearance(seg, c).min()) for c in paper.clouds)
        assert closest < 1.0, (a, b, closest)


def test_paper_scene_mission_of_section_v(paper):
    """Start [22, −22, 0], targets [−12, 18, 11] then [−21, 18, 0], as printed in Section V."""
    np.testing.assert_array_equal(paper.start, (22.0, -22.0, 0.0))
    np.testing.assert_array_equal(np.asarray(paper.targets), [[-12, 18, 11], [-21, 18, 0]])


def test_encounter_scene_geometry(encounter):
    """The UAV starts 2-4.5 m from the region and its straight line to the target passes
    within 1.5 m of the cloud."""
    cloud = encounter.clouds[0]
    start_clearance = float(clearance(np.asarray(encounter.start, float), cloud))
    assert 2.0 <= start_clearance <= 4.5
    seg = _segment(encounter.start, encounter.targets[0])
    assert float(clearance(seg, cloud).min()) < 1.5


# --- shapes ---------------------------------------------------------------------------------

def test_shape_membership():
    """Box, Cylinder, Union and Difference contain exactly the expected test points."""
    box, cyl, uni, diff = (SHAPES[k] for k in ("box", "cylinder", "union", "difference"))
    pts = np.array([[1.0, 2.0, 3.0], [2.0, 3.5, 5.0], [2.01, 2.0, 3.0]])
    np.testing.assert_array_equal(box.contains(pts), [True, True, False])
    pts = np.array([[-3.0, 4.0, 2.5], [-3.0, 5.49, 0.1], [-3.0, 5.51, 1.0], [-3.0, 4.0, 5.1]])
    np.testing.assert_array_equal(cyl.contains(pts), [True, True, False, False])
    pts = np.array([[-1.9, 0.0, 2.0], [1.5, 3.4, 2.0], [-1.0, 2.0, 2.0]])
    np.testing.assert_array_equal(uni.contains(pts), [True, True, False])
    # outer box, inner cavity (open towards +y), and outside
    pts = np.array([[0.0, -1.8, 5.0], [0.0, 1.0, 5.0], [3.0, 0.0, 5.0]])
    np.testing.assert_array_equal(diff.contains(pts), [True, False, False])
    assert box.contains(np.array([1.0, 2.0, 3.0]))  # a single (3,) point works too


# --- LiDAR ----------------------------------------------------------------------------------

def _random_scene():
    return make_scene("random", 3)


@pytest.mark.parametrize("factory", [paper_scene, encounter_scene, _random_scene])
@pytest.mark.parametrize("r_s", [0.7, 3.0])
def test_lidar_matches_brute_force(factory, r_s, rng):
    """Per region, the scan returns exactly the points within r_s of the UAV (brute force),
    in their cloud order, at random positions in the workspace and near the clouds (a random
    scene: several regions, in view at once or not, each cut from one query's sorted
    indices)."""
    scene = factory()
    lidar = Lidar(scene.clouds, r_s)
    everything = scene.all_points
    positions = np.vstack([
        rng.uniform(WORKSPACE_LOWER, WORKSPACE_UPPER, size=(40, 3)),
        everything[rng.choice(len(everything), 40)] + rng.normal(scale=1.0, size=(40, 3)),
        np.asarray(scene.start, float),
    ])
    seen = 0
    for p in positions:
        scan = lidar.scan(p)
        assert len(scan) == len(scene.clouds)
        for got, cloud in zip(scan, scene.clouds, strict=True):
            expected = cloud[np.linalg.norm(cloud - p, axis=1) <= r_s]
            assert got.shape == expected.shape
            np.testing.assert_array_equal(got, expected)
            seen += len(got)
    assert seen > 0  # the near-cloud positions do see points


@pytest.mark.parametrize("position", [(-24.0, -24.0, 24.0), (1000.0, -1000.0, 500.0)])
def test_lidar_far_from_everything_is_empty(paper, position):
    """Out of range of every cloud, each region's scan is an empty (0, 3) array."""
    p = np.asarray(position)
    assert float(clearance(p, paper.all_points)) > 3.0
    scan = Lidar(paper.clouds, 3.0).scan(p)
    assert len(scan) == len(paper.clouds)
    for s in scan:
        assert s.shape == (0, 3)


@pytest.mark.parametrize("range_", [0.0, -3.0, float("nan"), float("inf")])
def test_lidar_bad_range(paper, range_):
    """The LiDAR range must be finite and > 0."""
    with pytest.raises(ValueError, match="range"):
        Lidar(paper.clouds, range_)


@pytest.mark.parametrize("position", [(0.0, 0.0), (0.0, np.nan, 0.0)])
def test_lidar_bad_position(paper, position):
    """A scan needs a finite (3,) position."""
    with pytest.raises(ValueError, match="position"):
        Lidar(paper.clouds, 3.0).scan(position)


# --- validation -----------------------------------------------------------------------------

@pytest.mark.parametrize("density", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_density(density):
    """A region or a Halton cloud needs a finite density > 0."""
    with pytest.raises(ValueError, match="density"):
        Region("r", SHAPES["box"], density)
    with pytest.raises(ValueError, match="density"):
        halton_cloud(SHAPES["box"], density, seed=0)


def test_unknown_scenario():
    """make_scene rejects an unknown name with a ValueError naming the scenario."""
    with pytest.raises(ValueError, match="scenario"):
        make_scene("nope")

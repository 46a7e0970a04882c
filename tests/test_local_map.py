"""The local voxel map: what enters it, what survives in it, what leaves it, and its size."""

import math

import numpy as np
import pytest

from paper_repro.config import SensorParams
from paper_repro.world.lidar import Lidar
from paper_repro.world.local_map import VoxelMap
from paper_repro.world.shapes import Box, halton_cloud

EMPTY = [np.zeros((0, 3))]


def _wall(seed=0):
    """A 4 × 0.5 × 4 m wall 1.5 m in front of the origin, at 3 points/m³."""
    return halton_cloud(Box((1.75, 0.0, 0.0), (0.5, 4.0, 4.0)), 3.0, seed)


def test_one_return_is_not_enough_and_repeated_hits_are():
    m = VoxelMap()
    point = [np.array([[1.0, 0.2, 0.3]])]
    needed = math.ceil(m.occupied / m.hit)
    for k in range(needed - 1):
        m.update(point, np.zeros(3), 0.01 * k)
        assert not m.occupied_mask.any()
    m.update(point, np.zeros(3), 0.1)
    assert m.occupied_mask.sum() == 1
    np.testing.assert_allclose(m.regions(np.zeros(3), 3.0, 1)[0], point[0])


def test_spurious_returns_never_become_occupied():
    # Far from the only region, every return is spurious: two per scan, uniform in the sphere.
    far = [np.array([[40.0, 40.0, 10.0]])]
    lidar = Lidar(far, noise=SensorParams(spurious_rate=2.0, seed=3))
    m, position = VoxelMap(), np.array([0.0, 0.0, 5.0])
    returns = 0
    for k in range(2000):
        scan = lidar.scan(position)
        returns += len(scan[0])
        m.update(scan, position, 0.01 * k)
        assert not m.occupied_mask.any(), f"a spurious voxel became occupied at scan {k}"
    assert returns > 3000  # the sensor did invent returns


def test_a_confirmed_voxel_survives_dropouts_and_is_cleared_once_seen_empty():
    m = VoxelMap()
    point = [np.array([[1.0, 0.2, 0.3]])]
    for k in range(20):
        m.update(point, np.zeros(3), 0.01 * k)
    survives = math.floor((m.clamp[1] - m.release) / -m.miss)
    assert survives == 20
    for k in range(survives):  # the return is dropped this many scans in a row
        m.update(EMPTY, np.zeros(3), 1.0 + 0.01 * k)
        assert m.occupied_mask.sum() == 1
    m.update(EMPTY, np.zeros(3), 2.0)
    assert not m.occupied_mask.any()


def test_an_occupied_voxel_is_released_below_release_not_below_occupied():
    # Hits and misses that balance near the threshold: with the hysteresis the voxel stays in
    # the controller's set; without it (release = occupied) it leaves and enters again.
    point = [np.array([[1.0, 0.2, 0.3]])]
    changes = {}
    for release in (-1.0, 2.0):
        m, state, flips = VoxelMap(release=release), False, 0
        # 3 hits (L = 2.55), 3 misses (1.8), then cycles of 5 hits and 17 misses
        # (5 × 0.85 = 17 × 0.25): L swings about 2, across the threshold at every hit
        cycle = [True, False, False, False] * 4 + [True] + [False] * 5
        pattern = [True] * 3 + [False] * 3 + cycle * 20
        for k, hit in enumerate(pattern):
            m.update(point if hit else EMPTY, np.zeros(3), 0.01 * k)
            now = bool(m.occupied_mask.any())
            flips += now != state
            state = now
        changes[release] = flips
    assert changes[-1.0] == 1  # entered once, never left
    assert changes[2.0] >= 20


def test_the_returns_of_a_point_on_a_voxel_face_make_one_point():
    # A point on the face x = 1.0 between two 0.5 m voxels, seen with 5 cm range noise: its
    # returns fall on both sides. Associated with the nearest representative they make one
    # point; counted by the voxel they fall in, two.
    rng = np.random.default_rng(4)
    true = np.array([1.0, 0.2, 0.3])
    counts = {}
    for merge in (0.2, 0.0):
        m = VoxelMap(merge_radius=merge)
        for k in range(300):
            m.update([true + rng.normal(0.0, 0.05, (1, 3))], np.zeros(3), 0.01 * k)
        mapped = m.regions(np.zeros(3), 3.0, 1)[0]
        counts[merge] = len(mapped)
        if merge:
            assert np.linalg.norm(mapped[0] - true) < 0.02  # the mean of 300 returns
    assert counts == {0.2: 1, 0.0: 2}


def test_a_noisy_lidar_with_dropouts_keeps_the_wall_and_averages_its_noise():
    wall = _wall()
    noise = SensorParams(range_noise=0.05, dropout=0.2, spurious_rate=2.0, seed=1)
    lidar, m = Lidar([wall], noise=noise), VoxelMap()
    position = np.zeros(3)
    in_view = wall[np.linalg.norm(wall - position, axis=1) <= 3.0 - math.sqrt(3) * 0.5]
    raw_error, kept = [], []
    for k in range(300):
        scan = lidar.scan(position)
        m.update(scan, position, 0.01 * k)
        if k >= 50:
            raw = scan[0]
            raw_error.append(np.min(np.linalg.norm(raw[:, None] - wall[None], axis=2), 1))
            near = m.regions(position, 3.0, 1)[0]
            # every point that lies fully in view stays in the map through the dropouts
            kept.append(np.min(np.linalg.norm(in_view[:, None] - near[None], axis=2), 1))
    assert np.max(kept) < 0.5 * m.voxel
    mapped = m.regions(position, 3.0, 1)[0]
    map_error = np.min(np.linalg.norm(mapped[:, None] - wall[None], axis=2), 1)
    # a voxel's mean of returns sits closer to the true point than one noisy return does
    assert np.median(map_error) < 0.5 * np.median(np.concatenate(raw_error))


def test_points_behind_the_vehicle_persist_and_forgetting_is_by_distance_or_age():
    wall = _wall()
    m = VoxelMap(keep_radius=10.0, max_age=5.0)
    lidar = Lidar([wall])
    for k in range(10):
        m.update(lidar.scan(np.zeros(3)), np.zeros(3), 0.01 * k)
    n = int(m.occupied_mask.sum())
    assert n > 0
    away = np.array([-6.0, 0.0, 0.0])  # the wall is out of range, 7.5 m behind
    m.update(lidar.scan(away), away, 1.0)
    assert int(m.occupied_mask.sum()) == n
    m.update(lidar.scan(away), away, 6.0)  # unseen for more than max_age
    assert len(m) == 0
    m2 = VoxelMap(keep_radius=5.0)
    for k in range(10):
        m2.update(lidar.scan(np.zeros(3)), np.zeros(3), 0.01 * k)
    m2.update(lidar.scan(away), away, 1.0)  # beyond keep_radius
    assert len(m2) == 0


def test_memory_stays_bounded_on_a_long_flight():
    rng = np.random.default_rng(0)
    clouds = [halton_cloud(Box((x, 0.0, 0.0), (1.0, 6.0, 6.0)), 3.0, i)
              for i, x in enumerate(np.arange(2.0, 200.0, 4.0))]
    lidar = Lidar(clouds, noise=SensorParams(spurious_rate=2.0, seed=2))
    m = VoxelMap(max_voxels=400, keep_radius=6.0)
    peak = 0
    for k, x in enumerate(np.arange(0.0, 200.0, 0.05)):
        p = np.array([x, rng.normal(0, 0.1), 0.0])
        m.update(lidar.scan(p), p, 0.01 * k)
        peak = max(peak, len(m))
        assert np.all(np.linalg.norm(m.centre - p, axis=1) <= 6.0)
    assert peak <= 400


def test_excluded_regions_stay_out_and_regions_keep_their_labels():
    a, b = np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    m = VoxelMap()
    for k in range(5):
        m.update([a, b], np.zeros(3), 0.01 * k, exclude=[False, True])
    got = m.regions(np.zeros(3), 3.0, 2)
    np.testing.assert_allclose(got[0], a)
    assert got[1].shape == (0, 3)


@pytest.mark.parametrize("kwargs,word", [
    ({"voxel": 0.0}, "voxel"), ({"miss": 0.1}, "miss"), ({"occupied": 0.5}, "occupied"),
    ({"clamp_high": 1.0}, "clamp_high"), ({"keep_radius": 2.0}, "keep_radius"),
    ({"max_voxels": 0}, "max_voxels"), ({"max_age": 0.0}, "max_age"),
    ({"mean_window": 0}, "mean_window"), ({"release": 3.0}, "release"),
    ({"release": -3.0}, "release"), ({"merge_radius": 0.5}, "merge_radius"),
    ({"merge_radius": -0.1}, "merge_radius")])
def test_bad_parameters_are_named(kwargs, word):
    with pytest.raises(ValueError, match=word):
        VoxelMap(**kwargs)


def test_bad_update_arguments_are_named():
    m = VoxelMap()
    with pytest.raises(ValueError, match="position"):
        m.update(EMPTY, [0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="exclude"):
        m.update(EMPTY, np.zeros(3), 0.0, exclude=[True, False])
    with pytest.raises(ValueError, match="scan must hold finite"):
        m.update([np.array([[1.0, np.nan, 0.0]])], np.zeros(3), 0.0)
    assert len(m) == 0  # refused before anything entered


# --- the map in the closed loop (``sensor.map_voxel``) ----------------------------------------

def test_map_voxel_is_checked():
    from paper_repro import SensorParams

    for bad in (-0.1, 3.0, float("nan")):
        with pytest.raises(ValueError, match="map_voxel"):
            SensorParams(map_voxel=bad)


def test_the_map_reader_maps_static_regions_and_passes_moving_ones_through():
    import dataclasses

    from paper_repro import Config
    from paper_repro.sim.perception import Perception
    from paper_repro.world.scenarios import make_scene

    scene = make_scene("encounter")
    base = Config()
    paper = Perception(base, scene)
    assert paper.read_map is None and paper.local_map is None  # the paper reads the raw scan
    cfg = dataclasses.replace(base, sensor=dataclasses.replace(base.sensor, map_voxel=0.5))
    read = Perception(cfg, scene).read_map
    n = len(scene.clouds)
    a = np.array([[1.0, 0.0, 0.0]])
    scan = [a] + [np.zeros((0, 3))] * (n - 1)
    still = [np.zeros(3)] * n
    for k in range(3):  # three hits confirm the voxel
        got = read(scan, np.zeros(3), 0.01 * k, still)
    np.testing.assert_allclose(got[0], a)
    empty = [np.zeros((0, 3))] * n
    assert len(read(empty, np.zeros(3), 0.05, still)[0]) == 1  # a dropped return persists
    moving = [np.array([1.0, 0.0, 0.0])] + [np.zeros(3)] * (n - 1)
    b = np.array([[0.0, 1.0, 0.0]])
    got = read([b] + [np.zeros((0, 3))] * (n - 1), np.zeros(3), 0.06, moving)
    np.testing.assert_allclose(got[0], b)  # a moving region: this scan, not the map


def test_the_map_needs_a_3d_scene():
    import dataclasses

    from paper_repro import Config
    from paper_repro.sim.perception import Perception
    from paper_repro.world.planar import planar_scene

    base = Config()
    cfg = dataclasses.replace(base, sensor=dataclasses.replace(base.sensor, map_voxel=0.5))
    with pytest.raises(ValueError, match="map_voxel"):
        Perception(cfg, planar_scene())


def test_a_noisy_flight_reading_the_map_stays_clear_and_stops_chattering():
    """The encounter with the noisy LiDAR of the sensor-noise study: reading the raw scan, the
    visible set changes at every scan and the thrusts chatter; reading the map, the set is
    steady, the thrusts' power above 5 Hz is the issue's goal (≤ 0.1) and the flight stays
    clear."""
    import dataclasses

    from paper_repro import Config, SimulationParams, simulate
    from paper_repro.analysis.metrics import summary_row
    from paper_repro.studies.catalogue import NOISY_LIDAR

    rows = {}
    for voxel in (0.0, 0.5):
        cfg = dataclasses.replace(
            Config(), sensor=dataclasses.replace(NOISY_LIDAR, map_voxel=voxel),
            simulation=SimulationParams(scenario="encounter", max_steps=700))
        result = simulate(cfg, progress=False)
        rows[voxel] = (summary_row(result), np.abs(np.diff(result.visible_points)).mean())
    (raw, raw_changes), (mapped, map_changes) = rows[0.0], rows[0.5]
    assert mapped["min_clearance_m"] > 0.35
    assert map_changes < 0.1 * raw_changes
    assert raw["hf_energy_fraction"] > 0.5  # the noise does make the raw scan chatter
    assert mapped["hf_energy_fraction"] <= 0.1
    assert mapped["tv_u_rate_N_per_s"] < 0.1 * raw["tv_u_rate_N_per_s"]

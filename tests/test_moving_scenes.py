"""Regions that move rigidly: :class:`Motion`, moving scenes, the LiDAR at time t, and the
closed loop with moving regions (true clearance, the velocities handed to the controller).

Closed loops here use a fake controller that hovers (no solver is built), except one short
free flight of the real controller that times the ``crossing`` and ``oncoming`` scenes.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math

import numpy as np
import pytest

from paper_repro import Config, NMPCParams, SimulationParams
from paper_repro.config import SensorParams
from paper_repro.problem.ocp import NMPCSolution
from paper_repro.sim.loop import simulate
from paper_repro.sim.result import SimulationResult
from paper_repro.studies.runs import run_key
from paper_repro.vehicles.quadrotor import equilibrium
from paper_repro.world.lidar import Lidar
from paper_repro.world.motion import Motion
from paper_repro.world.random_scenes import RandomSceneParams, random_scene
from paper_repro.world.scenarios import MEETING_TIME, make_scene
from paper_repro.world.scene import Region, Scene
from paper_repro.world.shapes import Box

# --- Motion ---------------------------------------------------------------------------------

ZIGZAG = Motion((0.0, 2.0, 4.0), ((0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (2.0, 4.0, 0.0)))


@pytest.mark.parametrize("t, offset, velocity", [
    (-1.0, (0, 0, 0), (0, 0, 0)),      # before the first time: the first offset, at rest
    (0.0, (0, 0, 0), (1, 0, 0)),
    (1.0, (1, 0, 0), (1, 0, 0)),       # linear in between
    (2.0, (2, 0, 0), (0, 2, 0)),       # a breakpoint: the segment that starts there
    (3.0, (2, 2, 0), (0, 2, 0)),
    (4.0, (2, 4, 0), (0, 2, 0)),
    (6.5, (2, 9, 0), (0, 2, 0)),       # after the last time: the last segment goes on
])
def test_motion_interpolates_and_extrapolates(t, offset, velocity):
    np.testing.assert_allclose(ZIGZAG.offset(t), offset, atol=1e-12)
    np.testing.assert_allclose(ZIGZAG.velocity(t), velocity, atol=1e-12)
    assert ZIGZAG.offset(t).shape == ZIGZAG.velocity(t).shape == (3,)


def test_offsets_at_many_times_are_the_offsets_one_at_a_time():
    """The vectorised c(t) is :meth:`Motion.offset` bit for bit, breakpoints, the time before
    the first and the extrapolation after the last included; a bad time array is named."""
    t = np.array([-1.0, 0.0, 0.7, 2.0, 3.3, 4.0, 6.5, 1e3])
    for m in (ZIGZAG, Motion.constant((0.5, -1.0, 0.2)), Motion((3.0,), ((1.0, 1.0, 1.0),))):
        np.testing.assert_array_equal(m.offsets_at(t), np.array([m.offset(s) for s in t]))
    with pytest.raises(ValueError, match="^times t must be a 1-D array of finite numbers"):
        ZIGZAG.offsets_at(np.array([0.0, np.nan]))


def test_motion_constant_and_single_time():
    """Motion.constant(v, c0): c(t) = c0 + v·t for t ≥ 0; a single time is at rest for ever;
    the stored values are plain floats, and a Motion round-trips through JSON."""
    m = Motion.constant((0.5, -1.0, 0.0), start_offset=(1.0, 2.0, 3.0))
    for t in (0.0, 0.3, 1.0, 17.0):
        np.testing.assert_allclose(m.offset(t), np.array([1, 2, 3]) + t * np.array(
            [0.5, -1.0, 0.0]), atol=1e-12)
        np.testing.assert_allclose(m.velocity(t), (0.5, -1.0, 0.0), atol=1e-15)
    still = Motion((3.0,), ((1.0, 1.0, 1.0),))
    for t in (0.0, 3.0, 100.0):
        np.testing.assert_array_equal(still.offset(t), (1, 1, 1))
        np.testing.assert_array_equal(still.velocity(t), (0, 0, 0))
    assert all(type(v) is float for v in m.times)
    again = Motion.from_dict(json.loads(json.dumps(m.to_dict())))
    assert again == m and hash(again) == hash(m)


@pytest.mark.parametrize("times, offsets, field", [
    ((), (), "Motion.times"),
    ((0.0, 0.0), ((0, 0, 0), (1, 0, 0)), "Motion.times"),
    ((1.0, 0.0), ((0, 0, 0), (1, 0, 0)), "Motion.times"),
    ((0.0, math.nan), ((0, 0, 0), (1, 0, 0)), "Motion.times"),
    (("0", 1.0), ((0, 0, 0), (1, 0, 0)), "Motion.times"),
    ((0.0, 1.0), ((0, 0, 0),), "Motion.offsets"),
    ((0.0, 1.0), ((0, 0, 0), (1, 0)), r"Motion.offsets\[1\]"),
    ((0.0, 1.0), ((0, 0, math.inf), (1, 0, 0)), r"Motion.offsets\[0\]"),
])
def test_motion_validation_names_the_field(times, offsets, field):
    with pytest.raises(ValueError, match=field):
        Motion(times, offsets)


def test_motion_bad_arguments():
    with pytest.raises(ValueError, match="velocity"):
        Motion.constant((1.0, 0.0))
    with pytest.raises(ValueError, match="start_offset"):
        Motion.constant((1.0, 0.0, 0.0), start_offset=(0.0, math.nan, 0.0))
    for t in (math.nan, "1", None):
        with pytest.raises(ValueError, match="time t"):
            ZIGZAG.offset(t)


# --- scenes ---------------------------------------------------------------------------------

# Invariance, not a result: the fingerprints and the SHA-256 of json.dumps(to_dict(),
# sort_keys=True) computed by the code *before* motions existed (commit 9dd5191). Cached runs
# are keyed by them: a static scene must describe itself exactly as it did.
STATIC_BEFORE_MOTIONS = {
    ("paper", 7): ("aca83a0f90ef9775c054565ca03a1a842a5591232e0ff4bdf62a254bbee9d544",
                   "3e0b9fd474154e07fc14b573e0c9da66a9263b2f59c1e223dc60de2157bfd6a7"),
    ("encounter", 7): ("ae8b9c502aa0fe7a6ee5c1558f7d677bb4db14521eccb1da97765be57b456356",
                       "465e4c5cba9080f317125530b9bd6d6a994c8ead1abb5f33d7a0486d2fc18ace"),
    ("random", 3): ("502941573777cbafe9ee99ecb3c42901274f633e9718224ce05c38cd8c313055",
                    "4275cba67a6126ffb34aa224a8429927ce4eb5f363e7ebc983a46873e700f493"),
}


@pytest.mark.parametrize("name, seed", list(STATIC_BEFORE_MOTIONS))
def test_static_scene_description_unchanged(name, seed):
    scene = make_scene(name, seed)
    fingerprint, described = STATIC_BEFORE_MOTIONS[name, seed]
    assert not scene.is_moving and scene.motions is None
    assert scene.fingerprint() == fingerprint
    data = scene.to_dict()
    assert "motions" not in data
    assert hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest() == described
    # Motions that are all None are a static scene.
    same = dataclasses.replace(scene, motions=(None,) * len(scene.regions))
    assert same.motions is None and same.fingerprint() == fingerprint
    assert scene.clouds_at(12.0) is scene.clouds


def test_run_key_follows_the_prediction():
    """The key is a function of the configuration: an explicit "static" is the default's key,
    another prediction is another run."""
    static = Config(nmpc=NMPCParams(prediction="static"))
    assert run_key(static, 1000, "fp") == run_key(Config(), 1000, "fp")
    oracle = Config(nmpc=NMPCParams(prediction="oracle"))
    assert run_key(oracle, 1000, "fp") != run_key(Config(), 1000, "fp")


@pytest.mark.parametrize("value", ["none", "Static", 1, None])
def test_prediction_is_validated(value):
    with pytest.raises(ValueError, match="prediction"):
        NMPCParams(prediction=value)


@pytest.mark.parametrize("name", ["crossing", "oncoming", "random-crossing"])
def test_moving_scene_round_trips(name):
    """to_dict → JSON → from_dict, with the stored clouds or regenerating them: the same
    fingerprint, motions and clouds at any time; the motions enter the fingerprint."""
    scene = make_scene(name, 3)
    assert scene.is_moving and len(scene.motions) == len(scene.regions)
    data = json.loads(json.dumps(scene.to_dict()))
    assert len(data["motions"]) == len(scene.regions)
    for clouds in (scene.clouds, None):
        again = Scene.from_dict(data, clouds)
        assert again.fingerprint() == scene.fingerprint() == data["fingerprint"]
        assert again.motions == scene.motions
        for a, b in zip(again.clouds_at(7.5), scene.clouds_at(7.5), strict=True):
            np.testing.assert_array_equal(a, b)
    still = dataclasses.replace(scene, motions=None)
    assert not still.is_moving and still.fingerprint() != scene.fingerprint()
    with pytest.raises(ValueError, match="fingerprint"):
        bad = dict(data, motions=[Motion.constant((0.0, 0.0, 9.0)).to_dict()
                                  for _ in scene.regions])
        Scene.from_dict(bad, scene.clouds)


def test_scene_motions_validated():
    scene = make_scene("encounter")
    with pytest.raises(ValueError, match="motions"):
        dataclasses.replace(scene, motions=(ZIGZAG, ZIGZAG))
    with pytest.raises(ValueError, match="motions"):
        dataclasses.replace(scene, motions=("fast",))


def test_clouds_at_moves_each_region_rigidly():
    scene = make_scene("crossing")
    (cloud,) = scene.clouds
    for t in (0.0, 3.0, MEETING_TIME, 20.0):
        (moved,) = scene.clouds_at(t)
        np.testing.assert_allclose(moved - cloud, np.broadcast_to([0.0, t, 0.0], cloud.shape),
                                   atol=1e-12)


# --- the crossing and oncoming scenes -------------------------------------------------------

@pytest.fixture(scope="module")
def straight_flight():
    """The real controller flying the crossing scene's start → target with no region at all
    (no avoidance, hence what any prediction that ignores the region would fly): 10 s."""
    from paper_repro.solvers.factory import make_controller

    config = Config(simulation=SimulationParams(scenario="crossing"))
    crossing = make_scene("crossing")
    free = Scene("free", (), crossing.start, crossing.targets)
    return simulate(config, make_controller(config), max_steps=1000, scene=free,
                    progress=False)


@pytest.mark.parametrize("name", ["crossing", "oncoming"])
def test_flown_straight_the_uav_meets_the_region(straight_flight, name):
    """Flying straight, the UAV is inside the moving region's box at some time between 5 and
    10 s; at the start it is more than the LiDAR range (3 m) from it; the finish line is ahead
    of the meeting point, 2 m past the box's far face."""
    scene = make_scene(name)
    (region,), (motion,) = scene.regions, scene.motions
    positions, times = straight_flight.x[:-1, :3], straight_flight.t
    inside = np.array([region.shape.contains(p - motion.offset(t))
                       for p, t in zip(positions, times, strict=True)])
    assert inside.any()
    first = times[np.argmax(inside)]
    assert 5.0 <= first <= 10.0, first
    start = np.asarray(scene.start)
    assert np.linalg.norm(scene.clouds_at(0.0)[0] - start, axis=1).min() > 3.0
    point, direction = (np.asarray(v) for v in scene.finish)
    np.testing.assert_array_equal(direction, (1.0, 0.0, 0.0))
    far_face = scene.clouds_at(first)[0][:, 0].max()
    assert point[0] == pytest.approx(far_face + 2.0, abs=0.1)
    assert np.linalg.norm(np.asarray(scene.targets[0]) - start) == pytest.approx(40.0)


def test_crossing_and_oncoming_velocities():
    crossing, oncoming = make_scene("crossing"), make_scene("oncoming")
    np.testing.assert_allclose(crossing.motions[0].velocity(5.0), (0.0, 1.0, 0.0), atol=1e-15)
    np.testing.assert_allclose(oncoming.motions[0].velocity(5.0), (-0.5, 0.0, 0.0), atol=1e-15)
    # The crossing box is centred on the path at the meeting time.
    centre = np.mean(crossing.clouds_at(MEETING_TIME)[0], axis=0)
    assert abs(centre[1]) < 0.1 and abs(centre[0] + 18.0) < 0.1


# --- random crossing scenes -----------------------------------------------------------------

@pytest.mark.parametrize("seed", range(8))
def test_random_crossing_scene(seed):
    """The static field of the seed, clouds included, each region with a constant horizontal
    velocity across the line (0.5-1.5 m/s), its centre crossing the line within 5 s of the
    UAV's expected arrival; start and target keep their clearance at every time."""
    params = RandomSceneParams()
    static, moving = random_scene(seed), random_scene(seed, moving=True)
    assert moving.name == f"random-crossing-{seed}" and static.name == f"random-{seed}"
    assert moving.regions == static.regions and moving.finish == static.finish
    for a, b in zip(moving.clouds, static.clouds, strict=True):
        np.testing.assert_array_equal(a, b)
    assert make_scene("random-crossing", seed).fingerprint() == moving.fingerprint()
    assert moving.fingerprint() != static.fingerprint()

    start, target = np.asarray(moving.start), np.asarray(moving.targets[0])
    length = np.linalg.norm(target - start)
    u = (target - start) / length
    n = np.array([-u[1], u[0], 0.0])
    for cloud, motion in zip(moving.clouds, moving.motions, strict=True):
        v = motion.velocity(0.0)
        assert abs(v @ u) < 1e-12 and v[2] == 0.0
        assert params.speed[0] <= np.linalg.norm(v) <= params.speed[1]
        centre = np.mean(cloud, axis=0) - start
        crossing = -((centre + motion.offset(0.0)) @ n) / (v @ n)
        arrival = -params.approach_time * math.log(1.0 - (centre @ u) / length)
        assert abs(crossing - arrival) <= params.crossing_spread + 1e-9
        assert crossing > 0.0
        np.testing.assert_allclose((centre + motion.offset(crossing)) @ n, 0.0, atol=1e-9)
    for t in (0.0, 10.0, 30.0, 60.0):
        points = np.concatenate(moving.clouds_at(t))
        assert np.linalg.norm(points - start, axis=1).min() >= params.clearance
        assert np.linalg.norm(points - target, axis=1).min() >= params.clearance


@pytest.mark.parametrize("seed", range(4))
def test_a_random_crossing_timed_to_another_pace_moves_the_same_regions_sooner(seed):
    """``approach_time`` (``SimulationParams``) times the same crossings to another pace: the
    field, its clouds and the regions' velocities are the seed's; each region's centre is on
    the line at the expected arrival for that pace plus the same draw from the spread, so the
    crossing times of two paces differ by the difference of their arrivals exactly."""
    slow, fast = make_scene("random-crossing", seed), make_scene("random-crossing", seed, 27.0)
    assert fast.name == f"random-crossing-{seed}@27s"
    assert make_scene("random-crossing", seed, 150.0).fingerprint() == slow.fingerprint()
    assert fast.fingerprint() != slow.fingerprint()
    assert fast.regions == slow.regions and fast.finish == slow.finish
    for a, b in zip(fast.clouds, slow.clouds, strict=True):
        np.testing.assert_array_equal(a, b)
    start, target = np.asarray(slow.start), np.asarray(slow.targets[0])
    length = np.linalg.norm(target - start)
    u = (target - start) / length
    n = np.array([-u[1], u[0], 0.0])
    for cloud, m_slow, m_fast in zip(slow.clouds, slow.motions, fast.motions, strict=True):
        v = m_slow.velocity(0.0)
        np.testing.assert_allclose(m_fast.velocity(0.0), v, rtol=0, atol=1e-12)
        centre = np.mean(cloud, axis=0) - start
        crossing = {pace: -((centre + m.offset(0.0)) @ n) / (v @ n)
                    for pace, m in ((150.0, m_slow), (27.0, m_fast))}
        log_share = math.log(1.0 - min(max(centre @ u, 0.0), 0.99 * length) / length)
        np.testing.assert_allclose(crossing[150.0] - crossing[27.0], -(150.0 - 27.0) * log_share,
                                   atol=1e-9)


def test_the_pace_of_crossings_is_refused_for_other_scenes():
    with pytest.raises(ValueError, match="approach_time"):
        make_scene("random", 1, 27.0)
    with pytest.raises(ValueError, match="approach_time"):
        SimulationParams(scenario="paper", approach_time=27.0)
    with pytest.raises(ValueError, match="approach_time"):
        SimulationParams(scenario="random-crossing", approach_time=-1.0)
    assert SimulationParams(scenario="random-crossing", approach_time=27.0).approach_time == 27


def test_random_moving_flag_and_params_validated():
    with pytest.raises(ValueError, match="moving"):
        random_scene(1, moving="yes")
    for field, value in (("speed", (0.0, 1.0)), ("speed", (2.0, 1.0)),
                         ("approach_time", 0.0), ("crossing_spread", -1.0)):
        with pytest.raises(ValueError, match=field):
            dataclasses.replace(RandomSceneParams(), **{field: value})


# --- LiDAR ----------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["crossing", "random-crossing"])
@pytest.mark.parametrize("noise", [None, SensorParams(range_noise=0.05, dropout=0.2,
                                                      spurious_rate=3.0, seed=4)])
def test_lidar_at_t_is_the_static_scan_of_the_moved_clouds(name, noise, rng):
    """At time t a LiDAR with motions returns exactly what a static LiDAR over
    ``scene.clouds_at(t)`` returns (same points, same order, same noise draws), at positions
    near the moved clouds; ``scan(p)`` is ``scan(p, 0.0)``."""
    scene = make_scene(name, 5)
    moving = Lidar(scene.clouds, 3.0, noise, motions=scene.motions)
    seen = 0
    for t in (0.0, 4.3, 8.0, 19.99):
        clouds = scene.clouds_at(t)
        static = Lidar(list(clouds), 3.0, noise)
        points = np.concatenate(clouds)
        positions = points[rng.choice(len(points), 15)] + rng.normal(scale=1.5, size=(15, 3))
        moving.reset()
        for p in positions:
            got, expected = moving.scan(p, t), static.scan(p)
            assert len(got) == len(expected) == len(scene.regions)
            for a, b in zip(got, expected, strict=True):
                np.testing.assert_array_equal(a, b)
                seen += len(a)
    assert seen > 0
    p = np.asarray(scene.start) + 1.0
    moving.reset()
    first = moving.scan(p)
    moving.reset()
    for a, b in zip(first, moving.scan(p, 0.0), strict=True):
        np.testing.assert_array_equal(a, b)


def test_true_velocities_and_lidar_validation():
    from paper_repro.world.truth import scene_velocities

    scene = make_scene("oncoming")
    lidar = Lidar(scene.clouds, 3.0, motions=scene.motions)
    (v,) = scene_velocities(scene, 2.0)
    np.testing.assert_allclose(v, (-0.5, 0.0, 0.0), atol=1e-15)
    static = make_scene("encounter")
    assert all(np.array_equal(v, np.zeros(3)) for v in scene_velocities(static, 3.0))
    with pytest.raises(ValueError, match="time t"):
        scene_velocities(scene, math.nan)
    with pytest.raises(ValueError, match="motions"):
        Lidar(scene.clouds, 3.0, motions=(ZIGZAG, ZIGZAG))
    with pytest.raises(ValueError, match="time t"):
        lidar.scan(scene.start, math.nan)


# --- closed loop ----------------------------------------------------------------------------

class HoverController:
    """A stand-in controller: always hovers, and records what it is given."""

    def __init__(self, config: Config, horizon: int = 5):
        _, self.u_hover = equilibrium(np.zeros(3), 0.0, config.quadrotor)
        self.horizon = horizon
        self.calls = []

    def reset(self):
        self.calls = []

    def hover_guess(self, x0):
        return self._plan(x0)

    def _plan(self, x0):
        x0 = np.asarray(x0, float)
        return NMPCSolution(np.tile(self.u_hover, (self.horizon, 1)),
                            np.tile(x0, (self.horizon + 1, 1)), x0.copy(),
                            np.asarray(self.u_hover, float).copy(), True, "hover", 1, 1e-4,
                            0.0)

    def solve(self, x0, target, visible, previous=None, **kwargs):
        self.calls.append({"x": np.array(x0), "visible": [v.copy() for v in visible],
                           **kwargs})
        return self._plan(x0)


def _approaching_scene():
    """A 2 m box 6 m ahead of a hovering UAV, coming at it at 1 m/s along −x."""
    box = Region("incoming", Box((6.0, 0.0, 5.0), (2.0, 2.0, 2.0)))
    return Scene("approach", (box,), (0.0, 0.0, 5.0), ((-10.0, 0.0, 5.0),), 3,
                 motions=(Motion.constant((-1.0, 0.0, 0.0)),))


@pytest.fixture(scope="module")
def approach_runs():
    scene = _approaching_scene()
    runs = {}
    for prediction in ("static", "oracle", "kalman"):
        config = Config(nmpc=NMPCParams(prediction=prediction))
        ctl = HoverController(config)
        result = simulate(config, ctl, max_steps=300, scene=scene, progress=False)
        runs[prediction] = (result, ctl.calls)
    return runs


def test_clearance_is_measured_to_the_true_positions(approach_runs):
    """The box comes at the hovering UAV: the recorded clearance is the distance to the box
    where it is at each step (brute force), shrinking from ≈5 m to ≈2 m in 3 s, and the LiDAR
    starts seeing it once it is within 3 m."""
    result, calls = approach_runs["static"]
    scene = result.scene
    assert result.steps == 300 and result.outcome == "step_limit"
    for k in range(0, 300, 10):
        expected = np.linalg.norm(scene.clouds_at(result.t[k])[0] - result.x[k, :3],
                                  axis=1).min()
        assert result.clearance[k] == pytest.approx(expected, abs=1e-12)
    assert result.clearance[0] > 4.5 and result.clearance[-1] < 2.5
    assert np.all(np.diff(result.clearance) <= 1e-9)
    assert result.visible_points[0] == 0 and result.visible_points[-1] > 0
    k = 250
    np.testing.assert_array_equal(calls[k]["visible"][0],
                                  Lidar(list(scene.clouds_at(result.t[k]))).scan(
                                      result.x[k, :3])[0])


@pytest.mark.parametrize("moving", [True, False])
def test_a_result_holds_every_scan_the_controller_was_handed(moving, tmp_path):
    """``SimulationResult.scan(k)`` is, bit for bit, what the controller was given at step k,
    and so after a save and a load. Seen from a hovering UAV, a box that comes at it gives a
    new scan at almost every step; a box at rest gives one scan, stored once."""
    scene = _approaching_scene()
    start = (0.0, 0.0, 5.0) if moving else (3.4, 0.0, 5.0)  # the box at rest: 1.6 m away
    scene = dataclasses.replace(scene, start=start, motions=scene.motions if moving else None)
    config = Config()
    ctl = HoverController(config)
    result = simulate(config, ctl, max_steps=300, scene=scene, progress=False)
    again = SimulationResult.load(result.save(tmp_path / "run"))
    assert len(ctl.calls) == result.steps == 300
    for k, call in enumerate(ctl.calls):
        for res in (result, again):
            got = res.scan(k)
            assert len(got) == len(call["visible"]) == 1
            assert np.array_equal(got[0], call["visible"][0])
    distinct, in_view = len(result.scan_sizes), np.count_nonzero(result.visible_points)
    assert in_view > 50
    assert distinct == (1 + in_view if moving else 1)  # moving: the empty scan, then each
    with pytest.raises(ValueError, match="k must be a step 0..299"):
        result.scan(300)
    older = dataclasses.replace(result, scan_points=None, scan_sizes=None, scan_index=None)
    assert again.has("scan") and again.has("y") and not older.has("scan")
    assert not again.has("region_velocities")  # the static prediction hands none
    with pytest.raises(ValueError, match="saved before the scans were stored"):
        older.scan(0)
    with pytest.raises(ValueError, match="name must be 'scan' or one of"):
        result.has("scans")


@pytest.mark.parametrize("moving", [True, False])
def test_the_clearance_of_a_flight_is_the_brute_force_distance_at_each_step(moving):
    """``TrueClearance.along`` (the loop measures every step at once, after the flight): the
    distance to the clouds where they are at each time, NaN at a position that is not
    finite (a diverged plant), for a moving scene and a static one."""
    from paper_repro.world.truth import TrueClearance

    scene = _approaching_scene()
    if not moving:
        scene = dataclasses.replace(scene, motions=None)
    rng = np.random.default_rng(5)
    y = rng.uniform(-2.0, 8.0, (40, 3))
    y[7] = np.nan
    t = np.linspace(0.0, 4.0, len(y))
    got = TrueClearance(scene).along(y, t)
    for k in range(len(y)):
        if k == 7:
            assert np.isnan(got[k])
            continue
        clouds = scene.clouds_at(t[k]) if moving else scene.clouds
        expected = min(np.linalg.norm(c - y[k], axis=1).min() for c in clouds)
        assert got[k] == pytest.approx(expected, abs=1e-12)


def test_prediction_decides_what_the_controller_gets(approach_runs):
    """static: ``solve`` is called without ``velocities`` (as before moving regions); oracle:
    the true velocity of every region at every step; kalman: one finite (3,) estimate per
    region."""
    _, calls = approach_runs["static"]
    assert all("velocities" not in c for c in calls)
    _, calls = approach_runs["oracle"]
    assert len(calls) == 300
    for c in calls:
        (v,) = c["velocities"]
        np.testing.assert_allclose(v, (-1.0, 0.0, 0.0), atol=1e-15)
    if "kalman" in approach_runs:
        result, calls = approach_runs["kalman"]
        for c in calls:
            (v,) = c["velocities"]
            assert np.shape(v) == (3,) and np.all(np.isfinite(v))
        assert result.steps == 300


def test_moving_result_saves_and_loads(approach_runs, tmp_path):
    """The result keeps its scene with the motions, through save and load."""
    result, _ = approach_runs["oracle"]
    loaded = SimulationResult.load(result.save(tmp_path / "run"))
    assert loaded.scene.is_moving and loaded.scene.motions == result.scene.motions
    assert loaded.scene.fingerprint() == result.scene.fingerprint()
    assert loaded.config.nmpc.prediction == "oracle"
    np.testing.assert_array_equal(loaded.clearance, result.clearance)
    for a, b in zip(loaded.scene.clouds_at(2.5), result.scene.clouds_at(2.5), strict=True):
        np.testing.assert_array_equal(a, b)

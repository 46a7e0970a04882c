"""The plant of ``config.plant``: RotorPy with its effects, an estimated state, a delay; each
does what it says, and the defaults fly as before."""

import dataclasses

import numpy as np
import pytest

from paper_repro.config import Config, PlantParams, SimulationParams
from paper_repro.sim.imperfect import (
    DelayedInput,
    EstimatedState,
    EstimateFilter,
    LatencyCompensation,
)
from paper_repro.sim.loop import simulate
from paper_repro.sim.plant import QuadrotorPlant, plant_for, wind_of
from paper_repro.vehicles.quadrotor import quadrotor_model

ENCOUNTER = Config(simulation=SimulationParams(scenario="encounter"))


class Recorder:
    """A plant that moves x by u (x_next = x + u) and records the inputs it was given."""

    def __init__(self):
        self.inputs = []

    def step(self, x, u):
        self.inputs.append(np.array(u))
        return np.asarray(x, float) + np.asarray(u, float)


def test_an_estimate_with_latency_is_the_state_of_that_many_steps_ago():
    plant = EstimatedState(Recorder(), np.zeros(2), latency=2)
    x = np.zeros(2)
    plant.reset(x)
    seen = []
    for _ in range(5):
        seen.append(plant.measure(x))
        x = plant.step(x, np.array([1.0, -1.0]))
    # the vehicle at k is (k, −k); it is seen at k as it was at k − 2 (at rest before 0)
    np.testing.assert_array_equal(np.array(seen)[:, 0], [0, 0, 0, 1, 2])


def test_the_estimates_noise_has_its_standard_deviation_and_its_seed():
    sigma = np.array([0.002, 0.03])
    plant = EstimatedState(Recorder(), sigma, latency=0, seed=5)
    plant.reset(np.zeros(2))
    noise = np.array([plant.measure(np.zeros(2)) for _ in range(20_000)])
    # 20,000 samples: the sample σ is within 2 % of σ (about 4 standard errors)
    np.testing.assert_allclose(noise.std(axis=0), sigma, rtol=0.02)
    assert abs(np.corrcoef(noise.T)[0, 1]) < 0.03
    again = EstimatedState(Recorder(), sigma, latency=0, seed=5)
    again.reset(np.zeros(2))
    np.testing.assert_array_equal(again.measure(np.zeros(2)), noise[0])


def test_a_delayed_input_arrives_that_many_steps_late_after_the_rest_input():
    inner = Recorder()
    plant = DelayedInput(inner, delay=2, rest_input=[9.0])
    plant.reset(np.zeros(1))
    x = np.zeros(1)
    for k in range(5):
        x = plant.step(x, np.array([float(k)]))
    assert [float(u[0]) for u in inner.inputs] == [9.0, 9.0, 0.0, 1.0, 2.0]


@pytest.mark.parametrize("make, match", [
    (lambda: EstimatedState(Recorder(), [-0.1], 0), "sigma"),
    (lambda: EstimatedState(Recorder(), [0.1], 1.5), "latency"),
    (lambda: DelayedInput(Recorder(), 0, [0.0]), "delay"),
    (lambda: PlantParams(motor_lag=0.03), "motor_lag .* needs simulator 'rotorpy'"),
    (lambda: PlantParams(simulator="rotorpy", wind=(3.0, 0.0, 0.0)), "act through drag"),
    (lambda: PlantParams(simulator="gazebo"), "simulator"),
    (lambda: PlantParams(estimation="gps"), "estimation"),
    (lambda: PlantParams(turbulence="strong"), "turbulence"),
    (lambda: PlantParams(delay_steps=-1), "delay_steps"),
    (lambda: PlantParams(compensate_latency=True), "compensate_latency needs a latency"),
    (lambda: PlantParams(delay_steps=1, compensate_latency=1), "compensate_latency must be"),
    (lambda: LatencyCompensation(Recorder(), Recorder(), 0, [0.0]), "steps"),
    (lambda: PlantParams(estimate_filter_time=0.05), "estimate_filter_time filters a noisy"),
    (lambda: PlantParams(estimation="mocap", estimate_filter_time=-0.05),
     "estimate_filter_time must be"),
    (lambda: EstimateFilter(Recorder(), Recorder(), 0.01, 0.0, 0, [0.0]), "time_constant"),
    (lambda: PlantParams(simulator="rotorpy", wind=(1.0, float("nan"), 0.0),
                         rotor_drag=1e-4), "wind must be 3 finite numbers"),
])
def test_bad_plant_settings_are_refused_by_name(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_the_default_plant_is_ours_and_is_not_in_the_run_key():
    assert isinstance(plant_for(quadrotor_model(), Config()), QuadrotorPlant)
    assert "plant" not in Config().key_dict()
    on = Config(plant=PlantParams(delay_steps=1))
    assert on.key_dict()["plant"]["delay_steps"] == 1


def test_the_plant_settings_build_their_wrappers():
    cfg = Config(plant=PlantParams(estimation="mocap", delay_steps=2))
    plant = plant_for(quadrotor_model(), cfg)
    assert isinstance(plant, DelayedInput) and plant.delay == 2
    assert isinstance(plant.plant, EstimatedState) and plant.plant.latency == 1
    assert isinstance(plant.plant.plant, QuadrotorPlant)


@pytest.mark.parametrize("latency, delay", [(0, 1), (2, 0), (1, 2)])
def test_the_compensated_state_is_the_one_the_next_input_meets(latency, delay):
    """With the nominal model as the plant and no noise, the prediction over L + d steps is
    exact: the state given at step k is the true state at step k + d, when the input computed
    from it starts to act (before the flight, the vehicle rests with the rest input)."""
    x0, rest = np.zeros(2), np.zeros(2)  # x + 0 = x: the rest input of this model
    plant = EstimatedState(Recorder(), np.zeros(2), latency)
    if delay:
        plant = DelayedInput(plant, delay, rest)
    plant = LatencyCompensation(plant, Recorder(), latency + delay, rest)
    plant.reset(x0)
    rng = np.random.default_rng(1)
    x, given, truth = x0, [], [x0]
    for _ in range(12):
        given.append(plant.measure(x))
        x = plant.step(x, rng.normal(size=2))
        truth.append(x)
    for k in range(len(given) - delay):
        np.testing.assert_allclose(given[k], truth[k + delay], atol=1e-12)


@pytest.mark.parametrize("latency, delay", [(0, 0), (2, 0), (1, 2)])
def test_without_noise_the_filter_is_the_state_its_estimate_is_of(latency, delay):
    """With the nominal model as the plant and no noise, the prediction through the input
    that acted is exact whatever the gain: the filter gives the state L steps ago, the one the
    estimate is of (and, compensated over L + d, the state the next input meets)."""
    x0, rest = np.zeros(2), np.zeros(2)
    plant = EstimatedState(Recorder(), np.zeros(2), latency)
    if delay:
        plant = DelayedInput(plant, delay, rest)
    filtered = EstimateFilter(plant, Recorder(), 0.01, 0.2, latency + delay, rest)
    compensated = LatencyCompensation(filtered, Recorder(), latency + delay, rest) \
        if latency + delay else filtered
    compensated.reset(x0)
    rng = np.random.default_rng(2)
    x, given, seen, truth = x0, [], [], [x0]
    for _ in range(12):
        given.append(compensated.measure(x))
        seen.append(filtered.measure(x))  # read twice in a step: corrected once
        x = compensated.step(x, rng.normal(size=2))
        truth.append(x)
    for k in range(len(given)):
        np.testing.assert_allclose(seen[k], truth[max(k - latency, 0)], atol=1e-12)
        if k + delay < len(truth):
            np.testing.assert_allclose(given[k], truth[k + delay], atol=1e-12)


def test_the_filter_leaves_sigma_times_the_root_of_k_over_two_minus_k_of_white_noise():
    """At rest (x + 0 = x), the error obeys e = (1 − K)·e + K·n: a white noise of σ leaves
    σ·√(K/(2 − K)) once the filter has settled."""
    sigma, ts, tau = 0.03, 0.01, 0.05
    k = 1 - np.exp(-ts / tau)
    filtered = EstimateFilter(EstimatedState(Recorder(), [sigma], 0, seed=3), Recorder(), ts,
                              tau, 0, [0.0])
    filtered.reset(np.zeros(1))
    x, errors = np.zeros(1), []
    for _ in range(20000):
        x = filtered.step(x, np.zeros(1))
        errors.append(filtered.measure(x)[0])
    assert np.std(errors[100:]) == pytest.approx(sigma * np.sqrt(k / (2 - k)), rel=0.05)


def test_the_filter_sits_inside_the_compensation_and_stays_out_of_the_run_key_when_off():
    cfg = Config(plant=PlantParams(estimation="vio", delay_steps=1, compensate_latency=True,
                                   estimate_filter_time=0.05))
    plant = plant_for(quadrotor_model(), cfg)
    assert isinstance(plant, LatencyCompensation) and isinstance(plant.plant, EstimateFilter)
    assert plant.plant.steps == 3 + 1 and isinstance(plant.plant.nominal, QuadrotorPlant)
    assert plant.plant.gain == pytest.approx(1 - np.exp(-cfg.nmpc.ts / 0.05))
    off = Config(plant=PlantParams(estimation="vio", delay_steps=1))
    assert "estimate_filter_time" not in off.key_dict()["plant"]
    assert cfg.key_dict()["plant"]["estimate_filter_time"] == 0.05


def test_the_compensation_wraps_the_plant_and_predicts_with_the_nominal_model():
    cfg = Config(plant=PlantParams(estimation="vio", delay_steps=1, compensate_latency=True))
    plant = plant_for(quadrotor_model(), cfg)
    assert isinstance(plant, LatencyCompensation) and plant.steps == 3 + 1
    assert isinstance(plant.nominal, QuadrotorPlant) and isinstance(plant.plant, DelayedInput)


def test_another_vehicle_cannot_fly_rotorpy():
    from paper_repro.vehicles.unicycle import unicycle_model

    with pytest.raises(ValueError, match="for the quadrotor"):
        plant_for(unicycle_model(), Config(plant=PlantParams(simulator="rotorpy")))


def test_the_wind_of_the_settings_has_its_mean_and_its_gust():
    cfg = Config(plant=PlantParams(simulator="rotorpy", rotor_drag=1e-4, wind=(3.0, 0.0, 0.0),
                                   gust=(0.0, 2.0, 0.0), gust_duration=1.0, gust_start=4.0))
    wind = wind_of(cfg, altitude=2.0)
    np.testing.assert_array_equal(wind(0.0), [3.0, 0.0, 0.0])
    np.testing.assert_allclose(wind(4.5), [3.0, 2.0, 0.0])  # the 1-cosine peak at mid-gust


def test_a_delay_and_an_estimate_move_the_flight_and_it_stays_clear():
    """A 1-step delay and a motion-capture estimate on the encounter's first 4 s: the flight
    moves by millimetres to centimetres, every solve succeeds and the cloud stays clear."""
    base = simulate(ENCOUNTER, max_steps=400, progress=False)
    cfg = dataclasses.replace(ENCOUNTER, plant=PlantParams(estimation="mocap", delay_steps=1))
    run = simulate(cfg, max_steps=400, progress=False)
    moved = np.abs(run.x[:, :3] - base.x[:, :3]).max()
    assert 1e-4 < moved < 0.1
    assert run.success.all() and run.clearance.min() > 0.5


def test_rotorpy_with_every_effect_off_flies_our_closed_loop():
    """The agreement the sim-to-real study rests on: the same closed loop, to 1e-9 m."""
    pytest.importorskip("rotorpy.vehicles.multirotor")
    base = simulate(ENCOUNTER, max_steps=200, progress=False)
    cfg = dataclasses.replace(ENCOUNTER, plant=PlantParams(simulator="rotorpy"))
    run = simulate(cfg, max_steps=200, progress=False)
    assert np.abs(run.x - base.x).max() < 1e-9


def test_the_command_line_names_the_plant():
    import argparse

    from paper_repro.cli.parser import COMMANDS
    from paper_repro.cli.run import run_config

    parser = argparse.ArgumentParser()
    COMMANDS["run"].add_arguments(parser)
    args = parser.parse_args(["--out", "unused", "--plant", "rotorpy", "--motor-lag", "0.03",
                              "--rotor-drag", "1e-4", "--wind", "3", "--turbulence", "light",
                              "--estimation", "vio", "--delay", "2", "--hover-thrust", "2",
                              "--motor-lag-compensation", "0.03", "--estimate-filter", "0.05",
                              "--set", "plant.seed=4"])
    assert run_config(args).plant == PlantParams(
        simulator="rotorpy", motor_lag=0.03, rotor_drag=1e-4, wind=(0.0, 3.0, 0.0),
        turbulence="light", estimation="vio", delay_steps=2, hover_thrust_time=2.0,
        motor_lag_compensation=0.03, estimate_filter_time=0.05, seed=4)
    with pytest.raises(ValueError, match="--motor-lag -0.1.*motor_lag must be"):
        run_config(parser.parse_args(["--out", "unused", "--plant", "rotorpy",
                                      "--motor-lag", "-0.1"]))


def test_a_gust_timed_by_clearance_starts_where_the_vehicle_first_comes_that_close():
    """The encounter's start, flown straight at its nearest cloud point 5 cm a step: the gust
    is off until the first step within 1.2 m of it, then the 1-cosine from that step's time."""
    from scipy.spatial import cKDTree

    from paper_repro.sim.plant import GustTrigger
    from paper_repro.world.scenarios import make_scene
    from paper_repro.world.wind import OneCosineGust

    scene = make_scene("encounter")
    start = np.asarray(scene.start, float)
    points = scene.all_points
    nearest = points[cKDTree(points).query(start)[1]]
    step = np.zeros(12)
    step[:3] = 0.05 * (nearest - start) / np.linalg.norm(nearest - start)
    gust = OneCosineGust((0.0, 2.0, 0.0), duration=0.1, start=0.0)
    plant = GustTrigger(Recorder(), gust, scene, distance=1.2, ts=0.01)
    assert np.all(gust(0.0) == 0)  # off until the vehicle comes close
    plant.reset(np.zeros(12))
    x = np.zeros(12)
    x[:3] = start
    first = None
    for k in range(200):
        near = np.min(np.linalg.norm(points - x[:3], axis=1))
        first = k if first is None and near < 1.2 else first
        x = plant.step(x, step)
        assert np.isinf(gust.start) if first is None else gust.start == first * 0.01
    assert first is not None and first > 0
    np.testing.assert_allclose(gust(first * 0.01 + 0.05), [0.0, 2.0, 0.0])  # its peak
    plant.reset(np.zeros(12))
    assert np.isinf(gust.start)
    with pytest.raises(ValueError, match="gust_clearance times a gust"):
        PlantParams(simulator="rotorpy", rotor_drag=1e-4, gust_clearance=1.0)
    with pytest.raises(ValueError, match="needs the scene"):
        plant_for(quadrotor_model(), Config(plant=PlantParams(
            simulator="rotorpy", rotor_drag=1e-4, gust=(0.0, 2.0, 0.0), gust_clearance=1.0)))


class WeakRotors:
    """Our quadrotor whose rotors make ``scale`` times the thrust commanded."""

    def __init__(self, scale):
        self.plant, self.scale = QuadrotorPlant(ENCOUNTER.quadrotor, ENCOUNTER.nmpc.ts), scale

    def step(self, x, u):
        return self.plant.step(x, self.scale * np.asarray(u, float))


def _hover(scale, latency, delay, seconds=12.0, tau=1.0):
    """Send the nominal hover thrusts for ``seconds`` through the estimate; (wrapper, states)."""
    from paper_repro.sim.imperfect import HoverThrustEstimate

    model = quadrotor_model()
    rest = model.rest(np.zeros(12))[1]
    x = np.zeros(12)
    x[2] = 5.0
    plant = EstimatedState(WeakRotors(scale), np.zeros(12), latency)
    if delay:
        plant = DelayedInput(plant, delay, rest)
    q = ENCOUNTER.quadrotor
    plant = HoverThrustEstimate(plant, ENCOUNTER.nmpc.ts, q.mass, q.gravity, tau,
                                (model.input_lower, model.input_upper), latency + delay, rest)
    plant.reset(x)
    states = [x]
    for _ in range(int(round(seconds / ENCOUNTER.nmpc.ts))):
        plant.measure(x)
        x = plant.step(x, rest)
        states.append(x)
    return plant, np.array(states)


@pytest.mark.parametrize("latency, delay", [(0, 0), (2, 1)])
@pytest.mark.parametrize("scale", [0.9, 1.1])
def test_the_hover_thrust_estimate_learns_the_missing_thrust_and_stops_the_sag(scale, latency,
                                                                              delay):
    """Rotors that make 90 % (110 %) of the thrust: the estimate tends to 0.9 (1.1), whatever
    the latency, and the vehicle held at the nominal hover thrusts stops accelerating."""
    plant, x = _hover(scale, latency, delay)
    assert plant.estimate == pytest.approx(scale, rel=1e-3)
    vz = x[:, 8]
    assert abs(vz[-1] - vz[-101]) < 1e-3 * abs(vz[100] - vz[0])  # the last second vs the first
    _, drift = _hover(scale, latency, delay, seconds=12.0, tau=1e9)  # (practically) off
    assert abs(drift[-1, 8] - drift[-101, 8]) > 1e3 * abs(vz[-1] - vz[-101])


def test_the_hover_thrust_estimate_stays_at_one_on_the_nominal_vehicle():
    plant, x = _hover(1.0, 1, 1, seconds=3.0)
    assert plant.estimate == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(x[-1, :3], x[0, :3], atol=1e-6)


def test_the_hover_thrust_setting_wraps_the_plant_outside_the_delay():
    from paper_repro.sim.imperfect import HoverThrustEstimate

    cfg = Config(plant=PlantParams(estimation="mocap", delay_steps=1, hover_thrust_time=2.0))
    plant = plant_for(quadrotor_model(), cfg)
    assert isinstance(plant, HoverThrustEstimate) and plant.latency == 2
    assert isinstance(plant.plant, DelayedInput)
    with pytest.raises(ValueError, match="hover_thrust_time"):
        PlantParams(hover_thrust_time=0.0)


class LaggingRotors:
    """A first-order lag of time constant ``tau`` on each thrust, over steps of ``ts``: the
    state is the thrust, x_next = a·x + (1 − a)·c with a = exp(−ts/tau) (exact for a held c)."""

    def __init__(self, tau, ts=0.01):
        self.a = np.exp(-ts / tau)

    def step(self, x, c):
        return self.a * np.asarray(x, float) + (1 - self.a) * np.asarray(c, float)


def test_the_motor_lead_makes_lagging_rotors_follow_a_ramp_and_keeps_a_constant():
    """A thrust ramp through a 50 ms lag trails by τ·slope; sent with the lead for τ̂ = τ it
    trails by a sixth of that (what is left is the sampling's half step); a constant thrust is
    sent as it is, and the lead never leaves the bounds."""
    from paper_repro.sim.imperfect import MotorLagCompensation

    tau, ts, slope = 0.05, 0.01, 2.0  # s, s, N/s
    ramp = 5.0 + slope * ts * np.arange(200)
    trail = {}
    for lead in (False, True):
        plant = LaggingRotors(tau, ts)
        if lead:
            plant = MotorLagCompensation(plant, ts, tau, ([0.0], [20.0]))
        f = np.array([5.0])
        for u in ramp:
            f = plant.step(f, [u])
        trail[lead] = ramp[-1] - f[0]
    assert trail[False] == pytest.approx(slope * tau, rel=0.15)
    assert abs(trail[True]) < trail[False] / 6
    plant = MotorLagCompensation(LaggingRotors(tau, ts), ts, tau, ([0.0], [20.0]))
    f = np.array([7.0])
    for _ in range(5):
        f = plant.step(f, [7.0])
    assert f[0] == pytest.approx(7.0, abs=1e-12)
    clipped = MotorLagCompensation(Recorder(), ts, tau, ([0.0], [8.0]))
    clipped.step(np.zeros(1), [7.0])
    clipped.step(np.zeros(1), [7.9])  # 7.9 + 5·0.9 = 12.4, clipped to the bound 8
    assert clipped.plant.inputs[-1][0] == 8.0
    with pytest.raises(ValueError, match="motor_lag_compensation"):
        PlantParams(motor_lag_compensation=-0.05)

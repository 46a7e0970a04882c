"""Bring your own vehicle: a point-mass "drone" (a 3-D double integrator) written here, in
a few lines of CasADi, flown by the same closed loop, both solvers and the same problem (21)
as the quadrotor. Nothing in the package knows this vehicle."""

import dataclasses

import casadi as ca
import numpy as np
import pytest

from paper_repro import BarrierParams, Config, NMPCParams, simulate
from paper_repro.sim.loop import Faults
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.base import Equilibria, VehicleModel
from paper_repro.world.scene import Region, Scene
from paper_repro.world.shapes import Box


def point_mass(max_accel: float = 2.0) -> VehicleModel:
    """x = (p, v) ∈ R⁶ (m, m/s), u = a ∈ R³ (m/s²), y = p; at rest wherever it is."""
    x, u, a = ca.SX.sym("x", 6), ca.SX.sym("u", 3), ca.SX.sym("a", 3)
    rest = Equilibria(state=ca.Function("x_a", [a], [ca.vertcat(a, ca.SX.zeros(3))]),
                      input=ca.Function("u_a", [a], [ca.DM.zeros(3)]),
                      of_state=lambda xs: np.asarray(xs, float)[:3])
    return VehicleModel(
        "point_mass", dynamics=ca.Function("f_c", [x, u], [ca.vertcat(x[3:], u)]),
        output=ca.Function("h", [x], [x[:3]]),
        state_lower=(-25, -25, 0, -3, -3, -3), state_upper=(25, 25, 25, 3, 3, 3),
        input_lower=(-max_accel,) * 3, input_upper=(max_accel,) * 3,
        equilibria=rest, position=(0, 1, 2), velocity=(3, 4, 5))


CONFIG = Config(
    nmpc=dataclasses.replace(NMPCParams(), horizon=20, ts=0.05, q=(1, 1, 1, 0.5, 0.5, 0.5),
                             r=(0.1, 0.1, 0.1), t=(30.0, 30.0, 30.0), region_slots=1,
                             points_per_region=64),
    barrier=BarrierParams(d_min=0.5, mu=1e3))

# A 2 m wall across the straight line from start to target, a little below its middle.
SCENE = Scene("wall", (Region("wall", Box((3.5, -1.5, 0.5), (4.0, 1.0, 3.5)), density=20.0),),
              start=(0.0, -0.3, 2.0), targets=((8.0, -0.3, 2.0),))


@pytest.fixture(scope="module")
def flights():
    """Both solvers, from rest to the target past the wall (at most 160 steps, 8 s)."""
    model = point_mass()
    out = {}
    for solver in ("rti", "reference"):
        cfg = dataclasses.replace(CONFIG, solver=dataclasses.replace(CONFIG.solver,
                                                                     nlp_solver=solver))
        out[solver] = simulate(cfg, make_controller(cfg, model), max_steps=160,
                               progress=False, scene=SCENE)
    return out


def test_the_closed_loop_flies_a_vehicle_of_its_own(flights):
    run = flights["rti"]
    assert run.x.shape == (len(run.t) + 1, 6) and run.u.shape == (len(run.t), 3)
    np.testing.assert_array_equal(run.x[0], [0.0, -0.3, 2.0, 0, 0, 0])  # at rest at the start
    assert run.success.all() and run.outcome == "completed"  # the target reached
    assert run.visible_points.max() > 0  # the LiDAR saw the wall on the way


def test_it_stays_clear_of_the_cloud(flights):
    """The barrier keeps D ≥ d_min = 0.5 m², about 1 m from the nearest point (½·d² = 0.5
    at d = 1 m; the smoothed D lies a little below ½·d²)."""
    for run in flights.values():
        assert run.clearance.min() > 0.9


def test_the_fast_path_agrees_with_the_reference(flights):
    """One Gauss-Newton step per instant against IPOPT converged at every instant: the two
    closed loops stay within 5 mm of each other."""
    rti, ref = flights["rti"], flights["reference"]
    assert ref.success.all() and len(rti.t) == len(ref.t)
    assert np.linalg.norm(rti.x[:, :3] - ref.x[:, :3], axis=1).max() < 0.005


def test_without_a_controller_simulate_builds_one_for_the_vehicle(flights):
    """``simulate(config, model=...)`` builds the model's controller, not the quadrotor's,
    and flies what the explicit controller flew."""
    run = simulate(CONFIG, model=point_mass(), max_steps=20, progress=False, scene=SCENE)
    np.testing.assert_array_equal(run.x, flights["rti"].x[:21])


def test_a_model_that_is_not_the_controllers_is_refused():
    from paper_repro.vehicles.unicycle import unicycle_model

    controller = make_controller(CONFIG, point_mass())
    with pytest.raises(ValueError, match="model 'unicycle' .* is not the controller's"):
        simulate(CONFIG, controller, model=unicycle_model(), scene=SCENE, max_steps=1)


def test_its_plant_is_its_own_dynamics():
    """Without a plant of its own, the loop integrates the model's f_c: from rest under a
    constant a, p moves ½·a·T_s²."""
    from paper_repro.sim.plant import plant_for

    plant = plant_for(point_mass(), CONFIG)
    x = plant.step(np.zeros(6), [1.0, 0.0, -1.0])
    np.testing.assert_allclose(x, [0.5 * 0.05**2, 0, -0.5 * 0.05**2, 0.05, 0, -0.05],
                               atol=1e-15)


class ExactPlant:
    """A plant written here: the double integrator's exact flow under zero-order hold
    (p + v·T_s + ½·a·T_s², v + a·T_s), counting its resets and steps."""

    def __init__(self, ts: float):
        self.ts, self.resets, self.steps = ts, [], 0

    def reset(self, x0):
        self.resets.append(np.array(x0))

    def step(self, x, u):
        self.steps += 1
        p, v, a = x[:3], x[3:], np.asarray(u, float)
        return np.concatenate([p + v * self.ts + 0.5 * a * self.ts**2, v + a * self.ts])


class BiasedSensorPlant(ExactPlant):
    """The same flow, measured with a fixed position bias (m)."""

    def __init__(self, ts: float, bias):
        super().__init__(ts)
        self.bias = np.concatenate([bias, np.zeros(3)])

    def measure(self, x):
        return x + self.bias


def test_a_plant_written_here_flies_the_loop(flights):
    """RK4 integrates a double integrator under a constant input exactly, so the plant
    written here flies the loop as the default plant does, to rounding; the loop resets it
    once, at the start, and steps it once per instant."""
    plant = ExactPlant(CONFIG.nmpc.ts)
    run = simulate(CONFIG, make_controller(CONFIG, point_mass()), max_steps=160,
                   progress=False, scene=SCENE, plant=plant)
    assert len(plant.resets) == 1 and plant.steps == len(run.t)
    np.testing.assert_array_equal(plant.resets[0], run.x[0])
    assert run.outcome == flights["rti"].outcome and len(run.t) == len(flights["rti"].t)
    np.testing.assert_allclose(run.x, flights["rti"].x, rtol=0, atol=1e-9)


def test_the_controller_is_given_what_the_plant_measured():
    """With a position bias b in the measurement, the controller brings the *measured*
    position to the target: the vehicle itself comes to rest at y_t − b."""
    bias = np.array([0.4, -0.2, 0.1])
    open_scene = Scene("open", (), start=(0.0, 0.0, 2.0), targets=((2.0, 0.0, 2.0),))
    plant = BiasedSensorPlant(CONFIG.nmpc.ts, bias)
    run = simulate(CONFIG, make_controller(CONFIG, point_mass()), max_steps=300,
                   progress=False, scene=open_scene, plant=plant)
    np.testing.assert_allclose(run.x[-1, :3], np.array([2.0, 0.0, 2.0]) - bias, atol=0.02)
    assert np.abs(run.x[-1, 3:]).max() < 0.02  # at rest there


def test_faults_act_on_what_the_plant_measured():
    """A state fault sees the plant's measurement, not the true state: the bias is there."""
    bias = np.array([0.4, 0.0, 0.0])
    seen = []
    faults = Faults(state=lambda k, x: seen.append(x.copy()) or x)
    plant = BiasedSensorPlant(CONFIG.nmpc.ts, bias)
    run = simulate(CONFIG, make_controller(CONFIG, point_mass()), max_steps=3,
                   progress=False, scene=SCENE, plant=plant, faults=faults)
    np.testing.assert_allclose(np.array(seen) - run.x[:3], np.tile(plant.bias, (3, 1)),
                               atol=1e-15)


def test_an_object_without_a_step_is_refused_as_a_plant():
    with pytest.raises(ValueError, match="^plant must have a step"):
        simulate(CONFIG, model=point_mass(), scene=SCENE, max_steps=1, plant=object())


def test_a_converged_cold_start_gives_the_reference_plan_in_one_solve():
    """From rest 1.5 m before the wall, one ``solve`` of the default controller
    (``cold_start="converged"``) returns IPOPT's plan within 1 mm; one Gauss-Newton step from
    rest (``cold_start="rti"``) stops centimetres short of it."""
    from paper_repro.world.lidar import Lidar

    model = point_mass()

    def solver(**options):
        return make_controller(dataclasses.replace(
            CONFIG, solver=dataclasses.replace(CONFIG.solver, **options)), model)

    x0, target = np.array([2.0, -0.3, 2.0, 0, 0, 0]), np.array([8.0, -0.3, 2.0])
    visible = Lidar(SCENE.clouds).scan(x0[:3])
    assert sum(len(v) for v in visible) > 0
    reference = solver(nlp_solver="reference").solve(x0, target, visible)
    assert reference.success
    converged = solver().solve(x0, target, visible)
    one_step = solver(cold_start="rti").solve(x0, target, visible)
    assert converged.status == "converged" and converged.iterations > 1
    gap = np.abs(converged.x[:, :3] - reference.x[:, :3]).max()
    assert gap < 1e-3
    assert np.abs(one_step.x[:, :3] - reference.x[:, :3]).max() > 10 * gap


def test_a_bad_cold_start_is_refused_by_name():
    from paper_repro.config import SolverParams

    with pytest.raises(ValueError, match="cold_start"):
        SolverParams(cold_start="warm")

"""The tracking NMPC (Sections II and IV) and its closed loop on the encounter scene."""

import dataclasses

import numpy as np
import pytest

from paper_repro import (
    BarrierParams,
    Config,
    DistanceParams,
    Lidar,
    NMPCParams,
    SensorParams,
    SimulationParams,
    SolverParams,
    clearance,
    make_scene,
)
from paper_repro.config_history import MOVED
from paper_repro.problem.ocp import OCP
from paper_repro.sim.loop import simulate
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.vehicles.quadrotor import equilibrium, plant_step, rk4_discretisation

# The encounter region has about 40 points: one slot of 48 holds every visible point, so the
# problem is the paper's while the NLP stays small enough for CI.
SMALL = NMPCParams(region_slots=1, points_per_region=48)
ENCOUNTER = SimulationParams(scenario="encounter")


def _config(metric="smooth", **nmpc):
    return Config(distance=DistanceParams(metric=metric), simulation=ENCOUNTER,
                  nmpc=dataclasses.replace(SMALL, **nmpc))


@pytest.fixture(scope="module")
def smooth_controller():
    return TrackingNMPC(_config("smooth"))


@pytest.fixture(scope="module")
def scene():
    return make_scene("encounter")


def _check_bounds(ctl, sol, x0, tol=1e-6):
    p = ctl.config.quadrotor
    xl, xu = np.array(p.state_lower), np.array(p.state_upper)
    assert np.all(sol.u >= np.array(p.input_lower) - tol)
    assert np.all(sol.u <= np.array(p.input_upper) + tol)
    # x_0 is the measurement; x_1..x_N must lie in 𝒳.
    assert np.allclose(sol.x[0], x0, atol=1e-9)
    assert np.all(sol.x[1:] >= xl - tol) and np.all(sol.x[1:] <= xu + tol)
    xal, xau, ual, uau = p.relaxed_bounds(ctl.config.nmpc.lam)
    assert np.all(sol.x_a >= xal - tol) and np.all(sol.x_a <= xau + tol)
    assert np.all(sol.u_a >= ual - tol) and np.all(sol.u_a <= uau + tol)


def test_solve_from_hover_respects_bounds_dynamics_and_terminal_constraint(smooth_controller,
                                                                            scene):
    ctl = smooth_controller
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    visible = Lidar(scene.clouds).scan(x0[:3])
    assert sum(len(v) for v in visible) > 0, "the test needs a region in view"
    sol = ctl.solve(x0, scene.targets[0], visible)
    assert sol.success, sol.status
    _check_bounds(ctl, sol, x0)
    np.testing.assert_allclose(sol.x[-1], sol.x_a, atol=1e-7)  # x_N = x_a
    f = rk4_discretisation(ctl.config.nmpc.ts)
    for j in range(ctl.horizon):  # multiple-shooting defects closed
        np.testing.assert_allclose(np.asarray(f(sol.x[j], sol.u[j])).ravel(), sol.x[j + 1],
                                   atol=1e-7)
    # (x_a, u_a) is an equilibrium: zero roll, pitch, velocities and hover thrust.
    np.testing.assert_allclose(sol.x_a[[3, 4, 6, 7, 8, 9, 10, 11]], 0.0, atol=1e-7)
    np.testing.assert_allclose(sol.u_a, ctl.config.quadrotor.hover_thrust, atol=1e-6)
    # The artificial output moves towards the target.
    assert sol.x_a[0] > x0[0]


def test_change_of_target_mid_flight_keeps_every_solve_feasible(smooth_controller):
    """The point of the artificial equilibrium: a new set-point never makes the OCP infeasible."""
    ctl = smooth_controller
    x, _ = equilibrium([0.0, 0.0, 5.0])
    plan = None
    first, second = np.array([20.0, 10.0, 12.0]), np.array([-20.0, -15.0, 1.0])
    targets = [first] * 60 + [second] * 60
    for k, target in enumerate(targets):
        if k == 60:
            y_a_at_switch = plan.x_a[:3].copy()
        sol = ctl.solve(x, target, (), previous=plan)
        assert sol.success, f"step {k}: {sol.status}"
        _check_bounds(ctl, sol, x)
        plan = sol
        x = plant_step(x, sol.u[0], ctl.config.nmpc.ts)
    # After the switch the artificial output heads for the new target.
    assert np.linalg.norm(sol.x_a[:3] - second) < np.linalg.norm(y_a_at_switch - second) - 0.01


def test_target_outside_workspace_keeps_x_a_in_relaxed_box(smooth_controller):
    ctl = smooth_controller
    x, _ = equilibrium([24.7, -24.0, 24.85])
    plan = None
    for _ in range(40):
        sol = ctl.solve(x, [60.0, -70.0, 40.0], (), previous=plan)
        assert sol.success
        _check_bounds(ctl, sol, x)
        plan = sol
        x = plant_step(x, sol.u[0], ctl.config.nmpc.ts)
    xal, xau, _, _ = ctl.config.quadrotor.relaxed_bounds(ctl.config.nmpc.lam)
    # Pushed against the relaxed box, not beyond it.
    assert sol.x_a[0] == pytest.approx(xau[0], abs=1e-6)
    assert sol.x_a[2] == pytest.approx(xau[2], abs=1e-6)
    assert xau[0] < ctl.config.quadrotor.state_upper[0]


@pytest.mark.slow
def test_target_inside_cloud_settles_at_safe_equilibrium(smooth_controller, scene):
    ctl = smooth_controller
    cloud = scene.clouds[0]
    target = cloud.mean(axis=0)
    lidar = Lidar(scene.clouds)
    x, _ = equilibrium(target + np.array([0.0, -2.6, 0.0]))
    plan = None
    gaps = []
    for k in range(400):
        sol = ctl.solve(x, target, lidar.scan(x[:3]),
                        previous=plan)
        assert sol.success, f"step {k}: {sol.status}"
        plan = sol
        x = plant_step(x, sol.u[0], ctl.config.nmpc.ts)
        gaps.append(clearance(x[:3], cloud))
    assert min(gaps) > 0.5
    # The artificial equilibrium rests outside the cloud, at the barrier's margin.
    assert clearance(sol.x_a[:3], cloud) > 0.5
    # and the UAV has (nearly) stopped there instead of pushing in.
    assert np.linalg.norm(x[6:9]) < 0.05
    assert np.linalg.norm(x[:3] - sol.x_a[:3]) < 0.1


@pytest.mark.slow
def test_encounter_closed_loop_passes_region_with_clearance_smooth(smooth_controller, scene):
    """The smooth metric flies past the L-shaped corner, never closer than 0.5 m, no failure."""
    result = simulate(_config("smooth"), controller=smooth_controller, max_steps=1700,
                      progress=False)
    near_arm_far_face = scene.regions[0].shape.parts[0].bounds()[1][0]
    assert result.x[-1, 0] > near_arm_far_face, "the UAV did not get past the near arm"
    assert result.clearance.min() > 0.5
    assert result.failures == 0
    assert result.visible_points.max() > 0


def test_euclidean_variant_records_failures_instead_of_crashing(scene):
    """With a tiny iteration limit most solves fail: the run goes on on the shifted plan."""
    ctl = TrackingNMPC(_config("euclidean"), max_iter=3)
    result = simulate(_config("euclidean"), controller=ctl, max_steps=60, progress=False)
    assert result.steps == 60
    assert result.failures > 0
    assert "Maximum_Iterations_Exceeded" in set(result.status[~result.success])
    assert np.all(np.isfinite(result.x))


@pytest.mark.slow
def test_euclidean_variant_agrees_with_the_fast_path_near_the_corner(scene):
    """150 IPOPT steps of the Euclidean baseline 1.6 m from the corner: every solve succeeds,
    every state stays in 𝒳 and every input in 𝒰, and the real-time solver flies the same
    path to within a centimetre (both read the same description of problem 21)."""
    from paper_repro.solvers.factory import make_controller

    near = dataclasses.replace(scene, start=(-18.6, 0.0, 2.0))
    cfg = _config("euclidean")
    ref = simulate(cfg, controller=TrackingNMPC(cfg), max_steps=150, progress=False,
                   scene=near)
    rti = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, nlp_solver="rti"))
    fast = simulate(rti, controller=make_controller(rti), max_steps=150, progress=False,
                    scene=near)
    assert ref.failures == 0 and ref.visible_points.max() > 0
    p = cfg.quadrotor
    assert np.all(ref.u >= np.array(p.input_lower) - 1e-6)
    assert np.all(ref.u <= np.array(p.input_upper) + 1e-6)
    assert np.all(ref.x >= np.array(p.state_lower) - 1e-6)
    assert np.all(ref.x <= np.array(p.state_upper) + 1e-6)
    assert np.linalg.norm(fast.x[:, :3] - ref.x[:, :3], axis=1).max() < 0.01


def test_config_round_trips_through_dict():
    cfg = Config(barrier=BarrierParams(form="definition", d_min=0.8),
                 nmpc=NMPCParams(horizon=20), distance=DistanceParams(metric="euclidean"))
    assert Config.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError, match="unknown barrier parameters"):
        Config.from_dict({"barrier": {"dmin": 1.0}})


def test_a_config_saved_before_the_solver_options_moved_loads_them_in_their_new_place():
    """A ``config.json`` of the former layout (solver options in ``nmpc``, the LiDAR's range
    and the prediction in ``simulation``) loads into ``solver``, ``sensor`` and ``nmpc``; a
    setting given in both places is refused rather than one of them silently dropped."""
    # (the solver's settings added since hold the values that flew before them)
    new = Config(nmpc=NMPCParams(prediction="kalman"),
                 solver=SolverParams(nlp_solver="reference", sqp_iterations=3, line_search=True,
                                     qp_solver="hpipm", cold_start="rti", relaxed_qp=False,
                                     shared_barrier=False),
                 sensor=SensorParams(range=4.5, dropout=0.1))
    old = new.to_dict()
    old["nmpc"].update(solver="reference", sqp_iterations=3, line_search=True,
                       qp_solver="hpipm")
    old["simulation"].update(lidar_range=4.5, prediction="kalman")
    del old["solver"], old["sensor"]["range"], old["nmpc"]["prediction"]
    assert Config.from_dict(old) == new
    box = {("nmpc", name) for name in ("state_lower", "state_upper", "input_lower",
                                       "input_upper")}  # tested with the run cache
    assert set(MOVED) == {("nmpc", "solver"), ("nmpc", "sqp_iterations"),
                          ("nmpc", "line_search"), ("nmpc", "qp_solver"),
                          ("simulation", "lidar_range"), ("simulation", "prediction")} | box
    both = new.to_dict()
    both["simulation"]["lidar_range"] = 4.5
    with pytest.raises(ValueError, match=r"simulation.lidar_range .* sensor.range"):
        Config.from_dict(both)


class _Unread:
    """A config part that fails the moment anything reads it."""

    def __init__(self, name):
        self._name = name

    def __getattr__(self, attr):
        raise AssertionError(f"the problem read {self._name}.{attr}")


@pytest.mark.parametrize("vehicle", ["quadrotor", "unicycle"])
def test_the_problem_reads_neither_the_solver_options_nor_the_mission(vehicle):
    """Problem (21) is built from the vehicle, the distance, the barrier, ``nmpc`` and the
    LiDAR's range only: with ``solver`` and ``simulation`` replaced by parts that raise when
    read, the OCP still builds, and it is the same problem (same scan layout and step)."""
    from paper_repro.vehicles.unicycle import unicycle_config, unicycle_model

    cfg = unicycle_config() if vehicle == "unicycle" else Config()
    model = unicycle_model() if vehicle == "unicycle" else None
    blind = Config(**{f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)})
    object.__setattr__(blind, "solver", _Unread("solver"))
    object.__setattr__(blind, "simulation", _Unread("simulation"))
    seen, full = OCP(blind, model), OCP(cfg, model)
    assert seen.scan == full.scan and seen.step == full.step and seen.horizon == full.horizon


@pytest.mark.parametrize("kwargs, name", [
    (dict(epsilon=0.5), "epsilon"), (dict(kappa=0.0), "kappa"), (dict(delta=1.0), "delta"),
    (dict(d_min=-1.0), "d_min"), (dict(form="other"), "form"), (dict(mu=float("nan")), "mu"),
])
def test_bad_barrier_parameters_are_rejected(kwargs, name):
    with pytest.raises(ValueError, match=name):
        BarrierParams(**kwargs)


@pytest.mark.parametrize("kwargs, name", [
    (dict(horizon=0), "horizon"), (dict(ts=0.0), "ts"), (dict(lam=1.0), "lam"),
    (dict(r=(3.0, 0.0, 3.0, 3.0)), "r"), (dict(points_per_region=0), "points_per_region"),
])
def test_bad_nmpc_parameters_are_rejected(kwargs, name):
    with pytest.raises(ValueError, match=name):
        NMPCParams(**kwargs)


@pytest.mark.parametrize("name, size", [("q", 11), ("r", 3), ("t", 2)])
def test_weights_must_fit_the_model(name, size):
    """Weights of another vehicle's size are refused when the problem is built, naming the
    field and the size the quadrotor needs."""
    with pytest.raises(ValueError, match=rf"^nmpc\.{name} must have .* for the quadrotor"):
        OCP(_config(**{name: (1.0,) * size}))


def test_bad_solve_arguments_are_rejected(smooth_controller):
    with pytest.raises(ValueError, match="x0"):
        smooth_controller.solve(np.zeros(11), np.zeros(3))
    with pytest.raises(ValueError, match="target"):
        smooth_controller.solve(np.zeros(12), [0.0, np.nan, 1.0])


@pytest.mark.parametrize("solver", ["rti", "reference"])
def test_cli_run_saves_a_loadable_result(tmp_path, capsys, solver):
    from paper_repro.cli.parser import main
    from paper_repro.sim.result import SimulationResult

    out = tmp_path / "run"
    assert main(["run", "--scenario", "encounter", "--metric", "smooth", "--solver", solver,
                 "--max-steps", "3", "--out", str(out), "--no-progress"]) == 0
    line = capsys.readouterr().out.strip()
    assert "encounter/smooth (mission): step_limit after 3 steps" in line
    assert "failed solves 0" in line
    result = SimulationResult.load(out)
    assert result.steps == 3 and result.config.solver.nlp_solver == solver
    frame = result.to_frame()
    assert len(frame) == 3 and {"t", "x", "f1", "x_a", "clearance"} <= set(frame.columns)
    np.testing.assert_array_equal(result.positions, result.x[:, :3])
    assert result.meta["casadi"] and "git_commit" in result.meta

"""A second vehicle through the same description, the same two solvers and the same closed
loop: the unicycle in a planar scene (p = 2)."""

import dataclasses

import numpy as np
import pytest

from paper_repro.sim.loop import simulate
from paper_repro.sim.result import SimulationResult
from paper_repro.solvers.factory import make_controller
from paper_repro.solvers.rti import RealTimeNMPC
from paper_repro.vehicles.unicycle import unicycle_config, unicycle_model
from paper_repro.world.lidar import Lidar
from paper_repro.world.planar import planar_scene


@pytest.fixture(scope="module")
def scene():
    return planar_scene()


def _fly(scene, metric="smooth", solver="rti", steps=200):
    config = unicycle_config(metric, solver)
    return simulate(config, make_controller(config, unicycle_model()), max_steps=steps,
                    progress=False, scene=scene)


@pytest.fixture(scope="module")
def runs(scene):
    """Smooth metric, 200 steps (10 s): the IPOPT reference and the real-time iteration."""
    return {solver: _fly(scene, solver=solver) for solver in ("reference", "rti")}


def test_the_unicycle_model_rests_where_it_stands():
    """Its parametrisation a = (p_x, p_y, θ), (v, ω) = 0 gives equilibria: f_c = 0."""
    model = unicycle_model()
    assert (model.nx, model.nu, model.ny) == (3, 2, 2)
    x_a, u_a = model.rest([1.0, -2.0, 0.7])
    np.testing.assert_array_equal(x_a, [1.0, -2.0, 0.7])
    np.testing.assert_array_equal(np.asarray(model.dynamics(x_a, u_a)).ravel(), 0.0)


def test_the_planar_scene_is_two_dimensional(scene):
    assert scene.dim == 2 and scene.clouds[0].shape[1] == 2
    with pytest.raises(ValueError, match="targets must be finite 2-D positions"):
        type(scene)("bad", scene.regions, (0.0, 0.0), ((1.0, 2.0, 3.0),),
                    clouds=scene.clouds)


def test_converged_sqp_equals_ipopt_on_one_instant(scene):
    """1.5 m from the wall, turning down to pass below it: the Gauss-Newton SQP iterated to
    convergence and IPOPT solve the same problem (21) for the unicycle. (Head-on, at rest in
    front of the wall, the problem has several local optima: back up and turn, or not.)"""
    model = unicycle_model()
    x0 = np.array([2.5, -1.5, -0.6])
    visible = Lidar(list(scene.clouds), 3.0, dim=2).scan(x0[:2])
    assert len(visible[0]) > 10
    target = scene.targets[0]
    fast = RealTimeNMPC(unicycle_config("smooth"), model, max_iter=60, step_tol=1e-10)
    ref = make_controller(unicycle_config("smooth", "reference"), model)
    a = fast.solve(x0, target, visible)
    b = ref.solve(x0, target, visible)
    assert a.success and b.success and a.status == "converged"
    np.testing.assert_allclose(a.x, b.x, atol=1e-6)
    np.testing.assert_allclose(a.u, b.u, atol=1e-6)
    np.testing.assert_allclose(a.x_a, b.x_a, atol=1e-6)
    np.testing.assert_array_equal(a.u_a, 0.0)


def test_real_time_iteration_stays_within_a_centimetre_of_ipopt(runs):
    """One SQP step per instant, over 10 s of closed loop past the wall's corner."""
    ref, rti = runs["reference"], runs["rti"]
    assert ref.success.all() and rti.success.all()
    assert rti.visible_points.max() > 0 and len(rti.t) == len(ref.t)
    deviation = np.linalg.norm(rti.x[:, :2] - ref.x[:, :2], axis=1)
    assert deviation.max() < 0.01


def test_smooth_metric_leads_round_the_wall_and_euclidean_stalls_in_front(scene):
    """The smoothed distance's gradient leans towards the cloud's centroid and leads the
    robot round the L to its target; the Euclidean one points straight back and the robot
    stops in front of the wall, a stall the closed loop tells from the output's speed (the
    unicycle has no velocity state). Neither ever comes closer than the margin allows."""
    out = {m: _fly(scene, m, steps=500) for m in ("smooth", "euclidean")}
    cloud = scene.clouds[0]
    assert out["smooth"].outcome == "completed" and out["smooth"].x[-1, 0] > cloud[:, 0].max()
    assert out["euclidean"].outcome == "stalled"
    assert out["euclidean"].x[-1, 0] < cloud[:, 0].min()
    for run in out.values():
        assert run.success.all() and run.clearance.min() > 0.5
    # The stop is a stall, not chattering: the robot is at rest.
    assert np.abs(out["euclidean"].u[-50:]).max() < 1e-3


def test_a_planar_vehicle_needs_a_planar_scene():
    from paper_repro.world.scenarios import make_scene

    config = unicycle_config()
    with pytest.raises(ValueError, match="2 position states"):
        simulate(config, model=unicycle_model(), scene=make_scene("encounter"), max_steps=1)


def test_a_saved_run_names_its_vehicle_s_columns_and_keeps_its_positions(runs, tmp_path):
    """The result carries y = h(x) for every state and the unicycle's names: the frame and the
    plots read the vehicle from the run, not from the shape of its arrays."""
    run = runs["rti"]
    assert run.positions.shape == (run.steps + 1, 2)
    np.testing.assert_array_equal(run.positions, run.x[:, :2])  # h selects (p_x, p_y)
    again = SimulationResult.load(run.save(tmp_path / "run"))
    np.testing.assert_array_equal(again.positions, run.positions)
    frame = again.to_frame()
    assert {"p_x", "p_y", "theta", "v", "omega", "p_x_a", "p_y_a", "v_a"} <= set(frame.columns)
    assert "x" not in frame.columns and "f1" not in frame.columns
    np.testing.assert_array_equal(frame["theta"], run.x[:-1, 2])


def test_a_vehicle_s_names_are_checked():
    model = unicycle_model()
    with pytest.raises(ValueError, match="state_names must be 3 distinct identifiers"):
        dataclasses.replace(model, state_names=("p_x", "p_x", "theta"))
    with pytest.raises(ValueError, match="input_names must be 2 distinct identifiers"):
        dataclasses.replace(model, input_names=("v",))
    assert dataclasses.replace(model, state_names=()).description()["states"] == ["x0", "x1",
                                                                                  "x2"]

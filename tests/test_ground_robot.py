"""A second vehicle through the same description and the same two solvers: the unicycle."""

import numpy as np
import pytest

from paper_repro.solvers.factory import make_controller
from paper_repro.solvers.rti import RealTimeNMPC
from paper_repro.vehicles.unicycle import unicycle_config, unicycle_model
from paper_repro.world.planar import fly, planar_scan, planar_scene


@pytest.fixture(scope="module")
def scene():
    return planar_scene()


@pytest.fixture(scope="module")
def runs(scene):
    """Smooth metric, 200 steps (10 s): the IPOPT reference and the real-time iteration."""
    out = {}
    for solver in ("reference", "rti"):
        ctl = make_controller(unicycle_config("smooth", solver), unicycle_model())
        out[solver] = fly(ctl, scene, steps=200)
    return out


def test_the_unicycle_model_rests_where_it_stands():
    """Its parametrisation a = (p_x, p_y, θ), (v, ω) = 0 gives equilibria: f_c = 0."""
    model = unicycle_model()
    assert (model.nx, model.nu, model.ny) == (3, 2, 2)
    x_a, u_a = model.rest([1.0, -2.0, 0.7])
    np.testing.assert_array_equal(x_a, [1.0, -2.0, 0.7])
    np.testing.assert_array_equal(np.asarray(model.dynamics(x_a, u_a)).ravel(), 0.0)


def test_converged_sqp_equals_ipopt_on_one_instant(scene):
    """1.5 m from the wall, turning down to pass below it: the Gauss-Newton SQP iterated to
    convergence and IPOPT solve the same problem (21) for the unicycle. (Head-on, at rest in
    front of the wall, the problem has several local optima: back up and turn, or not.)"""
    model = unicycle_model()
    x0 = np.array([2.5, -1.5, -0.6])
    visible = planar_scan(*_tree(scene), x0[:2])
    assert len(visible[0]) > 10
    fast = RealTimeNMPC(unicycle_config("smooth"), model, max_iter=60, step_tol=1e-10)
    ref = make_controller(unicycle_config("smooth", "reference"), model)
    a = fast.solve(x0, scene.target, visible)
    b = ref.solve(x0, scene.target, visible)
    assert a.success and b.success and a.status == "converged"
    np.testing.assert_allclose(a.x, b.x, atol=1e-6)
    np.testing.assert_allclose(a.u, b.u, atol=1e-6)
    np.testing.assert_allclose(a.x_a, b.x_a, atol=1e-6)
    np.testing.assert_array_equal(a.u_a, 0.0)


def test_real_time_iteration_stays_within_a_centimetre_of_ipopt(runs):
    """One SQP step per instant, over 10 s of closed loop past the wall's corner."""
    ref, rti = runs["reference"], runs["rti"]
    assert ref.success.all() and rti.success.all()
    assert rti.visible.max() > 0
    deviation = np.linalg.norm(rti.x[:, :2] - ref.x[:, :2], axis=1)
    assert deviation.max() < 0.01


def test_smooth_metric_leads_round_the_wall_and_euclidean_stops_in_front(scene):
    """The smoothed distance's gradient leans towards the cloud's centroid and leads the
    robot round the L; the Euclidean one points straight back and the robot stops. Neither
    ever comes closer than the safety margin allows."""
    out = {m: fly(make_controller(unicycle_config(m), unicycle_model()), scene, steps=500)
           for m in ("smooth", "euclidean")}
    wall_x = scene.cloud[:, 0].max()
    assert out["smooth"].x[-1, 0] > wall_x and out["euclidean"].x[-1, 0] < scene.cloud[:, 0].min()
    for run in out.values():
        assert run.success.all() and run.clearance.min() > 0.5
    # The stop is a stall, not chattering: the robot is at rest.
    assert np.abs(out["euclidean"].u[-50:]).max() < 1e-3


def _tree(scene):
    from scipy.spatial import cKDTree

    return cKDTree(scene.cloud), scene.cloud


@pytest.mark.parametrize("kwargs, name", [
    (dict(steps=0), "steps"), (dict(substeps=1.5), "substeps"),
    (dict(lidar_range=-1.0), "lidar_range")])
def test_bad_flight_settings_are_named_before_flying(kwargs, name):
    class NeverSolves:  # fly must refuse before it touches the controller
        def __getattr__(self, item):
            raise AssertionError("the controller was used")

    with pytest.raises(ValueError, match=f"^{name} must be"):
        fly(NeverSolves(), **kwargs)

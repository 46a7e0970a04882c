"""The smooth sensing window: points enter and leave D continuously at the LiDAR's range."""

import casadi as ca
import numpy as np
import pytest

from paper_repro import Config, DistanceParams, SensorParams, SimulationParams, SolverParams
from paper_repro.problem.distance import CloudWeights, sensing_window, smooth_distance
from paper_repro.problem.ocp import OCP
from paper_repro.problem.scan import ScanLayout

R_S = 3.0


def test_the_window_is_one_inside_zero_at_the_range_and_flat_at_both_ends():
    r = np.linspace(0.0, 3.5, 3501)
    log_psi = sensing_window(r, R_S, 1.0)
    psi = np.exp(log_psi)
    assert np.all(psi[r <= 2.0] == 1.0) and np.all(psi[r >= R_S] == 0.0)
    assert np.all(np.diff(psi) <= 0)  # non-increasing in range
    # Flat at both ends: the slope over the last and first millimetre of the band is tiny.
    inner = np.exp(sensing_window(np.array([2.0, 2.001]), R_S, 1.0))
    outer = np.exp(sensing_window(np.array([2.999, 3.0]), R_S, 1.0))
    assert abs(np.diff(inner)[0]) < 1e-100 and abs(np.diff(outer)[0]) < 1e-100
    assert psi[r == 2.5][0] == pytest.approx(0.5)  # symmetric step


def _distance_with_window(point_range, y, others, window):
    """D(y) and ∇D(y) of the scan seen from the origin, one point at ``point_range`` on +x."""
    layout = ScanLayout("smooth", 0.3, 0.8, 1.0, slots=1, capacity=16, window=window,
                        sensor_range=R_S)
    moving = np.array([[point_range, 0.0, 0.0]])
    visible = np.vstack([others, moving]) if point_range < R_S else others  # the LiDAR
    packed = layout.pack([visible], np.zeros(3))
    params, beta, _ = layout.region_barrier()
    ys = ca.SX.sym("y", 3)
    b = beta(ys)
    fn = ca.Function("d", [ys, params], [b, ca.gradient(b, ys)])
    value, grad = fn(y, packed)
    return float(value) + 1.0, np.asarray(grad).ravel()


@pytest.fixture(scope="module")
def others():
    rng = np.random.default_rng(5)
    return rng.uniform([1.5, -0.5, -0.5], [2.3, 0.5, 0.5], size=(10, 3))


def test_d_and_its_gradient_move_continuously_as_a_point_crosses_the_range(others):
    """A point moved radially across r_s: with the window, D and ∇D change by O(step) from one
    position to the next, across the boundary included; with the hard cut-off they jump."""
    y = np.array([2.6, 0.4, 0.3])
    ranges = np.linspace(2.6, 3.2, 601)  # 1 mm steps, r_s inside
    for window, continuous in ((0.5, True), (0.0, False)):
        d, g = zip(*(_distance_with_window(r, y, others, window) for r in ranges))
        d, g = np.array(d), np.array(g)
        jump_d = np.abs(np.diff(d)).max()
        jump_g = np.abs(np.diff(g, axis=0)).max()
        if continuous:
            assert jump_d < 1e-3 and jump_g < 5e-3
            # Finite differences in the point's range are bounded across r_s, and vanish
            # where the point is out of view and just inside it (every derivative of ψ is 0).
            slope = np.diff(d) / np.diff(ranges)
            assert np.abs(slope).max() < 1.0
            assert np.all(slope[ranges[1:] > R_S] == 0.0)
        else:
            # The hard cut-off: a step at r_s, 60 times the window's largest 1 mm change.
            assert jump_d > 5e-3 and jump_g > 0.05


def test_window_weights_equal_the_plain_ones_inside_and_drop_points_at_the_range(others):
    """With every point within r_s − w the window changes nothing; a point at r_s is gone."""
    layout = ScanLayout("smooth", 0.3, 0.8, 1.0, slots=1, capacity=16, window=0.5,
                        sensor_range=R_S)
    plain = ScanLayout("smooth", 0.3, 0.8, 1.0, slots=1, capacity=16)
    np.testing.assert_array_equal(layout.pack([others], np.zeros(3)),
                                  plain.pack([others], np.zeros(3)))
    edge = np.vstack([others, [[R_S, 0.0, 0.0]]])
    np.testing.assert_array_equal(layout.pack([edge], np.zeros(3)),
                                  plain.pack([others], np.zeros(3)))
    # The numeric distance with presence weights equals the packed one.
    log_p = sensing_window(np.linalg.norm(edge, axis=1), R_S, 0.5)
    y = np.array([2.6, 0.4, 0.3])
    full = smooth_distance(y, CloudWeights.from_cloud(edge[:-1], 0.8, log_p[:-1]), 0.3, 0.8)
    assert full == pytest.approx(smooth_distance(y, others, 0.3, 0.8), rel=1e-14)


def test_the_window_is_an_option_of_the_config_read_by_both_solvers():
    cfg = Config(distance=DistanceParams(window=0.5))
    assert OCP(cfg).scan.window == 0.5 and OCP(cfg).scan.sensor_range == 3.0
    assert OCP(Config()).scan.window == 0.0  # off by default: the paper's set-up
    with pytest.raises(ValueError, match=r"^distance\.window must be < sensor\.range"):
        Config(distance=DistanceParams(window=3.0))
    with pytest.raises(ValueError, match="^window must be a finite number >= 0"):
        DistanceParams(window=-0.1)
    assert Config(distance=DistanceParams(window=1.0),
                  sensor=SensorParams(range=4.0)).distance.window == 1.0


def test_both_solvers_fly_the_window_and_agree():
    """The window lives in the packed scan, so both solvers read it: near the encounter's
    corner the converged SQP equals IPOPT with the window on, and what the solvers are given
    differs from the hard cut-off's (a point at 2.5-3 m weighs less)."""
    import dataclasses

    from paper_repro import Lidar, NMPCParams, make_scene
    from paper_repro.solvers.ipopt import TrackingNMPC
    from paper_repro.solvers.rti import RealTimeNMPC
    from paper_repro.vehicles.quadrotor import equilibrium

    scene = make_scene("encounter")
    small = NMPCParams(region_slots=1, points_per_region=48)
    cfg = Config(distance=DistanceParams(window=0.5), nmpc=small,
                 simulation=SimulationParams(scenario="encounter"))
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.2
    visible = Lidar(scene.clouds).scan(x0[:3])
    ranges = np.linalg.norm(visible[0] - x0[:3], axis=1)
    assert np.any(ranges > 2.5), "the test needs points in the window's band"
    fast = RealTimeNMPC(cfg, max_iter=40, step_tol=1e-10)
    a = fast.solve(x0, scene.targets[0], visible)
    b = TrackingNMPC(dataclasses.replace(cfg, solver=SolverParams(
        nlp_solver="reference"))).solve(x0, scene.targets[0], visible)
    assert a.success and b.success
    np.testing.assert_allclose(a.x, b.x, atol=1e-4)
    windowed = fast.obstacle_parameters(visible, x0[:3])
    hard = OCP(dataclasses.replace(cfg, distance=DistanceParams())).scan.pack(visible, x0[:3])
    assert windowed.shape == hard.shape and np.abs(windowed - hard).max() > 0.1

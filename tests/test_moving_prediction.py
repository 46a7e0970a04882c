"""Moving regions predicted over the horizon: β at stage j is that of the cloud moved by v·τ_j."""

import dataclasses

import casadi as ca
import numpy as np
import pytest

from paper_repro import (
    Config,
    DistanceParams,
    Lidar,
    NMPCParams,
    SimulationParams,
    SolverParams,
    make_scene,
)
from paper_repro.config import BarrierParams
from paper_repro.problem.distance import smooth_distance
from paper_repro.problem.ocp import OCP
from paper_repro.problem.scan import ScanLayout
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.solvers.rti import RealTimeNMPC
from paper_repro.vehicles.quadrotor import equilibrium

SMALL = NMPCParams(region_slots=1, points_per_region=48)


def _config(prediction="oracle", solver="rti", metric="smooth"):
    return Config(distance=DistanceParams(metric=metric),
                  simulation=SimulationParams(scenario="encounter"),
                  nmpc=dataclasses.replace(SMALL, prediction=prediction),
                  solver=SolverParams(nlp_solver=solver))


def test_a_rigid_translation_shifts_the_query():
    """D^{A+c}(y) = D^A(y − c): the packed slot with velocity v, evaluated τ s after the scan,
    is the distance to the scanned cloud moved by v·τ (W, V and the centroid move along)."""
    rng = np.random.default_rng(2)
    cloud = rng.uniform(-1.0, 1.0, size=(12, 3)) + [2.0, 0.0, 0.0]
    layout = ScanLayout("smooth", 0.3, 0.8, 1.0, slots=1, capacity=16, moving=True)
    v = np.array([0.4, -1.1, 0.2])
    params, beta, _ = layout.region_barrier()
    y, tau = ca.SX.sym("y", 3), ca.SX.sym("tau")
    fn = ca.Function("b", [y, params, tau], [beta(y, tau)])
    packed = layout.pack([cloud], np.zeros(3), [v])
    for t in (0.0, 0.1, 0.35):
        query = rng.normal(size=3)
        moved = smooth_distance(query, cloud + v * t, 0.3, 0.8)
        assert float(fn(query, packed, t)) + 1.0 == pytest.approx(moved, rel=1e-12)


@pytest.mark.parametrize("metric", ["smooth", "euclidean"])
def test_the_reaction_margin_grows_with_the_regions_speed_only(metric):
    """β = D − ½(√(2·d_min) + ‖v‖·t_r)²: the safe distance lengthened by the way the region
    covers in t_r; a region at rest keeps the paper's β = D − d_min, and t_r = 0 is the
    paper's barrier whatever the speed."""
    rng = np.random.default_rng(5)
    cloud = rng.uniform(-1.0, 1.0, size=(10, 3)) + [2.5, 0.0, 0.0]
    d_min, t_r = 1.0, 0.8
    plain = ScanLayout(metric, 0.3, 0.8, d_min, slots=1, capacity=16, moving=True)
    widened = dataclasses.replace(plain, reaction_time=t_r)
    y = ca.SX.sym("y", 3)
    fns = {}
    for name, layout in (("plain", plain), ("widened", widened)):
        params, beta, _ = layout.region_barrier()
        fns[name] = ca.Function(name, [y, params], [beta(y, 0.0)])
    query = np.array([0.3, 0.2, -0.1])
    for v in (np.zeros(3), np.array([0.6, -0.8, 0.0]), np.array([1.5, 0.0, 0.3])):
        packed = plain.pack([cloud], np.zeros(3), [v])
        b0, b1 = float(fns["plain"](query, packed)), float(fns["widened"](query, packed))
        margin = 0.5 * (np.sqrt(2 * d_min) + np.linalg.norm(v) * t_r) ** 2
        assert b1 == pytest.approx(b0 + d_min - margin, rel=1e-12, abs=1e-12)
        assert (b1 == pytest.approx(b0, abs=1e-12)) == (np.linalg.norm(v) == 0)


def test_a_reaction_margin_needs_a_prediction_that_hands_velocities():
    with pytest.raises(ValueError, match=r"^barrier.reaction_time needs nmpc.prediction"):
        Config(barrier=BarrierParams(reaction_time=1.0))
    with pytest.raises(ValueError, match="^reaction_time must be a finite number >= 0"):
        BarrierParams(reaction_time=-0.5)
    cfg = Config(barrier=BarrierParams(reaction_time=1.0), nmpc=NMPCParams(prediction="kalman"))
    assert OCP(cfg).scan.reaction_time == 1.0


def test_velocities_are_checked_before_the_solve():
    static = OCP(_config("static")).scan
    with pytest.raises(ValueError, match="^velocities need a layout built for moving"):
        static.pack([np.ones((2, 3))], np.zeros(3), [np.zeros(3)])
    moving = OCP(_config("oracle")).scan
    assert moving.moving and moving.size == static.size + 3
    with pytest.raises(ValueError, match=r"^velocities must hold one \(3,\) array per region"):
        moving.pack([np.ones((2, 3))], np.zeros(3), [])
    with pytest.raises(ValueError, match=r"^velocities\[0\]"):
        moving.pack([np.ones((2, 3))], np.zeros(3), [np.array([0.0, np.nan, 0.0])])


@pytest.fixture(scope="module")
def instant():
    scene = make_scene("encounter")
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.2
    visible = Lidar(scene.clouds).scan(x0[:3])
    assert sum(len(v) for v in visible) > 0
    return x0, scene.targets[0], visible


def test_converged_sqp_equals_ipopt_with_a_moving_region(instant):
    """Both solvers read the same prediction: with the region coming at the UAV at 2 m/s (0.7 m
    over the horizon, into the barrier's range) the converged SQP and IPOPT agree, and the
    plan differs from the static one: it backs away."""
    x0, target, visible = instant
    towards = [np.array([-2.0, 0.0, 0.0]) if len(v) else np.zeros(3) for v in visible]
    fast = RealTimeNMPC(_config(), max_iter=100, step_tol=1e-10)
    ref = TrackingNMPC(_config(solver="reference"))
    a = fast.solve(x0, target, visible, velocities=towards)
    b = ref.solve(x0, target, visible, velocities=towards)
    assert a.success and b.success and a.status == "converged"
    np.testing.assert_allclose(a.x, b.x, atol=1e-4)
    np.testing.assert_allclose(a.u, b.u, atol=1e-3)
    still = fast.solve(x0, target, visible, velocities=[np.zeros(3)] * len(visible))
    static = RealTimeNMPC(_config("static"), max_iter=60, step_tol=1e-10).solve(
        x0, target, visible)
    # At rest, the moving layout is the static problem; moving, the plan changes.
    np.testing.assert_allclose(still.u, static.u, atol=1e-9)
    assert np.abs(a.u - static.u).max() > 1e-3
    assert a.x[-1, 0] < static.x[-1, 0]

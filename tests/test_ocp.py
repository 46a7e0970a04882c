"""The one description of problem (21): its terms, its scan layout, its QP layout, any model."""

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
from paper_repro.problem.distance import CloudWeights, euclidean_distance, smooth_distance
from paper_repro.problem.ocp import OCP
from paper_repro.problem.scan import (
    PAD_LOG_WEIGHT,
    ScanLayout,
    check_visible,
    drop_non_finite,
)
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.solvers.linearisation import QPLayout
from paper_repro.solvers.rti import QPChain, RealTimeNMPC
from paper_repro.vehicles.base import VehicleModel
from paper_repro.vehicles.quadrotor import equilibrium, quadrotor_model

SMALL = NMPCParams(region_slots=1, points_per_region=48)


def _config(metric="smooth", solver="rti", **barrier):
    return Config(distance=DistanceParams(metric=metric),
                  barrier=BarrierParams(**barrier),
                  simulation=SimulationParams(scenario="encounter"),
                  nmpc=SMALL, solver=SolverParams(nlp_solver=solver))


# --- the penalty ---------------------------------------------------------------------------------

@pytest.mark.parametrize("epsilon", [1.0, 1.5, 2.0, 3.0])
def test_penalty_derivatives_equal_casadi_ad(epsilon):
    """F' and F'' used by the Gauss-Newton path are the derivatives of the F that the IPOPT
    transcription minimises (CasADi's AD), from deep in the flat part to the steep one."""
    ocp = OCP(_config(epsilon=epsilon))
    g = ca.SX.sym("g")
    f = ocp.penalty(g)
    ad = ca.Function("ad", [g], [ca.jacobian(f, g), ca.hessian(f, g)[0]])
    mine = ca.Function("mine", [g], list(ocp.penalty_derivatives(g)))
    for value in np.r_[np.linspace(-3.0, 3.0, 60), -50.0, 20.0]:
        d1, d2 = (float(v) for v in ad(value))
        m1, m2 = (float(v) for v in mine(value))
        assert m1 == pytest.approx(d1, rel=1e-6, abs=1e-300)
        assert m2 == pytest.approx(d2, rel=1e-6, abs=1e-300)
    # At g = 0 exactly, AD differentiates the |z| of the overflow-free form as if it had a
    # kink (sign(0) = 0); F is smooth there, and F'' is the limit from either side.
    m2 = float(mine(0.0)[1])
    assert m2 == pytest.approx(float(ad(1e-9)[1]), rel=1e-6)
    assert m2 == pytest.approx(float(ad(-1e-9)[1]), rel=1e-6)
    # Far in the flat part (κg ≈ −1000) the softplus underflows: the derivatives stay 0, finite.
    m1, m2 = (float(v) for v in mine(-100.0))
    assert m1 == 0.0 and m2 == 0.0


def test_penalty_is_convex_increasing_and_tends_to_the_hinge():
    """F = (1/κ)[ln(1 + e^{κg})]^ε: for ε = 1, within ln 2 / κ of max(0, g)."""
    ocp = OCP(_config(epsilon=1.0))
    g = np.linspace(-2.0, 2.0, 401)
    F = np.array([float(ocp.penalty(v)) for v in g])
    assert np.all(np.diff(F) > 0) and np.all(np.diff(F, 2) > -1e-12)
    assert np.max(np.abs(F - np.maximum(g, 0.0))) <= np.log(2) / ocp.kappa + 1e-12


def test_violations_pair_each_output_with_the_next_and_rest_at_y_a():
    """g_j = c·β_j − β_{j+1} with β_{N+1} = β(y_a), then g_a = (c − 1)·β(y_a) (eq. 18)."""
    ocp = OCP(_config())
    betas = [0.3, 0.1, -0.2, 0.5]  # β(y_0), β(y_1), β(y_2), β(y_a)
    c = ocp.decay
    assert ocp.violations(betas) == pytest.approx(
        [c * 0.3 - 0.1, c * 0.1 + 0.2, c * -0.2 - 0.5, (c - 1) * 0.5])


# --- the scan layout ------------------------------------------------------------------------------

def _slot(layout, packed, slot):
    cap, dim = layout.capacity, layout.dim
    per = cap * (dim + 1) + (2 if layout.metric == "smooth" else 1)
    block = packed[slot * per:(slot + 1) * per]
    pts = block[:cap * dim].reshape(dim, cap).T
    return pts, block[cap * dim:cap * (dim + 1)], block[cap * (dim + 1):]


def test_more_points_than_capacity_keeps_the_nearest_with_the_whole_cloud_weights():
    """A region with more points than a slot holds keeps the nearest ones, with ln W computed
    from every visible point (W and V belong to the cloud seen, not to the slot)."""
    rng = np.random.default_rng(0)
    cloud = rng.uniform(-1.0, 1.0, size=(30, 3)) + [2.0, 0.0, 0.0]
    layout = ScanLayout("smooth", 0.3, 0.8, 1.0, slots=1, capacity=8)
    packed = layout.pack([cloud], np.zeros(3))
    assert packed.size == layout.size
    pts, log_w, (log_v, active) = _slot(layout, packed, 0)
    nearest = np.sort(np.argsort(np.linalg.norm(cloud, axis=1))[:8])
    np.testing.assert_array_equal(pts, cloud[nearest])
    full = CloudWeights.from_cloud(cloud, 0.8)
    np.testing.assert_allclose(log_w, full.log_weights[nearest])
    assert log_v == pytest.approx(full.log_volume) and active == 1.0


def test_more_regions_than_slots_keeps_the_nearest_regions_and_pads_the_rest():
    far, near, middle = (np.array([[d, 0.0, 0.0], [d, 0.5, 0.0]]) for d in (9.0, 1.0, 4.0))
    layout = ScanLayout("euclidean", 0.3, 0.8, 1.0, slots=2, capacity=4)
    packed = layout.pack([far, near, middle], np.zeros(3))
    kept = [_slot(layout, packed, s) for s in range(2)]
    np.testing.assert_array_equal(kept[0][0][:2], near)
    np.testing.assert_array_equal(kept[1][0][:2], middle)
    for pts, mask, (active,) in kept:
        np.testing.assert_array_equal(mask, [1, 1, 0, 0])
        assert active == 1.0 and np.all(pts[2:] == 1e3)
    # A scan with fewer regions than slots: the empty slot is inactive (its penalty is 0).
    one = layout.pack([np.empty((0, 3)), near], np.zeros(3))
    pts, mask, (active,) = _slot(layout, one, 1)
    assert active == 0.0 and mask[0] == 1.0 and np.all(pts == 1e3)
    smooth = ScanLayout("smooth", 0.3, 0.8, 1.0, slots=2, capacity=4)
    _, log_w, _ = _slot(smooth, smooth.pack([near], np.zeros(3)), 0)
    assert np.all(log_w[2:] == PAD_LOG_WEIGHT)


def test_dropping_non_finite_returns_hands_over_a_checked_scan():
    """drop_non_finite removes the rows with a non-finite coordinate and counts them; a scan
    of (k, p) float regions comes back in check_visible's checked form (not checked again),
    anything else as a list that check_visible refuses with its message."""
    good = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    bad = np.array([[1.0, np.nan, 3.0], [4.0, 5.0, 6.0], [np.inf, 0.0, 0.0]])
    scan, dropped = drop_non_finite([good, bad, np.zeros((0, 3))], 3)
    assert dropped == 2 and check_visible(scan, 3) is scan
    np.testing.assert_array_equal(scan[1], bad[1:2])
    assert scan[0] is good
    transposed, dropped = drop_non_finite([good.T], 3)
    assert dropped == 0 and isinstance(transposed, list)
    with pytest.raises(ValueError, match=r"visible\[0\] must be a \(k, 3\) array"):
        check_visible(transposed, 3)


def test_padding_leaves_the_barrier_unchanged():
    """β of a packed slot equals D − d_min of the visible points alone, for both metrics and
    in the plane too: padding contributes exactly 0."""
    rng = np.random.default_rng(1)
    for dim in (3, 2):
        cloud = rng.uniform(-1.0, 1.0, size=(5, dim)) + np.r_[1.5, np.zeros(dim - 1)]
        y = rng.normal(size=dim) * 0.3
        for metric in ("smooth", "euclidean"):
            layout = ScanLayout(metric, 0.3, 0.8, 1.0, slots=1, capacity=16, dim=dim)
            params, beta, _ = layout.region_barrier()
            ys = ca.SX.sym("y", dim)
            fn = ca.Function("b", [ys, params], [beta(ys)])
            value = float(fn(y, layout.pack([cloud], y)))
            exact = (smooth_distance(y, cloud, 0.3, 0.8) if metric == "smooth"
                     else euclidean_distance(y, cloud))
            assert value == pytest.approx(exact - 1.0, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("metric", ["smooth", "euclidean"])
@pytest.mark.parametrize("moving", [False, True])
def test_an_unused_slot_is_one_inactive_dummy_point_however_often_it_is_packed(metric, moving):
    """The block of a slot no region fills is made once per layout: packing it again, around
    scans that fill other slots, gives the same numbers and leaves it unchanged."""
    layout = ScanLayout(metric, 0.3, 0.8, 1.0, slots=3, capacity=8, moving=moving)
    per_slot = layout.size // 3
    rng = np.random.default_rng(2)
    first = None
    for _ in range(3):
        cloud = rng.normal(size=(5, 3)) + 2.0
        velocity = [rng.normal(size=3)] if moving else None
        packed = layout.pack([cloud], np.zeros(3), velocity)
        unused = packed[per_slot:].reshape(2, per_slot)
        assert np.array_equal(unused[0], unused[1])
        first = unused[0].copy() if first is None else first
        assert np.array_equal(unused[0], first)
    points = first[:8 * 3].reshape(3, 8).T  # column-major (capacity, p)
    assert np.all(points == 1e3)
    weights = first[8 * 3:8 * 4]
    if metric == "smooth":  # ln W: the dummy point 0, the padding −1e30; then ln V, active
        assert weights[0] == 0.0 and np.all(weights[1:] == PAD_LOG_WEIGHT)
        assert list(first[8 * 4:8 * 4 + 2]) == [0.0, 0.0]
    else:  # the mask: the dummy point only; then active
        assert weights[0] == 1.0 and np.all(weights[1:] == 0.0) and first[8 * 4] == 0.0
    if moving:
        assert np.all(first[-3:] == 0.0)


# --- the QP layout --------------------------------------------------------------------------------

def _random_blocks(layout, rng):
    h = []
    for s in layout.sizes:
        m = rng.normal(size=(s, s))
        h.append((m @ m.T + s * np.eye(s)).ravel(order="F"))
    h = np.concatenate(h)
    q = rng.normal(size=layout.nw)
    j = rng.normal(size=layout.n_ab + layout.nc * layout.nz[-1])
    gap = rng.normal(size=layout.n_gap_rows)
    eq = rng.normal(size=layout.nc)
    return h, q, j, gap, eq


@pytest.mark.parametrize("qp_solver", ["riccati", "hpipm"])
def test_qp_layout_matches_the_dense_qp(qp_solver):
    """The stage QP that the backends solve is the dense QP the layout assembles: with loose
    bounds, both backends return the solution of its KKT system."""
    layout = QPLayout(horizon=4, nx=3, nu=2, na=2, ns=1, nc=5)
    h, q, j, gap, eq = _random_blocks(layout, np.random.default_rng(3))
    H, A = layout.dense(h, j)
    assert np.allclose(H, H.T)
    m = A.shape[0]
    kkt = np.block([[H, A.T], [A, np.zeros((m, m))]])
    exact = np.linalg.solve(kkt, np.r_[-q, -np.r_[gap, eq]])[:layout.nw]
    chain = QPChain(layout, qp_solver)
    big = np.full(layout.nw, 1e3)
    dw = chain.solve(h, q, j, gap, eq, -big, big)
    np.testing.assert_allclose(dw, exact, atol=1e-7)
    assert chain.counts[qp_solver] == 1 and chain.counts["failed"] == 0


def test_the_chain_reports_the_interior_points_iterations_of_its_last_qp():
    """``last_ipm_iterations``: the interior point's iterations in the last QP, 0 when the
    active-set method solved it alone. Clipping every input at half its unbounded value
    moves more bounds than a budget of one factorisation allows (the interior point takes
    the QP, which stays feasible with one terminal row); the same QP with loose bounds is
    the active set's from a reset."""
    layout = QPLayout(horizon=6, nx=3, nu=2, na=2, ns=1, nc=1)
    h, q, j, gap, eq = _random_blocks(layout, np.random.default_rng(3))
    chain = QPChain(layout, "riccati-ipm")
    chain.budget = 1
    big = np.full(layout.nw, 1e3)
    free = chain.solve(h, q, j, gap, eq, -big, big)
    lb, ub = -big.copy(), big.copy()
    half = 0.5 * np.abs(free[layout.iu])
    lb[layout.iu], ub[layout.iu] = -half, half
    clipped = chain.solve(h, q, j, gap, eq, lb, ub)
    assert chain.counts["ipm"] == 1 and chain.last_ipm_iterations >= 1
    assert np.all(np.abs(clipped[layout.iu]) <= half + 1e-9)
    assert np.any(np.isclose(np.abs(clipped[layout.iu]), half))  # bounds hold with equality
    chain.reset()
    chain.solve(h, q, j, gap, eq, -big, big)
    assert chain.counts["riccati"] == 2 and chain.last_ipm_iterations == 0


def test_qp_layout_places_every_variable_once():
    layout = QPLayout(horizon=5, nx=4, nu=2, na=3, ns=2, nc=4)
    used = np.concatenate([layout.ix.ravel(), layout.iu.ravel(), layout.ia.ravel()])
    assert len(np.unique(used)) == len(used)
    assert layout.nw - len(used) == 2 * 5  # the carried β of stages 1..N
    X, U, a = np.arange(20.0).reshape(5, 4), -np.arange(10.0).reshape(5, 2), np.r_[7.0, 8, 9]
    dx, du, da = layout.gather(layout.scatter(X, U, a))
    np.testing.assert_array_equal(dx, X)
    np.testing.assert_array_equal(du, U)
    np.testing.assert_array_equal(da, a)


# --- any model --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def scene():
    return make_scene("encounter")


def test_a_model_without_parametrisation_reaches_the_same_optimum(scene):
    """The quadrotor stripped of its equilibrium parametrisation: the real-time solver then
    carries (x_a, u_a) with f_c(x_a, u_a) = 0 as terminal rows. Converged, it reaches the
    optimum that IPOPT finds with the parametrisation, and the Riccati solver handles every
    QP."""
    cfg = _config()
    hover = (cfg.quadrotor.hover_thrust,) * 4
    plain = dataclasses.replace(quadrotor_model(cfg), equilibria=None, rest_input=hover)
    fast = RealTimeNMPC(cfg, plain, max_iter=40, step_tol=1e-10, capacities=())
    assert fast.ocp.na == 16 and fast.layout.nc == 24
    ref = TrackingNMPC(_config(solver="reference"))
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.2
    visible = Lidar(scene.clouds).scan(x0[:3])
    assert sum(len(v) for v in visible) > 0
    a, b = fast.solve(x0, scene.targets[0], visible), ref.solve(x0, scene.targets[0], visible)
    assert a.success and b.success and a.status == "converged"
    np.testing.assert_allclose(a.x_a, b.x_a, atol=1e-5)
    np.testing.assert_allclose(a.u_a, b.u_a, atol=1e-5)
    np.testing.assert_allclose(a.x, b.x, atol=1e-4)
    assert fast.qp_counts["riccati"] == a.iterations and fast.qp_counts["hpipm"] == 0


def test_the_quadrotor_equilibrium_box_is_the_relaxed_box_at_position_and_yaw():
    ocp = OCP(_config())
    xal, xau, _, _ = ocp.config.quadrotor.relaxed_bounds(ocp.config.nmpc.lam)
    lo, hi = ocp.equilibrium_box
    np.testing.assert_array_equal(lo, xal[[0, 1, 2, 5]])
    np.testing.assert_array_equal(hi, xau[[0, 1, 2, 5]])
    x_a, u_a = ocp.equilibrium_of(np.r_[1.0, 2.0, 3.0, 0.4])
    np.testing.assert_array_equal(x_a, equilibrium([1.0, 2.0, 3.0], 0.4)[0])
    assert np.all(u_a == ocp.config.quadrotor.hover_thrust)


def test_the_state_box_is_x_inside_and_holds_a_measured_state_outside_with_room():
    ocp = OCP(_config())
    lo, hi = ocp.state_bounds
    x0, _ = equilibrium([1.0, 2.0, 3.0])
    assert all(a is b for a, b in zip(ocp.state_box(x0), ocp.state_bounds))
    x0[9], x0[3] = 3.1, -0.7  # roll rate above π/2, roll below −π/6
    low, up = ocp.state_box(x0)
    # Only the violated sides move, each to twice the excess beyond its bound.
    assert up[9] == pytest.approx(hi[9] + 2 * (3.1 - hi[9]))
    assert low[3] == pytest.approx(lo[3] - 2 * (lo[3] + 0.7))
    keep = np.ones(ocp.nx, bool)
    keep[[3, 9]] = False
    np.testing.assert_array_equal(low[keep], lo[keep])
    np.testing.assert_array_equal(up[keep], hi[keep])
    assert low[9] == lo[9] and up[3] == hi[3]
    assert np.all(low < x0) and np.all(x0 < up)  # strictly inside: room to move outwards
    # Positions stay hard (the ground, the walls): relaxing them let the room compound.
    sunk = x0.copy()
    sunk[2] = -0.01
    low2, up2 = ocp.state_box(sunk)
    assert low2[2] == lo[2] == 0.0 and up2[9] == up[9]
    sunk[[3, 9]] = 0.0
    assert all(a is b for a, b in zip(ocp.state_box(sunk), ocp.state_bounds))
    # Both solvers' bounds on x_1..x_N come from it.
    layout = QPLayout.of(ocp)
    lb, ub = layout.bounds(ocp, ocp.state_box(x0))
    np.testing.assert_array_equal(lb[layout.ix], np.tile(low, (ocp.horizon, 1)))
    np.testing.assert_array_equal(ub[layout.ix], np.tile(up, (ocp.horizon, 1)))


_X = ca.SX.sym("x", 2)


def _model(**changes):
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    fields = dict(name="cart", dynamics=ca.Function("f", [x, u], [ca.vertcat(x[1], u)]),
                  output=ca.Function("h", [x], [ca.vertcat(x[0], 0)]),
                  state_lower=(-1, -1), state_upper=(1, 1), input_lower=(-1,),
                  input_upper=(1,))
    fields.update(changes)
    return VehicleModel(**fields)


@pytest.mark.parametrize("changes, message", [
    (dict(name="my cart"), "^name must be an identifier"),
    (dict(output=ca.Function("h", [_X], [_X[0]])), "^output must be .* shape \\(2,\\) or \\(3,\\)"),
    (dict(state_lower=(-1, 2)), r"^state_lower\[1\] must be < state_upper\[1\]"),
    (dict(input_upper=(1, 2)), "^input_upper must be 1 finite"),
    (dict(position=(2,)), r"^position must hold state indices in \[0, 2\)"),
])
def test_a_bad_model_is_refused_naming_the_field(changes, message):
    assert _model().nx == 2 and _model().ny == 2
    with pytest.raises(ValueError, match=message):
        _model(**changes)


# --- the import graph -------------------------------------------------------------------------




def _a_with_shifted_yaw(a):
    return ca.vertcat(a[0], a[1], a[2], 0, 0, a[3] + 1.0, 0, 0, 0, 0, 0, 0)


@pytest.mark.parametrize("state", ["selection", "affine"])
def test_the_numeric_equilibrium_is_casadis_to_the_bit(state):
    """equilibrium_of gathers a selection by indexing and sends anything else to CasADi:
    either way the numbers are CasADi's own, bit for bit, on random parameters."""
    model = quadrotor_model()
    if state == "affine":  # ψ_a = a_3 + 1: not a selection, CasADi evaluates it
        a = ca.SX.sym("a", 4)
        e = model.equilibria
        model = dataclasses.replace(model, equilibria=dataclasses.replace(
            e, state=ca.Function("state", [a], [_a_with_shifted_yaw(a)])))
    ocp = OCP(_config(), model=model)
    sym = ca.SX.sym("a", 4)
    exact = ca.Function("exact", [sym], [*ocp.equilibrium(sym)])
    for a in np.random.default_rng(4).normal(scale=10.0, size=(20, 4)):
        ours = ocp.equilibrium_of(a)
        theirs = [np.asarray(v, float).ravel() for v in exact(a)]
        for mine, casadi_value in zip(ours, theirs, strict=True):
            assert mine.shape == casadi_value.shape
            assert np.array_equal(mine, casadi_value)

"""The structure-exploiting solver (Gauss-Newton SQP + HPIPM) against the IPOPT reference."""

import dataclasses

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
from paper_repro.analysis.metrics import COLLISION_CLEARANCE
from paper_repro.problem.scan import check_visible
from paper_repro.sim.loop import simulate
from paper_repro.sim.plant import QuadrotorPlant
from paper_repro.solvers.factory import make_controller
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.solvers.linearisation import RUNGS_ENV
from paper_repro.solvers.rti import CAPACITIES, RealTimeNMPC
from paper_repro.vehicles.quadrotor import equilibrium, rk4_discretisation

SMALL = NMPCParams(region_slots=1, points_per_region=48)


def _config(metric="smooth", solver="rti"):
    return Config(distance=DistanceParams(metric=metric),
                  simulation=SimulationParams(scenario="encounter"),
                  nmpc=SMALL, solver=SolverParams(nlp_solver=solver))


@pytest.fixture(scope="module")
def scene():
    return make_scene("encounter")


@pytest.fixture(scope="module")
def reference():
    return TrackingNMPC(_config(solver="reference"))


def test_make_controller_follows_the_config():
    assert isinstance(make_controller(_config(solver="rti")), RealTimeNMPC)
    assert isinstance(make_controller(_config(solver="reference")), TrackingNMPC)
    with pytest.raises(ValueError, match="solver"):
        SolverParams(nlp_solver="acados")


@pytest.mark.parametrize("metric", ["smooth", "euclidean"])
def test_converged_sqp_reaches_the_ipopt_optimum(reference, scene, metric):
    """Iterated to convergence, the Gauss-Newton SQP solves the same OCP: same optimum."""
    fast = RealTimeNMPC(_config(metric), max_iter=40, step_tol=1e-10)
    ipopt = reference if metric == "smooth" else TrackingNMPC(_config(metric, "reference"))
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.2  # moving towards the region
    visible = Lidar(scene.clouds).scan(x0[:3])
    assert sum(len(v) for v in visible) > 0
    ref = ipopt.solve(x0, scene.targets[0], visible)
    sol = fast.solve(x0, scene.targets[0], visible)
    assert ref.success and sol.success and sol.status == "converged"
    np.testing.assert_allclose(sol.x_a, ref.x_a, atol=1e-5)
    np.testing.assert_allclose(sol.x, ref.x, atol=1e-4)
    np.testing.assert_allclose(sol.u, ref.u, atol=1e-3)
    # Feasibility of the fast solution itself: dynamics, x_N = x_a, bounds.
    f = rk4_discretisation(0.01)
    for j in range(fast.horizon):
        np.testing.assert_allclose(np.asarray(f(sol.x[j], sol.u[j])).ravel(), sol.x[j + 1],
                                   atol=1e-8)
    np.testing.assert_allclose(sol.x[-1], sol.x_a, atol=1e-8)
    p = fast.config.quadrotor
    assert np.all(sol.u >= np.array(p.input_lower) - 1e-8)
    assert np.all(sol.u <= np.array(p.input_upper) + 1e-8)
    assert np.all(np.abs(sol.x[1:, 9:]) <= np.pi / 2 + 1e-8)


@pytest.mark.slow
def test_fast_path_tracks_the_reference_in_closed_loop(reference, scene):
    """A short closed loop along the corner: the real-time iteration stays on the reference
    trajectory (a tolerance on states, never on time)."""
    near = dataclasses.replace(scene, start=(-18.6, 0.0, 2.0))  # 1.6 m from the corner
    ref = simulate(_config(solver="reference"), controller=reference, max_steps=250,
                   progress=False, scene=near)
    fast = simulate(_config(), controller=make_controller(_config()), max_steps=250,
                    progress=False, scene=near)
    assert fast.failures == 0 and ref.failures == 0
    assert fast.visible_points.max() > 0
    deviation = np.linalg.norm(fast.x[:, :3] - ref.x[:, :3], axis=1)
    assert deviation.max() < 0.01
    assert abs(fast.clearance.min() - ref.clearance.min()) < 0.01


def _qp_config(qp_solver):
    return dataclasses.replace(_config(), solver=SolverParams(qp_solver=qp_solver))


def test_riccati_and_hpipm_give_the_same_closed_loop(scene):
    """The two QP solvers return the same QP solutions, so the closed loops coincide; the
    warm-started Riccati solver handles (nearly) every QP itself, without HPIPM."""
    near = dataclasses.replace(scene, start=(-18.6, 0.0, 2.0))
    runs = {name: simulate(_qp_config(name), max_steps=300, progress=False, scene=near)
            for name in ("riccati", "hpipm")}
    assert runs["riccati"].visible_points.max() > 0
    np.testing.assert_allclose(runs["riccati"].x, runs["hpipm"].x, atol=1e-6)
    counts = runs["riccati"].meta["qp_counts"]
    assert counts["failed"] == 0 and counts["riccati"] >= 0.95 * 300
    hpipm = runs["hpipm"].meta["qp_counts"]  # the converged cold start takes a few more QPs
    assert hpipm["riccati"] == hpipm["relaxed"] == hpipm["failed"] == 0
    assert hpipm["hpipm"] >= 300


def test_the_interior_point_flies_the_same_closed_loop(scene):
    """``riccati-ipm`` with an active-set budget of one factorisation hands every QP whose
    active set changes to the interior point, whose polished solutions are the same QP
    solutions: the closed loop is the Riccati solver's, and HPIPM is never called."""
    near = dataclasses.replace(scene, start=(-18.6, 0.0, 2.0))
    ctl = make_controller(_qp_config("riccati-ipm"))
    ctl.qp.budget = 1
    ipm = simulate(_qp_config("riccati-ipm"), controller=ctl, max_steps=300, progress=False,
                   scene=near)
    ref = simulate(_qp_config("riccati"), max_steps=300, progress=False, scene=near)
    counts = ipm.meta["qp_counts"]
    assert counts["ipm"] >= 1 and counts["hpipm"] == 0 and counts["failed"] == 0
    np.testing.assert_allclose(ipm.x, ref.x, atol=1e-6)


def test_on_a_crossing_the_interior_point_takes_what_the_active_set_gives_up():
    """A box crossing the path (oracle prediction, full steps): the active set changes by
    dozens of bounds from one QP to the next. The ``riccati`` chain leaves such QPs to HPIPM;
    ``riccati-ipm`` (the default) solves every one on its own kernels, and flies as clear."""
    cfg = Config(simulation=SimulationParams(scenario="crossing"),
                 nmpc=dataclasses.replace(SMALL, prediction="oracle"))
    runs, counts = {}, {}
    for qp_solver in ("riccati", "riccati-ipm"):
        ctl = RealTimeNMPC(cfg, qp_solver=qp_solver)
        runs[qp_solver] = simulate(cfg, controller=ctl, max_steps=750, progress=False)
        counts[qp_solver] = ctl.qp_counts
    assert counts["riccati"]["hpipm"] > 0  # the case exists
    assert counts["riccati-ipm"]["ipm"] > 0 and counts["riccati-ipm"]["hpipm"] == 0
    assert runs["riccati-ipm"].failures == 0
    assert runs["riccati-ipm"].clearance.min() > COLLISION_CLEARANCE


def test_hpipm_is_handed_the_dense_qp_entry_for_entry():
    """The nonzeros handed to HPIPM are a fixed permutation of the linearisation's blocks: the
    sparse H and A must equal :meth:`QPLayout.dense` of the same blocks, bit for bit."""
    chain = make_controller(_qp_config("riccati")).qp
    lay, rng = chain.layout, np.random.default_rng(3)
    h = rng.normal(size=int(np.sum(np.square(lay.sizes))))
    j = rng.normal(size=lay.n_ab + lay.nc * lay.nz[-1])
    H, A = chain.matrices(h, j)
    dense_h, dense_a = lay.dense(h, j)
    assert np.array_equal(np.array(H), dense_h) and np.array_equal(np.array(A), dense_a)
    assert H.nnz() == np.count_nonzero(dense_h)


def test_when_the_riccati_solver_gives_up_hpipm_takes_over(scene):
    """With a single EQP allowed, the cold first QP (rate bounds binding, none guessed) is
    left to HPIPM, whose active set then seeds the Riccati solver: same trajectory."""
    ctl = make_controller(_qp_config("riccati"))
    ctl.qp.riccati.max_outer = 1
    fast = simulate(_qp_config("riccati"), controller=ctl, max_steps=60, progress=False)
    ref = simulate(_qp_config("hpipm"), max_steps=60, progress=False)
    counts = fast.meta["qp_counts"]
    assert counts["hpipm"] >= 1 and counts["riccati"] >= 1 and counts["failed"] == 0
    np.testing.assert_allclose(fast.x, ref.x, atol=1e-6)


def test_without_compiled_code_the_same_step_comes_out(scene):
    """compile=False (no C compiler): CasADi's virtual machine and HPIPM, same SQP step."""
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.3
    visible = Lidar(scene.clouds).scan(x0[:3])
    plain = RealTimeNMPC(_config(), compile=False)
    assert plain.qp_solver == "hpipm"
    a = plain.solve(x0, scene.targets[0], visible)
    b = make_controller(_config()).solve(x0, scene.targets[0], visible)
    assert a.success and b.success
    np.testing.assert_allclose(a.u, b.u, atol=1e-6)
    np.testing.assert_allclose(a.x, b.x, atol=1e-8)


@pytest.mark.parametrize("metric", ["smooth", "euclidean"])
def test_a_smaller_lidar_capacity_gives_the_same_step(scene, metric):
    """A scan of a few points goes to the smallest capacity that holds it: padding contributes
    exactly 0, so the step equals the one of the full capacity."""
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.3
    visible = Lidar(scene.clouds).scan(x0[:3])
    counts = [len(v) for v in visible]
    assert 0 < max(counts) <= 16
    ladder = RealTimeNMPC(_config(metric))
    full = RealTimeNMPC(_config(metric), capacities=())
    rungs = [c for c in CAPACITIES if c < SMALL.points_per_region] + [SMALL.points_per_region]
    assert ladder.ladder.capacities == rungs
    fitting = min(c for c in rungs if c >= max(counts))
    assert ladder.ladder.for_scan(visible).scan.capacity == fitting
    a = ladder.solve(x0, scene.targets[0], visible)
    b = full.solve(x0, scene.targets[0], visible)
    np.testing.assert_allclose(a.u, b.u, rtol=0, atol=1e-10)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    # Nothing in range: the capacity-1 linearisation, still the same step.
    empty = [np.empty((0, 3))]
    scan = ladder.ladder.for_scan(empty).scan
    assert scan.capacity == 1
    # An empty scan is packed once: the same parameters wherever the UAV is.
    np.testing.assert_array_equal(ladder.ladder.pack(empty, x0[:3] + 7.0, scan),
                                  scan.pack(empty, x0[:3]))
    a = ladder.solve(x0, scene.targets[0], empty)
    b = full.solve(x0, scene.targets[0], empty)
    np.testing.assert_allclose(a.u, b.u, rtol=0, atol=1e-10)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="capacities"):
        RealTimeNMPC(_config(), capacities=(0,))
    # Built in the background, every rung is loaded after ready(), which then waits for nothing.
    assert ladder.ready() >= 0.0
    assert ladder.ready() == 0.0


@pytest.mark.parametrize("metric", ["smooth", "euclidean"])
def test_rungs_made_when_needed_give_the_steps_of_rungs_made_at_once(scene, metric,
                                                                     monkeypatch):
    """PAPER_REPRO_RUNGS=needed: the smallest rung at the start, each other one when a scan
    first needs it, every one after ``ready()``; the same steps, bit for bit, as with every
    rung made at once. Another value is refused, by name."""
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.3
    scans = [[np.empty((0, 3))], Lidar(scene.clouds).scan(x0[:3])]
    monkeypatch.setenv(RUNGS_ENV, "all")
    at_once = RealTimeNMPC(_config(metric))
    monkeypatch.setenv(RUNGS_ENV, "needed")
    needed = RealTimeNMPC(_config(metric))
    assert [r.scan.capacity for r in needed.ladder.rungs] == [1]
    assert [r.scan.capacity for r in at_once.ladder.rungs] == at_once.ladder.capacities
    for visible in scans:
        a = at_once.solve(x0, scene.targets[0], visible)
        b = needed.solve(x0, scene.targets[0], visible)
        assert a.u.tobytes() == b.u.tobytes() and a.x.tobytes() == b.x.tobytes()
    fitting = needed.ladder.for_scan(scans[1]).scan.capacity
    assert [r.scan.capacity for r in needed.ladder.rungs] == [1, fitting]
    assert needed.ready() >= 0.0
    assert [r.scan.capacity for r in needed.ladder.rungs] == needed.ladder.capacities
    monkeypatch.setenv(RUNGS_ENV, "some")
    with pytest.raises(ValueError, match="PAPER_REPRO_RUNGS must be 'all' or 'needed'"):
        RealTimeNMPC(_config(metric))


def test_the_warm_start_is_the_reanchored_plan_bit_for_bit(scene):
    """The SQP starts from the previous plan moved to the measured state, the numbers of
    NMPCSolution.reanchored to the bit (built without the intermediate solution)."""
    ctl = RealTimeNMPC(_config())
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    x0[6] = 0.3
    plan = ctl.solve(x0, scene.targets[0], Lidar(scene.clouds).scan(x0[:3]))
    x1 = x0 + np.linspace(0.001, 0.012, 12)
    X, U, a = ctl._guess(x1, plan)
    moved = plan.reanchored(x1, ctl.ocp.model.position)
    expected = moved.x.copy()
    expected[0] = x1
    assert X.tobytes() == expected.tobytes() and U.tobytes() == moved.u.tobytes()
    assert a.tobytes() == ctl.ocp.parameters_of(moved.x_a, moved.u_a).tobytes()


def test_a_repeated_scan_is_packed_once_and_the_same_bit_for_bit(scene):
    """The ladder keeps the last packing of each capacity with the regions' bytes: a scan
    that sees the same points again (most steps) gets it back, equal bit for bit to a fresh
    packing wherever the UAV is; new points, or a region trimmed to its nearest points
    (which depends on where the UAV is), are packed afresh."""
    ladder = RealTimeNMPC(_config()).ladder
    x0, _ = equilibrium([-18.3, 0.2, 2.0])
    visible = check_visible(Lidar(scene.clouds).scan(x0[:3]))
    assert 0 < max(len(v) for v in visible) <= 48
    scan = ladder.for_scan(visible).scan
    first = ladder.pack(visible, x0[:3], scan)
    again = ladder.pack(check_visible([v.copy() for v in visible]), x0[:3] + 0.5, scan)
    assert again is first
    assert again.tobytes() == scan.pack(visible, x0[:3] + 0.5).tobytes()
    moved = check_visible([v + 0.01 for v in visible])
    assert ladder.pack(moved, x0[:3], scan).tobytes() == scan.pack(moved, x0[:3]).tobytes()
    # Two points in a slot of one: the nearest is kept, so the packing depends on where.
    one = ladder.rungs[0].scan
    two = check_visible([np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])])
    for z in (0.5, -0.5, 0.5):
        y = np.array([0.0, 0.0, z])
        assert ladder.pack(two, y, one).tobytes() == one.pack(two, y).tobytes()


def test_euclidean_metric_flies_past_the_corner_on_the_fast_path(scene):
    """The Euclidean baseline on the fast path, 1.6 m from the corner: every solve succeeds,
    every input stays in 𝒰, and the UAV keeps clear of the cloud it sees."""
    near = dataclasses.replace(scene, start=(-18.6, 0.0, 2.0))
    cfg = _config("euclidean")
    result = simulate(cfg, max_steps=300, progress=False, scene=near)
    assert result.failures == 0 and result.visible_points.max() > 0
    p = cfg.quadrotor
    assert np.all(result.u >= np.array(p.input_lower) - 1e-8)
    assert np.all(result.u <= np.array(p.input_upper) + 1e-8)
    assert result.clearance.min() > COLLISION_CLEARANCE
    assert result.x[-1, 0] > near.start[0] + 0.05  # it moved on, towards the target


def test_qp_failure_is_reported_not_raised(scene):
    """An impossible step (initial state far outside the bounds) makes the QP fail; the solver
    reports it and the closed loop would fall back on the shifted plan."""
    fast = RealTimeNMPC(_config())
    x0, _ = equilibrium([-18.0, 0.0, 2.0])
    # Pitch rate 40 rad/s: even in the relaxed box (OCP.state_box) the rotors' 110 rad/s²
    # cannot bring it to rest (x_N = x_a) within the horizon's 0.35 s.
    x0[10] = 40.0
    sol = fast.solve(x0, scene.targets[0], ())
    assert not sol.success
    assert sol.status == "qp_failed"


def test_a_state_outside_x_is_flown_back_into_it_where_hard_bounds_had_no_plan(scene):
    """The moving-obstacle study's diverged run: a roll rate of 3.1 rad/s (bound π/2) after a
    near-collision. Braking it into 𝒳 within one step of 0.01 s needs 153 rad/s² where the
    rotors give 110, so with 𝒳 as hard bounds the QP has no solution (checked first). With
    the relaxed box every solve succeeds and the closed loop is back in 𝒳 within 0.1 s."""
    fast = RealTimeNMPC(_config())
    ocp = fast.ocp
    x0, _ = equilibrium([-18.0, 0.0, 2.0])
    x0[9] = 3.1
    target = scene.targets[0]
    hard = RealTimeNMPC(_config(), relaxed_qp=False)
    hard.ocp.state_box = lambda x: hard.ocp.state_bounds  # no relaxation
    assert hard.solve(x0, target, ()).status == "qp_failed"

    plant = QuadrotorPlant(ocp.config.quadrotor, ts=ocp.config.nmpc.ts)
    lo, hi = ocp.state_bounds
    x, plan, inside = x0, None, []
    for _ in range(100):
        plan = fast.solve(x, target, (), previous=plan)
        assert plan.success, plan.status
        x = plant.step(x, plan.u[0])
        inside.append(bool(np.all((lo <= x) & (x <= hi))))
    first = inside.index(True)
    assert first < 10 and all(inside[first:])
    assert fast.qp_counts["failed"] == 0


def test_both_solvers_find_the_same_plan_in_the_relaxed_box(reference, scene):
    """From a state outside 𝒳 both solvers read the same relaxed box (OCP.state_box): the
    converged SQP and IPOPT reach the same optimum, and the plan keeps to that box."""
    fast = RealTimeNMPC(_config(), max_iter=40, step_tol=1e-10)
    x0, _ = equilibrium([-18.0, 0.0, 2.0])
    x0[9] = 3.1
    ref = reference.solve(x0, scene.targets[0], ())
    sol = fast.solve(x0, scene.targets[0], ())
    assert ref.success and sol.success and sol.status == "converged"
    np.testing.assert_allclose(sol.x, ref.x, atol=1e-4)
    np.testing.assert_allclose(sol.u, ref.u, atol=1e-3)
    low, up = fast.ocp.state_box(x0)
    assert up[9] > np.pi / 2  # relaxed
    for plan in (sol, ref):
        assert np.all(plan.x[1:] >= low - 1e-7) and np.all(plan.x[1:] <= up + 1e-7)


def test_bad_options_are_rejected():
    with pytest.raises(ValueError, match="max_iter"):
        RealTimeNMPC(_config(), max_iter=0)
    with pytest.raises(ValueError, match="qp_solver"):
        RealTimeNMPC(_config(), qp_solver="osqp")
    with pytest.raises(ValueError, match="line_search"):
        RealTimeNMPC(_config(), line_search="yes")
    with pytest.raises(ValueError, match="qp_solver"):
        SolverParams(qp_solver="osqp")
    with pytest.raises(ValueError, match="x0"):
        RealTimeNMPC(_config()).solve(np.zeros(3), np.zeros(3))


# --- the line search ---------------------------------------------------------------------------


def test_line_search_changes_nothing_where_full_steps_descend(scene):
    """Past the corner of the static encounter every full step decreases the merit function:
    no step is shortened and the flight is the full-step flight bit for bit."""
    near = dataclasses.replace(scene, start=(-18.6, 0.0, 2.0))
    cfg = _config()
    runs = {}
    for line_search in (True, False):  # every instant one step, the first one too
        ctl = RealTimeNMPC(cfg, line_search=line_search, cold_start="rti")
        runs[line_search] = simulate(cfg, controller=ctl, max_steps=300, progress=False,
                                     scene=near)
        assert ctl.step_counts["full"] == 300 and ctl.step_counts["shortened"] == 0
    assert runs[True].visible_points.max() > 0
    np.testing.assert_array_equal(runs[True].x, runs[False].x)


def test_line_search_stops_the_period_two_oscillation_on_a_crossing():
    """A box crossing the path at 1 m/s (oracle prediction): with full steps the thrusts jump
    between their bounds at every sample once the region is near; the line search (with its
    damping) shortens a few steps and the jumps all but vanish, with more clearance."""
    cfg = Config(simulation=SimulationParams(scenario="crossing"),
                 nmpc=dataclasses.replace(SMALL, prediction="oracle"))
    jumps, clearance = {}, {}
    for line_search in (True, False):  # every instant one step, the first one too
        ctl = RealTimeNMPC(cfg, line_search=line_search, cold_start="rti")
        result = simulate(cfg, controller=ctl, max_steps=750, progress=False)
        assert result.failures == 0
        jumps[line_search] = int((np.abs(np.diff(result.u, axis=0)).max(axis=1) > 5.0).sum())
        clearance[line_search] = result.clearance.min()
        assert (ctl.step_counts["shortened"] > 0) == line_search
    assert jumps[False] > 50  # the oscillation is there to be stopped
    assert jumps[True] < 0.2 * jumps[False]
    assert clearance[True] > clearance[False] > COLLISION_CLEARANCE


def test_merit_line_search_shortens_overshooting_steps_and_damps_the_next_qps():
    """On a merit that rises along the full step the step is halved until Armijo holds, δ
    starts at ``damping_start`` and grows; full steps relax δ back to 0. A descending full
    step is taken as it is, with one evaluation."""
    from paper_repro.solvers.line_search import MeritLineSearch
    from paper_repro.solvers.linearisation import QPLayout

    layout = QPLayout(horizon=2, nx=1, nu=1, na=1, ns=0, nc=1)
    search = MeritLineSearch(layout, damping_start=10.0, grow=4.0, relax=2.0)
    h = np.zeros(sum(s * s for s in layout.sizes))
    h[layout.hessian_diagonal] = 1.0
    q = -np.ones(layout.nw)
    dw = np.ones(layout.nw)  # slope qᵀΔw = −n_w < 0; no residuals, so ν = 0
    gap, eq = np.zeros(layout.n_gap_rows), np.zeros(layout.nc)
    trials = []

    def bowl(centre):  # J(w + αΔw) of a 1-D bowl along the step, minimum at α = centre
        def values(step, alpha):
            trials.append(alpha)
            return np.array([layout.nw * (alpha - centre) ** 2]), gap, eq
        return values

    cost = layout.nw * 0.25 ** 2
    alpha, _ = search(dw, h, q, gap, eq, cost, bowl(0.25))
    # J(1) > J(0) and J(½) = J(0): both fail Armijo's sufficient decrease; J(¼) = 0 passes.
    assert alpha == 0.25 and trials == [1.0, 0.5, 0.25]
    assert search.damping == 10.0 and search.counts == {"full": 0, "shortened": 1}
    search(dw, h, q, gap, eq, cost, bowl(0.25))
    assert search.damping == 40.0
    damped = h.copy()
    search.damp(damped)
    np.testing.assert_array_equal(damped - h, np.where(np.isin(np.arange(h.size),
                                                                layout.hessian_diagonal), 40, 0))
    trials.clear()
    for _ in range(9):  # a step to the minimum: full, one evaluation each, δ relaxes
        assert search(dw, h, q, gap, eq, layout.nw * 1.0, bowl(1.0))[0] == 1.0
    assert trials == [1.0] * 9 and search.damping == 0.0  # 40/2⁹ < 10/100: off
    with pytest.raises(ValueError, match="max_trials"):
        MeritLineSearch(layout, max_trials=-1)
    with pytest.raises(ValueError, match="damping_start"):
        MeritLineSearch(layout, damping_start=0.0)

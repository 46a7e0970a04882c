"""The Riccati active-set QP solver against dense solutions of the same QPs."""

import casadi as ca
import numpy as np
import pytest

from paper_repro.solvers import riccati_qp
from paper_repro.solvers.riccati_qp import StageQP


def _random_qp(rng, nx, nu, nc, box=True):
    """A random stage-structured QP with a strictly feasible point z* inside the bounds."""
    n = len(nu)
    sizes = [nx[j] + nu[j] for j in range(n)] + [nx[n]]
    h = []
    for s in sizes:
        m = rng.normal(size=(s, s))
        h.append(m.T @ m + 0.1 * np.eye(s))
    ab = [rng.normal(scale=0.6, size=(nx[j + 1], sizes[j])) for j in range(n)]
    b = [rng.normal(scale=0.1, size=nx[j + 1]) for j in range(n)]
    z_star = [rng.uniform(-0.5, 0.5, size=sizes[0])]
    for j in range(n):
        x1 = ab[j] @ z_star[j] + b[j]
        z_star.append(np.r_[x1, rng.uniform(-0.5, 0.5, size=sizes[j + 1] - nx[j + 1])])
    z_star = np.concatenate(z_star)
    c = rng.normal(size=(nc, nx[n]))
    d = c @ z_star[-nx[n]:]
    q = rng.normal(scale=20.0, size=len(z_star))  # pulls the optimum onto many bounds
    lb, ub = np.full(len(z_star), -np.inf), np.full(len(z_star), np.inf)
    if box:
        lb = z_star - rng.uniform(0.2, 1.0, size=len(z_star))
        ub = z_star + rng.uniform(0.2, 1.0, size=len(z_star))
    data = {"h": np.concatenate([m.ravel(order="F") for m in h]), "q": q,
            "ab": np.concatenate([m.ravel(order="F") for m in ab]), "b": np.concatenate(b),
            "c": c.ravel(order="F"), "d": d, "lb": lb, "ub": ub}
    return data, _dense(h, ab, b, c, d, sizes, nx)


def _dense(h, ab, b, c, d, sizes, nx):
    """The same QP as dense matrices: H, equality rows A w = rhs."""
    n = len(ab)
    off = np.r_[0, np.cumsum(sizes)]
    nw = off[-1]
    big_h = np.zeros((nw, nw))
    for j, m in enumerate(h):
        big_h[off[j]:off[j + 1], off[j]:off[j + 1]] = m
    rows, rhs = [], []
    for j in range(n):
        r = np.zeros((nx[j + 1], nw))
        r[:, off[j]:off[j + 1]] = ab[j]
        r[:, off[j + 1]:off[j + 1] + nx[j + 1]] -= np.eye(nx[j + 1])
        rows.append(r)
        rhs.append(-b[j])
    r = np.zeros((len(d), nw))
    r[:, off[n]:] = c
    rows.append(r)
    rhs.append(d)
    return big_h, np.vstack(rows), np.concatenate(rhs)


DIMS = [([3, 4, 4, 4, 4, 4, 4], [2, 2, 2, 2, 2, 2], 2),
        ([4] + [9] * 10, [4] * 10, 6)]  # x_0 of another size, as in the NMPC (a_0 only)


@pytest.mark.parametrize("nx,nu,nc", DIMS)
def test_without_bounds_it_solves_the_kkt_system(nx, nu, nc):
    rng = np.random.default_rng(0)
    data, (big_h, a_eq, rhs) = _random_qp(rng, nx, nu, nc, box=False)
    qp = StageQP(nx, nu, nc)
    res = qp.solve(**data)
    assert res.success and res.n_active == 0 and res.outer == 1
    nw, m = len(data["q"]), len(rhs)
    kkt = np.block([[big_h, a_eq.T], [a_eq, np.zeros((m, m))]])
    exact = np.linalg.solve(kkt, np.r_[-data["q"], rhs])[:nw]
    np.testing.assert_allclose(res.z, exact, atol=1e-8)


def _reference(big_h, a_eq, rhs, data):
    """Solution and bound multipliers from qpOASES (dense)."""
    solver = ca.conic("ref", "qpoases", {"h": ca.DM(big_h).sparsity(),
                                         "a": ca.DM(a_eq).sparsity()},
                      {"printLevel": "none", "error_on_fail": True})
    sol = solver(h=big_h, g=data["q"], a=a_eq, lba=rhs, uba=rhs, lbx=data["lb"],
                 ubx=data["ub"])
    return np.asarray(sol["x"]).ravel(), np.asarray(sol["lam_x"]).ravel()


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("nx,nu,nc", DIMS)
def test_from_a_cold_start_it_matches_a_dense_active_set_solver(nx, nu, nc, seed):
    """No guess at all: the dual active-set steps alone find the optimum, with a dozen or
    so bounds binding (some of them dependent on the terminal equality)."""
    rng = np.random.default_rng(seed)
    data, (big_h, a_eq, rhs) = _random_qp(rng, nx, nu, nc)
    qp = StageQP(nx, nu, nc, max_outer=500)
    res = qp.solve(**data)
    assert res.success, res.status
    z_ref, _ = _reference(big_h, a_eq, rhs, data)
    assert res.n_active >= 5  # the test means something: bounds do bind
    np.testing.assert_allclose(res.z, z_ref, atol=1e-6)
    # And the solution is feasible on its own.
    np.testing.assert_allclose(a_eq @ res.z, rhs, atol=1e-8)
    assert np.all(res.z >= data["lb"] - 1e-8) and np.all(res.z <= data["ub"] + 1e-8)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("nx,nu,nc", DIMS)
def test_a_wrong_guess_is_repaired(nx, nu, nc, seed):
    """The guess misses two binding bounds and holds one that does not bind."""
    rng = np.random.default_rng(seed)
    data, (big_h, a_eq, rhs) = _random_qp(rng, nx, nu, nc)
    z_ref, lam_ref = _reference(big_h, a_eq, rhs, data)
    qp = StageQP(nx, nu, nc, max_outer=500)
    qp.seed(z_ref, data["lb"], data["ub"], lam_ref)
    held = np.flatnonzero(qp.active)
    qp.active[rng.choice(held, size=2, replace=False)] = 0
    qp.active[rng.choice(np.flatnonzero(qp.active == 0))] = -1
    res = qp.solve(**data)
    assert res.success, res.status
    assert res.changes >= 1
    np.testing.assert_allclose(res.z, z_ref, atol=1e-6)


def test_warm_start_reuses_the_active_set():
    nx, nu, nc = DIMS[1]
    data, _ = _random_qp(np.random.default_rng(3), nx, nu, nc)
    qp = StageQP(nx, nu, nc, max_outer=500)
    cold = qp.solve(**data)
    assert cold.success and cold.outer > 1
    # A slightly perturbed QP, as from one sampling instant to the next.
    data["q"] = data["q"] + 1e-3 * np.random.default_rng(4).normal(size=data["q"].shape)
    warm = qp.solve(**data)
    assert warm.success and warm.outer == 1 and warm.changes == 0
    np.testing.assert_allclose(warm.z, cold.z, atol=1e-2)


@pytest.mark.parametrize("method", ["solve", "interior_point"])
def test_a_bound_qp_solves_what_its_arrays_hold_now_bit_for_bit(method):
    """bind() checks the arrays once; every call then solves their current contents, the
    same numbers as solve() or interior_point() given them; bad arrays fail at bind()."""
    nx, nu, nc = DIMS[1]
    rng = np.random.default_rng(5)
    data, _ = _random_qp(rng, nx, nu, nc)
    bound_qp, free_qp = StageQP(nx, nu, nc, max_outer=500), StageQP(nx, nu, nc, max_outer=500)
    bound = bound_qp.bind(**data)
    for _ in range(3):  # the QP of the next instant, written into the same arrays
        a, b = getattr(bound, method)(), getattr(free_qp, method)(**data)
        assert a.success and a.z.tobytes() == b.z.tobytes()
        np.testing.assert_array_equal(bound_qp.active, free_qp.active)
        data["q"] += 1e-2 * rng.normal(size=data["q"].shape)
    with pytest.raises(ValueError, match="h must be a contiguous float64 array"):
        bound_qp.bind(**{**data, "h": data["h"][::2]})


@pytest.mark.parametrize("seed", range(4))
def test_reusing_the_factors_of_unchanged_stages_changes_nothing_but_the_work(seed):
    """After an active-set change at stage k the stages above k keep their factors: the
    same iterates bit for bit, with fewer stage factorisations than a full one per iterate."""
    nx, nu, nc = DIMS[1]
    data, _ = _random_qp(np.random.default_rng(seed), nx, nu, nc)
    runs = {}
    for reuse in (True, False):
        qp = StageQP(nx, nu, nc, max_outer=500, reuse_factors=reuse)
        runs[reuse] = qp.solve(**data)
    reused, full = runs[True], runs[False]
    assert reused.success and full.success and full.outer > 3
    np.testing.assert_array_equal(reused.z, full.z)
    assert (reused.outer, reused.changes) == (full.outer, full.changes)
    stages = len(nu) + 1
    assert full.stages == full.outer * stages
    assert reused.stages < full.stages


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("nx,nu,nc,sizes", [(*d, (d[0][1], d[1][1])) for d in DIMS]
                         + [([4] + [5] * 3 + [6] * 4, [3] * 7, 2, (6, 3))])
def test_kernels_for_fixed_sizes_give_the_generic_kernels_numbers(nx, nu, nc, sizes, seed):
    """The stage kernels compiled for the sizes of most stages do the same operations in the
    same order as the generic ones: the same iterates, bit for bit. The last structure mixes
    stages of both kinds (x_0, stages of another size, the change of size)."""
    data, _ = _random_qp(np.random.default_rng(seed), nx, nu, nc)
    runs = {}
    for specialise in (True, False):
        qp = StageQP(nx, nu, nc, max_outer=500, specialise=specialise)
        runs[specialise] = qp, qp.solve(**data)
    (fixed_qp, fixed), (generic_qp, generic) = runs[True], runs[False]
    assert fixed_qp.specialised_for == sizes and generic_qp.specialised_for is None
    assert fixed.success and generic.success and generic.outer > 1
    np.testing.assert_array_equal(fixed.z, generic.z)
    assert (fixed.outer, fixed.changes, fixed.passes, fixed.stages) == (
        generic.outer, generic.changes, generic.passes, generic.stages)


def test_seeding_with_a_solution_needs_one_factorisation():
    nx, nu, nc = DIMS[0]
    data, (big_h, a_eq, rhs) = _random_qp(np.random.default_rng(5), nx, nu, nc)
    z_ref, lam_ref = _reference(big_h, a_eq, rhs, data)
    qp = StageQP(nx, nu, nc)
    qp.seed(z_ref, data["lb"], data["ub"], lam_ref)
    res = qp.solve(**data)
    assert res.success and res.outer == 1
    np.testing.assert_allclose(res.z, z_ref, atol=1e-6)


def test_an_infeasible_qp_is_reported_and_the_active_set_kept():
    nx, nu, nc = DIMS[0]
    data, _ = _random_qp(np.random.default_rng(6), nx, nu, nc)
    qp = StageQP(nx, nu, nc, max_outer=500)
    assert qp.solve(**data).success
    kept = qp.active.copy()
    # Every input pinned to a narrow band while C x_N = d asks for something far away.
    data["lb"], data["ub"] = data["lb"] * 0.0 - 0.01, data["ub"] * 0.0 + 0.01
    data["d"] = data["d"] + 100.0
    res = qp.solve(**data)
    assert not res.success
    np.testing.assert_array_equal(qp.active, kept)


def test_bad_dimensions_are_rejected():
    with pytest.raises(ValueError, match="nx"):
        StageQP([3, 3], [2, 2], 1)
    with pytest.raises(ValueError, match="nx"):
        StageQP([0, 3, 3], [2, 2], 1)
    with pytest.raises(ValueError, match="rho"):
        StageQP([3, 3, 3], [2, 2], 1, rho=0.0)
    with pytest.raises(ValueError, match="nc must be an integer >= 0"):
        StageQP([3, 3, 3], [2, 2], -1)
    with pytest.raises(ValueError, match="max_outer"):
        StageQP([3, 3, 3], [2, 2], 1, max_outer=0)
    with pytest.raises(ValueError, match="reuse_factors must be True or False"):
        StageQP([3, 3, 3], [2, 2], 1, reuse_factors=1)
    with pytest.raises(ValueError, match="specialise must be True or False"):
        StageQP([3, 3, 3], [2, 2], 1, specialise="yes")
    qp = StageQP([3, 3, 3], [2, 2], 1)
    with pytest.raises(ValueError, match="h must be a contiguous float64 array of 59"):
        qp.solve(*(np.zeros(4),) * 8)
    with pytest.raises(ValueError, match="float64"):
        qp.solve(*(np.zeros(59, dtype=np.float32),) * 8)


# --- the interior point on the same kernels ----------------------------------------------------

def _unpolished(qp, data):
    """The interior point's own iterate (its polish given no factorisation to spend)."""
    budget, riccati_qp.POLISH_BUDGET = riccati_qp.POLISH_BUDGET, 0
    try:
        return qp.interior_point(**data)
    finally:
        riccati_qp.POLISH_BUDGET = budget


@pytest.mark.parametrize("nx,nu,nc", DIMS)
def test_the_interior_point_without_bounds_solves_the_kkt_system(nx, nu, nc):
    """No bound: the starting point is the equality-constrained QP's solution, the terminal
    rows exact through their Schur complement (not the augmented Lagrangian)."""
    data, (big_h, a_eq, rhs) = _random_qp(np.random.default_rng(1), nx, nu, nc, box=False)
    res = StageQP(nx, nu, nc).interior_point(**data)
    assert res.success and res.iterations == 0
    nw, m = len(data["q"]), len(rhs)
    kkt = np.block([[big_h, a_eq.T], [a_eq, np.zeros((m, m))]])
    exact = np.linalg.solve(kkt, np.r_[-data["q"], rhs])[:nw]
    np.testing.assert_allclose(res.z, exact, atol=1e-8)
    np.testing.assert_allclose(a_eq @ res.z, rhs, atol=1e-10)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("nx,nu,nc", DIMS)
def test_the_interior_point_from_nothing_matches_a_dense_active_set_solver(nx, nu, nc, seed):
    """Cold, with a dozen or so bounds binding: the interior point's own iterate is near the
    optimum (within a few 1e-3 at ipm_tol = 1e-6: its accuracy fades as λ/s spans more than
    double precision resolves, and driven to μ ~ 1e-9 it drifts by 1e-2 here; the random data's
    last bits, which the BLAS of the machine sets, move it by up to 2e-3), and the active-set
    method it seeds polishes it to the exact one in a factorisation or two."""
    data, (big_h, a_eq, rhs) = _random_qp(np.random.default_rng(seed), nx, nu, nc)
    z_ref, _ = _reference(big_h, a_eq, rhs, data)
    raw_res = _unpolished(StageQP(nx, nu, nc), data)
    qp = StageQP(nx, nu, nc)
    res = qp.interior_point(**data)
    assert res.success and res.polished, res.status
    assert 1 <= res.iterations <= 30 and res.mu < 1e-6
    assert np.count_nonzero(qp.active) >= 5  # bounds do bind
    np.testing.assert_allclose(res.z, z_ref, atol=1e-6)
    assert raw_res.success and not raw_res.polished
    np.testing.assert_allclose(raw_res.z, z_ref, atol=3e-3)
    np.testing.assert_allclose(a_eq @ raw_res.z, rhs, atol=1e-9)
    # the polished solution seeds the next call: the same QP again is one factorisation
    again = qp.solve(**data)
    assert again.success and again.outer == 1 and again.changes == 0


@pytest.mark.parametrize("scale", [0.1, 10.0, 100.0])
@pytest.mark.parametrize("seed", range(4))
def test_the_interior_points_start_scales_with_the_gradient(seed, scale):
    """The cost scaled by c (H and q: the same minimiser, multipliers c times larger, as the
    moving design's are 20 times the paper barrier's): the same solution, in about as many
    iterations, since the start scales with the cost (its curvature with max|H|, its
    multipliers with max|q|). (From a fixed start the
    moving design's QPs took 23 iterations in the median and up to 50, against 12.)"""
    nx, nu, nc = DIMS[1]
    data, (big_h, a_eq, rhs) = _random_qp(np.random.default_rng(seed), nx, nu, nc)
    scaled = dict(data, h=data["h"] * scale, q=data["q"] * scale)
    z_ref, _ = _reference(big_h, a_eq, rhs, data)
    plain, big = (StageQP(nx, nu, nc).interior_point(**d) for d in (data, scaled))
    assert plain.success and big.success
    np.testing.assert_allclose(big.z, z_ref, atol=1e-6)
    assert abs(big.iterations - plain.iterations) <= 4, (plain.iterations, big.iterations)


@pytest.mark.parametrize("seed", range(3))
def test_the_interior_point_kernels_for_fixed_sizes_give_the_generic_numbers(seed):
    """The Schur complement compiled for a constant number of terminal rows does the same
    operations in the same order as the generic one."""
    nx, nu, nc = DIMS[1]
    data, _ = _random_qp(np.random.default_rng(seed), nx, nu, nc)
    runs = [StageQP(nx, nu, nc, specialise=s).interior_point(**data) for s in (True, False)]
    np.testing.assert_array_equal(runs[0].z, runs[1].z)
    assert runs[0].iterations == runs[1].iterations


def test_an_infeasible_qp_is_not_solved_by_the_interior_point():
    nx, nu, nc = DIMS[0]
    data, _ = _random_qp(np.random.default_rng(6), nx, nu, nc)
    data["lb"], data["ub"] = data["lb"] * 0.0 - 0.01, data["ub"] * 0.0 + 0.01
    data["d"] = data["d"] + 100.0
    res = StageQP(nx, nu, nc).interior_point(**data)
    assert not res.success and not res.polished


@pytest.mark.parametrize("method", ["solve", "interior_point"])
def test_the_c_code_stays_inside_its_workspace(method):
    """The workspace each method asks for is all it writes: a tail of sentinels behind it
    comes back untouched (a wrong size would corrupt the heap, not fail)."""
    nx, nu, nc = DIMS[1]
    data, _ = _random_qp(np.random.default_rng(2), nx, nu, nc)
    qp = StageQP(nx, nu, nc, max_outer=500)
    lib = qp._lib
    size = (lib.stage_qp_workspace if method == "solve" else lib.stage_ipm_workspace)(
        qp.horizon, qp.nx.ctypes.data, qp.nu.ctypes.data, nc)
    padded = np.full(size + 64, 12345.0)
    if method == "solve":
        qp._work = padded
        qp._fixed = (*qp._fixed[:5], padded.ctypes.data, padded.size, *qp._fixed[7:])
    else:
        qp._ipm_work = padded
    assert getattr(qp, method)(**data).success
    assert np.all(padded[size:] == 12345.0) and np.any(padded[:size] != 12345.0)


def test_bad_interior_point_options_are_rejected():
    with pytest.raises(ValueError, match="ipm_tol"):
        StageQP([3, 3, 3], [2, 2], 1, ipm_tol=0.0)
    with pytest.raises(ValueError, match="ipm_max_iter must be an integer >= 1"):
        StageQP([3, 3, 3], [2, 2], 1, ipm_max_iter=0)

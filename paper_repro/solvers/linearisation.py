"""The real-time iteration's linearisation of problem (21) at the previous plan, and the layout
of the stage-wise QP it fills."""

from __future__ import annotations

import bisect
import itertools
import os
from typing import NamedTuple

import casadi as ca
import numpy as np

from paper_repro._native import NativeFunction, compiler
from paper_repro.problem.ocp import OCP
from paper_repro.problem.scan import ScanLayout

# --- the linearisation -------------------------------------------------------------------------

def linearisation(ocp: OCP, scan: ScanLayout | None = None,
                  values_only: bool = False, shared_barrier: bool = False) -> ca.Function:
    """CasADi function giving every block of the Gauss-Newton QP at the current iterate.

    Inputs: x0 (n_x), X (n_x × N: x_1..x_N), U (n_u × N), A (n_a × N+1: a at each stage),
    p (y_t, then the scan in ``scan``'s layout, the OCP's by default, then θ, the weights and
    barrier parameters of :attr:`~paper_repro.problem.ocp.OCP.runtime_values`: the code does
    not depend on their values, so another weight reuses it).
    Outputs, flattened column-major and concatenated over stages:
      h: Hessian blocks (stage 0: (a, u); stages 1..N−1: (x, a, s, u); stage N: (x, a, s)),
      q: gradient, j: [A_j B_j] gap Jacobians then the terminal Jacobian C (the −I blocks of the
      gaps are constants), gap: residuals φ(z_j, u_j) − z_{j+1}, eq: terminal residual,
      cost: the objective of (21) at the iterate (the value whose gradient is q).
    ``values_only``: a function of the same inputs giving only (cost, gap, eq), what the line
    search needs at a trial point (no derivative is built).

    ``shared_barrier``: the barrier β of every slot, and its gradient in y, is one function
    evaluated for all stages at once (a loop in the generated C), and each stage reads its
    value and gradient: β_j + ∂β/∂y·(h(x) − y_j), exact in value and first derivative, all the
    Gauss-Newton model needs. The stage's code then does not grow with the scan's capacity;
    only the barrier's does, once. ``False``: β is written out inside each stage's
    expression (its value and derivatives expanded there).
    """
    theta = ca.SX.sym("theta", len(ocp.runtime_values))
    ocp = ocp.with_symbols(theta)  # weights and barrier parameters read at run time
    scan = (scan or ocp.scan).with_symbols(ocp.scan.eta, ocp.scan.eta_squared, ocp.scan.d_min)
    yt, params, active, beta = _barriers(ocp, scan, theta)
    stages = _stages(ocp, scan, yt, params, active, beta, values_only, shared_barrier)
    return _horizon(ocp, scan, stages, params, beta, values_only, shared_barrier)


def _barriers(ocp: OCP, scan: ScanLayout, theta):
    """The symbols and the barrier of every region slot: (y_t, the parameter column (y_t, the
    scan, then θ), the slots' active flags, ``beta(y, params, when=0,
    at_equilibrium=False)``)."""
    yt = ca.SX.sym("y_t", ocp.ny)
    scan_params, beta_slots, active = scan.barriers()
    params = ca.vertcat(yt, scan_params, theta)
    y = ca.SX.sym("y", ocp.ny)
    # β at τ s after the scan (moving regions); static, τ does not enter (the paper's C).
    tau = ca.SX.sym("tau")
    if scan.moving:
        beta_fn = ca.Function("beta", [y, params, tau], [beta_slots(y, tau)])
        beta_a_fn = (ca.Function("beta_a", [y, params, tau], [beta_slots(y, tau, True)])
                     if scan.equilibrium_lookahead > 0 else beta_fn)
    else:
        beta_fn = ca.Function("beta", [y, params], [beta_slots(y)])

    def beta(yy, pp, when=0.0, at_equilibrium=False):
        if not scan.moving:
            return beta_fn(yy, pp)
        return (beta_a_fn if at_equilibrium else beta_fn)(yy, pp, when)

    return yt, params, active, beta


def _stages(ocp: OCP, scan: ScanLayout, yt, params, active, beta, values_only: bool,
            shared_barrier: bool):
    """The three stage functions (stage 0, stages 1..N−1, stage N): each gives its cost, its
    gradient and Gauss-Newton Hessian blocks (unless ``values_only``), the Jacobian of its
    dynamics and the next stage's z. With ``shared_barrier`` β reaches a stage as inputs: its
    value b (ns,), its gradient db (ns × p) and the output y_ref it was evaluated at."""
    nx, nu, ns, na, ny = ocp.nx, ocp.nu, scan.slots, ocp.na, ocp.ny
    f, h = ocp.f, ocp.h
    tau, tau_a = ca.SX.sym("tau"), ca.SX.sym("tau_a")  # τ_j; τ_{N+1} at y_a

    def stage_beta(yy, name):
        """β at yy inside a stage, and the stage's extra inputs."""
        if not shared_barrier:
            return None, []
        b = ca.SX.sym(f"b_{name}", ns)
        if values_only:
            return b, [b]
        db, ref = ca.SX.sym(f"db_{name}", ns, ny), ca.SX.sym(f"y_{name}", ny)
        return b + ca.mtimes(db, yy - ref), [b, db, ref]

    def terms(residual, penalties, v):
        return _terms(ocp, residual, penalties, v, values_only)

    def dynamics(phi, v):
        return _dynamics(phi, v, values_only)

    # Stage 0: v = (a, u); x0 is known.
    x0 = ca.SX.sym("x0", nx)
    a = ca.SX.sym("a", na)
    u = ca.SX.sym("u", nu)
    v0 = ca.vertcat(a, u)
    x_a, u_a = ocp.equilibrium(a)
    b0 = ca.SX.sym("b_0", ns)  # β(y_0), a constant of the stage: x0 is known
    phi0 = ca.vertcat(f(x0, u), a, b0 if shared_barrier else beta(h(x0), params))
    stage0 = ca.Function("stage0", [x0, a, u, params] + ([b0] if shared_barrier else []),
                         terms(ocp.tracking_residual(x0, u, x_a, u_a), [], v0)
                         + dynamics(phi0, v0))

    # Stages 1..N−1: v = (x, a, s, u), s_j = β(y_{j−1}) carried.
    x = ca.SX.sym("x", nx)
    s = ca.SX.sym("s", ns)
    vj = ca.vertcat(x, a, s, u)
    bj, extra_j = stage_beta(h(x), "j")
    if bj is None:
        bj = beta(h(x), params, tau)  # stage j: τ = j·h
    gj = [(ocp.violation(s[i], bj[i]), active[i]) for i in range(ns)]
    phij = ca.vertcat(f(x, u), a, bj)
    # The stage also hands on β(y_j), the next stage's s_{j+1}: each β is evaluated once, at
    # its own stage (with its gradient), rather than again, alone, at the next one.
    stage = ca.Function("stage", [s, x, a, u, params, tau] + extra_j,
                        [bj, *terms(ocp.tracking_residual(x, u, x_a, u_a), gj, vj),
                         *dynamics(phij, vj)])

    # Stage N: v = (x, a, s); cost T‖y_a − y_t‖², the last barrier terms; x_N = x_a (and
    # x_a = f(x_a, u_a) without a parametrisation).
    vn = ca.vertcat(x, a, s)
    y_a = h(x_a)
    bn, extra_n = stage_beta(h(x), "n")
    ba, extra_a = stage_beta(y_a, "a")
    if bn is None:
        bn, ba = beta(h(x), params, tau), beta(y_a, params, tau_a, at_equilibrium=True)
    gn_terms = []
    for i in range(ns):
        gn_terms += [(ocp.violation(s[i], bn[i]), active[i]),
                     (ocp.violation(bn[i], ba[i]), active[i]),
                     (ocp.equilibrium_violation(ba[i]), active[i])]
    eq_res = ca.vertcat(x - x_a, ocp.equilibrium_rows(a))
    stage_n = ca.Function("stage_n", [x, a, s, params, tau, tau_a] + extra_n + extra_a,
                          terms(ocp.offset_residual(y_a, yt), gn_terms, vn)
                          + ([] if values_only else [ca.vec(ca.jacobian(eq_res, vn))])
                          + [eq_res])
    return stage0, stage, stage_n


def _terms(ocp: OCP, residual, penalties, v, values_only: bool) -> list:
    """A stage's cost ‖r‖² + μ Σ active·F(g) and, unless ``values_only``, its exact gradient
    and Gauss-Newton Hessian (as vec(H), ∇) with respect to v; ``penalties`` are (g, active)
    pairs."""
    cost = ca.sumsqr(residual)
    for g, weight in penalties:
        cost += ocp.mu * weight * ocp.penalty(g)
    if values_only:
        return [cost]
    jr = ca.jacobian(residual, v)
    hess = 2 * ca.mtimes(jr.T, jr)
    grad = 2 * ca.mtimes(jr.T, residual)
    for g, weight in penalties:
        jg = ca.jacobian(g, v)
        d1, d2 = ocp.penalty_derivatives(g)
        hess += ocp.mu * weight * d2 * ca.mtimes(jg.T, jg)
        grad += ocp.mu * weight * d1 * jg.T
    return [cost, ca.vec(hess), grad]


def _dynamics(phi, v, values_only: bool) -> list:
    """Unless ``values_only`` the Jacobian [A_j B_j] of φ, then φ (the next stage's z)."""
    return [phi] if values_only else [ca.vec(ca.jacobian(phi, v)), phi]


def _horizon(ocp: OCP, scan: ScanLayout, stages, params, beta, values_only: bool,
             shared_barrier: bool) -> ca.Function:
    """The stages chained over the horizon (stages 1..N−1 as one ``mapaccum``, a loop in C),
    with the shared barrier's values mapped over the horizon when it is on; the outputs of
    :func:`linearisation`."""
    stage0, stage, stage_n = stages
    n, nx, nu, ns, na, ny = ocp.horizon, ocp.nx, ocp.nu, scan.slots, ocp.na, ocp.ny
    h = ocp.h
    X0 = ca.MX.sym("x0", nx)
    X = ca.MX.sym("X", nx, n)
    U = ca.MX.sym("U", nu, n)
    A = ca.MX.sym("A", na, n + 1)
    P = ca.MX.sym("p", params.shape[0])
    tau = ocp.stage_time  # τ_j = j·h
    times = ca.DM(tau(np.arange(1, n))).T  # stages 1..N−1
    shared_j = shared_n = shared_a = []
    if shared_barrier:
        # β and ∂β/∂y at every stage's output, one function mapped over the horizon.
        yb, tb = ca.SX.sym("y", ny), ca.SX.sym("tau")
        outs_b = [beta(yb, params, tb)]
        outs_a = [beta(yb, params, tb, at_equilibrium=True)]
        if not values_only:
            outs_b.append(ca.jacobian(outs_b[0], yb))
            outs_a.append(ca.jacobian(outs_a[0], yb))
        beta_y = ca.Function("beta_y", [yb, params, tb], outs_b)
        beta_ya = ca.Function("beta_ya", [yb, params, tb], outs_a)
        Y = h.map(n)(X)  # y_1..y_N
        Bs = beta_y.map(n)(Y, ca.repmat(P, 1, n), ca.DM(tau(np.arange(1, n + 1))).T)
        Bs = Bs if isinstance(Bs, (list, tuple)) else [Bs]
        Ya = h(ocp.equilibrium(A[:, n])[0])
        Ba = beta_ya(Ya, P, tau(n + 1))
        Ba = Ba if isinstance(Ba, (list, tuple)) else [Ba]
        b0_val = beta_y(h(X0), P, 0.0)
        b0_val = b0_val[0] if isinstance(b0_val, (list, tuple)) else b0_val
        if values_only:
            shared_j, shared_n, shared_a = [Bs[0][:, :n - 1]], [Bs[0][:, n - 1]], [Ba[0]]
        else:
            shared_j = [Bs[0][:, :n - 1], Bs[1][:, :ny * (n - 1)], Y[:, :n - 1]]
            shared_n = [Bs[0][:, n - 1], Bs[1][:, ny * (n - 1):], Y[:, n - 1]]
            shared_a = [Ba[0], Ba[1], Ya]
        out0 = stage0(X0, A[:, 0], U[:, 0], P, b0_val)
    else:
        out0 = stage0(X0, A[:, 0], U[:, 0], P)
    # Stages 1..N−1 in turn, each s_j the β(y_{j−1}) of the stage before (stage 0's from φ_0).
    mid = stage.mapaccum("mid", n - 1, [0], [0])
    outm = mid(out0[-1][nx + na:], X[:, : n - 1], A[:, 1:n], U[:, 1:], ca.repmat(P, 1, n - 1),
               times, *shared_j)
    outn = stage_n(X[:, n - 1], A[:, n], outm[0][:, n - 2], P, tau(n), tau(n + 1), *shared_n,
                   *shared_a)
    outm = outm[1:]
    cost = out0[0] + ca.sum2(outm[0]) + outn[0]
    # Gap residuals φ(z_j, u_j) − z_{j+1}. The iterate's s_{j+1} is always β(y_j) itself (it
    # is never stored, only recomputed), so the s part of every gap is exactly zero.
    zero_s = ca.MX.zeros(ns, 1)
    phis = ca.horzcat(out0[-1], outm[-1])
    gaps = ca.vertcat(*[ca.vertcat(phis[:nx, j] - X[:, j], phis[nx:nx + na, j] - A[:, j + 1],
                                   zero_s)
                        for j in range(n)])
    name = (f"rti_{'values' if values_only else 'linearisation'}_{ocp.model.name}"
            + ("_shared" if shared_barrier else ""))
    if values_only:
        outs, names = [cost, gaps, outn[-1]], ["cost", "gap", "eq"]
    else:
        H = ca.vertcat(out0[1], ca.vec(outm[1]), outn[1])
        Q = ca.vertcat(out0[2], ca.vec(outm[2]), outn[2])
        J = ca.vertcat(out0[3], ca.vec(outm[3]), outn[3])
        outs = [H, Q, J, gaps, outn[-1], cost]
        names = ["h", "q", "j", "gap", "eq", "cost"]
    return ca.Function(name, [X0, X, U, A, P], [ca.densify(v) for v in outs],
                       ["x0", "X", "U", "A", "p"], names)


class Rung(NamedTuple):
    """One capacity of the ladder: its scan layout, its linearisation and the values-only
    function of the line search (see :func:`linearisation`; ``None`` without a line
    search)."""

    scan: ScanLayout
    linearisation: ca.Function | NativeFunction
    values: ca.Function | NativeFunction | None


RUNGS_ENV = "PAPER_REPRO_RUNGS"
"""Environment variable: which rungs a :class:`LinearisationLadder` compiles. ``all`` (the
default): every rung, in the background, from the start. ``needed``: the smallest at the
start, each other one when a scan first needs it (short runs and the tests compile less)."""


def rungs_at_once() -> bool:
    """Whether every rung is compiled from the start (:data:`RUNGS_ENV`); an unknown value is
    refused, by name."""
    value = os.environ.get(RUNGS_ENV, "all")
    if value not in ("all", "needed"):
        raise ValueError(f"{RUNGS_ENV} must be 'all' or 'needed', got {value!r}")
    return value == "all"


class LinearisationLadder:
    """The linearisation compiled for several LiDAR capacities (points per region slot).

    A scan uses the smallest capacity that holds it. Padding contributes exactly 0, so every
    capacity gives the same QP; the small ones skip the padding's arithmetic. With 16 points
    in view the capacity-16 linearisation takes about a fifth of the time of the capacity-120
    one, and with at most one point per region (nothing in range, say) the capacity-1 one
    about half of the capacity-16 one. The cost grows by about 3 µs per point of capacity
    (2 slots × 35 stages), so the ladder is fine where scans of a paper mission fall (half see
    nothing, a third hold 17-48 points).

    Parameters
    ----------
    ocp : the problem; its ``scan.capacity`` is the largest rung.
    capacities : the smaller rungs.
    compile : build C (cached, :class:`~paper_repro._native.NativeFunction`); without it, or
        without a compiler, one rung evaluated in CasADi's virtual machine. The rungs are
        compiled in the background, one gcc per core; a rung is waited for when a scan first
        needs it (:meth:`wait` waits for all). Which rungs start at once is
        :data:`RUNGS_ENV`'s choice: all of them (the default), or the smallest, then each
        when a scan first needs it.
    values : also build each rung's values-only function (what the line search evaluates);
        without a line search it is never called, and not compiling it halves the first
        build on a new machine.
    shared_barrier : the barrier evaluated once for all stages (see :func:`linearisation`):
        a third of the C to compile at the largest capacity, the same numbers to rounding.

    Attributes
    ----------
    capacities : every rung's capacity, increasing.  native : compiled or not.
    """

    def __init__(self, ocp: OCP, capacities=(), compile: bool = True, values: bool = True,
                 shared_barrier: bool = False):
        top = ocp.scan.capacity
        all_at_once = rungs_at_once()

        def build(scan=None, values_only=False):
            return linearisation(ocp, scan, values_only, shared_barrier)

        fn = build()
        self.sizes = [fn.nnz_out(i) for i in range(fn.n_out())]
        self.native = bool(compile and compiler() is not None)
        if not self.native:
            self.capacities = [top]
            self._rungs = {top: Rung(ocp.scan, fn, build(values_only=True) if values else None)}
        else:
            self.capacities = sorted({c for c in capacities if c < top} | {top})

            def rung(cap: int) -> Rung:
                """The rung of capacity ``cap``, its C compiling in the background."""
                scan = ocp.scan.with_capacity(cap)
                return Rung(scan, NativeFunction(fn if cap == top else build(scan),
                                                 background=True),
                            NativeFunction(build(scan, values_only=True), background=True)
                            if values else None)

            self._rung = rung
            # The smallest first (a flight starts with little in view), then the largest,
            # which takes longest (a few seconds to a minute).
            caps = self.capacities
            self._rungs = {cap: rung(cap) for cap in
                           (caps[:1] + caps[:0:-1] if all_at_once else caps[:1])}
        self._last = {}  # capacity -> (the regions' bytes, their packing): see pack()

    @property
    def rungs(self) -> list[Rung]:
        """The rungs made so far (every one, unless :data:`RUNGS_ENV` is ``needed``), by
        increasing capacity."""
        return [self._rungs[c] for c in self.capacities if c in self._rungs]

    def wait(self) -> float:
        """Make every rung not made yet, then wait until every one is compiled and loaded;
        the seconds waited."""
        for cap in self.capacities:
            if cap not in self._rungs:
                self._rungs[cap] = self._rung(cap)
        return sum(fn.load() for rung in self.rungs for fn in rung[1:]
                   if isinstance(fn, NativeFunction))

    def for_scan(self, visible) -> Rung:
        """The rung of the smallest capacity that holds the scan (made now if it was not)."""
        need = max(map(len, visible), default=0)
        i = bisect.bisect_left(self.capacities, need)
        cap = self.capacities[min(i, len(self.capacities) - 1)]  # too many: the nearest kept
        rung = self._rungs.get(cap)
        if rung is None:
            rung = self._rungs[cap] = self._rung(cap)
        return rung

    def pack(self, visible, position, scan: ScanLayout, velocities=None) -> np.ndarray:
        """:meth:`ScanLayout.pack` of a checked scan
        (:func:`~paper_repro.problem.scan.check_visible`), made once for a scan that repeats.

        Where the packing does not depend on where the vehicle is, it is a function of the
        scan's points alone: nothing in view (the vehicle is out of range: half the steps of
        a paper mission), or no sensing window, no velocities and every region in view
        fitting its slot and the slots. The vehicle then sees exactly the previous step's
        points most of the time (97 % of the paper mission's steps with a region in view),
        so the last such packing of each capacity is kept with the regions' bytes and
        returned, bit for bit the same, while they do not change. The result is shared:
        read it, do not write it."""
        in_view = [v for v in visible if len(v)]
        if in_view and not (velocities is None and (scan.window == 0 or scan.metric != "smooth")
                            and len(in_view) <= scan.slots
                            and max(map(len, in_view)) <= scan.capacity):
            return scan.pack(visible, position, velocities)
        key = tuple(v.tobytes() for v in visible)
        last = self._last.get(scan.capacity)
        if last is None or last[0] != key:
            # Nothing in view packs the same with or without velocities (every slot unused).
            packed = scan.pack(visible, position, velocities if in_view else None)
            last = self._last[scan.capacity] = (key, packed)
        return last[1]

    @staticmethod
    def evaluate(fn, x0, X, U, a, params):
        """``fn`` (a rung's linearisation or values) at this iterate: [h, q, j, gap, eq, cost]
        or [cost, gap, eq] (see :func:`linearisation`); ``X`` (N, n_x), ``U`` (N, n_u), ``a``
        (n_a,) at every stage. Native outputs are the function's own buffers (overwritten by
        its next call)."""
        if isinstance(fn, NativeFunction):
            ins = fn.inputs
            ins[0][:, 0], ins[1][:], ins[2][:], ins[3][:], ins[4][:, 0] = \
                x0, X.T, U.T, a[:, None], params
            fn()
            return fn.outputs
        A = np.tile(a[:, None], (1, X.shape[0] + 1))
        return [np.asarray(v).ravel() for v in fn(x0, X.T, U.T, A, params)]


# --- the QP's layout ---------------------------------------------------------------------------

class QPLayout:
    """Where every variable, block and bound of the stage QP sits. Pure index arithmetic.

    The variable vector w stacks stage by stage: z_0 = a_0, u_0; then z_j = (x_j, a_j, s_j),
    u_j for j = 1..N−1; then z_N = (x_N, a_N, s_N). The constraints are the gap rows
    z_{j+1} = [A_j B_j](z_j, u_j) + b_j of every stage and the ``nc`` terminal rows on z_N.

    Parameters
    ----------
    horizon : N.  nx, nu : n_x, n_u.  na : size of a.  ns : region slots (carried β).
    nc : terminal rows.
    """

    def __init__(self, horizon: int, nx: int, nu: int, na: int, ns: int, nc: int):
        n = horizon
        self.horizon, self.nx, self.nu, self.na, self.ns, self.nc = n, nx, nu, na, ns, nc
        nz = nx + na + ns
        self.nz = [na] + [nz] * n  # state size per stage (x_0 is known: only a_0)
        self.sizes = [na + nu] + [nz + nu] * (n - 1) + [nz]
        self.offsets = offsets = np.concatenate([[0], np.cumsum(self.sizes)])
        self.nw = nw = int(offsets[-1])

        # Hessian: dense diagonal blocks, stored by the linearisation one after the other,
        # each in column-major order; runs of equal sizes as (offsets, size).
        diagonal, k = [], 0
        for size in self.sizes:
            diagonal.append(k + np.arange(size) * (size + 1))
            k += size * size
        self.hessian_diagonal = np.concatenate(diagonal)  # positions of H's diagonal in h
        # runs of stages with blocks of one size: (the entries of w of each stage, count ×
        # size; the size)
        self._uniform_runs = [(offsets[np.array(list(g))][:, None] + np.arange(size), size)
                              for size, g in itertools.groupby(range(n + 1),
                                                               key=lambda j: self.sizes[j])]
        index = -np.ones((nw, nw), dtype=int)
        k = 0
        for j, s in enumerate(self.sizes):
            o = offsets[j]
            index[o:o + s, o:o + s] = np.arange(k, k + s * s).reshape(s, s, order="F")
            k += s * s
        self.hessian_entries = _entries(index)

        # Constraints: gap rows of stage j: [A_j B_j] on stage j, −I on stage j+1; then the
        # terminal rows C z_N = d on stage N. The sources index (j[:n_ab], −1s, j[n_ab:]).
        rows = [nz] * n + [nc]
        row_off = np.concatenate([[0], np.cumsum(rows)])
        index = -np.ones((int(row_off[-1]), nw), dtype=int)
        k = 0
        for j in range(n):
            r, s = row_off[j], self.sizes[j]
            index[r:r + nz, offsets[j]:offsets[j] + s] = \
                np.arange(k, k + nz * s).reshape(nz, s, order="F")
            k += nz * s
        self.n_ab = k  # entries of [A_j B_j] in the linearisation's j
        for j in range(n):
            r, o = row_off[j], offsets[j + 1]
            index[r + np.arange(nz), o + np.arange(nz)] = k + np.arange(nz)
        k += nz * n
        r, o = row_off[n], offsets[n]
        index[r:r + nc, o:o + nz] = np.arange(k, k + nc * nz).reshape(nc, nz, order="F")
        self.constraint_entries = _entries(index)
        self.n_gap_rows = nz * n

        # Positions of x_1..x_N, u_0..u_{N−1} and a_0..a_N in w.
        self.ix = np.array([offsets[j] + np.arange(nx) for j in range(1, n + 1)])
        self.iu = np.array([offsets[j] + self.nz[j] + np.arange(nu) for j in range(n)])
        self.ia = np.array([offsets[0] + np.arange(na)]
                           + [offsets[j] + nx + np.arange(na) for j in range(1, n + 1)])

    @classmethod
    def of(cls, ocp: OCP) -> QPLayout:
        """The layout of an OCP's stage QP."""
        a = ca.SX.sym("a", ocp.na)
        nc = ocp.nx + ocp.equilibrium_rows(a).shape[0]
        return cls(ocp.horizon, ocp.nx, ocp.nu, ocp.na, ocp.scan.slots, nc)

    def bounds(self, ocp: OCP, state_box=None) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) of w: 𝒳 on x_1..x_N (or ``state_box``, the (lower, upper) that
        :meth:`OCP.state_box` gives for a measured state outside 𝒳), 𝒰 on u, the equilibrium
        box on a_0 (the other a_j equal it), nothing on the carried β. Also sets
        :attr:`bounded`, the indices of the bounded entries (x, u and a_0: the steps that
        matter)."""
        lb, ub = np.full(self.nw, -np.inf), np.full(self.nw, np.inf)
        lb[self.ix], ub[self.ix] = ocp.state_bounds if state_box is None else state_box
        lb[self.iu], ub[self.iu] = ocp.input_bounds
        lb[self.ia[0]], ub[self.ia[0]] = ocp.equilibrium_box
        self.bounded = np.flatnonzero(np.isfinite(lb))
        return lb, ub

    def curvature(self, h, dw) -> float:
        """Δwᵀ H Δw from the linearisation's Hessian blocks ``h``."""
        total, k = 0.0, 0
        for (entries, size) in self._uniform_runs:  # runs of equal block sizes, one einsum each
            count = len(entries)
            blocks = h[k:k + count * size * size].reshape(count, size, size)
            parts = dw[entries]
            total += float(np.einsum("bi,bij,bj->", parts, blocks, parts))
            k += count * size * size
        return total

    def scatter(self, X, U, a, out: np.ndarray | None = None) -> np.ndarray:
        """w of the iterate: X (N, n_x) = x_1..x_N, U (N, n_u), a (n_a,) at every stage; the
        carried β are 0 (they are recomputed, never stored). ``out``: an (n_w,) array to
        write into, whose carried β entries are 0 (a buffer only this writes)."""
        w = np.zeros(self.nw) if out is None else out
        w[self.ix] = X
        w[self.iu] = U
        w[self.ia] = a
        return w

    def gather(self, dw):
        """(ΔX (N, n_x), ΔU (N, n_u), Δa (n_a,)) of a step of w."""
        return dw[self.ix], dw[self.iu], dw[self.ia[0]]

    def dense(self, h, j):
        """The dense Hessian H (n_w, n_w) and constraint matrix (rows, n_w) of the QP, from the
        linearisation's ``h`` and ``j``; the constraints are then
        A w = −(gap, eq)."""
        (hr, hc, hs), (ar, ac, asrc) = self.hessian_entries, self.constraint_entries
        H = np.zeros((self.nw, self.nw))
        H[hr, hc] = np.asarray(h)[hs]
        src = self._constraint_source(j)
        A = np.zeros((self.n_gap_rows + self.nc, self.nw))
        A[ar, ac] = src[asrc]
        return H, A

    def _constraint_source(self, j):
        j = np.asarray(j)
        return np.concatenate([j[:self.n_ab], -np.ones(self.n_gap_rows), j[self.n_ab:]])


def _entries(index: np.ndarray):
    """(rows, cols, sources) of the entries ≥ 0 of ``index``, in column-major order."""
    cols, rows = np.nonzero(index.T >= 0)
    return rows, cols, index[rows, cols]

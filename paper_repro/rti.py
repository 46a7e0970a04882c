"""Real-time NMPC: Gauss-Newton SQP on the OCP's stage structure, with a Riccati QP solver.

Same optimal control problem as :mod:`paper_repro.nmpc` (the IPOPT reference), rewritten so that
every term lives in one stage and a structure-exploiting QP solver applies:

* **Artificial equilibrium as constant states.** The quadrotor's equilibria are exactly
  (position, yaw) with hover thrust, so (x_a, u_a) = E(a), a = (p_a, ψ_a) ∈ R⁴, with no
  equilibrium constraint. ``a`` is carried along the horizon with a_{j+1} = a_j; x_N = x_a
  becomes the linear stage-N constraint x_N − E(a_N) = 0.
* **Barrier coupling as a carried state.** g_j = c·β(y_j) − β(y_{j+1}) couples two stages.
  Carrying s_{j+1} = β(y_j) (one state per region slot) makes g_j = c·s_{j+1} − β(y_{j+1}) a
  function of stage j+1 alone. The last terms, g_N = c·β(y_N) − β(y_a) and F(y_a), live at
  stage N with y_a = p_a.
* **Gauss-Newton Hessian.** The tracking terms are linear least squares; every penalty is
  F(g) with F = (1/κ)[ln(1 + e^{κg})]^ε convex and increasing (ε ≥ 1), so
  F''(g)·∇g∇gᵀ is a positive semidefinite curvature model (the exact penalty Hessian is
  indefinite and made the real-time iteration chatter in a prototype).

Each iteration linearises all stages with one call of a CasADi function generated as C, built
once with the system compiler and cached (:class:`~paper_repro._native.NativeFunction`), and
solves the QP with :class:`~paper_repro.stage_qp.StageQP`: a Riccati recursion that starts from
the previous instant's active set, so that one factorisation usually suffices. HPIPM (shipped
with CasADi) is the fallback and the alternative (``qp_solver="hpipm"``). The default runs up
to ``max_iter`` full SQP steps per sampling instant and stops early when the step is small.
"""

from __future__ import annotations

import dataclasses
import time

import casadi as ca
import numpy as np

from ._native import NativeFunction, compiler
from .config import Config
from .model import N_INPUTS, N_STATES, rk4_discretisation
from .nmpc import NMPCSolution, _as_vector, check_visible, pack_scan, region_barrier
from .stage_qp import StageQP

N_EQ = 4  # artificial equilibrium: position (3) and yaw


class RealTimeNMPC:
    """The paper's tracking NMPC solved by Gauss-Newton SQP on its stage structure.

    Parameters
    ----------
    config : run configuration (same fields as :class:`~paper_repro.nmpc.TrackingNMPC`).
    max_iter : SQP iterations per sampling instant (1 is the classic real-time iteration).
    step_tol : stop iterating when max |Δw| falls below this.
    qp_solver : ``"riccati"`` (default): :class:`~paper_repro.stage_qp.StageQP`, a Riccati
        recursion warm-started with the previous active set, with HPIPM as the fallback when
        it does not find the active set; ``"hpipm"``: HPIPM's interior-point method for
        every QP. Both return the same QP solution (to their tolerances).
    compile : build the linearisation as C code (cached). ``False`` uses CasADi's virtual
        machine (slower, no compiler needed) and HPIPM.
    capacities : smaller LiDAR capacities (points per region slot) compiled besides the
        config's ``points_per_region``; each scan uses the smallest that holds it. Same QP,
        less work: with 16 points in view the capacity-16 linearisation takes about a fifth of
        the time of the capacity-120 one, and with at most one point per region (nothing in
        range, say) the capacity-1 one about half of the capacity-16 one. The cost grows by
        about 3 µs per point of capacity (2 slots × 35 stages), so the ladder is fine where
        scans of a paper mission fall (half see nothing, a third hold 17-48 points)
        (``()``: the config's capacity only).

    Attributes
    ----------
    qp_counts : QPs solved so far by each path: ``riccati``, ``hpipm`` (as the chosen solver
        or as the fallback) and ``failed``.
    """

    def __init__(self, config: Config | None = None, max_iter: int = 1, step_tol: float = 1e-6,
                 qp_solver: str = "riccati", compile: bool = True,
                 capacities: tuple[int, ...] = (1, 8, 16, 24, 32, 48)):
        self.config = cfg = config or Config()
        if not (isinstance(max_iter, int) and max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
        if not step_tol > 0:
            raise ValueError(f"step_tol must be > 0, got {step_tol!r}")
        if not all(isinstance(c, int) and c >= 1 for c in capacities):
            raise ValueError(f"capacities must be integers >= 1, got {capacities!r}")
        if qp_solver not in ("riccati", "hpipm"):
            raise ValueError(f"qp_solver must be 'riccati' or 'hpipm', got {qp_solver!r}")
        self.max_iter, self.step_tol = max_iter, step_tol
        p = cfg.nmpc
        self.horizon, self.region_slots = p.horizon, p.region_slots
        self.points_per_region = p.points_per_region
        self.metric = cfg.distance.metric
        self._hover = np.full(N_INPUTS, cfg.quadrotor.hover_thrust)
        self._layout()
        fn = _linearisation(cfg)
        self._lin_sizes = [fn.nnz_out(i) for i in range(fn.n_out())]
        native = compile and compiler() is not None
        self.qp_solver = qp_solver if native else "hpipm"
        # The linearisation writes straight into fixed buffers (NativeFunction); without a
        # compiler it runs in CasADi's virtual machine. Compiled, it comes in several LiDAR
        # capacities: a scan uses the smallest that holds it. Padding contributes exactly 0,
        # so every capacity gives the same QP; the small ones skip the padding's arithmetic.
        self._lins = [(p.points_per_region, cfg, fn)]
        if native:
            self._lins = []
            for cap in sorted({c for c in capacities if c < p.points_per_region}
                              | {p.points_per_region}):
                c_cfg = dataclasses.replace(
                    cfg, nmpc=dataclasses.replace(p, points_per_region=cap))
                c_fn = fn if cap == p.points_per_region else _linearisation(c_cfg)
                self._lins.append((cap, c_cfg, NativeFunction(c_fn)))
        self._riccati = (StageQP(self._nz, [N_INPUTS] * self.horizon, N_STATES)
                         if self.qp_solver == "riccati" else None)
        self._hpipm = ca.conic("rti_qp", "hpipm", {"h": self._h_sp, "a": self._a_sp},
                               {"N": self.horizon, "nx": self._nz,
                                "nu": [N_INPUTS] * self.horizon + [0],
                                "ng": [0] * self.horizon + [N_STATES],
                                # 'robust' converges where 'speed' stalls on this problem;
                                # bounds of ±1e4 on the free variables keep HPIPM's
                                # tolerances relative.
                                "hpipm": {"iter_max": 100, "mode": "robust"}, "inf": 1e4,
                                "error_on_fail": False, "print_problem": False})
        self._qp_matrices = self._matrix_function()
        self.qp_counts = {"riccati": 0, "hpipm": 0, "failed": 0}
        self._empty_scans = {}  # capacity -> packed parameters of a scan that sees nothing

    def _matrix_function(self) -> ca.Function:
        """Blocks of the linearisation -> HPIPM's sparse H and A (a fixed permutation)."""
        h_src = ca.MX.sym("h", self._lin_sizes[0])
        j_src = ca.MX.sym("j", self._lin_sizes[2])
        a_src = ca.vertcat(j_src[:self._n_ab], ca.DM(self._minus_ones), j_src[self._n_ab:])
        h = ca.MX(self._h_sp, h_src[self._h_perm.tolist()])
        amat = ca.MX(self._a_sp, a_src[self._a_perm.tolist()])
        return ca.Function("rti_qp_matrices", [h_src, j_src], [h, amat])

    # --- public ------------------------------------------------------------------------------

    def solve(self, x0, target, visible=(), previous: NMPCSolution | None = None
              ) -> NMPCSolution:
        """Same contract as :meth:`paper_repro.nmpc.TrackingNMPC.solve`, except the warm start:
        the previous plan moved to the current position (:meth:`NMPCSolution.reanchored`).
        With one iteration per instant that keeps the closed loop within about a millimetre
        of the converged solution, where the time-shifted plan drifts by centimetres.

        ``status`` is ``"iterated"`` (``max_iter`` SQP steps taken, the real-time iteration's
        normal outcome), ``"converged"`` (step below ``step_tol``) or ``"qp_failed"``."""
        start = time.perf_counter()  # solve_time includes packing the scan: the whole call
        x0 = _as_vector("x0", x0, N_STATES)
        target = _as_vector("target", target, 3)
        visible = check_visible(visible)
        lin, lin_cfg = self._linearisation_for(visible)
        params = np.concatenate([target, self._pack_scan(visible, x0, lin_cfg)])
        guess = previous.reanchored(x0) if previous is not None else self.hover_guess(x0)
        X = np.array(guess.x, dtype=float)  # (N+1, 12)
        X[0] = x0
        U = np.array(guess.u, dtype=float)
        a = np.array([*guess.x_a[:3], guess.x_a[5]], dtype=float)

        success, status, it = False, "iterated", 0
        for it in range(1, self.max_iter + 1):  # noqa: B007 - `it` is reported below
            step, ok = self._sqp_step(lin, x0, X, U, a, params)
            if not ok:
                success, status = False, "qp_failed"
                break
            X[1:] += step["x"]
            U += step["u"]
            a += step["a"]
            if step["size"] < self.step_tol:
                success, status = True, "converged"
                break
        else:
            success, status = True, "iterated"  # real-time iteration: the last iterate is used
        elapsed = time.perf_counter() - start
        finite = np.isfinite(X).all() and np.isfinite(U).all() and np.isfinite(a).all()
        x_a = self._x_eq(a)
        return NMPCSolution(U, X, x_a, self._hover.copy(), bool(success and finite), status, it,
                            elapsed, np.nan)

    def reset(self) -> None:
        """Forget everything carried from one solve to the next (the Riccati solver's active
        set and multipliers), so that a new flight starts from a clean slate and is
        bit-identical whether this controller is new or reused. ``qp_counts`` keeps counting."""
        if self._riccati is not None:
            self._riccati.reset()

    def hover_guess(self, x0) -> NMPCSolution:
        x0 = np.asarray(x0, float)
        x_a = self._x_eq(np.array([x0[0], x0[1], x0[2], x0[5]]))
        n = self.horizon
        return NMPCSolution(np.tile(self._hover, (n, 1)), np.tile(x_a, (n + 1, 1)), x_a,
                            self._hover.copy(), True, "guess", 0, 0.0, np.nan)

    def obstacle_parameters(self, visible, position) -> np.ndarray:
        return pack_scan(visible, position, self.config)

    # --- internals -----------------------------------------------------------------------------

    def _x_eq(self, a):
        x = np.zeros(N_STATES)
        x[:3], x[5] = a[:3], a[3]
        return x

    def _pack_scan(self, visible, x0, cfg):
        """:func:`~paper_repro.nmpc.pack_scan`, except that the packing of an empty scan, the
        same wherever the UAV is, is made once per capacity (empty scans are common: nothing
        in LiDAR range)."""
        if any(len(v) for v in visible):
            return pack_scan(visible, x0[:3], cfg)
        cap = cfg.nmpc.points_per_region
        if cap not in self._empty_scans:
            self._empty_scans[cap] = pack_scan((), x0[:3], cfg)
        return self._empty_scans[cap]

    def _linearisation_for(self, visible):
        """The compiled linearisation of the smallest capacity that holds the scan."""
        need = max((len(v) for v in visible), default=0)
        for cap, cfg, fn in self._lins:
            if need <= cap:
                return fn, cfg
        return self._lins[-1][2], self._lins[-1][1]  # pack_scan keeps the nearest points

    def _linearise(self, lin, x0, X, U, a, params):
        """Every stage's QP blocks at this iterate: h, q, j ([A_j B_j] then C), gap, eq."""
        A = np.tile(a[:, None], (1, self.horizon + 1))
        if isinstance(lin, NativeFunction):
            ins = lin.inputs
            ins[0][:, 0], ins[1][:], ins[2][:], ins[3][:], ins[4][:, 0] = \
                x0, X[1:].T, U.T, A, params
            lin()
            return lin.outputs
        return [np.asarray(v).ravel() for v in lin(x0, X[1:].T, U.T, A, params)]

    def _sqp_step(self, lin, x0, X, U, a, params):
        """One Gauss-Newton SQP step: linearise every stage, solve the QP."""
        w = np.zeros(self._nw)  # the iterate; s entries are 0 and unbounded
        w[self._iw_x] = X[1:]
        w[self._iw_u] = U
        w[self._iw_a] = a
        h, q, j, gap, eq = self._linearise(lin, x0, X, U, a, params)
        lb, ub = self._lbw - w, self._ubw - w
        dw = None
        if self._riccati is not None:
            res = self._riccati.solve(h, q, j[:self._n_ab], gap, j[self._n_ab:], -eq, lb, ub)
            if res.success:
                dw = res.z
                self.qp_counts["riccati"] += 1
        if dw is None:
            dw = self._solve_hpipm(h, q, j, gap, eq, lb, ub)
        ok = dw is not None and bool(np.isfinite(dw).all())
        if not ok:
            self.qp_counts["failed"] += 1
            return {}, False
        size = float(np.abs(dw[self._bounded]).max())
        return {"x": dw[self._iw_x], "u": dw[self._iw_u], "a": dw[self._iw_a[0]],
                "size": size}, True

    def _solve_hpipm(self, h, q, j, gap, eq, lb, ub):
        """The QP by HPIPM; its active set then seeds the Riccati solver's next call."""
        hmat, amat = self._qp_matrices(h, j)
        rhs = -np.concatenate([gap, eq])
        sol = self._hpipm(h=hmat, g=q, a=amat, lba=rhs, uba=rhs, lbx=lb, ubx=ub)
        if not self._hpipm.stats().get("success", False):
            return None
        self.qp_counts["hpipm"] += 1
        dw = np.asarray(sol["x"]).ravel()
        if self._riccati is not None:
            self._riccati.seed(dw, lb, ub, np.asarray(sol["lam_x"]).ravel())
        return dw

    def _layout(self):
        """Sparsity of the QP and the maps from the compiled function's blocks to it."""
        n, ns = self.horizon, self.region_slots
        self._ns = ns
        nz_mid = N_STATES + N_EQ + ns
        self._nz = [N_EQ] + [nz_mid] * n
        sizes = [N_EQ + N_INPUTS] + [nz_mid + N_INPUTS] * (n - 1) + [nz_mid]
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        nw = int(offsets[-1])

        # Hessian: dense diagonal blocks, stored by the compiled function one after the other,
        # each in column-major order.
        index = -np.ones((nw, nw), dtype=int)
        k = 0
        for j, s in enumerate(sizes):
            o = offsets[j]
            index[o:o + s, o:o + s] = np.arange(k, k + s * s).reshape(s, s, order="F")
            k += s * s
        self._h_sp, self._h_perm = _sparsity_and_perm(index)

        # Constraints: gap rows of stage j: [A_j B_j] on stage j, −I on stage j+1; then the
        # terminal rows x_N − E(a_N) = 0: [I, −∂E/∂a, 0] on stage N.
        rows = [nz_mid] * n + [N_STATES]
        row_off = np.concatenate([[0], np.cumsum(rows)])
        index = -np.ones((int(row_off[-1]), nw), dtype=int)
        k = 0
        for j in range(n):
            r, s = row_off[j], sizes[j]
            index[r:r + nz_mid, offsets[j]:offsets[j] + s] = \
                np.arange(k, k + nz_mid * s).reshape(nz_mid, s, order="F")
            k += nz_mid * s
        n_ab = k
        for j in range(n):
            r, o = row_off[j], offsets[j + 1]
            index[r + np.arange(nz_mid), o + np.arange(nz_mid)] = n_ab + np.arange(nz_mid)
        n_ab += nz_mid * n
        r, o = row_off[n], offsets[n]
        index[r:r + N_STATES, o:o + nz_mid] = \
            np.arange(n_ab, n_ab + N_STATES * nz_mid).reshape(N_STATES, nz_mid, order="F")
        self._a_sp, self._a_perm = _sparsity_and_perm(index)
        self._n_ab = n_ab - nz_mid * n  # entries of [A_j B_j] in the compiled output
        self._minus_ones = -np.ones(nz_mid * n)

        # Positions of x_1..x_N, u_0..u_{N−1} and a_0..a_N in the variable vector.
        self._nw = nw
        self._iw_x = np.array([offsets[j] + np.arange(N_STATES) for j in range(1, n + 1)])
        self._iw_u = np.array([offsets[j] + self._nz[j] + np.arange(N_INPUTS)
                               for j in range(n)])
        self._iw_a = np.array([offsets[0] + np.arange(N_EQ)]
                              + [offsets[j] + N_STATES + np.arange(N_EQ)
                                 for j in range(1, n + 1)])

        # Bounds of the full variable vector.
        p = self.config.nmpc
        xl, xu = np.asarray(p.state_lower), np.asarray(p.state_upper)
        ul, uu = np.asarray(p.input_lower), np.asarray(p.input_upper)
        xal, xau, _, _ = p.relaxed_bounds()
        al, au = np.r_[xal[:3], xal[5]], np.r_[xau[:3], xau[5]]
        free = np.full(N_EQ + ns, np.inf)
        lb = [al, ul]
        ub = [au, uu]
        for _ in range(1, n):
            lb += [xl, -free, ul]
            ub += [xu, free, uu]
        lb += [xl, -free]
        ub += [xu, free]
        self._lbw, self._ubw = np.concatenate(lb), np.concatenate(ub)
        # x, u and a_0: the steps that matter (indices: faster to gather than a mask)
        self._bounded = np.flatnonzero(np.isfinite(self._lbw))


def _sparsity_and_perm(index: np.ndarray):
    """Column-major sparsity of the entries ≥ 0 of ``index`` and their source positions."""
    cols, rows = np.nonzero(index.T >= 0)  # column-major order
    sp = ca.Sparsity.triplet(index.shape[0], index.shape[1], rows.tolist(), cols.tolist())
    return sp, index[rows, cols]


def _linearisation(cfg: Config) -> ca.Function:
    """CasADi function giving every block of the Gauss-Newton QP at the current iterate.

    Inputs: x0 (12), X (12 × N: x_1..x_N), U (4 × N), A (4 × N+1: a at each stage), params.
    Outputs, flattened column-major and concatenated over stages:
      H blocks (stage 0: (a, u); stages 1..N−1: (x, a, s, u); stage N: (x, a, s)), gradient q,
      [A_j B_j] gap Jacobians followed by nothing else (the −I blocks are constants),
      gap residuals φ(z_j, u_j) − z_{j+1}, terminal residual x_N − E(a_N).
    """
    p, b, d = cfg.nmpc, cfg.barrier, cfg.distance
    n, ns = p.horizon, p.region_slots
    f = rk4_discretisation(p.prediction_step, cfg.quadrotor)
    hover = cfg.quadrotor.hover_thrust
    sq_q, sq_r, sq_t = (np.sqrt(np.asarray(v, float)) for v in (p.q, p.r, p.t))
    c = b.decay

    # Barrier of every region slot, as a function of y and the packed parameters.
    yt = ca.SX.sym("y_t", 3)
    slots = [region_barrier(d.metric, d.eta, b.d_min, p.points_per_region) for _ in range(ns)]
    obstacle = ca.vertcat(*[s[0] for s in slots])
    params = ca.vertcat(yt, obstacle)
    y = ca.SX.sym("y", 3)
    beta = ca.Function("beta", [y, params],
                       [ca.vertcat(*[s[1](y) for s in slots])])
    active = ca.vertcat(*[s[0][-1] for s in slots])

    def eq_state(a):
        return ca.vertcat(a[:3], 0, 0, a[3], ca.SX.zeros(6))

    def gn(residual, barrier_args, v):
        """Gauss-Newton Hessian and exact gradient of ‖r‖² + μ Σ active·F(g)."""
        jr = ca.jacobian(residual, v)
        h = 2 * ca.mtimes(jr.T, jr)
        q = 2 * ca.mtimes(jr.T, residual)
        for g, weight in barrier_args:
            jg = ca.jacobian(g, v)
            d1, d2 = _penalty_derivatives(g, b.kappa, b.epsilon)
            h += b.mu * weight * d2 * ca.mtimes(jg.T, jg)
            q += b.mu * weight * d1 * jg.T
        return h, q

    # Stage 0: v = (a, u); x0 is known.
    x0 = ca.SX.sym("x0", N_STATES)
    a = ca.SX.sym("a", N_EQ)
    u = ca.SX.sym("u", N_INPUTS)
    v0 = ca.vertcat(a, u)
    r0 = ca.vertcat(sq_q * (x0 - eq_state(a)), sq_r * (u - hover))
    h0, q0 = gn(r0, [], v0)
    phi0 = ca.vertcat(f(x0, u), a, beta(x0[:3], params))
    stage0 = ca.Function("stage0", [x0, a, u, params],
                         [ca.vec(h0), q0, ca.vec(ca.jacobian(phi0, v0)), phi0])

    # Stages 1..N−1: v = (x, a, s, u), s_j = β(y_{j−1}) carried.
    x = ca.SX.sym("x", N_STATES)
    s = ca.SX.sym("s", ns)
    vj = ca.vertcat(x, a, s, u)
    rj = ca.vertcat(sq_q * (x - eq_state(a)), sq_r * (u - hover))
    bj = beta(x[:3], params)
    gj = [(c * s[i] - bj[i], active[i]) for i in range(ns)]
    hj, qj = gn(rj, gj, vj)
    phij = ca.vertcat(f(x, u), a, bj)
    x_prev = ca.SX.sym("x_prev", N_STATES)
    inner = ca.Function("inner", [x, a, s, u, params],
                        [ca.vec(hj), qj, ca.vec(ca.jacobian(phij, vj)), phij])
    h_, q_, ab_, phi_ = inner(x, a, beta(x_prev[:3], params), u, params)
    stage = ca.Function("stage", [x_prev, x, a, u, params], [h_, q_, ab_, phi_])

    # Stage N: v = (x, a, s); cost T‖p_a − y_t‖², the last barrier terms; x_N = E(a).
    vn = ca.vertcat(x, a, s)
    bn, ba = beta(x[:3], params), beta(a[:3], params)
    gn_terms = []
    for i in range(ns):
        gn_terms += [(c * s[i] - bn[i], active[i]), (c * bn[i] - ba[i], active[i]),
                     ((c - 1.0) * ba[i], active[i])]
    hn, qn = gn(sq_t * (a[:3] - yt), gn_terms, vn)
    eq_res = x - eq_state(a)
    inner_n = ca.Function("inner_n", [x, a, s, params],
                          [ca.vec(hn), qn, ca.vec(ca.jacobian(eq_res, vn)), eq_res])
    hN, qN, jN, eN = inner_n(x, a, beta(x_prev[:3], params), params)
    stage_n = ca.Function("stage_n", [x_prev, x, a, params], [hN, qN, jN, eN])

    # Whole horizon.
    X0 = ca.MX.sym("x0", N_STATES)
    X = ca.MX.sym("X", N_STATES, n)
    U = ca.MX.sym("U", N_INPUTS, n)
    A = ca.MX.sym("A", N_EQ, n + 1)
    P = ca.MX.sym("p", params.shape[0])
    h0m, q0m, j0m, phi0m = stage0(X0, A[:, 0], U[:, 0], P)
    mid = stage.map(n - 1, "serial")
    xprev = ca.horzcat(X0, X[:, : n - 2])
    hm, qm, jm, phim = mid(xprev, X[:, : n - 1], A[:, 1:n], U[:, 1:], P)
    hN_, qN_, jN_, eN_ = stage_n(X[:, n - 2], X[:, n - 1], A[:, n], P)
    # Gap residuals φ(z_j, u_j) − z_{j+1}. The iterate's s_{j+1} is always β(y_j) itself (it
    # is never stored, only recomputed), so the s part of every gap is exactly zero.
    zero_s = ca.MX.zeros(ns, 1)
    phis = ca.horzcat(phi0m, phim)
    gaps = ca.vertcat(*[ca.vertcat(phis[:N_STATES, j] - X[:, j],
                                   phis[N_STATES:N_STATES + N_EQ, j] - A[:, j + 1], zero_s)
                        for j in range(n)])
    H = ca.vertcat(h0m, ca.vec(hm), hN_)
    Q = ca.vertcat(q0m, ca.vec(qm), qN_)
    J = ca.vertcat(j0m, ca.vec(jm), jN_)

    outs = [ca.densify(v) for v in (H, Q, J, gaps, eN_)]
    return ca.Function("rti_linearisation", [X0, X, U, A, P], outs,
                       ["x0", "X", "U", "A", "p"], ["h", "q", "j", "gap", "eq"])


def _penalty_derivatives(g, kappa: float, epsilon: float):
    """F'(g) and F''(g) of F = (1/κ)·sp(κg)^ε, sp the softplus, in overflow-free form."""
    z = kappa * g
    # sp is clamped away from 0 so that sp^(ε−2) stays finite where it underflows; there
    # σ = 0 as well, so the products are exactly 0.
    sp = ca.fmax(ca.fmax(z, 0) + ca.log1p(ca.exp(-ca.fabs(z))), 1e-300)
    sig = 1.0 / (1.0 + ca.exp(-z))
    d1 = epsilon * sp ** (epsilon - 1) * sig
    d2 = kappa * epsilon * ((epsilon - 1) * sp ** (epsilon - 2) * sig**2
                            + sp ** (epsilon - 1) * sig * (1 - sig))
    return d1, d2

"""Real-time NMPC: Gauss-Newton SQP on the stage structure of problem (21).

The same :class:`~paper_repro.problem.ocp.OCP` as the IPOPT reference
(:mod:`paper_repro.solvers.ipopt`),
rewritten so that every term lives in one stage and a structure-exploiting QP solver applies:

* **Artificial equilibrium as constant states.** a is carried along the horizon with
  a_{j+1} = a_j. With an equilibrium parametrisation (the quadrotor: a = (p_a, ψ_a), hover
  thrust) (x_a, u_a) = (state(a), input(a)) and x_N = x_a is the linear stage-N row
  x_N − state(a_N) = 0. Without one, a = (x_a, u_a) and the stage-N rows are x_N − x_a = 0 and
  x_a − f(x_a, u_a) = 0 (:class:`~paper_repro.solvers.riccati_qp.StageQP` takes any terminal rows).
* **Barrier coupling as a carried state.** g_j = c·β(y_j) − β(y_{j+1}) couples two stages.
  Carrying s_{j+1} = β(y_j) (one state per region slot) makes g_j = c·s_{j+1} − β(y_{j+1}) a
  function of stage j+1 alone. The last terms, g_N = c·β(y_N) − β(y_a) and F(y_a), live at
  stage N.
* **Gauss-Newton Hessian.** The tracking terms are linear least squares; every penalty is
  F(g) with F convex and increasing (ε ≥ 1), so F''(g)·∇g∇gᵀ is a positive semidefinite
  curvature model (the exact penalty Hessian is indefinite and made the real-time iteration
  chatter in a prototype).

Four parts, one job each:

* :func:`linearisation`: the CasADi function that evaluates every stage's QP blocks at the
  iterate, built from the ``OCP``'s terms (derivatives by CasADi's AD, the penalty's from
  :meth:`~paper_repro.problem.ocp.OCP.penalty_derivatives`).
* :class:`LinearisationLadder`: that function compiled as C for several LiDAR capacities; a
  scan uses the smallest that holds it.
* :class:`QPLayout`: where every variable, block and bound sits in the stage QP (pure index
  arithmetic; :meth:`QPLayout.dense` assembles the dense QP, for tests and for HPIPM).
* :class:`QPChain`: the QP backends, the Riccati solver
  (:class:`~paper_repro.solvers.riccati_qp.StageQP`, warm-started with the previous active
  set) first and HPIPM as its fallback, with counters; optionally, as the last resort, the
  same QP with soft state bounds (:class:`~paper_repro.solvers.relaxed_qp.RelaxedQP`).

:class:`RealTimeNMPC` is the thin SQP loop that joins them: up to ``max_iter`` steps per
sampling instant, stopping early when the step is small, each step shortened by
:class:`~paper_repro.solvers.line_search.MeritLineSearch` when it does not decrease the merit
function enough.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import casadi as ca
import numpy as np

from paper_repro._native import NativeFunction, compiler
from paper_repro.config import COLD_STARTS, QP_SOLVERS, Config
from paper_repro.problem.ocp import OCP, NMPCSolution
from paper_repro.problem.scan import check_visible
from paper_repro.solvers.line_search import MeritLineSearch
from paper_repro.solvers.linearisation import LinearisationLadder, QPLayout
from paper_repro.solvers.relaxed_qp import RelaxedQP
from paper_repro.solvers.riccati_qp import BoundStageQP, StageQP
from paper_repro.solvers.riccati_qp import build_in_background as build_qp_library
from paper_repro.validation import as_vector
from paper_repro.vehicles.base import VehicleModel

COLD_START_ITERATIONS = 100
"""The most damped SQP steps a ``"converged"`` cold start takes, unless ``max_iter`` allows
more."""

CAPACITIES = (1, 8, 16, 24, 32, 48, 64)
"""The LiDAR capacities (points per region slot) compiled besides the config's
``points_per_region`` (see :class:`LinearisationLadder`). Random passages see up to 64 points
of a region at a time; without the 64 rung the 4 % of their steps that see 49-64 went to the
capacity-120 linearisation, at twice the cost."""


class RealTimeNMPC:
    """Problem (21) solved by Gauss-Newton SQP on its stage structure.

    Parameters
    ----------
    config : run configuration (as for :class:`~paper_repro.solvers.ipopt.TrackingNMPC`).
    model : the vehicle, the quadrotor by default (see :class:`~paper_repro.problem.ocp.OCP`).
    max_iter : SQP iterations per sampling instant (1 is the classic real-time iteration).
    step_tol : stop iterating when max |Δw| over x, u and a_0 falls below this.
    qp_solver : ``"riccati-ipm"`` (default): :class:`~paper_repro.solvers.riccati_qp.StageQP`,
        a Riccati recursion warm-started with the previous active set, within a budget of
        :data:`IPM_ACTIVE_SET_BUDGET` factorisations, then the interior-point method on the
        same Riccati kernels (:meth:`StageQP.interior_point`), HPIPM last; ``"riccati"``: the
        active-set method without a budget, HPIPM as its fallback when it does not find the
        active set; ``"hpipm"``: HPIPM's interior-point method for every QP. All return the
        same QP solution (to their tolerances).
    compile : build the linearisation as C code (cached). ``False`` uses CasADi's virtual
        machine (slower, no compiler needed) and HPIPM.
    capacities : smaller LiDAR capacities (points per region slot) compiled besides the
        config's ``points_per_region`` (see :class:`LinearisationLadder`; ``()``: the
        config's capacity only).
    line_search : ``None`` (default): ``config.solver.line_search``. ``True``: the damped RTI,
        which shortens a step that does not decrease the ℓ1 merit function enough and damps
        the next QPs after it (:class:`MeritLineSearch`); smoother than the paper's
        controller with the Euclidean metric. ``False``: every full step (the textbook
        real-time iteration, whose inputs fall into a period-2 oscillation between their
        bounds when a region moves at the vehicle).
    cold_start : ``None`` (default): ``config.solver.cold_start``. ``"rti"``: a solve without
        a previous plan (the first of a flight, or the first after :meth:`reset`) takes
        ``max_iter`` steps from rest, like every other instant. ``"converged"``: that solve
        iterates the damped SQP (:class:`MeritLineSearch`) until the step is below
        ``step_tol``, at most :data:`COLD_START_ITERATIONS` steps (or ``max_iter``, if more),
        so that a single ``solve`` from rest returns a
        solution of (21), not one Gauss-Newton step towards one. From rest the full step can
        lead to another local solution than the reference's: over an obstacle rather than
        round it.
    shared_barrier : ``None`` (default): ``config.solver.shared_barrier``. ``True``: the
        barrier of every slot is evaluated once for all stages and read by each
        (:func:`~paper_repro.solvers.linearisation.linearisation`): a third to a quarter of
        the C to compile, slightly faster, the same QP to rounding. ``False``: written out
        inside each stage.
    relaxed_qp : ``None`` (default): ``config.solver.relaxed_qp``. ``True``: a QP that no
        backend solves (an infeasible linearisation) is solved again with soft state bounds
        and terminal rows (:class:`~paper_repro.solvers.relaxed_qp.RelaxedQP`, an exact ℓ1
        penalty); its step is taken and the solve's status is ``"relaxed"``. ``False``: the
        solve fails (``"qp_failed"``).

    Attributes
    ----------
    ocp : the problem.  layout : its :class:`QPLayout`.
    qp_counts : QPs solved so far by each path: ``riccati``, ``ipm`` (``"riccati-ipm"``
        only), ``hpipm`` (as the chosen solver or as the fallback), ``relaxed``
        (``relaxed_qp`` only) and ``failed``.
    step_counts : SQP steps taken so far: ``full`` (α = 1) and ``shortened`` (α < 1).
    last_failure : why the last ``qp_failed`` solve failed (:attr:`QPChain.last_failure`,
        and ``outside_state_box``: x0 was outside 𝒳, so the relaxed box was imposed).
    last_relaxation : why the hard QP failed at the first relaxed QP of the last
        ``"relaxed"`` solve (:attr:`QPChain.last_relaxation`, and ``outside_state_box``).
    """

    def __init__(self, config: Config | None = None, model: VehicleModel | None = None,
                 max_iter: int = 1, step_tol: float = 1e-6, qp_solver: str = "riccati-ipm",
                 compile: bool = True, capacities: tuple[int, ...] = CAPACITIES,
                 line_search: bool | None = None, cold_start: str | None = None,
                 relaxed_qp: bool | None = None, shared_barrier: bool | None = None):
        if not (isinstance(max_iter, int) and max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
        if not step_tol > 0:
            raise ValueError(f"step_tol must be > 0, got {step_tol!r}")
        if not all(isinstance(c, int) and c >= 1 for c in capacities):
            raise ValueError(f"capacities must be integers >= 1, got {capacities!r}")
        if not (line_search is None or isinstance(line_search, bool)):
            raise ValueError(f"line_search must be True, False or None (the config's), got "
                             f"{line_search!r}")
        if qp_solver not in QP_SOLVERS:
            raise ValueError(f"qp_solver must be one of {QP_SOLVERS}, got {qp_solver!r}")
        self.ocp = ocp = OCP(config, model)
        self.config, self.horizon = ocp.config, ocp.horizon
        solver = self.config.solver
        line_search = solver.line_search if line_search is None else line_search
        cold_start = solver.cold_start if cold_start is None else cold_start
        relaxed_qp = solver.relaxed_qp if relaxed_qp is None else relaxed_qp
        shared_barrier = solver.shared_barrier if shared_barrier is None else shared_barrier
        if cold_start not in COLD_STARTS:
            raise ValueError(f"cold_start must be one of {COLD_STARTS}, got {cold_start!r}")
        if not isinstance(relaxed_qp, bool):
            raise ValueError(f"relaxed_qp must be True or False, got {relaxed_qp!r}")
        self.max_iter, self.step_tol = max_iter, step_tol
        self.layout = lay = QPLayout.of(ocp)
        self._theta = ocp.runtime_values  # the run-time numbers of the compiled code
        # The QP solver's library compiles while the linearisations are generated.
        qp_library = (build_qp_library(lay.nz, [lay.nu] * lay.horizon, lay.nc)
                      if compile and qp_solver != "hpipm" and compiler() is not None else None)
        self.cold_start = cold_start
        converge = cold_start == "converged"
        if not isinstance(shared_barrier, bool):
            raise ValueError(f"shared_barrier must be True or False, got {shared_barrier!r}")
        self.ladder = LinearisationLadder(ocp, capacities, compile,
                                          values=line_search or converge,
                                          shared_barrier=shared_barrier)
        self.qp_solver = qp_solver if self.ladder.native else "hpipm"
        if qp_library is not None:
            qp_library.exception()  # built (a failure: the QP chain's own build reports it)
        bounded = np.isfinite(ocp.state_bounds[0]) | np.isfinite(ocp.state_bounds[1])
        self.qp = QPChain(self.layout, self.qp_solver,
                          RelaxedQP(self.layout, bounded) if relaxed_qp else None)
        self.line_search = MeritLineSearch(self.layout, max_trials=4 if line_search else 0)
        self._cold_search = MeritLineSearch(self.layout) if converge else None
        self._lbw, self._ubw = self.layout.bounds(ocp)
        position = np.array(ocp.model.position, dtype=np.intp)
        self._has_position = len(position) > 0
        # the position entries of x: a slice where they are consecutive (the quadrotor's
        # 0:3), which indexes without a gather
        self._position = (slice(int(position[0]), int(position[-1]) + 1)
                          if len(position) and np.array_equal(
                              position, np.arange(position[0], position[-1] + 1))
                          else position)
        # Buffers of every solve, whose contents never outlive it: the iterate w (n_w,) (its
        # carried β stay 0) and the step's bounds lb − w, ub − w (n_w,).
        self.last_failure: dict | None = None  # why the last failed solve failed
        self.last_relaxation: dict | None = None  # why the hard QP of the last relaxed one did
        nw = self.layout.nw
        self._w, self._step_lower, self._step_upper = np.zeros(nw), np.empty(nw), np.empty(nw)
        self._anchor = np.zeros(ocp.nx)  # the move of the previous plan, m (position only)
        self._bound_qps = {}  # a compiled rung's QP, bound at its first solve: _bound_qp

    @property
    def qp_counts(self) -> dict[str, int]:
        return self.qp.counts

    @property
    def step_counts(self) -> dict[str, int]:
        return self.line_search.counts

    # --- public ------------------------------------------------------------------------------

    def solve(self, x0, target, visible=(), previous: NMPCSolution | None = None,
              velocities=None) -> NMPCSolution:
        """Same contract as :meth:`paper_repro.solvers.ipopt.TrackingNMPC.solve`, except the warm
        start:
        the previous plan moved to the current position (:meth:`NMPCSolution.reanchored`).
        With one iteration per instant that keeps the closed loop within about a millimetre
        of the converged solution, where the time-shifted plan drifts by centimetres.

        ``status`` is ``"iterated"`` (``max_iter`` SQP steps taken, the real-time iteration's
        normal outcome), ``"converged"`` (step below ``step_tol``) or ``"qp_failed"``."""
        start = time.perf_counter()  # solve_time includes packing the scan: the whole call
        ocp, layout = self.ocp, self.layout
        x0 = as_vector("x0", x0, ocp.nx)
        target = as_vector("target", target, ocp.ny)
        visible = check_visible(visible, ocp.ny)
        rung = self.ladder.for_scan(visible)
        # A rung still compiling is waited for once; the wait is not the solve's time.
        waited = sum(fn.load() for fn in rung[1:] if isinstance(fn, NativeFunction))
        params = np.concatenate([target, self.ladder.pack(visible, ocp.output(x0), rung.scan,
                                                          velocities), self._theta])
        X, U, a = self._guess(x0, previous)
        search, max_iter = self.line_search, self.max_iter
        if previous is None and self._cold_search is not None:  # a converged cold start
            search, max_iter = self._cold_search, max(max_iter, COLD_START_ITERATIONS)
            search.reset()
        lbw, ubw = self._lbw, self._ubw
        box = ocp.state_box(x0)
        if box[0] is not ocp.state_bounds[0] or box[1] is not ocp.state_bounds[1]:
            lbw, ubw = layout.bounds(ocp, box)  # x0 violates 𝒳: the relaxed box (rare)
        bound_qp = self._bound_qp(rung.linearisation)
        lower, upper = self._step_lower, self._step_upper

        def values(dw, alpha):  # (cost, gap, eq) at the iterate moved by α·Δw
            dx, du, da = layout.gather(dw)
            return self.ladder.evaluate(rung.values, x0, X[1:] + alpha * dx, U + alpha * du,
                                        a + alpha * da, params)

        success, status, it, merit, relaxed = False, "iterated", 0, np.nan, False
        for it in range(1, max_iter + 1):  # noqa: B007 - `it` is reported below
            w = layout.scatter(X[1:], U, a, out=self._w)
            h, q, j, gap, eq, cost = self.ladder.evaluate(rung.linearisation, x0, X[1:], U, a,
                                                          params)
            damped = search.damp(h)
            np.subtract(lbw, w, out=lower)
            np.subtract(ubw, w, out=upper)
            dw = (self.qp.solve_bound(bound_qp) if bound_qp is not None
                  else self.qp.solve(h, q, j, gap, eq, lower, upper))
            if dw is None:
                success, status = False, "qp_failed"
                self.last_failure = {**self.qp.last_failure,
                                     "outside_state_box": lbw is not self._lbw}
                break
            if self.qp.last_relaxed and not relaxed:  # the first relaxed QP of this solve
                relaxed, self.last_relaxation = True, {
                    **self.qp.last_relaxation, "outside_state_box": lbw is not self._lbw}
            alpha, merit = search(dw, h, q, gap, eq, float(cost[0]), values)
            dx, du, da = layout.gather(dw)
            if alpha != 1.0:  # (1.0·Δ is Δ, bit for bit: the full step skips the products)
                dx, du, da = alpha * dx, alpha * du, alpha * da
            X[1:] += dx
            U += du
            a += da
            # Converged: a full, undamped step below the tolerance (a shortened or damped
            # step is small without being near the solution).
            if (alpha == 1.0 and not damped
                    and float(np.abs(dw[layout.bounded]).max()) < self.step_tol):
                success, status = True, "converged"
                break
        else:
            success, status = True, "iterated"  # real-time iteration: the last iterate is used
        if relaxed and success:
            status = "relaxed"
        elapsed = time.perf_counter() - start - waited
        finite = np.isfinite(X).all() and np.isfinite(U).all() and np.isfinite(a).all()
        x_a, u_a = ocp.equilibrium_of(a)
        return NMPCSolution(U, X, x_a, u_a, bool(success and finite), status, it, elapsed,
                            merit)

    def _bound_qp(self, fn):
        """A compiled rung writes its QP into the same buffers at every call: its QP is bound
        to them once, at its first solve (checked and addressed there, not at every step).
        ``None`` for a rung evaluated by CasADi."""
        if isinstance(fn, NativeFunction) and fn not in self._bound_qps:
            self._bound_qps[fn] = self.qp.bind(*fn.outputs[:5], self._step_lower,
                                               self._step_upper)
        return self._bound_qps.get(fn)

    def ready(self) -> float:
        """Wait until every compiled linearisation is built and loaded (they build in the
        background, and a solve waits only for the one its scan needs); the seconds waited.
        Call it before timing whole flights from a cold cache."""
        return self.ladder.wait()

    def reset(self) -> None:
        """Forget everything carried from one solve to the next (the Riccati solver's active
        set and multipliers, the line search's damping), so that a new flight starts from a
        clean slate and is bit-identical whether this controller is new or reused.
        ``qp_counts`` and ``step_counts`` keep counting."""
        self.qp.reset()
        self.line_search.reset()

    def hover_guess(self, x0) -> NMPCSolution:
        """Rest where the vehicle is for the whole horizon (the quadrotor: hover)."""
        return self.ocp.rest(x0)

    def obstacle_parameters(self, visible, position, velocities=None) -> np.ndarray:
        """The LiDAR scan in the parameter layout of the config's capacity."""
        return self.ocp.scan.pack(visible, position, velocities)

    def _guess(self, x0: np.ndarray, previous: NMPCSolution | None):
        """The iterate the SQP starts from, as new arrays: X (N+1, n_x) with X[0] = x0, U
        (N, n_u) and a (n_a,). The previous plan moved to x0
        (:meth:`NMPCSolution.reanchored`, the same numbers without building it), shifted in
        time for a vehicle without position states, or rest at x0 without a previous plan."""
        if previous is None or not self._has_position:
            guess = self.hover_guess(x0) if previous is None else previous.shifted()
            X = np.array(guess.x, dtype=float)
            X[0] = x0
            return (X, np.array(guess.u, dtype=float),
                    self.ocp.parameters_of(guess.x_a, guess.u_a))
        position, move = self._position, self._anchor
        move[position] = x0[position] - previous.x[0, position]
        X = previous.x + move
        X[0] = x0
        return (X, np.array(previous.u, dtype=float),
                self.ocp.parameters_of(previous.x_a + move, previous.u_a))


# --- the QP backends ---------------------------------------------------------------------------

IPM_ACTIVE_SET_BUDGET = 4
"""Factorisations the active-set method may spend before ``"riccati-ipm"`` hands the QP to
the interior point. A warm-started QP takes one or two; where a region moves across the
horizon the active set changes by dozens of bounds, one factorisation each (up to 170 on the
swept pillar), while the interior point takes about a dozen whatever changed. On the swept
pillar the slowest calls were those that spent the budget first: 4 rather than 8 took their
p99 from 2.1-2.3 to 2.0-2.2 ms."""


class QPChain:
    """The QP backends in order: the warm-started Riccati solver, then (``"riccati-ipm"``) the
    interior point on its kernels, then HPIPM.

    Parameters
    ----------
    layout : the QP's :class:`QPLayout`.
    qp_solver : ``"riccati"`` (Riccati first, HPIPM when it fails), ``"riccati-ipm"``
        (Riccati within :data:`IPM_ACTIVE_SET_BUDGET` factorisations, then the interior
        point, then HPIPM) or ``"hpipm"`` (HPIPM only).
    relaxed : the last resort, a :class:`~paper_repro.solvers.relaxed_qp.RelaxedQP` of the
        same layout, or ``None`` (a QP no backend solves fails).

    Attributes
    ----------
    counts : QPs solved by ``riccati``, by ``ipm``, by ``hpipm`` (chosen or as fallback), by
        ``relaxed`` (with a last resort), and ``failed``.
    last_relaxed : whether the last QP's step came from the relaxed QP.
    last_ipm_iterations : the interior point's iterations in the last :meth:`solve_bound`
        (0 when it did not run): what an instant's QP cost, for the benchmarks.
    last_failure : why the last QP that no backend solved failed: each backend's status
        (``None`` where it did not run) and whether the QP's data were finite; ``None``
        until a QP fails.
    last_relaxation : why the hard QP failed the last time the relaxed QP stepped in (the
        same fields as ``last_failure``); ``None`` until it does.
    """

    def __init__(self, layout: QPLayout, qp_solver: str = "riccati-ipm",
                 relaxed: RelaxedQP | None = None):
        self.layout = lay = layout
        self.relaxed = relaxed
        self.last_relaxed = False
        n = lay.horizon
        self.riccati = (StageQP(lay.nz, [lay.nu] * n, lay.nc)
                        if qp_solver != "hpipm" else None)
        self.budget = IPM_ACTIVE_SET_BUDGET if qp_solver == "riccati-ipm" else None
        self._interior_next = False  # the next QP straight to the interior point
        (hr, hc, hs), (ar, ac, asrc) = lay.hessian_entries, lay.constraint_entries
        h_sp = ca.Sparsity.triplet(lay.nw, lay.nw, hr.tolist(), hc.tolist())
        a_sp = ca.Sparsity.triplet(lay.n_gap_rows + lay.nc, lay.nw, ar.tolist(), ac.tolist())
        self.hpipm = ca.conic("rti_qp", "hpipm", {"h": h_sp, "a": a_sp},
                              {"N": n, "nx": lay.nz, "nu": [lay.nu] * n + [0],
                               "ng": [0] * n + [lay.nc],
                               # 'robust' converges where 'speed' stalls on this problem;
                               # bounds of ±1e4 on the free variables keep HPIPM's
                               # tolerances relative.
                               "hpipm": {"iter_max": 100, "mode": "robust"}, "inf": 1e4,
                               "error_on_fail": False, "print_problem": False})
        # Blocks of the linearisation -> the nonzeros of HPIPM's sparse H and A, in the
        # column-major order of their sparsity (a fixed permutation of the sources).
        self._h_sp, self._a_sp, self._h_of, self._a_of = h_sp, a_sp, hs, asrc
        self.counts = {"riccati": 0, "hpipm": 0, "failed": 0}
        self.last_ipm_iterations = 0
        self.last_failure: dict | None = None
        self.last_relaxation: dict | None = None
        if self.budget is not None:
            self.counts["ipm"] = 0
        if relaxed is not None:
            self.counts["relaxed"] = 0

    def solve(self, h, q, j, gap, eq, lb, ub) -> np.ndarray | None:
        """The step Δw of the QP min ½ΔwᵀHΔw + qᵀΔw s.t. the linearised gaps and terminal rows,
        lb ≤ Δw ≤ ub; ``None`` when no backend solves it. (The same QP from the same arrays
        at every step: :meth:`bind` them once, then :meth:`solve_bound`.)"""
        return self.solve_bound(self.bind(h, q, j, gap, eq, lb, ub))

    def bind(self, h, q, j, gap, eq, lb, ub) -> BoundQP:
        """The QP whose blocks live in these arrays (a compiled linearisation's output buffers
        and the controller's bound buffers), checked once; refill them in place and solve
        with :meth:`solve_bound` as often as needed."""
        riccati = d = None
        if self.riccati is not None:
            n_ab = self.layout.n_ab
            d = np.empty_like(eq)  # C x_N = d: the terminal rows' right-hand side, −eq
            riccati = self.riccati.bind(h, q, j[:n_ab], gap, j[n_ab:], d, lb, ub)
        return BoundQP((h, q, j, gap, eq, lb, ub), d, riccati)

    def solve_bound(self, bound: BoundQP) -> np.ndarray | None:
        """:meth:`solve` on the current contents of a bound QP's arrays."""
        dw = res = ipm = None
        riccati = bound.riccati
        self.last_ipm_iterations = 0
        if riccati is not None:
            np.negative(bound.arrays[4], out=bound.d)
            if not self._interior_next:
                res = riccati.solve(max_outer=self.budget)
                if res.success:
                    dw = res.z
                    self.counts["riccati"] += 1
            if dw is None and self.budget is not None:
                before = self.riccati.active.copy()
                ipm = riccati.interior_point()
                self.last_ipm_iterations = ipm.iterations
                if ipm.success:
                    dw = ipm.z
                    self.counts["ipm"] += 1
                # A set that moved by more than the budget will likely move as much at the
                # next instant (a region crossing the horizon): go straight to the interior
                # point then, and back to the active set once the set settles.
                changed = int(np.count_nonzero(self.riccati.active != before))
                self._interior_next = ipm.success and changed > self.budget
            else:
                self._interior_next = False
        hpipm = None
        if dw is None:
            dw = self._solve_hpipm(*bound.arrays)
            hpipm = str(self.hpipm.stats().get("return_status", "unknown"))
        self.last_relaxed = False
        if dw is None or not np.isfinite(dw).all():
            cause = {
                "active_set": None if res is None else res.status,
                "interior_point": None if ipm is None else ipm.status,
                "hpipm": hpipm,
                # the linearisation's numbers (a free variable's bounds are ±inf by design)
                "finite_data": (all(np.isfinite(a).all() for a in bound.arrays[:5])
                                and not any(np.isnan(a).any() for a in bound.arrays[5:])),
                "finite_step": dw is not None}
            if self.relaxed is not None:
                dw = self.relaxed.solve(*bound.arrays)
                if dw is not None:
                    self.counts["relaxed"] += 1
                    self.last_relaxed, self.last_relaxation = True, cause
                    return dw
                cause["relaxed"] = self.relaxed.last_status
            self.counts["failed"] += 1
            self.last_failure = cause
            return None
        return dw

    def reset(self) -> None:
        """Forget the Riccati solver's active set and multipliers (``counts`` keep counting)."""
        if self.riccati is not None:
            self.riccati.reset()
        self._interior_next = False

    def matrices(self, h, j) -> tuple[ca.DM, ca.DM]:
        """HPIPM's sparse H (n_w, n_w) and constraint matrix A (rows, n_w), the same as
        :meth:`QPLayout.dense`, from the linearisation's ``h`` and ``j``."""
        # A list converts to a DM about twice as fast as an array of ~17,000 numbers.
        return (ca.DM(self._h_sp, np.asarray(h)[self._h_of].tolist()),
                ca.DM(self._a_sp, self.layout._constraint_source(j)[self._a_of].tolist()))

    def _solve_hpipm(self, h, q, j, gap, eq, lb, ub):
        """The QP by HPIPM; its active set then seeds the Riccati solver's next call."""
        hmat, amat = self.matrices(h, j)
        rhs = -np.concatenate([gap, eq])
        sol = self.hpipm(h=hmat, g=q, a=amat, lba=rhs, uba=rhs, lbx=lb, ubx=ub)
        if not self.hpipm.stats().get("success", False):
            return None
        self.counts["hpipm"] += 1
        dw = np.asarray(sol["x"]).ravel()
        if self.riccati is not None:
            self.riccati.seed(dw, lb, ub, np.asarray(sol["lam_x"]).ravel())
        return dw


class BoundQP(NamedTuple):
    """A QP bound to the arrays its data live in (:meth:`QPChain.bind`).

    Attributes
    ----------
    arrays : (h, q, j, gap, eq, lb, ub), as :meth:`QPChain.solve` takes them.
    d : (n_c,) buffer of the terminal rows' right-hand side −eq (``None`` without the
        Riccati solver).
    riccati : the Riccati solver bound to them
        (:class:`~paper_repro.solvers.riccati_qp.BoundStageQP`; ``None`` for HPIPM only).
    """

    arrays: tuple[np.ndarray, ...]
    d: np.ndarray | None
    riccati: BoundStageQP | None

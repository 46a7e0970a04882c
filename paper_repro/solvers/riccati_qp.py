"""A Riccati QP solver for the SQP's stage-structured QPs, warm-started with the active set.

The QP of every real-time iteration has the optimal-control structure

    min  Σ_j ½ z_jᵀ H_j z_j + q_jᵀ z_j,     z_j = (x_j, u_j),  z_N = x_N,
    s.t. x_{j+1} = [A_j B_j] z_j + b_j,      C x_N = d,        lb ≤ z ≤ ub,

with x_0 free. Between two sampling instants the set of bounds that hold with equality barely
changes (the plan is re-anchored, not re-planned), so an interior-point method, which
rediscovers it in about a dozen Riccati factorisations, does more work than needed. This
solver keeps the active set and its multipliers from the previous call. Every iterate solves
the equality-constrained QP with the active bounds fixed:

* one Riccati factorisation; the fixed bounds and C x_N = d enter by an augmented Lagrangian
  (weight ``rho`` times the largest Hessian diagonal), whose multipliers are refined by cheap
  vector passes until the equalities hold to ``eq_tol``;
* the recursion runs backward from stage N, so stage j's factors depend on the bounds of
  stages j..N only: after a change of the active set, the stages above the highest changed
  one keep their factors. On the crossing's escape manoeuvre this halves the work of the hard
  QPs (a median 2.6 full factorisations for 4 iterates).

The guess is first made dual feasible (bounds whose multiplier has the wrong sign are
released), then repaired by dual active-set steps (Goldfarb and Idnani, 1983): the most
violated bound is moved to its bound along the affine solution path, releasing any fixed bound
whose multiplier reaches zero first; a bound that depends on the fixed ones gets a pure dual
step. For a strictly convex QP this terminates from any start, a cold one included; with the
previous instant's set it usually takes a single factorisation.

The result is the QP's exact solution (to the tolerances), not an approximation. When
``max_outer`` equality-QP solves do not suffice the call reports failure, and the caller falls
back on an interior-point solver: HPIPM, or :meth:`StageQP.interior_point`, Mehrotra's
predictor-corrector method on the same stage kernels (a dozen factorisations of H + Σ
whatever the active set; the terminal rows exact through their Schur complement; its iterate
then seeds this method, which polishes it to the exact solution, mostly in one
factorisation). The C source is ``_riccati_qp.c``; it is compiled once per
machine (see :mod:`paper_repro._native`), with its stage kernels also instantiated for the
sizes of most stages (``specialise``): constant loop lengths let the compiler unroll them and
keep their sums in registers. On the crossing's hard QPs (stages of 18 states and 4 inputs)
a full factorisation then takes about 0.045 ms instead of 0.14 ms, a vector pass 7 µs
instead of 15 µs, for the same iterates (376 captured QPs: 0.22 / 0.68 / 1.6 ms median / p90
/ p99 against 0.61 / 1.9 / 5.2 ms).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from importlib import resources

import numpy as np

from paper_repro._native import build_in_background as _native_build_in_background
from paper_repro._native import load_library

_D = ctypes.POINTER(ctypes.c_double)
_ARGS = ("h", "q", "ab", "b", "c", "d", "lb", "ub")  # solve()'s arrays, in order
STATUS = {0: "solved", 1: "active_set_not_found", 2: "infeasible_or_inconsistent",
          3: "not_positive_definite", 4: "workspace"}
IPM_STATUS = {0: "solved", 1: "iteration_limit", 3: "not_positive_definite", 4: "workspace"}
POLISH_BUDGET = 3
"""Factorisations the active-set method may spend polishing an interior-point solution. Of
the swept pillar's 630 QPs that went to the interior point, 610 are polished within 3 (one
factorisation for nearly all) and 611 within 20: a polish that fails fails whatever it may
spend, and the interior point's own iterate is returned."""


class _Stats(ctypes.Structure):
    _fields_ = [("outer", ctypes.c_int), ("passes", ctypes.c_int), ("changes", ctypes.c_int),
                ("n_active", ctypes.c_int), ("stages", ctypes.c_int)]


class _IPMStats(ctypes.Structure):
    _fields_ = [("iterations", ctypes.c_int), ("mu", ctypes.c_double),
                ("residual", ctypes.c_double)]


def _specialised_sizes(nx, nu) -> tuple[int, int] | None:
    """The (nx_j, nu_j) of most stages with nx_{j+1} = nx_j, which the library is compiled
    for (None when no stage qualifies)."""
    pairs = [(int(nx[j]), int(nu[j])) for j in range(len(nu)) if nx[j + 1] == nx[j]]
    return max(set(pairs), key=pairs.count) if pairs else None


def _source() -> bytes:
    return resources.files("paper_repro.solvers").joinpath("_riccati_qp.c").read_bytes()


def _flags(sizes: tuple[int, int, int] | None) -> tuple[str, ...]:
    return () if sizes is None else (f"-DSQP_NX={sizes[0]}", f"-DSQP_NU={sizes[1]}",
                                     f"-DSQP_NC={sizes[2]}")


def build_in_background(nx, nu, nc: int):
    """Start compiling the library a :class:`StageQP` of these sizes loads (its default,
    specialised kernels), in the background (:func:`~paper_repro._native.build_in_background`);
    the future of its path. A controller starts it first, then generates its linearisations
    while gcc works."""
    sizes = _specialised_sizes(np.asarray(nx), np.asarray(nu))
    return _native_build_in_background(
        "stage_qp", _source(), flags=_flags(None if sizes is None else (*sizes, int(nc))))


def _library(sizes: tuple[int, int, int] | None = None):
    """The compiled solver; with ``sizes`` = (a, b, c), its stage kernels are also
    instantiated for nx_j = nx_{j+1} = a, nu_j = b, and the interior point's Schur complement
    for c terminal rows (one library per triple, cached like the others)."""
    lib = load_library("stage_qp", _source(), flags=_flags(sizes))
    lib.stage_qp_workspace.restype = ctypes.c_size_t
    lib.stage_qp_workspace.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p,
                                       ctypes.c_int]
    lib.stage_qp_solve.restype = ctypes.c_int
    ptr, i, f = ctypes.c_void_p, ctypes.c_int, ctypes.c_double
    lib.stage_qp_solve.argtypes = [i, ptr, ptr, ptr, ptr, ptr, ptr, i, ptr, ptr, ptr, ptr, ptr,
                                   ptr, ptr, f, f, f, i, i, i, ptr, ctypes.c_size_t, ptr, ptr]
    lib.stage_ipm_workspace.restype = ctypes.c_size_t
    lib.stage_ipm_workspace.argtypes = lib.stage_qp_workspace.argtypes
    lib.stage_qp_ipm.restype = ctypes.c_int
    lib.stage_qp_ipm.argtypes = [i, ptr, ptr, ptr, ptr, ptr, ptr, i, ptr, ptr, ptr, ptr, f, i,
                                 ptr, ctypes.c_size_t, ptr, ptr, ptr, ptr]
    return lib


@dataclass
class StageQPResult:
    z: np.ndarray
    status: str
    outer: int    # active-set iterations (factorisations)
    passes: int   # vector passes
    changes: int  # active-set changes
    n_active: int
    stages: int   # stage factorisations (N + 1 per full factorisation; fewer per partial one)

    @property
    def success(self) -> bool:
        return self.status == "solved"


@dataclass
class InteriorPointResult:
    z: np.ndarray
    status: str
    iterations: int
    mu: float        # mean complementarity s·λ of the interior point's last iterate
    residual: float  # its largest residual (slacks; dynamics and terminal rows relative to |z|)
    polished: bool   # z is the active-set method's exact solution, seeded by the iterate

    @property
    def success(self) -> bool:
        return self.status == "solved"


class StageQP:
    """Solver for one fixed stage structure; keeps the active set between calls.

    Parameters
    ----------
    nx : (N+1,) state sizes, x_0 included (x_0 is a free variable).
    nu : (N,) input sizes.
    nc : rows of the terminal equality C x_N = d.
    rho : augmented-Lagrangian weight of the fixed bounds and the terminal equality, relative
        to the largest diagonal entry of H (at least 1).
    eq_tol : the fixed bounds and C x_N = d hold to this (absolute).
    kkt_tol : tolerance of the bound and multiplier-sign checks.
    max_outer : equality-QP solves (factorisations) before giving up. The default, 40, spends
        at most about what one HPIPM solve of the NMPC's QP costs through CasADi (40 partial
        factorisations at 0.1-0.2 ms against 6-12 ms), so giving up never costs more than
        twice the fallback.
    max_passes : multiplier updates per factorisation; a set that cannot meet the equalities
        within them counts as inconsistent.
    reuse_factors : keep the factors of the stages above the highest changed bound (True);
        False refactorises every stage every time, the same numbers at more cost (a check).
    specialise : compile the stage kernels also for the constant sizes of most stages (True;
        see :func:`_specialised_sizes`); False uses the generic kernels only, the same
        numbers bit for bit at more cost (a check).
    """

    def __init__(self, nx, nu, nc: int, rho: float = 1e4, eq_tol: float = 1e-10,
                 kkt_tol: float = 1e-9, max_outer: int = 40, max_passes: int = 30,
                 reuse_factors: bool = True, specialise: bool = True, ipm_tol: float = 1e-6,
                 ipm_max_iter: int = 50):
        self.nx = np.ascontiguousarray(nx, dtype=np.intc)
        self.nu = np.ascontiguousarray(nu, dtype=np.intc)
        self.horizon = len(self.nu)
        if len(self.nx) != self.horizon + 1 or self.horizon < 1:
            raise ValueError(f"nx must have len(nu) + 1 = {self.horizon + 1} entries, "
                             f"got {len(self.nx)}")
        if np.any(self.nx < 1) or np.any(self.nu < 0):
            raise ValueError("nx must be >= 1 and nu >= 0 at every stage")
        if not (rho > 0 and eq_tol > 0 and kkt_tol > 0 and ipm_tol > 0):
            raise ValueError("rho, eq_tol, kkt_tol and ipm_tol must be > 0")
        for name, v, low in (("nc", nc, 0), ("max_outer", max_outer, 1),
                             ("max_passes", max_passes, 1), ("ipm_max_iter", ipm_max_iter, 1)):
            if not (isinstance(v, (int, np.integer)) and v >= low):
                raise ValueError(f"{name} must be an integer >= {low}, got {v!r}")
        self.nc = int(nc)
        self.sizes = np.r_[self.nx[:-1] + self.nu, self.nx[-1]]
        self.nw = int(self.sizes.sum())
        self._expected = {  # entries of every argument of solve()
            "h": int(np.sum(self.sizes ** 2)), "q": self.nw,
            "ab": int(np.sum(self.nx[1:] * self.sizes[:-1])), "b": int(self.nx[1:].sum()),
            "c": self.nc * int(self.nx[-1]), "d": self.nc, "lb": self.nw, "ub": self.nw}
        self.rho, self.eq_tol, self.kkt_tol = float(rho), float(eq_tol), float(kkt_tol)
        for name, v in (("reuse_factors", reuse_factors), ("specialise", specialise)):
            if not isinstance(v, bool):
                raise ValueError(f"{name} must be True or False, got {v!r}")
        self.max_outer, self.max_passes = int(max_outer), int(max_passes)
        self.ipm_tol, self.ipm_max_iter = float(ipm_tol), int(ipm_max_iter)
        self.reuse_factors = reuse_factors
        self.specialised_for = _specialised_sizes(self.nx, self.nu) if specialise else None
        self._lib = _library(None if self.specialised_for is None
                             else (*self.specialised_for, self.nc))
        self._work = np.zeros(self._lib.stage_qp_workspace(
            self.horizon, self.nx.ctypes.data, self.nu.ctypes.data, self.nc))
        self.z = np.zeros(self.nw)
        self.active = np.zeros(self.nw, dtype=np.int8)  # −1 lower, +1 upper, 0 free
        self.lam = np.zeros(self.nw)
        self.lam_c = np.zeros(self.nc)
        self._stats = _Stats()
        self._ipm_stats = _IPMStats()
        self._ipm_work = None  # allocated at the first interior-point call
        # The call's working copy of the active set and multipliers (kept only on success),
        # and the addresses of every buffer that never moves: a ctypes address costs about
        # a microsecond to look up, a dozen of them per call add up.
        self._trial = (np.zeros_like(self.active), np.zeros_like(self.lam),
                       np.zeros_like(self.lam_c))
        self._fixed = (self.nx.ctypes.data, self.nu.ctypes.data,
                       *(a.ctypes.data for a in self._trial), self._work.ctypes.data,
                       self._work.size, self.z.ctypes.data, ctypes.byref(self._stats))

    def reset(self) -> None:
        """Forget the active set and the multipliers (the next call starts from none)."""
        self.active[:] = 0
        self.lam[:] = 0.0
        self.lam_c[:] = 0.0

    def seed(self, z, lb, ub, lam, tol: float = 1e-7) -> None:
        """Take the active set of a solution found elsewhere (an interior-point solver's):
        bounds that ``z`` meets within ``tol`` and whose multiplier ``lam`` (CasADi's sign
        convention: < 0 at a lower bound, > 0 at an upper one) is not zero."""
        z, lb, ub, lam = (np.asarray(v, float) for v in (z, lb, ub, lam))
        at_lower = (z - lb < tol) & (lam < -self.kkt_tol)
        at_upper = (ub - z < tol) & (lam > self.kkt_tol)
        self.active[:] = 0
        self.active[at_lower], self.active[at_upper] = -1, 1
        self.lam[:] = np.where(self.active != 0, lam, 0.0)
        self.lam_c[:] = 0.0

    def solve(self, h, q, ab, b, c, d, lb, ub, max_outer: int | None = None) -> StageQPResult:
        """h: H blocks, ab: [A_j B_j] blocks (each column-major, concatenated), q, b, d, lb,
        ub: vectors (±inf for no bound); c: C column-major. Arrays must be contiguous float64
        of the sizes the structure implies; the returned ``z`` is a copy. ``max_outer``
        overrides the constructor's budget for this call. (A QP solved again and again from
        the same arrays, refilled in place, is checked once with :meth:`bind`.)"""
        return self._solve(self._addresses(h, q, ab, b, c, d, lb, ub), max_outer)

    def interior_point(self, h, q, ab, b, c, d, lb, ub) -> InteriorPointResult:
        """The same QP by the interior-point method on the same Riccati kernels (Mehrotra's
        predictor-corrector; the terminal rows exact through their Schur complement; see
        ``stage_qp_ipm`` in ``_riccati_qp.c``): about a dozen factorisations whatever the
        active set, where the active-set method needs one per change. Its iterate, converged
        to ``ipm_tol`` (complementarity and relative residuals), names the active set: the
        bounds whose barrier curvature λ/s exceeds 10⁴. That set and its multipliers seed
        the active-set method, which then *polishes* the solution within
        :data:`POLISH_BUDGET` factorisations (one, mostly): the QP's exact solution, as
        :meth:`solve` gives it, rather than the interior point's approximation, whose
        accuracy fades as λ/s spans more than double precision resolves. When the polish
        fails, the interior point's iterate is returned (``polished`` False). Same
        arguments as :meth:`solve`."""
        return self._interior_point(self._addresses(h, q, ab, b, c, d, lb, ub))

    def bind(self, h, q, ab, b, c, d, lb, ub) -> BoundStageQP:
        """The QP whose data live in these arrays (same arguments as :meth:`solve`), checked
        once: refill them in place and call the result's ``solve()`` or
        ``interior_point()`` as often as needed. The arrays must stay where they are (the
        binding keeps them alive)."""
        return BoundStageQP(self, (h, q, ab, b, c, d, lb, ub))

    def _solve(self, addresses: tuple[int, ...], max_outer: int | None) -> StageQPResult:
        """:meth:`solve` on the arrays at these addresses (checked by :meth:`_addresses`)."""
        h, q, ab, b, c, d, lb, ub = addresses
        active, lam, lam_c = self._trial
        active[:], lam[:], lam_c[:] = self.active, self.lam, self.lam_c
        nx, nu, p_active, p_lam, p_lam_c, work, work_size, z, stats = self._fixed
        info = self._lib.stage_qp_solve(
            self.horizon, nx, nu, h, q, ab, b, self.nc, c, d, lb, ub, p_active, p_lam, p_lam_c,
            self.rho, self.eq_tol, self.kkt_tol,
            self.max_outer if max_outer is None else int(max_outer), self.max_passes,
            int(self.reuse_factors), work, work_size, z, stats)
        s = self._stats
        if info == 0:  # keep the active set for the next call only when it is right
            self.active[:], self.lam[:], self.lam_c[:] = active, lam, lam_c
        return StageQPResult(self.z.copy(), STATUS.get(info, f"error {info}"), s.outer,
                             s.passes, s.changes, s.n_active, s.stages)

    def _interior_point(self, addresses: tuple[int, ...]) -> InteriorPointResult:
        """:meth:`interior_point` on the arrays at these addresses."""
        h, q, ab, b, c, d, lb, ub = addresses
        if self._ipm_work is None:
            self._ipm_work = np.zeros(self._lib.stage_ipm_workspace(
                self.horizon, self.nx.ctypes.data, self.nu.ctypes.data, self.nc))
        active, lam, _ = self._trial
        work, st = self._ipm_work, self._ipm_stats
        info = self._lib.stage_qp_ipm(
            self.horizon, self.nx.ctypes.data, self.nu.ctypes.data, h, q, ab, b, self.nc, c, d,
            lb, ub, self.ipm_tol, self.ipm_max_iter, work.ctypes.data, work.size,
            self.z.ctypes.data, lam.ctypes.data, active.ctypes.data, ctypes.byref(st))
        result = InteriorPointResult(self.z.copy(), IPM_STATUS.get(info, f"error {info}"),
                                     st.iterations, st.mu, st.residual, False)
        if info not in (0, 1):  # a factorisation failed: no iterate to start from
            return result
        self.active[:] = active
        self.lam[:] = np.where(active != 0, lam, 0.0)
        self.lam_c[:] = 0.0
        polished = self._solve(addresses, max_outer=POLISH_BUDGET)
        if polished.success:  # exact, even from an iterate short of ipm_tol
            result.z, result.polished, result.status = polished.z, True, "solved"
        else:  # the next call starts from the interior point's set
            self.active[:] = active
            self.lam[:] = np.where(active != 0, lam, 0.0)
        return result

    def _addresses(self, *args) -> tuple[int, ...]:
        """The addresses of solve()'s arrays, after checking each one's type and size."""
        for name, a in zip(_ARGS, args):
            if not (isinstance(a, np.ndarray) and a.dtype == np.float64
                    and a.flags.c_contiguous and a.size == self._expected[name]):
                raise ValueError(f"{name} must be a contiguous float64 array of "
                                 f"{self._expected[name]} entries")
        return tuple(a.ctypes.data for a in args)


class BoundStageQP:
    """A :class:`StageQP` bound to the arrays its QP data live in (:meth:`StageQP.bind`).

    The real-time iteration writes every QP into the same buffers (the compiled
    linearisation's outputs, the controller's bounds), so their types, sizes and addresses
    are checked and looked up once here rather than at every call: a ctypes address costs
    about a microsecond, and eight checks and addresses were a tenth of the QP's wrapper.
    Same results as :meth:`StageQP.solve` on the same arrays, bit for bit.

    Attributes
    ----------
    qp : the solver (its active set and multipliers are shared with every binding).
    arrays : (h, q, ab, b, c, d, lb, ub), kept alive at their addresses.
    """

    def __init__(self, qp: StageQP, arrays: tuple[np.ndarray, ...]):
        self.qp, self.arrays = qp, arrays
        self._addresses = qp._addresses(*arrays)

    def solve(self, max_outer: int | None = None) -> StageQPResult:
        """:meth:`StageQP.solve` on the bound arrays' current contents."""
        return self.qp._solve(self._addresses, max_outer)

    def interior_point(self) -> InteriorPointResult:
        """:meth:`StageQP.interior_point` on the bound arrays' current contents."""
        return self.qp._interior_point(self._addresses)

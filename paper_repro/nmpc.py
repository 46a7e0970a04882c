"""Tracking NMPC with artificial equilibrium and smooth CBF penalties (Sections II and IV).

The optimal control problem (eq. 21: eq. 7 with the cost of eq. 20)::

    min_{u, x_a, u_a}  Σ_{j<N} ‖x_j − x_a‖²_Q + ‖u_j − u_a‖²_R + ‖y_a − y_t‖²_T
                       + μ Σ_i ( F(y_a, 𝒪_i) + Σ_{j=0}^{N} F(y_j, 𝒪_i) )
    s.t.  x_0 = x,  x_{j+1} = f(x_j, u_j),  (x_j, u_j) ∈ 𝒳 × 𝒰,
          x_a = f(x_a, u_a),  (x_a, u_a) ∈ λ(𝒳 × 𝒰),  x_N = x_a

with β = D − d_min (eq. 17), g(y_j) = c·β(y_j) − β(y_{j+1}) (eq. 18; c = 1 − δ as printed,
or c = δ as in Definition 1, see :class:`~paper_repro.config.BarrierParams`), y_{N+1} = y_a
(the artificial equilibrium is where the prediction rests), and
F = (1/κ)[ln(1 + e^{κg})]^ε (eq. 19).

The NLP is described once and built once (:class:`TrackingNMPC`); :meth:`TrackingNMPC.solve`
is the hot path. What the LiDAR sees enters as parameters: ``region_slots`` slots of
``points_per_region`` points each. Unused point slots carry ln W = −1e30, so their terms are
exactly zero; unused region slots are multiplied by an ``active`` flag of exactly zero. The
weights W_j and the volume V are computed from the visible subset at every step (the UAV only
knows what is in range). A slot that sees more points than it holds keeps the nearest ones.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from . import distance as dist
from .config import Config
from .model import N_INPUTS, N_STATES, equilibrium, rk4_discretisation

PAD_LOG_WEIGHT = -1e30
_FAR_AWAY = 1e3  # position of the single dummy point of an inactive slot (its F is exactly 0)

_SUCCESS_STATUSES = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass
class NMPCSolution:
    """Result of one OCP solve.

    Attributes
    ----------
    u : (N, 4) planned inputs, N.  x : (N+1, 12) predicted states.
    x_a : (12,) artificial equilibrium state.  u_a : (4,) artificial equilibrium input, N.
    success : bool, the solver reported convergence.  status : solver's return status.
    iterations : int.  solve_time : s, wall time of the solver call.  cost : optimal value.
    """

    u: np.ndarray
    x: np.ndarray
    x_a: np.ndarray
    u_a: np.ndarray
    success: bool
    status: str
    iterations: int
    solve_time: float
    cost: float

    def shifted(self) -> NMPCSolution:
        """The plan one step later: drop the first stage and rest at the artificial equilibrium.

        This is both the warm start of the next solve and the fallback plan after a failure.
        """
        u = np.vstack([self.u[1:], self.u_a[None, :]])
        x = np.vstack([self.x[1:], self.x_a[None, :]])
        return NMPCSolution(u, x, self.x_a.copy(), self.u_a.copy(), self.success, self.status,
                            0, 0.0, self.cost)

    def reanchored(self, x0) -> NMPCSolution:
        """The same plan moved rigidly so that it starts at the position of ``x0``.

        The OCP is invariant to translations of position except through the target, the
        regions and the workspace walls, which move slowly relative to one sampling period. In
        cruise the optimal plan keeps its shape from one instant to the next (accelerate, then
        stop at x_a within the horizon), so moving it, rather than shifting it in time, is the
        better starting point for a single SQP iteration.
        """
        d = np.zeros_like(self.x_a)
        d[:3] = np.asarray(x0, float)[:3] - self.x[0, :3]
        return NMPCSolution(self.u.copy(), self.x + d, self.x_a + d, self.u_a.copy(),
                            self.success, self.status, 0, 0.0, self.cost)


class TrackingNMPC:
    """The paper's tracking NMPC, solved by IPOPT with the exact Hessian (the reference path).

    Parameters
    ----------
    config : :class:`~paper_repro.config.Config`; uses its ``quadrotor``, ``distance``,
        ``barrier`` and ``nmpc`` parts.
    max_iter : IPOPT iteration limit per solve.
    tol : IPOPT convergence tolerance.
    """

    def __init__(self, config: Config | None = None, max_iter: int = 200, tol: float = 1e-8):
        # Builds the NLP and IPOPT instance once: several seconds.
        self.config = config or Config()
        if not (isinstance(max_iter, int) and max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
        if not (tol > 0):
            raise ValueError(f"tol must be > 0, got {tol!r}")
        p = self.config.nmpc
        self.horizon = p.horizon
        self.region_slots = p.region_slots
        self.points_per_region = p.points_per_region
        self.metric = self.config.distance.metric
        self._build(max_iter, tol)

    # --- public ------------------------------------------------------------------------------

    def solve(self, x0, target, visible: Sequence[np.ndarray] = (),
              previous: NMPCSolution | None = None) -> NMPCSolution:
        """Solve the OCP from state ``x0`` towards output set-point ``target``.

        Parameters
        ----------
        x0 : (12,) current state.
        target : (3,) set-point y_t, m.
        visible : the LiDAR scan in its one accepted form (see :func:`check_visible`): a
            list or tuple with one finite (k_i, 3) array per region, k_i ≥ 0 (what
            :meth:`paper_repro.scene.Lidar.scan` returns); ``()`` when nothing is in view.
        previous : the plan of the previous sampling instant; the warm start is that plan
            shifted by one step (see :meth:`NMPCSolution.shifted`). Hover at the current
            position if omitted.
        """
        start = time.perf_counter()  # solve_time includes packing the scan: the whole call
        x0 = _as_vector("x0", x0, N_STATES)
        target = _as_vector("target", target, 3)
        visible = check_visible(visible)
        params = np.concatenate([target, self.obstacle_parameters(visible, x0[:3])])
        guess = previous.shifted() if previous is not None else self.hover_guess(x0)
        w0 = self._pack(guess.x, guess.u, guess.x_a, guess.u_a)
        w0[self._ix[0]] = x0
        lbw, ubw = self._lbw.copy(), self._ubw.copy()
        lbw[self._ix[0]] = x0
        ubw[self._ix[0]] = x0

        sol = self._solver(x0=w0, p=params, lbx=lbw, ubx=ubw, lbg=0.0, ubg=0.0)
        elapsed = time.perf_counter() - start
        stats = self._solver.stats()
        w = np.asarray(sol["x"]).ravel()
        x, u, x_a, u_a = self._unpack(w)
        status = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False)) or status in _SUCCESS_STATUSES
        success = success and bool(np.all(np.isfinite(w)))
        return NMPCSolution(u, x, x_a, u_a, success, status, int(stats.get("iter_count", -1)),
                            elapsed, float(sol["f"]))

    def reset(self) -> None:
        """Nothing to forget: each IPOPT solve starts from the guess it is given."""

    def hover_guess(self, x0) -> NMPCSolution:
        """Initial guess: hover at the current position and yaw for the whole horizon."""
        x_a, u_a = equilibrium(np.asarray(x0)[:3], float(np.asarray(x0)[5]),
                               self.config.quadrotor)
        n = self.horizon
        return NMPCSolution(np.tile(u_a, (n, 1)), np.tile(x_a, (n + 1, 1)), x_a, u_a,
                            True, "guess", 0, 0.0, np.nan)

    def obstacle_parameters(self, visible: Sequence[np.ndarray], position) -> np.ndarray:
        """The LiDAR scan in the NLP's parameter layout (see :func:`pack_scan`)."""
        return pack_scan(visible, position, self.config)

    # --- construction --------------------------------------------------------------------------

    def _build(self, max_iter: int, tol: float) -> None:
        cfg = self.config
        p, b = cfg.nmpc, cfg.barrier
        n, nx, nu = p.horizon, N_STATES, N_INPUTS
        f = rk4_discretisation(p.prediction_step, cfg.quadrotor)

        X = ca.SX.sym("X", nx, n + 1)
        U = ca.SX.sym("U", nu, n)
        xa = ca.SX.sym("x_a", nx)
        ua = ca.SX.sym("u_a", nu)
        yt = ca.SX.sym("y_t", 3)
        Q, R, T = (ca.diag(ca.DM(v)) for v in (p.q, p.r, p.t))

        cost = 0
        constraints = []
        for j in range(n):
            dx, du = X[:, j] - xa, U[:, j] - ua
            cost += ca.bilin(Q, dx, dx) + ca.bilin(R, du, du)
            constraints.append(X[:, j + 1] - f(X[:, j], U[:, j]))
        ya = xa[:3]
        cost += ca.bilin(T, ya - yt, ya - yt)
        constraints.append(X[:, n] - xa)
        constraints.append(xa - f(xa, ua))

        region_params = []
        outputs = [X[:3, j] for j in range(n + 1)] + [ya]  # y_0..y_N, then y_{N+1} = y_a
        for _ in range(self.region_slots):
            pr, barrier = region_barrier(cfg.distance.metric, cfg.distance.eta, b.d_min,
                                         self.points_per_region)
            region_params.append(pr)
            beta = [barrier(y) for y in outputs]
            beta_a = beta[-1]
            penalty = _softplus_penalty((b.decay - 1.0) * beta_a, b.kappa, b.epsilon)  # y_a
            for j in range(n + 1):
                penalty += _softplus_penalty(b.decay * beta[j] - beta[j + 1], b.kappa, b.epsilon)
            cost += b.mu * pr[-1] * penalty  # pr[-1] is the slot's active flag

        w = ca.vertcat(ca.vec(X), ca.vec(U), xa, ua)
        params = ca.vertcat(yt, *region_params)
        nlp = {"x": w, "p": params, "f": cost, "g": ca.vertcat(*constraints)}
        opts = {"ipopt": {"print_level": 0, "max_iter": max_iter, "tol": tol,
                          "sb": "yes", "mu_strategy": "adaptive"},
                "print_time": False}
        self._solver = ca.nlpsol("tracking_nmpc", "ipopt", nlp, opts)

        # Index maps into w, and bounds.
        idx = np.arange(w.shape[0])
        self._ix = idx[: nx * (n + 1)].reshape(n + 1, nx)
        off = nx * (n + 1)
        self._iu = idx[off: off + nu * n].reshape(n, nu)
        off += nu * n
        self._ixa = idx[off: off + nx]
        self._iua = idx[off + nx: off + nx + nu]
        xl, xu, ul, uu = (np.asarray(v, float) for v in
                          (p.state_lower, p.state_upper, p.input_lower, p.input_upper))
        xal, xau, ual, uau = p.relaxed_bounds()
        lbw, ubw = np.empty(w.shape[0]), np.empty(w.shape[0])
        lbw[self._ix], ubw[self._ix] = xl, xu
        lbw[self._iu], ubw[self._iu] = ul, uu
        lbw[self._ixa], ubw[self._ixa] = xal, xau
        lbw[self._iua], ubw[self._iua] = ual, uau
        self._lbw, self._ubw = lbw, ubw

    def _pack(self, x, u, x_a, u_a) -> np.ndarray:
        return np.concatenate([np.asarray(x).ravel(), np.asarray(u).ravel(), x_a, u_a])

    def _unpack(self, w):
        return w[self._ix], w[self._iu], w[self._ixa], w[self._iua]


def make_controller(config: Config | None = None, **options):
    """The controller named by ``config.nmpc.solver``: ``"rti"`` or ``"reference"``.

    ``options`` go to the controller's constructor (e.g. ``max_iter`` for IPOPT).
    """
    config = config or Config()
    if config.nmpc.solver == "reference":
        return TrackingNMPC(config, **options)
    from .rti import RealTimeNMPC

    options.setdefault("max_iter", config.nmpc.sqp_iterations)
    options.setdefault("qp_solver", config.nmpc.qp_solver)
    return RealTimeNMPC(config, **options)


def pack_scan(visible: Sequence[np.ndarray], position, config: Config) -> np.ndarray:
    """Pack a LiDAR scan into the parameter layout of the region slots.

    Parameters
    ----------
    visible : per region, the (k_i, 3) visible points (see :func:`check_visible`); regions
        with none are skipped.
    position : (3,) UAV position, m. If more regions are visible than there are slots
        (``config.nmpc.region_slots``), the nearest regions are kept; if a region shows more
        points than a slot holds (``points_per_region``), the nearest points are kept.
    config : supplies σ (for W and V, computed from the visible points) and the metric.

    Per slot the layout is (points (cap, 3) column-major, ln W (cap,), ln V, active) for the
    smooth metric and (points, mask (cap,), active) for the Euclidean one. Unused point slots
    have ln W = −1e30 (mask 0); an unused region slot holds one dummy point and active = 0.
    """
    sigma, metric = config.distance.sigma, config.distance.metric
    slots, cap = config.nmpc.region_slots, config.nmpc.points_per_region
    ref = _as_vector("position", position, 3)
    seen = [v for v in check_visible(visible) if len(v)]
    sq = [np.sum((v - ref) ** 2, axis=1) for v in seen]
    if len(seen) > slots:
        order = np.argsort([s.min() for s in sq])[:slots]
        seen, sq = [seen[i] for i in order], [sq[i] for i in order]
    blocks = []
    for slot in range(slots):
        pts = np.full((cap, 3), _FAR_AWAY)
        log_w = np.full(cap, PAD_LOG_WEIGHT)
        mask = np.zeros(cap)
        if slot < len(seen):
            cloud = seen[slot]
            weights = dist.CloudWeights.from_cloud(cloud, sigma)
            keep = np.arange(len(cloud))
            if len(cloud) > cap:
                keep = np.sort(np.argsort(sq[slot])[:cap])
            pts[: len(keep)] = cloud[keep]
            log_w[: len(keep)] = weights.log_weights[keep]
            mask[: len(keep)] = 1.0
            log_v, active = weights.log_volume, 1.0
        else:
            log_w[0], mask[0] = 0.0, 1.0
            log_v, active = 0.0, 0.0
        if metric == "smooth":
            blocks.append(np.concatenate([pts.ravel(order="F"), log_w, [log_v, active]]))
        else:
            blocks.append(np.concatenate([pts.ravel(order="F"), mask, [active]]))
    return np.concatenate(blocks)


def check_visible(visible) -> tuple[np.ndarray, ...]:
    """The one accepted form of a LiDAR scan, checked and never reshaped.

    ``visible`` must be a list or tuple with one finite (k_i, 3) array (or nested list) per
    region, k_i ≥ 0. A bare array, even (k, 3), is rejected: iterating over it would make
    every point a region of its own. Returns the regions as float arrays (no copy when they
    already are), in a tuple that later calls recognise as checked, so the check costs a few
    microseconds once per solve. Raises ``ValueError`` naming ``visible[i]``.
    """
    if type(visible) is _CheckedScan:
        return visible
    if not isinstance(visible, (list, tuple)):
        shape = f" of shape {visible.shape}" if isinstance(visible, np.ndarray) else ""
        raise ValueError(f"visible must be a list or tuple with one (k_i, 3) array per region, "
                         f"got {type(visible).__name__}{shape}; wrap one region's points in a "
                         "list: [points]")
    regions = []
    for i, v in enumerate(visible):
        arr = v if type(v) is np.ndarray and v.dtype == np.float64 else _region_array(i, v)
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise ValueError(f"visible[{i}] must be a (k, 3) array of points (k ≥ 0), got "
                             f"shape {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"visible[{i}] must hold finite coordinates only (drop the "
                             "non-finite returns before solving)")
        regions.append(arr)
    return _CheckedScan(regions)


class _CheckedScan(tuple):
    """A scan that :func:`check_visible` has accepted (so it is not checked twice)."""


def _region_array(i: int, value) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"visible[{i}] must be a (k, 3) array of points, got "
                         f"{type(value).__name__}") from None


def region_barrier(metric: str, eta: float, d_min: float, capacity: int):
    """Symbolic parameters of one region slot and β(y) = D(y) − d_min (eq. 17).

    Returns ``(params, beta)``: ``params`` is the slot's parameter column (its last entry is
    the ``active`` flag) and ``beta(y)`` the CasADi expression for a (3, 1) output ``y``.
    """
    pts = ca.SX.sym("points", capacity, 3)
    y = ca.SX.sym("y", 3)
    active = ca.SX.sym("active")
    if metric == "smooth":
        log_w = ca.SX.sym("log_w", capacity)
        log_v = ca.SX.sym("log_v")
        d = dist.smooth_distance_symbolic(y, pts, log_w, log_v, eta)
        extra = [log_w, log_v]
    else:
        mask = ca.SX.sym("mask", capacity)
        d = dist.euclidean_distance_symbolic(y, pts, mask)
        extra = [mask]
    beta_fn = ca.Function("beta", [y, pts, *extra], [d - d_min])
    params = ca.vertcat(ca.vec(pts), *extra, active)
    return params, lambda yy: beta_fn(yy, pts, *extra)


def _softplus_penalty(g, kappa: float, epsilon: float):
    """F = (1/κ)[ln(1 + e^{κg})]^ε (eq. 19), in the overflow-free form of the softplus."""
    z = kappa * g
    softplus = ca.fmax(z, 0) + ca.log1p(ca.exp(-ca.fabs(z)))
    return softplus**epsilon / kappa


def _as_vector(name, value, n):
    arr = np.asarray(value, dtype=float)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite array of shape ({n},), got {arr!r}")
    return arr

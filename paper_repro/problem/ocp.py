"""Problem (21), described once: the description that both solvers read.

The optimal control problem (eq. 21: eq. 7 with the cost of eq. 20)::

    min_{u, x_a, u_a}  Σ_{j<N} ‖x_j − x_a‖²_Q + ‖u_j − u_a‖²_R + ‖y_a − y_t‖²_T
                       + μ Σ_i ( F(g_a,i) + Σ_{j=0}^{N} F(g_j,i) )
    s.t.  x_0 = x,  x_{j+1} = f(x_j, u_j),  (x_j, u_j) ∈ 𝒳 × 𝒰,
          x_a = f(x_a, u_a),  (x_a, u_a) ∈ λ(𝒳 × 𝒰),  x_N = x_a

with y_j = h(x_j), y_a = h(x_a), β = D − d_min (eq. 17) for each region 𝒪_i in view,
g_j = c·β(y_j) − β(y_{j+1}) (eq. 18; c = 1 − δ as printed, or c = δ as in Definition 1, see
:class:`~paper_repro.config.BarrierParams`), y_{N+1} = y_a (the artificial equilibrium is where
the prediction rests, so g_a = c·β(y_a) − β(y_a)), and F = (1/κ)[ln(1 + e^{κg})]^ε (eq. 19).

:class:`OCP` holds every part of it: the model (discrete prediction f, output h, bounds, the
equilibrium parametrisation), the weights, the barrier violation g, the penalty F and its
derivatives, and the layout of the LiDAR scan (:class:`ScanLayout`). As acados keeps
``AcadosOcp`` apart from the solvers that read it, the IPOPT transcription
(:class:`paper_repro.solvers.ipopt.TrackingNMPC`) and the real-time solver
(:class:`paper_repro.solvers.rti.RealTimeNMPC`) both build from an ``OCP`` and write no term of
their own. :class:`NMPCSolution` and the :class:`Controller` protocol are what every solver
returns and offers; :func:`paper_repro.solvers.factory.make_controller` picks one.

Import graph: ``config → vehicles → problem.{distance, scan, ocp} → solvers.{ipopt, rti} →
solvers.factory``.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import casadi as ca
import numpy as np

from paper_repro.config import Config, relaxed_box
from paper_repro.problem.scan import ScanLayout
from paper_repro.vehicles.base import VehicleModel, rk4
from paper_repro.vehicles.quadrotor import quadrotor_model

# --- the problem -------------------------------------------------------------------------------

class OCP:
    """Problem (21) for one vehicle and one configuration.

    Parameters
    ----------
    config : uses its ``distance``, ``barrier`` and ``nmpc`` parts and the LiDAR's range
        ``sensor.range`` (and ``quadrotor`` when ``model`` is omitted); never the solver's
        options (``solver``) or the mission (``simulation``). The weights ``nmpc.q``,
        ``nmpc.r``, ``nmpc.t`` must have n_x, n_u and p entries.
    model : the vehicle (:class:`~paper_repro.vehicles.base.VehicleModel`); the quadrotor of
        ``config`` by default, whose 𝒳 × 𝒰 are ``config.quadrotor``'s boxes.

    Attributes
    ----------
    f : CasADi function x_{j+1} = f(x_j, u_j): RK4 over ``nmpc.prediction_step`` (eq. 1).
    h : CasADi function y = h(x).
    nx, nu, ny : n_x, n_u, p.  horizon : N.
    state_bounds, input_bounds : (lower, upper) of 𝒳 and 𝒰, (n_x,) and (n_u,) arrays.
    equilibrium_bounds : (x_a lower, x_a upper, u_a lower, u_a upper) of λ(𝒳 × 𝒰).
    scan : :class:`ScanLayout`, the LiDAR scan as parameters.
    """

    def __init__(self, config: Config | None = None, model: VehicleModel | None = None):
        self.config = cfg = config or Config()
        self.model = model = model or quadrotor_model(cfg)
        p, b = cfg.nmpc, cfg.barrier
        self.nx, self.nu, self.ny = model.nx, model.nu, model.ny
        for name, n, what in (("q", self.nx, "n_x"), ("r", self.nu, "n_u"),
                              ("t", self.ny, "p")):
            if len(getattr(p, name)) != n:
                raise ValueError(f"nmpc.{name} must have {what} = {n} entries for the "
                                 f"{model.name} model, got {len(getattr(p, name))}")
        self.horizon = p.horizon
        self.f = rk4(model.dynamics, p.prediction_step)
        self.h = model.output
        self._selected = selected_states(model.output)
        self.equilibria = model.equilibria
        self._equilibrium_fn = None  # numeric a -> (x_a, u_a), built on first use
        # never relaxed (see state_box); an index array, cheaper to index with than a list
        self._position_entries = np.array(model.position, dtype=np.intp)
        self._relaxable = np.ones(model.nx, dtype=bool)  # the entries state_box may relax
        self._relaxable[self._position_entries] = False
        self.state_bounds = (np.asarray(model.state_lower, float),
                             np.asarray(model.state_upper, float))
        self.input_bounds = (np.asarray(model.input_lower, float),
                             np.asarray(model.input_upper, float))
        self.equilibrium_bounds = (*relaxed_box(*self.state_bounds, p.lam),
                                   *relaxed_box(*self.input_bounds, p.lam))
        self._sqrt_weights = tuple(np.sqrt(np.asarray(v, float)) for v in (p.q, p.r, p.t))
        self.decay, self.mu = b.decay, b.mu
        self.kappa, self.epsilon = b.kappa, b.epsilon
        d = cfg.distance
        self.scan = ScanLayout(d.metric, d.eta, d.sigma, b.d_min, p.region_slots,
                               p.points_per_region, self.ny, d.window,
                               cfg.sensor.range, p.prediction != "static",
                               b.reaction_time, b.sweep_time, b.moving_d_min,
                               b.equilibrium_lookahead)
        self.step = p.prediction_step
        self.stage_time = p.stage_time  # τ_j = j·h

    # The numbers the compiled linearisation reads at run time, not at build time.

    @property
    def runtime_values(self) -> np.ndarray:
        """θ, the numbers the compiled linearisation reads at run time: √q (n_x), √r (n_u),
        √t (p), μ, κ, the decay c, η, η² and d_min, each as the problem computes it. Another
        weight, μ, κ, δ, η or d_min reuses the same compiled code."""
        s = self.scan
        return np.concatenate([*self._sqrt_weights,
                               [self.mu, self.kappa, self.decay, s.eta, s.eta**2, s.d_min]])

    def with_symbols(self, theta) -> OCP:
        """A copy of this problem whose weights, μ, κ, c, η and d_min are the entries of the
        symbol θ (CasADi SX, laid out as :attr:`runtime_values`): for building expressions."""
        nx, nu, ny = self.nx, self.nu, self.ny
        twin = copy.copy(self)
        twin._sqrt_weights = (theta[:nx], theta[nx:nx + nu], theta[nx + nu:nx + nu + ny])
        twin.mu, twin.kappa, twin.decay, eta, eta_sq, d_min = (
            theta[nx + nu + ny + i] for i in range(6))
        twin.scan = self.scan.with_symbols(eta, eta_sq, d_min)
        return twin

    # Cost terms, as residuals r whose squared norm is the term: the Gauss-Newton solver needs
    # the residual, the IPOPT transcription its square.

    def tracking_residual(self, x, u, x_a, u_a):
        """r_j with ‖r_j‖² = ‖x_j − x_a‖²_Q + ‖u_j − u_a‖²_R (the stage cost of eq. 20)."""
        sq, sr, _ = self._sqrt_weights
        return ca.vertcat(sq * (x - x_a), sr * (u - u_a))

    def offset_residual(self, y_a, y_t):
        """r with ‖r‖² = ‖y_a − y_t‖²_T (the offset cost of eq. 20)."""
        return self._sqrt_weights[2] * (y_a - y_t)

    def violation(self, beta, beta_next):
        """g = c·β(y_j) − β(y_{j+1}) (eq. 18): positive where the CBF condition is violated."""
        return self.decay * beta - beta_next

    def penalty(self, g):
        """F = (1/κ)[ln(1 + e^{κg})]^ε (eq. 19), in the overflow-free form of the softplus."""
        z = self.kappa * g
        softplus = ca.fmax(z, 0) + ca.log1p(ca.exp(-ca.fabs(z)))
        return softplus**self.epsilon / self.kappa

    def penalty_derivatives(self, g):
        """F'(g) and F''(g), in the same overflow-free form (tested against CasADi's AD of
        :meth:`penalty`). The Gauss-Newton model of μ·F(g(v)) is μF''·∇g∇gᵀ, convex because F
        is convex and increasing for ε ≥ 1."""
        z = self.kappa * g
        # sp is clamped away from 0 so that sp^(ε−2) stays finite where it underflows; there
        # σ = 0 as well, so the products are exactly 0.
        sp = ca.fmax(ca.fmax(z, 0) + ca.log1p(ca.exp(-ca.fabs(z))), 1e-300)
        sig = 1.0 / (1.0 + ca.exp(-z))
        sig_c = 1.0 / (1.0 + ca.exp(z))  # 1 − σ without cancellation where σ ≈ 1
        eps = self.epsilon
        d1 = eps * sp ** (eps - 1) * sig
        d2 = self.kappa * eps * ((eps - 1) * sp ** (eps - 2) * sig**2
                                 + sp ** (eps - 1) * sig * sig_c)
        return d1, d2

    def equilibrium_violation(self, beta_a):
        """g_a = c·β(y_a) − β(y_a) = (c − 1)·β(y_a): eq. (18) at the artificial equilibrium,
        where y_{j+1} = y_j = y_a (the term F(y_a) of the cost)."""
        return (self.decay - 1.0) * beta_a

    def violations(self, betas):
        """Every g of one region along the horizon, from β(y_0), …, β(y_N), β(y_a).

        Returns [g_0, …, g_N, g_a]: g_j pairs y_j with y_{j+1} (y_{N+1} = y_a) and g_a = (c − 1)·
        β(y_a) is the term F(y_a) of the cost. The penalty of the region is μ Σ F(g).
        """
        gs = [self.violation(betas[j], betas[j + 1]) for j in range(len(betas) - 1)]
        return gs + [self.equilibrium_violation(betas[-1])]

    def output(self, x) -> np.ndarray:
        """y = h(x) for a numeric state (n_x,): (p,) array, m. A plain index when h selects
        states (the quadrotor's position), as it does on every step of the closed loop."""
        if self._selected is not None:
            return np.asarray(x, float)[self._selected]
        return np.asarray(self.h(x), float).ravel()

    def state_box(self, x0) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper), (n_x,) each: the box the plan x_1..x_N must stay in, from the
        measured state x0 (n_x,). Both solvers read it at every sampling instant.

        While x0 ∈ 𝒳 this is 𝒳 itself (eq. 7, the paper). A measured state outside 𝒳 (a
        disturbance; or the plant overshooting a plan whose step the line search shortened,
        which leaves the model's gaps open, near a collision) would make the hard bounds
        infeasible from then on: a roll rate of 3.1 rad/s against the bound π/2 asks for
        153 rad/s² in one step of 0.01 s where the rotors give at most 110, so every later
        QP fails and the vehicle tumbles. A component that x0 violates by e is therefore
        bounded at 2e beyond its bound instead (room for the one or two steps the state keeps
        moving outwards while it is braked), on every stage of the plan. The relaxation is
        recomputed from every measurement, so it shrinks as the state comes back, and the
        terminal equality x_N = x_a still ends the plan at rest inside λ(𝒳 × 𝒰).

        The position entries (``model.position``: the workspace walls and the ground) stay
        hard. A position moves continuously, so the plan can always keep to them (the
        plant leaves them by rounding only, < 1e-3 m); relaxed, the room compounded (2e, the
        plant follows, 4e, …) and escapes sank 0.18 m below the ground.
        Returns the arrays of :attr:`state_bounds` themselves (not copies) when no entry
        is relaxed.
        """
        lower, upper = self.state_bounds
        x0 = np.asarray(x0, float)
        below, above = (x0 < lower) & self._relaxable, (x0 > upper) & self._relaxable
        if not (below | above).any():
            return lower, upper
        return (np.where(below, 2.0 * x0 - lower, lower),
                np.where(above, 2.0 * x0 - upper, upper))

    # The artificial equilibrium: a parametrisation (x_a, u_a) = E(a), read by both solvers.

    @property
    def na(self) -> int:
        """n_a: the size of a (the parametrisation's, or n_x + n_u for a = (x_a, u_a))."""
        e = self.equilibria
        return e.size if e is not None else self.nx + self.nu

    def equilibrium(self, a):
        """Symbolic (x_a, u_a) of a: (state(a), input(a)), or a split into (x_a, u_a)."""
        e = self.equilibria
        if e is not None:
            return e.state(a), e.input(a)
        return a[:self.nx], a[self.nx:]

    def equilibrium_rows(self, a):
        """The equalities that make (x_a, u_a) an equilibrium: none with a parametrisation
        (it holds by construction), f_c(x_a, u_a) = 0 without.

        f_c = 0 makes every RK4 stage zero, hence x_a = f(x_a, u_a) as eq. (7) asks; the
        rows x_a − f(x_a, u_a) themselves are T_s·f_c + O(T_s²), scaled down by T_s = 0.01 s,
        and the Riccati solver's multiplier passes could not meet them to its tolerance.
        """
        if self.equilibria is not None:
            return ca.SX(0, 1) if isinstance(a, ca.SX) else ca.MX(0, 1)
        x_a, u_a = self.equilibrium(a)
        return self.model.dynamics(x_a, u_a)

    @functools.cached_property
    def equilibrium_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) of a, (n_a,) each: the parametrisation's box, or λ(𝒳 × 𝒰) on
        (x_a, u_a). Found once (a parametrisation's entries by CasADi, about 0.1 ms, which a
        solve whose measured state leaves 𝒳 would otherwise pay again); read-only."""
        e = self.equilibria
        xal, xau, ual, uau = self.equilibrium_bounds
        if e is None:
            box = np.concatenate([xal, ual]), np.concatenate([xau, uau])
        elif e.lower is not None:
            box = np.array(e.lower, float), np.array(e.upper, float)
        else:
            entries = _entries_of(e.state)
            if entries is None:
                raise ValueError(f"equilibria of the {self.model.name} model need lower and "
                                 "upper bounds on a: its a_k are not entries of x_a")
            box = xal[entries], xau[entries]
        for bound in box:
            bound.flags.writeable = False
        return box

    def parameters_of(self, x_a, u_a) -> np.ndarray:
        """a of a numeric artificial equilibrium (x_a, u_a): (n_a,) array."""
        e = self.equilibria
        if e is not None:
            return np.array(e.of_state(x_a), dtype=float)
        return np.concatenate([x_a, u_a]).astype(float)

    def equilibrium_of(self, a) -> tuple[np.ndarray, np.ndarray]:
        """Numeric (x_a (n_x,), u_a (n_u,)) of a (n_a,)."""
        if self.equilibria is None:
            return a[:self.nx].copy(), a[self.nx:].copy()
        if self._equilibrium_fn is None:
            e = self.equilibria
            self._equilibrium_fn = (_numeric(e.state), _numeric(e.input))
        state, input_ = self._equilibrium_fn
        a = np.asarray(a, float)
        return state(a), input_(a)

    # Guesses.

    def rest(self, x0) -> NMPCSolution:
        """The plan that rests where the vehicle is for the whole horizon (the first guess)."""
        x_a, u_a = self.model.rest(x0)
        n = self.horizon
        return NMPCSolution(np.tile(u_a, (n, 1)), np.tile(x_a, (n + 1, 1)), x_a, u_a,
                            True, "guess", 0, 0.0, np.nan)


def selected_states(h: ca.Function) -> np.ndarray | None:
    """The indices i_k with h(x)_k = x_{i_k}, when h only selects states; else ``None``."""
    jac = _constant_jacobian(h)
    if jac is not None and np.all(jac.sum(axis=1) == 1) and not _at_zero(h).any():
        return np.argmax(jac, axis=1)
    return None


def _entries_of(state: ca.Function) -> np.ndarray | None:
    """The indices i_k with state(a)_{i_k} = a_k for every k (a is a selection of x_a's
    entries, the rest constant); else ``None``."""
    jac = _constant_jacobian(state)
    if jac is not None and np.all(jac.sum(axis=0) == 1) and np.all(jac.sum(axis=1) <= 1):
        entries = np.argmax(jac, axis=0)
        if not _at_zero(state)[entries].any():
            return entries
    return None


def _numeric(fn: ca.Function) -> Callable[[np.ndarray], np.ndarray]:
    """fn as a NumPy map v -> (n_out,). A selection plus constants (each output an entry of v
    or a constant, as the quadrotor's x_a(a) and u_a(a)) is gathered by indexing, the same
    numbers as CasADi's to the bit at a fraction of a CasADi call's cost; anything else goes
    through CasADi."""
    jac = _constant_jacobian(fn)
    if jac is not None and np.all(jac.sum(axis=1) <= 1):
        const = _at_zero(fn)
        picked = jac.sum(axis=1) == 1
        if not const[picked].any():
            source = np.argmax(jac, axis=1)

            entries = source[picked]

            def gather(v: np.ndarray) -> np.ndarray:
                out = const.copy()
                out[picked] = v[entries]
                return out
            return gather
    return lambda v: np.asarray(fn(v), float).ravel()


def _at_zero(fn: ca.Function) -> np.ndarray:
    return np.asarray(fn(np.zeros(fn.size1_in(0))), float).ravel()


def _constant_jacobian(fn: ca.Function) -> np.ndarray | None:
    """∂fn/∂v when it is constant with entries 0 and 1 (fn linear, a selection plus constants)."""
    v = ca.SX.sym("v", fn.size1_in(0))
    jac = ca.jacobian(fn(v), v)
    if ca.depends_on(jac, v):
        return None
    jac = np.asarray(ca.evalf(jac))
    return jac if np.all((jac == 0) | (jac == 1)) else None


# --- what every solver returns and offers ------------------------------------------------------

@dataclass
class NMPCSolution:
    """Result of one OCP solve.

    Attributes
    ----------
    u : (N, n_u) planned inputs.  x : (N+1, n_x) predicted states.
    x_a : (n_x,) artificial equilibrium state.  u_a : (n_u,) artificial equilibrium input.
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

    def reanchored(self, x0, position: Sequence[int] = (0, 1, 2)) -> NMPCSolution:
        """The same plan moved rigidly so that it starts at the position of ``x0``.

        ``position`` : the indices of the states that are the position, along which the
        dynamics are invariant (the quadrotor's first three). The OCP is invariant to
        translations of position except through the target, the regions and the workspace
        walls, which move slowly relative to one sampling period. In cruise the optimal plan
        keeps its shape from one instant to the next (accelerate, then stop at x_a within the
        horizon), so moving it, rather than shifting it in time, is the better starting point
        for a single SQP iteration.
        """
        idx = list(position)
        d = np.zeros_like(self.x_a)
        d[idx] = np.asarray(x0, float)[idx] - self.x[0, idx]
        return NMPCSolution(self.u.copy(), self.x + d, self.x_a + d, self.u_a.copy(),
                            self.success, self.status, 0, 0.0, self.cost)


class Controller(Protocol):
    """What the closed loop needs of a solver of problem (21)."""

    ocp: OCP
    horizon: int

    def solve(self, x0, target, visible: Sequence[np.ndarray] = (),
              previous: NMPCSolution | None = None, velocities=None) -> NMPCSolution:
        """Solve from state ``x0`` (n_x,) towards output set-point ``target`` (p,), m, with the
        LiDAR scan ``visible`` (see :func:`check_visible`); ``previous`` warm-starts;
        ``velocities`` (moving regions): one predicted (p,) velocity per region, m/s."""

    def reset(self) -> None:
        """Forget what is carried from one solve to the next (a new flight starts clean)."""

    def hover_guess(self, x0) -> NMPCSolution:
        """The plan that rests where the vehicle is (the guess without a previous plan)."""

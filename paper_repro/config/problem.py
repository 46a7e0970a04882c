"""The problem's data: the quadrotor of Table I, the distance, the barrier, the NMPC, and how
the solver solves it at each instant."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from paper_repro.validation import (
    is_number,
    require_choice,
    require_int,
    require_ordered,
    require_positive,
    require_vector,
)


def _diag(*values: float) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


@dataclass(frozen=True)
class QuadrotorParams:
    """UFMG/ProVANT quadrotor of Table I (SI units).

    Attributes
    ----------
    mass : kg, *paper* m = 2.24.
    arm : m, *paper* h = 0.332, distance from the centre of mass to each rotor.
    gravity : m/s², *paper* g = 9.81.
    thrust_coefficient : N·s², *paper* b = 9.5e-6.
    drag_coefficient : N·m·s², *paper* k_τ = 1.7e-7; the yaw torque of a rotor is
        (k_τ / b)·f_i.
    inertia : (Ixx, Iyy, Izz) in kg·m², *paper* (0.0363, 0.0363, 0.0615).
    state_lower, state_upper : (12,) the box 𝒳 of eq. (7), *paper*: position (m), Euler
        angles (rad), velocities (m/s), Euler-angle rates (rad/s). The position's box is the
        workspace.
    input_lower, input_upper : (4,) the box 𝒰 of the rotor thrusts, N, *paper* 0 ≤ f_i ≤ 12.
    """

    mass: float = 2.24
    arm: float = 0.332
    gravity: float = 9.81
    thrust_coefficient: float = 9.5e-6
    drag_coefficient: float = 1.7e-7
    inertia: tuple[float, float, float] = (0.0363, 0.0363, 0.0615)
    state_lower: tuple[float, ...] = _diag(
        -25, -25, 0, -math.pi / 6, -math.pi / 6, -math.pi, -5, -5, -3,
        -math.pi / 2, -math.pi / 2, -math.pi / 2,
    )
    state_upper: tuple[float, ...] = _diag(
        25, 25, 25, math.pi / 6, math.pi / 6, math.pi, 5, 5, 3,
        math.pi / 2, math.pi / 2, math.pi / 2,
    )
    input_lower: tuple[float, ...] = _diag(0, 0, 0, 0)
    input_upper: tuple[float, ...] = _diag(12, 12, 12, 12)

    def __post_init__(self):
        for name in ("mass", "arm", "gravity", "thrust_coefficient", "drag_coefficient"):
            require_positive(name, getattr(self, name))
        if not (isinstance(self.inertia, (tuple, list)) and len(self.inertia) == 3 and all(
                is_number(i) and math.isfinite(i) and i > 0 for i in self.inertia)):
            raise ValueError(
                f"inertia must be three finite values > 0 (kg·m²), got {self.inertia!r}")
        for name, n in (("state_lower", 12), ("state_upper", 12), ("input_lower", 4),
                        ("input_upper", 4)):
            require_vector(name, getattr(self, name), n)
        # 𝒳 and 𝒰 must be boxes with interior (lower < upper, per index), or the first QP
        # is infeasible and HPIPM fails without saying why.
        require_ordered("state_lower", self.state_lower, "state_upper", self.state_upper)
        require_ordered("input_lower", self.input_lower, "input_upper", self.input_upper)

    def relaxed_bounds(self, lam: float) -> tuple[np.ndarray, ...]:
        """λ(𝒳 × 𝒰) of this box (:func:`relaxed_box`), ``lam`` the λ of ``nmpc.lam``: x lower,
        x upper, u lower, u upper."""
        return (*relaxed_box(self.state_lower, self.state_upper, lam),
                *relaxed_box(self.input_lower, self.input_upper, lam))

    @property
    def yaw_torque_ratio(self) -> float:
        """k_τ / b in m: yaw reaction torque per newton of rotor thrust."""
        return self.drag_coefficient / self.thrust_coefficient

    @property
    def hover_thrust(self) -> float:
        """Thrust of each rotor at hover, N (m·g/4)."""
        return self.mass * self.gravity / 4.0


@dataclass(frozen=True)
class DistanceParams:
    """Smoothed point-to-cloud distance, eq. (8)-(11).

    Attributes
    ----------
    eta : η, m, *paper* 0.3. Smoothing length; D → ½·d² as η → 0.
    sigma : σ, m, *paper* 0.8. Regularisation scale of the weights W_σ, eq. (9).
    metric : ``"smooth"`` (D_{η,σ}) or ``"euclidean"`` (½·min_j‖y − a_j‖², the baseline).
    window : w, m, *chosen* 0 (off: the paper's hard cut-off at r_s). Width of the smooth
        sensing window (:func:`paper_repro.problem.distance.sensing_window`): a visible point at
        range
        r counts with weight ψ(r), 1 inside r_s − w, 0 at r_s, C∞ in between, in the
        centroid, W and V of the smooth metric. A point then enters and leaves D continuously
        as it crosses the LiDAR sphere. Must be < r_s (``sensor.range``); the
        smooth metric only.
    """

    eta: float = 0.3
    sigma: float = 0.8
    metric: str = "smooth"
    window: float = 0.0

    def __post_init__(self):
        require_positive("eta", self.eta)
        require_positive("sigma", self.sigma)
        require_choice("metric", self.metric, ("smooth", "euclidean"))
        if not (is_number(self.window) and math.isfinite(self.window) and self.window >= 0):
            raise ValueError(f"window must be a finite number >= 0 (m; 0 is off), got "
                             f"{self.window!r}")


@dataclass(frozen=True)
class BarrierParams:
    """Discrete CBF penalty, eq. (16)-(20).

    Attributes
    ----------
    delta : δ ∈ (0, 1), *paper* 0.95.
    d_min : m², *chosen* 1.0. Safety margin on D (β = D − d_min). D is half a squared
        distance, so d_min = 1.0 m² asks for about √2 ≈ 1.41 m from the smoothed cloud.
        The literal ½r² = 0.125 m² for r = 0.5 m gives a safe set that reaches into the
        clouds, because D stays near 0.2 m² even inside a sampled region.
    kappa : κ > 0, 1/m², *chosen* 10. Sharpness of the softplus in eq. (19): the penalty
        is within ln 2 / κ ≈ 0.07 m² of max(0, g).
    epsilon : ε ≥ 1, *chosen* 2. Curvature exponent of eq. (19); ε < 1 gives infinite
        (NaN) gradients where the penalty vanishes, so it is rejected.
    mu : μ, *paper* 5e4. Penalty weight.
    form : ``"printed"`` uses g = (1 − δ)·β_j − β_{j+1} exactly as eq. (18) is printed;
        ``"definition"`` uses g = δ·β_j − β_{j+1}, the form that matches Definition 1
        (β_{k+1} ≥ δ·β_k). The two differ: with δ = 0.95 the printed form lets β decay
        by at most 95 % per step, the definition form by at most 5 %.
    reaction_time : t_r, s, *chosen* 0 (off: the paper). For a region predicted to move
        (``nmpc.prediction`` ``"oracle"`` or ``"kalman"``) at velocity v, the safe distance
        √(2·d_min) grows by ‖v‖·t_r, the way the region covers in t_r: β = D −
        ½(√(2·d_min) + ‖v‖·t_r)². The CBF then starts the escape while the region is further
        off, in proportion to its speed, where the 0.35 s prediction alone sees it too late.
        A region at rest, and every region under the paper's static prediction, keeps
        β = D − d_min.
    sweep_time : t_s, s, *chosen* 0 (off: the paper). A region predicted to move at v is
        replaced, at every τ of the horizon, by the path it sweeps over the next t_s seconds:
        the union of its cloud moved by v·(τ + s) for s ∈ {0, t_s/4, …, t_s}
        (:data:`~paper_repro.problem.scan.SWEEP_SAMPLES` copies; the Euclidean metric takes
        their exact minimum, the smoothed one their soft minimum with the copies ahead
        ramping in with the speed, as ``moving_d_min`` does). The safe set then excludes where the
        region is going, in its direction of motion only, so the escape starts while the
        region is still t_s seconds away, and a region passing sideways costs no margin
        beside it. The swept D is never above the region's own, and equals it at rest.
    moving_d_min : m², *chosen* 0 (off: the paper). The margin of a region predicted to move:
        d_min rises smoothly to ``moving_d_min`` as the region's predicted speed goes from
        0.1 to 0.3 m/s (:data:`~paper_repro.problem.scan.MOVING_SPEEDS`; a smoothstep, so
        that a Kalman estimate jittering about a region at rest does not switch it). 0 keeps
        d_min for every region; 3 m² keeps a moving region √6 = 2.45 m away, within the 3 m
        the LiDAR sees.
    equilibrium_lookahead : t_a, s, *chosen* 0 (off: the paper). β at the artificial
        equilibrium y_a (the point y_{N+1} the prediction rests at, in g_N and g_a of eq. 18)
        is taken against the path a region predicted to move sweeps over the t_a seconds
        after the horizon, as ``sweep_time`` does for every stage. The horizon is 0.35 s, but
        the equilibrium is where the vehicle would stay: this asks it to be clear of where
        the region is going, so the prediction leaves the region's path seconds before the
        region arrives. In [0, 10].
    """

    delta: float = 0.95
    d_min: float = 1.0
    kappa: float = 10.0
    epsilon: float = 2.0
    mu: float = 5e4
    form: str = "printed"
    reaction_time: float = 0.0
    sweep_time: float = 0.0
    moving_d_min: float = 0.0
    equilibrium_lookahead: float = 0.0

    def __post_init__(self):
        if not (is_number(self.delta) and 0.0 < self.delta < 1.0):
            raise ValueError(f"delta must lie in (0, 1), got {self.delta!r}")
        require_positive("d_min", self.d_min)
        require_positive("kappa", self.kappa)
        require_positive("mu", self.mu)
        if not (is_number(self.epsilon) and math.isfinite(self.epsilon)
                and self.epsilon >= 1.0):
            raise ValueError(
                f"epsilon must be a finite value >= 1 (ε < 1 has unbounded gradients "
                f"where the penalty is zero), got {self.epsilon!r}"
            )
        require_choice("form", self.form, ("printed", "definition"))
        for name, high in (("reaction_time", math.inf), ("sweep_time", 5.0),
                           ("equilibrium_lookahead", 10.0)):
            value = getattr(self, name)
            if not (is_number(value) and math.isfinite(value) and 0 <= value <= high):
                raise ValueError(f"{name} must be a finite number in [0, {high:g}"
                                 f"{']' if high < math.inf else ')'} (s; 0 is off), got {value!r}")
        if not (is_number(self.moving_d_min) and math.isfinite(self.moving_d_min)
                and (self.moving_d_min == 0 or self.moving_d_min >= self.d_min)):
            raise ValueError(f"moving_d_min must be 0 (off) or a finite number >= d_min = "
                             f"{self.d_min} (m²), got {self.moving_d_min!r}")

    @property
    def decay(self) -> float:
        """Factor c in g = c·β_j − β_{j+1}: 1 − δ (printed) or δ (definition)."""
        return 1.0 - self.delta if self.form == "printed" else self.delta


PREDICTIONS = ("static", "oracle", "kalman")
"""How the problem predicts the regions it sees (``NMPCParams.prediction``)."""


@dataclass(frozen=True)
class NMPCParams:
    """Tracking NMPC of eq. (7) and (21), Section V.

    Attributes
    ----------
    horizon : N, *paper* 35.
    ts : T_s, s, *paper* 0.01. Sampling period of the controller and the plant.
    prediction_ts : s, *chosen* ``None`` (= ``ts``, as the paper). Step of the prediction
        model (eq. 1) in both solvers, when it should differ from the sampling period: the
        prediction then spans N·prediction_ts, and the terminal constraint x_N = x_a asks the
        UAV to be at rest at the artificial equilibrium after that time rather than N·T_s.
        See :mod:`paper_repro.analysis.clock` for why this sets the mission's clock.
    q, r, t : diagonals of Q (12), R (4), T (3), *paper*. Another vehicle
        (:class:`~paper_repro.vehicles.base.VehicleModel`) needs n_x, n_u and p entries; the
        :class:`~paper_repro.problem.ocp.OCP` checks them against its model.
    lam : λ ∈ (0, 1), *chosen* 0.99. The artificial equilibrium lies in λ(𝒳 × 𝒰),
        i.e. 25 cm inside the 25 m workspace walls; the relaxation only needs to keep
        (x_a, u_a) off the boundary (Limon et al. 2018), and the paper's targets sit at
        z = 0, which is the boundary itself (see ``relaxed_bounds``).
    prediction : how the problem predicts the regions it sees, ``"static"`` (*paper*: every
        region stays where it is seen, and the solver is called exactly as without moving
        regions), ``"oracle"`` (each region moves on at its true velocity, from the scene's
        motions) or ``"kalman"`` (at the velocity estimated from the scans by
        :class:`paper_repro.world.tracking.RegionTracker`). Only scenes with moving regions tell
        them apart. With ``"oracle"`` or ``"kalman"`` the problem carries each region's
        velocity among its parameters.
    region_slots : number of LiDAR-visible regions the NLP can hold at once.
    points_per_region : capacity of each region slot; scans with more visible points are
        reduced to the nearest ones (see ``paper_repro.solvers.ipopt``).
    """

    horizon: int = 35
    ts: float = 0.01
    prediction_ts: float | None = None
    q: tuple[float, ...] = _diag(1, 1, 1, 0.1, 0.1, 1, 1, 1, 1, 10, 10, 1)
    r: tuple[float, ...] = _diag(3, 3, 3, 3)
    t: tuple[float, ...] = _diag(1000, 1000, 1000)
    lam: float = 0.99
    prediction: str = "static"
    region_slots: int = 2
    points_per_region: int = 120

    def __post_init__(self):
        require_int("horizon", self.horizon, 1)
        require_positive("ts", self.ts)
        if self.prediction_ts is not None:
            require_positive("prediction_ts", self.prediction_ts)
        for name in ("q", "r", "t"):  # their length is the model's (checked by the OCP)
            require_vector(name, getattr(self, name), None)
        if any(x < 0 for x in self.q):
            raise ValueError(f"q must be >= 0 (Q ⪰ 0), got {self.q!r}")
        for name in ("r", "t"):
            if any(x <= 0 for x in getattr(self, name)):
                raise ValueError(f"{name} must be > 0 ({name.upper()} ≻ 0), got "
                                 f"{getattr(self, name)!r}")
        if not (is_number(self.lam) and 0.0 < self.lam < 1.0):
            raise ValueError(f"lam must lie in (0, 1), got {self.lam!r}")
        require_choice("prediction", self.prediction, PREDICTIONS)
        for name in ("region_slots", "points_per_region"):
            require_int(name, getattr(self, name), 1)

    @property
    def prediction_step(self) -> float:
        """Step of the prediction model in s: ``prediction_ts``, or ``ts`` when it is None."""
        return self.ts if self.prediction_ts is None else float(self.prediction_ts)

    def stage_time(self, j):
        """τ_j = j·h, s: the time of stage j of the prediction after the scan, ``j`` an int or
        an array of them. A region seen moving at v is predicted v·τ_j from where it was seen
        (y_{N+1} = y_a is stage N + 1). Every solver and figure reads it from here."""
        return j * self.prediction_step


def relaxed_box(lower, upper, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """The box [lower, upper] shrunk by λ about its centre: λ(𝒳 × 𝒰) of eq. (7).

    For a symmetric box this is exactly λ·𝒳; for the z bound [0, 25] and the input bound
    [0, 12] it keeps the scaling about the centre so that the relaxed set stays inside the
    original one.
    """
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    return mid - lam * half, mid + lam * half


COLD_STARTS = ("rti", "converged")
"""How the ``rti`` solver's first solve of a flight iterates (``SolverParams.cold_start``)."""

QP_SOLVERS = ("riccati", "riccati-ipm", "hpipm")
"""The QP chains of the ``rti`` solver (``SolverParams.qp_solver``,
:class:`paper_repro.solvers.rti.QPChain`)."""


@dataclass(frozen=True)
class SolverParams:
    """How problem (21) is solved at each sampling instant: options of the solvers, not data of
    the problem (as acados keeps its solver options apart from the OCP).

    Attributes
    ----------
    nlp_solver : ``"rti"`` (default, Gauss-Newton SQP with a Riccati QP,
        :mod:`paper_repro.solvers.rti`) or ``"reference"`` (IPOPT with the exact Hessian,
        :mod:`paper_repro.solvers.ipopt`, as the paper).
    sqp_iterations : SQP iterations per sampling instant of the ``rti`` solver (1 is the
        real-time iteration).
    line_search : *chosen* ``False``: the ``rti`` solver takes every full Gauss-Newton step, the
        textbook real-time iteration. ``True`` is the *damped RTI*
        (:class:`~paper_repro.solvers.line_search.MeritLineSearch`): steps are shortened on the
        ℓ1 merit function and the next instants' QPs get a Levenberg–Marquardt term. It is
        smoother than the paper's controller, not a faster way to the same one: with the
        Euclidean metric it removes most of the chattering the paper reports (Fig. 8), so it is
        not the default. It is the remedy where a region moves at the vehicle, where full steps
        fall into a period-2 oscillation that IPOPT does not show (``benchmarks/fidelity.py``).
    qp_solver : QP solver of the ``rti`` solver: ``"riccati-ipm"`` (default: a Riccati
        recursion warm-started with the previous active set (:mod:`~paper_repro.solvers.riccati_qp`)
        within a few factorisations (:data:`paper_repro.solvers.rti.IPM_ACTIVE_SET_BUDGET`),
        then an interior point on the same kernels, polished by the first; HPIPM last),
        ``"riccati"`` (the active set without a budget, HPIPM as its fallback, whose 5-15 ms
        calls break T_s where the set changes by dozens of bounds at once: a chattering
        Euclidean passage, a region crossing the horizon) or ``"hpipm"`` (HPIPM for every QP).
    cold_start : ``"converged"`` (default): the ``rti`` solver's first solve of a flight
        iterates the damped SQP to convergence, so that the flight starts from a solution of
        (21), as the reference does (:class:`~paper_repro.solvers.rti.RealTimeNMPC`).
        ``"rti"``: it takes ``sqp_iterations`` steps from rest, like every instant; from the
        hover guess one full step can settle on a worse local plan.
    shared_barrier : ``True``: the ``rti`` solver's compiled linearisation evaluates the
        barrier once for all stages, and each stage reads its value and gradient: about a
        third of the C to compile (15 s rather than 55 s at the default capacity), the same
        QP to rounding (1e-24 relative), and a call about a fifth cheaper. ``True`` is the
        default. ``False``: the barrier is written out in each stage.
    relaxed_qp : ``True``: a QP of the ``rti`` solver that no QP method solves (an infeasible
        linearisation: a state that cannot be brought back inside 𝒳, a plan that cannot end
        at rest within the horizon) is solved with soft state bounds and terminal rows
        (:mod:`~paper_repro.solvers.relaxed_qp`), and its step is taken; the default.
        ``False``: the solve fails and the closed loop applies the previous plan.
    """

    nlp_solver: str = "rti"
    sqp_iterations: int = 1
    line_search: bool = False
    qp_solver: str = "riccati-ipm"
    cold_start: str = "converged"
    relaxed_qp: bool = True
    shared_barrier: bool = True

    def __post_init__(self):
        require_choice("nlp_solver", self.nlp_solver, ("rti", "reference"))
        require_choice("qp_solver", self.qp_solver, QP_SOLVERS)
        require_choice("cold_start", self.cold_start, COLD_STARTS)
        for name in ("line_search", "relaxed_qp", "shared_barrier"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        require_int("sqp_iterations", self.sqp_iterations, 1)

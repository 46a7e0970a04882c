"""Every default parameter of the reproduction, in one place.

All settings are frozen dataclasses; make variants with :func:`dataclasses.replace`.
Values printed in the paper (Section V) are marked *paper*; values the paper leaves
open are marked *chosen* and justified here and in ``environment.md``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from paper_repro.config_history import moved_settings, with_added, without_added
from paper_repro.validation import (
    is_number,
    require_choice,
    require_int,
    require_ordered,
    require_positive,
    require_range,
    require_vector,
)


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
    """

    mass: float = 2.24
    arm: float = 0.332
    gravity: float = 9.81
    thrust_coefficient: float = 9.5e-6
    drag_coefficient: float = 1.7e-7
    inertia: tuple[float, float, float] = (0.0363, 0.0363, 0.0615)

    def __post_init__(self):
        for name in ("mass", "arm", "gravity", "thrust_coefficient", "drag_coefficient"):
            require_positive(name, getattr(self, name))
        if not (isinstance(self.inertia, (tuple, list)) and len(self.inertia) == 3 and all(
                is_number(i) and math.isfinite(i) and i > 0 for i in self.inertia)):
            raise ValueError(
                f"inertia must be three finite values > 0 (kg·m²), got {self.inertia!r}")

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


def _diag(*values: float) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


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
    state_lower, state_upper : (12,) bounds of the quadrotor's 𝒳, *paper*; position, Euler
        angles (rad), velocities (m/s), Euler-angle rates (rad/s). Another vehicle carries its
        own bounds.
    input_lower, input_upper : (4,) bounds of the quadrotor's 𝒰 in N, *paper* 0 ≤ f_i ≤ 12.
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
    lam: float = 0.99
    prediction: str = "static"
    region_slots: int = 2
    points_per_region: int = 120

    def __post_init__(self):
        require_int("horizon", self.horizon, 1)
        require_positive("ts", self.ts)
        if self.prediction_ts is not None:
            require_positive("prediction_ts", self.prediction_ts)
        for name, n in (("state_lower", 12), ("state_upper", 12), ("input_lower", 4),
                        ("input_upper", 4)):
            require_vector(name, getattr(self, name), n)
        for name in ("q", "r", "t"):  # their length is the model's (checked by the OCP)
            require_vector(name, getattr(self, name), None)
        # Cross-field: 𝒳 and 𝒰 must be boxes with interior (lower < upper, per index), or
        # the first QP is infeasible and HPIPM fails without saying why.
        require_ordered("state_lower", self.state_lower, "state_upper", self.state_upper)
        require_ordered("input_lower", self.input_lower, "input_upper", self.input_upper)
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

    def relaxed_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """λ(𝒳 × 𝒰) of the quadrotor's box (see :func:`relaxed_box`): x lower, x upper, u
        lower, u upper."""
        return (*relaxed_box(self.state_lower, self.state_upper, self.lam),
                *relaxed_box(self.input_lower, self.input_upper, self.lam))


def relaxed_box(lower, upper, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """The box [lower, upper] shrunk by λ about its centre: λ(𝒳 × 𝒰) of eq. (7).

    For a symmetric box this is exactly λ·𝒳; for the z bound [0, 25] and the input bound
    [0, 12] it keeps the scaling about the centre so that the relaxed set stays inside the
    original one.
    """
    lo, hi = np.asarray(lower, float), np.asarray(upper, float)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    return mid - lam * half, mid + lam * half


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
    line_search : *chosen* ``False``: the ``rti`` solver takes every full Gauss-Newton step,
        the textbook real-time iteration. ``True`` is the *damped RTI*
        (:class:`~paper_repro.solvers.rti.MeritLineSearch`): steps are shortened on the ℓ1 merit
        function and the next instants' QPs get a Levenberg–Marquardt term. It is smoother
        than the paper's controller, not a faster way to the same one: with the Euclidean
        metric it removes most of the chattering the paper reports (Fig. 8), so it is not the
        default. It is the remedy where a region moves at the vehicle, where full steps fall
        into a period-2 oscillation that IPOPT does not show (``benchmarks/fidelity.py``).
    qp_solver : QP solver of the ``rti`` solver: ``"riccati-ipm"`` (default: a Riccati
        recursion warm-started with the previous active set (:mod:`~paper_repro.solvers.riccati_qp`)
        within a few factorisations (:data:`paper_repro.solvers.rti.IPM_ACTIVE_SET_BUDGET`),
        then an interior point on the same kernels, polished by the first; HPIPM last),
        ``"riccati"`` (the active set without a budget, HPIPM as its fallback, whose 5-15 ms
        calls break T_s where the set changes by dozens of bounds at once: a chattering
        Euclidean passage, a region crossing the horizon) or ``"hpipm"`` (HPIPM for every QP).
    """

    nlp_solver: str = "rti"
    sqp_iterations: int = 1
    line_search: bool = False
    qp_solver: str = "riccati-ipm"

    def __post_init__(self):
        require_choice("nlp_solver", self.nlp_solver, ("rti", "reference"))
        require_choice("qp_solver", self.qp_solver, QP_SOLVERS)
        if not isinstance(self.line_search, bool):
            raise ValueError(f"line_search must be True or False, got {self.line_search!r}")
        require_int("sqp_iterations", self.sqp_iterations, 1)


@dataclass(frozen=True)
class SimulationParams:
    """The mission a closed loop flies: the scene, when it ends, and how its end is judged.

    Attributes
    ----------
    scenario : scene name (``"paper"``, ``"encounter"``, ``"random"``, or with moving
        regions ``"crossing"``, ``"oncoming"``, ``"random-crossing"``, see
        :func:`paper_repro.world.scenarios.make_scene`).
    kind : ``"mission"`` (reach every target in turn, as the paper) or ``"passage"`` (the run
        ends when the UAV crosses the scene's finish line, 2 m past the obstacle field of a
        random scene; needs a scene with a ``finish``).
    tolerance : m, *paper* 0.3. A target counts as reached when the UAV is closer than this.
    max_steps : upper bound on closed-loop steps (one step is T_s).
    seed : seed of the scene: the Halton point clouds (region i uses ``seed + i``) and, for
        ``"random"``, the layout.
    stall_speed, stall_time, stall_distance : m/s, s, m, *chosen* 0.01, 5, 2. The NMPC is
        local and can deadlock in front of a cloud: the run is *stalled*, and ends, when the
        speed stays below ``stall_speed`` for more than ``stall_time`` while the UAV is more
        than ``stall_distance`` from its target. Under the printed weights the speed of a
        free approach is about (distance to target)/150 s, i.e. 1 cm/s at 1.5 m, so a
        threshold of 1 m would flag every normal final approach; 2 m leaves a third above it.
    approach_time : s, *chosen* 150 (the printed set-up's lateral time constant). The pace a
        ``"random-crossing"`` scene times its crossings to (``RandomSceneParams``): a faster
        controller needs them sooner, or it passes first. Other scenes refuse another value.
    fault_steps : *chosen* 100 (1 s). A step whose measured state is not finite, or whose
        solve cannot start, is a *fault*: it is recorded and the previous plan is applied
        (shifted, as after a failed solve). After more than ``fault_steps`` faults in a row
        the run ends with the outcome ``"fault"``; the previous plan ends at rest at its
        artificial equilibrium, so holding it for a second is safe.
    """

    scenario: str = "paper"
    kind: str = "mission"
    tolerance: float = 0.3
    max_steps: int = 200_000
    seed: int = 7
    stall_speed: float = 0.01
    stall_time: float = 5.0
    stall_distance: float = 2.0
    fault_steps: int = 100
    approach_time: float = 150.0

    def __post_init__(self):
        require_choice("kind", self.kind, ("mission", "passage"))
        require_positive("tolerance", self.tolerance)
        for name in ("stall_speed", "stall_time", "stall_distance"):
            require_positive(name, getattr(self, name))
        if not (isinstance(self.scenario, str) and self.scenario):
            raise ValueError(f"scenario must be a scene name (a non-empty str), got "
                             f"{self.scenario!r}")
        require_int("max_steps", self.max_steps, 1)
        require_int("seed", self.seed, 0)
        require_int("fault_steps", self.fault_steps, 1)
        if not (is_number(self.approach_time) and 0 < self.approach_time <= 10_000 and (
                self.approach_time == 150.0 or self.scenario == "random-crossing")):
            raise ValueError(f"approach_time must be a number in (0, 10000] s, and 150 unless "
                             f"scenario is 'random-crossing', got {self.approach_time!r} for "
                             f"{self.scenario!r}")


@dataclass(frozen=True)
class SensorParams:
    """The virtual LiDAR (:class:`paper_repro.world.lidar.Lidar`): its range and, for studies,
    its imperfections.

    The defaults are a perfect sensor, as in the paper: every point within r_s is returned
    exactly, and nothing else. Noise is drawn from a generator seeded with ``seed``, so a
    flight is reproducible.

    Attributes
    ----------
    range : r_s, m, *paper* 3. The detection radius: a point is seen when it lies within r_s
        of the UAV. The problem reads it too, as the edge of the smooth sensing window
        (``distance.window``).
    range_noise : m, *chosen* 0. Standard deviation of Gaussian noise on the measured range,
        along the ray from the sensor to the point (the direction is exact).
    dropout : probability in [0, 1) that a point within range is not returned, *chosen* 0.
    spurious_rate : expected number of spurious returns per scan (Poisson), *chosen* 0; each
        lies uniformly inside the sensing sphere and is attributed to the region whose cloud
        holds the point nearest to it.
    seed : seed of the sensor's noise generator, an integer >= 0.
    map_voxel : m, *chosen* 0 (off: the controller reads the raw scan, as in the paper). With
        a voxel side > 0, the scans build a :class:`~paper_repro.world.local_map.VoxelMap`
        and the controller reads the map's points within r_s instead: what was seen
        persists, and noise averages down. Regions predicted to move (speed above
        ``MAPPED_SPEED``) stay out of the map and are read from the raw scan. In (0, r_s).
    """

    range: float = 3.0
    range_noise: float = 0.0
    dropout: float = 0.0
    spurious_rate: float = 0.0
    seed: int = 0
    map_voxel: float = 0.0

    def __post_init__(self):
        require_positive("range", self.range)
        for name in ("range_noise", "spurious_rate"):
            v = getattr(self, name)
            if not (is_number(v) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        require_range("dropout", self.dropout, 0.0, 1.0)
        require_int("seed", self.seed, 0)
        if not (is_number(self.map_voxel) and 0 <= self.map_voxel < self.range):
            raise ValueError(f"map_voxel must be 0 (off) or a voxel side in (0, range = "
                             f"{self.range}) m, got {self.map_voxel!r}")

    @property
    def perfect(self) -> bool:
        """True when the sensor adds no noise, drops nothing and invents nothing."""
        return self.range_noise == 0 and self.dropout == 0 and self.spurious_rate == 0


@dataclass(frozen=True)
class TrackerParams:
    """The region tracker of ``nmpc.prediction = "kalman"``
    (:class:`paper_repro.world.tracking.RegionTracker`): one constant-velocity Kalman filter
    per region, on the centroid of its visible points.

    Attributes
    ----------
    accel_noise : σ_a > 0, m/s², *chosen* 3. The white-acceleration process noise of the
        constant-velocity model. With the measurement noise r it sets the filter's bandwidth,
        ω ≈ √(σ_a / r) = 12 rad/s (a velocity time constant ≈ √2/ω ≈ 0.12 s). The studies'
        obstacles move at 0.5–1.5 m/s, at constant velocity or piecewise-linearly, so the
        filter must follow a sudden change of velocity (a corner of the path) within a
        horizon (0.35 s) or so: it is within 10 % after 0.2–0.45 s, the longest for a
        reversal from 1.5 to −1.5 m/s (σ_a = 2 takes 0.68 s there). Its steady-state velocity
        standard deviation under white centroid noise r, (√2·q^¾·(r²T_s)^¼)^½ ≈ 0.1 m/s,
        moves the predicted obstacle by ≈ 3.5 cm over the horizon; a larger σ_a (4: 0.13
        m/s) also lets more of the visible-subset drift through.
    centroid_noise : r > 0, m, *chosen* 0.02. Standard deviation of the visible centroid as a
        measurement of the region's position, per axis, when the visible subset is unchanged.
        A perfect LiDAR on a rigid region gives the exact centroid; 2 cm covers range noise of
        the order of 5 cm averaged over the tens of points of a region's view (σ/√k). Subset
        changes are handled apart (module docstring). r sets the bandwidth with σ_a: a
        smaller r at the same ratio σ_a/r reads a growing subset better (its step variance
        then dominates r²: 0.01 m/s of error instead of 0.09 at r = 5 mm, σ_a = 0.75) but
        lets any noise of the sensor into the velocity, and the gate, which scales with r,
        then holds back real changes of velocity (a 90° corner at 1 m/s takes 0.85 s).
    forget_after : > 0, s, *chosen* 1. A region unseen this long is forgotten (velocity zero);
        when it comes back it starts afresh. Short gaps (a region flickering at the range's
        edge, lost scans) are bridged by prediction; after 1 s (about three horizons) the
        velocity's own uncertainty has grown by σ_a·√(T_s·1 s) ≈ 0.3 m/s, a fifth to a half of
        the obstacles' speed, and a stale velocity applied to a region that comes back is
        worse than starting from rest.
    velocity_prior : > 0, m/s, *chosen* 2. Standard deviation of the velocity at first sight
        (zero mean): above the fastest obstacle of the studies (1.5 m/s), so that the second
        sight sets the velocity from the difference of the centroids, weighted: a third of
        the raw difference over one period, which with r = 2 cm is worth 2.8 m/s of noise,
        and the next scans complete it. Finite, so that a subset jump between the first two
        sights (typically the largest: one point, then two) is not read as a velocity of tens
        of m/s.
    gate_probability : in (0, 1), *chosen* 0.999, or ``None`` (no gate). The innovation gate
        (chi-square, ``dim`` degrees of freedom; 16.3 for dim = 3): a scan beyond it is
        softened onto it, not rejected.
    subset_jump : ≥ 0, *chosen* 2 (0 turns the mitigation off). Scale of the position
        variance added when the number of visible points changes, in RMS radii of the visible
        set (module docstring).
    """

    accel_noise: float = 3.0
    centroid_noise: float = 0.02
    forget_after: float = 1.0
    velocity_prior: float = 2.0
    gate_probability: float | None = 0.999
    subset_jump: float = 2.0

    def __post_init__(self):
        for name in ("accel_noise", "centroid_noise", "forget_after", "velocity_prior"):
            require_positive(name, getattr(self, name))
        p = self.gate_probability
        if p is not None and not (is_number(p) and 0.0 < p < 1.0):
            raise ValueError(f"gate_probability must lie in (0, 1), or be None (no gate), got "
                             f"{p!r}")
        if not (is_number(self.subset_jump) and math.isfinite(self.subset_jump)
                and self.subset_jump >= 0):
            raise ValueError(f"subset_jump must be a finite number >= 0 (0 is off), got "
                             f"{self.subset_jump!r}")


GUIDES = ("none", "grid")
"""What hands the NMPC its set-point (``GuideParams.planner``)."""


@dataclass(frozen=True)
class GuideParams:
    """The guide (:class:`paper_repro.world.guide.Guide`): a path on the local map's inflated
    occupancy, whose look-ahead point becomes the NMPC's set-point y_t.

    Attributes
    ----------
    planner : ``"none"`` (*paper*: the set-point is the mission's target) or ``"grid"``
        (the shortest path, by A*, on a 26-connected grid of the workspace; needs the local map,
        ``sensor.map_voxel`` > 0, and a 3-D scene).
    cell : m, *chosen* 1. Side of a grid cell.
    inflation : m, *chosen* 2. A cell is blocked when a mapped point lies within this of its
        centre: the printed barrier's safe distance √(2·d_min) = 1.41 m, and the half-cell a
        path between cell centres may cut. With 1.5 m the path led through gaps the NMPC
        cannot pass (under a wall, by the floor) and the vehicle stalled there.
    lookahead : m, *chosen* 8. The look-ahead point is the farthest path cell within this that
        the vehicle sees along a free segment.
    check_period : s, *chosen* 0.1. How often the guide reads the map and moves the set-point
        on (so y_t is constant for at least this long).
    replan_period : s, *chosen* 1. The least time between two plans; a plan is made when a
        newly mapped voxel blocks the path.
    max_turn : degrees, *chosen* 3. The most the guide's pull turns per check (30°/s), so
        that a new look-ahead point does not make the thrusts jump.
    climb : *chosen* 2. What a metre up or down costs the path, in metres along the level:
        the path keeps the flight's altitude unless a detour over or under is much shorter.
    stuck_time : s, *chosen* 2.5. A vehicle that moved less than 5 cm over this long, far
        from its goal, is stuck: the cells between it and its aim are avoided and the path is
        planned again (before the closed loop calls the run stalled, after 5 s).
    set_point_filter : s, *chosen* 0.5 (0: none). Time constant of a first-order filter on
        the set-point handed to the NMPC: the guide's set-point moves in small steps at every
        check, whose 10 Hz content reaches the thrusts; the filter makes it glide instead
        (``benchmarks/guide_filter.py`` measures it against none).
    """

    planner: str = "none"
    cell: float = 1.0
    inflation: float = 2.0
    lookahead: float = 8.0
    check_period: float = 0.1
    replan_period: float = 1.0
    max_turn: float = 3.0
    climb: float = 2.0
    stuck_time: float = 2.5
    set_point_filter: float = 0.5

    def __post_init__(self):
        require_choice("planner", self.planner, GUIDES)
        require_range("set_point_filter", self.set_point_filter, 0.0, math.inf)
        for name in ("cell", "inflation", "check_period", "replan_period", "max_turn", "climb",
                     "stuck_time"):
            require_positive(name, getattr(self, name))
        if not (is_number(self.lookahead) and math.isfinite(self.lookahead)
                and self.lookahead >= self.cell):
            raise ValueError(f"lookahead must be a finite number >= cell = {self.cell} m, got "
                             f"{self.lookahead!r}")


@dataclass(frozen=True)
class Config:
    """Everything that defines one run; saved as ``config.json`` beside each result.

    The problem's data are ``quadrotor``, ``distance``, ``barrier``, ``nmpc`` and the LiDAR's
    range (``sensor.range``); ``solver`` says how the problem is solved, and ``simulation`` and
    the rest of ``sensor`` describe the world it is flown in.

    A ``config.json`` written before a part existed (e.g. ``sensor``) loads with that part's
    defaults, and one written before a setting moved loads it in its new place
    (:meth:`from_dict`, :data:`~paper_repro.config_history.MOVED`).
    """

    quadrotor: QuadrotorParams = field(default_factory=QuadrotorParams)
    distance: DistanceParams = field(default_factory=DistanceParams)
    barrier: BarrierParams = field(default_factory=BarrierParams)
    nmpc: NMPCParams = field(default_factory=NMPCParams)
    solver: SolverParams = field(default_factory=SolverParams)
    simulation: SimulationParams = field(default_factory=SimulationParams)
    sensor: SensorParams = field(default_factory=SensorParams)
    guide: GuideParams = field(default_factory=GuideParams)
    tracker: TrackerParams = field(default_factory=TrackerParams)

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if not isinstance(getattr(self, f.name), f.default_factory):
                raise ValueError(f"{f.name} must be a {f.default_factory.__name__}, got "
                                 f"{getattr(self, f.name)!r}")
        if self.distance.window >= self.sensor.range:
            raise ValueError(f"distance.window must be < sensor.range = "
                             f"{self.sensor.range} m (a window as wide as the range "
                             f"sees nothing at full weight), got {self.distance.window!r}")
        if self.guide.planner != "none" and self.sensor.map_voxel == 0:
            raise ValueError(f"guide.planner {self.guide.planner!r} plans on the local map: "
                             "set sensor.map_voxel > 0 (a voxel side in m, e.g. 0.5)")
        for name in ("reaction_time", "sweep_time", "moving_d_min", "equilibrium_lookahead"):
            value = getattr(self.barrier, name)
            if value > 0 and self.nmpc.prediction == "static":
                raise ValueError(f"barrier.{name} needs nmpc.prediction 'oracle' or 'kalman': "
                                 "the static prediction (the paper's) hands the problem no "
                                 f"region velocity to act on, got {name} {value!r}")
        # Cross-field: the artificial equilibrium (hover at rest, eq. 7) must exist in
        # λ(𝒳 × 𝒰), or the OCP is infeasible at every step.
        xl, xu, ul, uu = self.nmpc.relaxed_bounds()
        hover = self.quadrotor.hover_thrust
        if not np.all((ul <= hover) & (hover <= uu)):
            raise ValueError(f"nmpc.input_lower/input_upper must hold the hover thrust "
                             f"m·g/4 = {hover:.4g} N inside λ(𝒰) = [{ul.min():.4g}, "
                             f"{uu.max():.4g}] N per rotor, got input bounds "
                             f"{self.nmpc.input_lower!r} to {self.nmpc.input_upper!r}")
        for i in (3, 4, *range(6, 12)):  # roll, pitch, velocities and rates are 0 at rest
            if not xl[i] <= 0.0 <= xu[i]:
                raise ValueError(f"nmpc.state_lower[{i}] < 0 < nmpc.state_upper[{i}] is needed "
                                 f"for hover (at rest this state is 0), got λ-relaxed bounds "
                                 f"[{xl[i]:.4g}, {xu[i]:.4g}]")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def key_dict(self) -> dict:
        """What a run's cache key hashes: :meth:`to_dict` without the settings of
        :data:`~paper_repro.config_history.ADDED` that hold the value they were added with."""
        data = self.to_dict()
        return without_added(data, Config().to_dict())

    @classmethod
    def from_dict(cls, data: dict) -> Config:
        """Inverse of :meth:`to_dict` and of :meth:`key_dict`; a missing part (an older file)
        takes its defaults, a setting in its former place
        (:data:`~paper_repro.config_history.MOVED`) is read into its new one, and a setting
        added since a part was written (:data:`~paper_repro.config_history.ADDED`) takes the
        value that flies as before it (``with_added``), not its default."""
        if not isinstance(data, dict):
            raise ValueError(f"config must be a dict of parts, got {type(data).__name__}")
        data = with_added(moved_settings(data))
        unknown = set(data) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise ValueError(f"config has unknown parts {sorted(unknown)}")
        parts = {}
        for f in dataclasses.fields(cls):
            sub_cls = f.default_factory
            sub = dict(data.get(f.name, {}))
            for sf in dataclasses.fields(sub_cls):
                if sf.name in sub and isinstance(sub[sf.name], list):
                    sub[sf.name] = tuple(sub[sf.name])
            unknown = set(sub) - {sf.name for sf in dataclasses.fields(sub_cls)}
            if unknown:
                raise ValueError(f"unknown {f.name} parameters: {sorted(unknown)}")
            parts[f.name] = sub_cls(**sub)
        return cls(**parts)


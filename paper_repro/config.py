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
            _require_positive(name, getattr(self, name))
        if len(self.inertia) != 3 or not all(math.isfinite(i) and i > 0 for i in self.inertia):
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
    """

    eta: float = 0.3
    sigma: float = 0.8
    metric: str = "smooth"

    def __post_init__(self):
        _require_positive("eta", self.eta)
        _require_positive("sigma", self.sigma)
        _require_choice("metric", self.metric, ("smooth", "euclidean"))


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
    """

    delta: float = 0.95
    d_min: float = 1.0
    kappa: float = 10.0
    epsilon: float = 2.0
    mu: float = 5e4
    form: str = "printed"

    def __post_init__(self):
        if not (0.0 < self.delta < 1.0):
            raise ValueError(f"delta must lie in (0, 1), got {self.delta!r}")
        _require_positive("d_min", self.d_min)
        _require_positive("kappa", self.kappa)
        _require_positive("mu", self.mu)
        if not (math.isfinite(self.epsilon) and self.epsilon >= 1.0):
            raise ValueError(
                f"epsilon must be a finite value >= 1 (ε < 1 has unbounded gradients "
                f"where the penalty is zero), got {self.epsilon!r}"
            )
        _require_choice("form", self.form, ("printed", "definition"))

    @property
    def decay(self) -> float:
        """Factor c in g = c·β_j − β_{j+1}: 1 − δ (printed) or δ (definition)."""
        return 1.0 - self.delta if self.form == "printed" else self.delta


def _diag(*values: float) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


@dataclass(frozen=True)
class NMPCParams:
    """Tracking NMPC of eq. (7) and (21), Section V.

    Attributes
    ----------
    horizon : N, *paper* 35.
    ts : T_s, s, *paper* 0.01.
    q, r, t : diagonals of Q (12), R (4), T (3), *paper*.
    state_lower, state_upper : (12,) bounds of 𝒳, *paper*; position, Euler angles (rad),
        velocities (m/s), Euler-angle rates (rad/s).
    input_lower, input_upper : (4,) bounds of 𝒰 in N, *paper* 0 ≤ f_i ≤ 12.
    lam : λ ∈ (0, 1), *chosen* 0.99. The artificial equilibrium lies in λ(𝒳 × 𝒰),
        i.e. 25 cm inside the 25 m workspace walls; the relaxation only needs to keep
        (x_a, u_a) off the boundary (Limon et al. 2018), and the paper's targets sit at
        z = 0, which is the boundary itself (see ``relaxed_bounds``).
    solver : ``"rti"`` (default, Gauss-Newton SQP with HPIPM, :mod:`paper_repro.rti`) or
        ``"reference"`` (IPOPT with the exact Hessian, :mod:`paper_repro.nmpc`, as the paper).
    sqp_iterations : SQP iterations per sampling instant of the ``rti`` solver (1 is the
        real-time iteration).
    qp_solver : QP solver of the ``rti`` solver: ``"riccati"`` (default, a Riccati recursion
        warm-started with the previous active set, :mod:`paper_repro.stage_qp`, HPIPM as its
        fallback) or ``"hpipm"`` (HPIPM's interior-point method for every QP).
    region_slots : number of LiDAR-visible regions the NLP can hold at once.
    points_per_region : capacity of each region slot; scans with more visible points are
        reduced to the nearest ones (see ``paper_repro.nmpc``).
    """

    horizon: int = 35
    ts: float = 0.01
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
    solver: str = "rti"
    sqp_iterations: int = 1
    qp_solver: str = "riccati"
    region_slots: int = 2
    points_per_region: int = 120

    def __post_init__(self):
        if not (isinstance(self.horizon, int) and self.horizon >= 1):
            raise ValueError(f"horizon must be an integer >= 1, got {self.horizon!r}")
        _require_positive("ts", self.ts)
        for name, n in (("q", 12), ("r", 4), ("t", 3), ("state_lower", 12),
                        ("state_upper", 12), ("input_lower", 4), ("input_upper", 4)):
            v = getattr(self, name)
            if len(v) != n or not all(math.isfinite(x) for x in v):
                raise ValueError(f"{name} must have {n} finite entries, got {v!r}")
        if any(x < 0 for x in self.q):
            raise ValueError(f"q must be >= 0 (Q ⪰ 0), got {self.q!r}")
        if any(x <= 0 for x in self.r + self.t):
            raise ValueError("r and t must be > 0 (R ≻ 0, T ≻ 0)")
        if not (0.0 < self.lam < 1.0):
            raise ValueError(f"lam must lie in (0, 1), got {self.lam!r}")
        _require_choice("solver", self.solver, ("rti", "reference"))
        _require_choice("qp_solver", self.qp_solver, ("riccati", "hpipm"))
        for name in ("region_slots", "points_per_region", "sqp_iterations"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")

    def relaxed_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """λ(𝒳 × 𝒰): the box shrunk by λ about its centre.

        For a symmetric box this is exactly λ·(𝒳 × 𝒰); for the z bound [0, 25] and the input
        bound [0, 12] it keeps the scaling about the centre so that the relaxed set stays
        inside the original one.
        """
        out = []
        for lo, hi in ((self.state_lower, self.state_upper), (self.input_lower, self.input_upper)):
            lo, hi = np.asarray(lo), np.asarray(hi)
            mid, half = (lo + hi) / 2, (hi - lo) / 2
            out += [mid - self.lam * half, mid + self.lam * half]
        return tuple(out)


@dataclass(frozen=True)
class SimulationParams:
    """Closed-loop mission settings.

    Attributes
    ----------
    scenario : scene name (``"paper"`` or ``"encounter"``).
    tolerance : m, *paper* 0.3. A target counts as reached when the UAV is closer than this.
    max_steps : upper bound on closed-loop steps (one step is T_s).
    lidar_range : r_s, m, *paper* 3.
    seed : seed of the Halton point clouds.
    """

    scenario: str = "paper"
    tolerance: float = 0.3
    max_steps: int = 200_000
    lidar_range: float = 3.0
    seed: int = 7

    def __post_init__(self):
        _require_positive("tolerance", self.tolerance)
        _require_positive("lidar_range", self.lidar_range)
        if not (isinstance(self.max_steps, int) and self.max_steps >= 1):
            raise ValueError(f"max_steps must be an integer >= 1, got {self.max_steps!r}")


@dataclass(frozen=True)
class Config:
    """Everything that defines one run; saved as ``config.json`` beside each result."""

    quadrotor: QuadrotorParams = field(default_factory=QuadrotorParams)
    distance: DistanceParams = field(default_factory=DistanceParams)
    barrier: BarrierParams = field(default_factory=BarrierParams)
    nmpc: NMPCParams = field(default_factory=NMPCParams)
    simulation: SimulationParams = field(default_factory=SimulationParams)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> Config:
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


def _require_positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value)
            and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def _require_choice(name: str, value: str, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")

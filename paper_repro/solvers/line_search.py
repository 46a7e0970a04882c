"""The step size of the real-time SQP: backtracking on the ℓ1 merit function of problem (21),
with damping of the next QPs when a step had to be shortened (:class:`MeritLineSearch`)."""

from __future__ import annotations

import numpy as np

from paper_repro.solvers.linearisation import QPLayout


class MeritLineSearch:
    """Backtracking on the ℓ1 merit function of problem (21) (Nocedal & Wright, 2006, §18.3),
    with Levenberg–Marquardt damping of the next QPs when a step had to be shortened.

        φ(w) = J(w) + ν·(‖gap(w)‖₁ + ‖eq(w)‖₁),

    J the objective of (21) and gap, eq its equality residuals. The QP step p is a descent
    direction of φ once ν ≥ (qᵀp + ½pᵀHp) / ((1 − ρ)‖c‖₁) (ρ = ½, c the residuals), so ν is
    raised to that bound at every step, and then α = 1, ½, ¼, … is taken as soon as

        φ(w + αp) ≤ φ(w) + η·α·Dφ,    Dφ = qᵀp − ν‖c‖₁  (η = 10⁻⁴, Armijo),

    up to 10⁻¹⁰·(1 + |φ|): near the solution every smaller change of φ is rounding.

    Why: the Gauss-Newton QP is a local model. Where a region moves at the vehicle the stiff
    penalty makes the full step overshoot, the next instant's step undo it, and the inputs
    alternate between their bounds at every sample (a period-2 oscillation of the textbook
    real-time iteration). Shortening the step stops the overshoot; the QP's own plan still
    swings, so after a shortened step the next QPs get the damping δ·I on their Hessian
    (δ grows ×``grow`` after every shortened step, from ``damping_start`` up to
    ``damping_max``, shrinks ÷``relax`` after every full one and is 0 again below
    ``damping_start``/100). δ changes the step, never the fixed point: the converged SQP
    solves (21) whatever δ is.

    Near the optimum every full step is accepted: the cost is one evaluation of (J, gap, eq)
    per iteration, without derivatives, and δ stays 0, so the iterates are those of the full
    steps bit for bit. When ``max_trials`` step sizes all fail the best one tried is taken (a
    real-time iteration must return); with ``max_trials = 0`` every full step is taken and δ
    stays 0.

    Attributes
    ----------
    counts : steps taken at full length (``full``) and shortened (``shortened``).
    damping : δ for the next QP.
    """

    def __init__(self, layout: QPLayout, max_trials: int = 4, armijo: float = 1e-4,
                 shrink: float = 0.5, damping_start: float = 10.0, damping_max: float = 1e5,
                 grow: float = 4.0, relax: float = 2.0):
        if not (isinstance(max_trials, int) and max_trials >= 0):
            raise ValueError(f"max_trials must be an integer >= 0, got {max_trials!r}")
        if not (0 < armijo < 0.5 and 0 < shrink < 1):
            raise ValueError(f"armijo must be in (0, 0.5) and shrink in (0, 1), got "
                             f"{armijo!r}, {shrink!r}")
        if not (0 < damping_start <= damping_max and grow > 1 and relax > 1):
            raise ValueError(f"need 0 < damping_start <= damping_max, grow > 1 and relax > 1, "
                             f"got {damping_start!r}, {damping_max!r}, {grow!r}, {relax!r}")
        self.layout, self.max_trials = layout, max_trials
        self.armijo, self.shrink = armijo, shrink
        self.feasible = 1e-12  # per residual
        self.damping_start, self.damping_max = damping_start, damping_max
        self.grow, self.relax = grow, relax
        self.counts = {"full": 0, "shortened": 0}
        self.damping = 0.0

    def reset(self) -> None:
        """No damping (a new flight)."""
        self.damping = 0.0

    def damp(self, h) -> bool:
        """Add δ to every diagonal entry of the Hessian blocks ``h`` (in place); whether δ > 0."""
        if self.damping > 0.0:
            h[self.layout.hessian_diagonal] += self.damping
            return True
        return False

    def __call__(self, dw, h, q, gap, eq, cost: float, values) -> tuple[float, float]:
        """(α, φ(w + αΔw)) for the QP step ``dw`` at the iterate whose linearisation is (h, q,
        gap, eq, cost); ``values(dw, α)`` returns (cost, gap, eq) at w + αΔw. Then adapts δ."""
        if self.max_trials == 0:
            self.counts["full"] += 1
            return 1.0, np.nan
        infeasibility = float(np.abs(gap).sum() + np.abs(eq).sum())
        slope = float(q @ dw)
        nu = 0.0
        # Residuals at rounding level count as feasible (ν from them would be noise).
        if infeasibility > self.feasible * (gap.size + eq.size):
            curvature = max(self.layout.curvature(h, dw), 0.0)
            nu = max(0.0, (slope + 0.5 * curvature) / (0.5 * infeasibility)) + 1.0
        merit0 = cost + nu * infeasibility
        descent = slope - nu * infeasibility
        # Near the solution the changes of φ are rounding (of φ and of the residuals that
        # the step restores): a change within 10⁻¹⁰·(1 + |φ|) counts as no increase.
        rounding = 1e-10 * (1.0 + abs(merit0))
        alpha, best = 1.0, (np.inf, 1.0)
        for _ in range(self.max_trials):
            c, g, e = values(dw, alpha)
            merit = float(c[0]) + nu * float(np.abs(g).sum() + np.abs(e).sum())
            if merit <= merit0 + self.armijo * alpha * min(descent, 0.0) + rounding:
                break
            best = min(best, (merit, alpha))
            alpha *= self.shrink
        else:
            merit, alpha = best
        if alpha == 1.0:
            self.counts["full"] += 1
            self.damping /= self.relax
            if self.damping < self.damping_start / 100:
                self.damping = 0.0
        else:
            self.counts["shortened"] += 1
            self.damping = min(max(self.damping * self.grow, self.damping_start),
                               self.damping_max)
        return alpha, merit

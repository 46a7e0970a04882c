"""The tuning's search space and objectives: which parameters Optuna may change, within which
ranges, what it minimises and which constraints a set-up must meet."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from paper_repro.config import Config


@dataclass(frozen=True)
class ParamRange:
    """The range of one tuned parameter.

    Attributes
    ----------
    name : field of :class:`~paper_repro.config.DistanceParams` (``eta``, ``sigma``) or
        :class:`~paper_repro.config.BarrierParams` (``d_min``, ``kappa``, ``mu``, ``delta``).
    low, high : bounds, inclusive, in the parameter's units; ``low < high``.
    step : grid spacing (``None``: continuous). ``high − low`` must be a whole number of steps.
    why : one sentence justifying the range (stored in the study, shown in the notebook).

    Why a grid. η, d_min, κ, μ and δ are constants of the compiled C of the real-time solver:
    every distinct value costs a build of about a minute (cached on disk by source hash), where a
    passage costs 5-10 s. On a grid a configuration can come back (crossover, a resumed study,
    the held-out evaluation of a Pareto point) and reuse its library; the steps are well below
    the effect sizes of the sweeps. σ is not compiled (it only weighs the visible points) and
    gets a finer grid only so that run names stay short.
    """

    name: str
    low: float
    high: float
    step: float | None = None
    why: str = ""

    def check(self, base: Config | None = None) -> None:
        """Raise ``ValueError`` naming the parameter if the range is empty, reversed, off its
        step, or reaches values the configuration rejects."""
        n = self.name
        if n not in TUNABLE:
            raise ValueError(f"parameter must be one of {sorted(TUNABLE)}, got {n!r}")
        for label, v in (("low", self.low), ("high", self.high)):
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)):
                raise ValueError(f"{n}: {label} must be a finite number, got {v!r}")
        if self.low > self.high:
            raise ValueError(f"{n}: lower bound {self.low:g} is above the upper bound "
                             f"{self.high:g}")
        if self.low == self.high:
            raise ValueError(f"{n}: the range [{self.low:g}, {self.high:g}] is empty (leave the "
                             "parameter out of the search space to fix it)")
        if self.step is not None:
            if not (isinstance(self.step, (int, float)) and math.isfinite(self.step)
                    and self.step > 0):
                raise ValueError(f"{n}: step must be a finite number > 0, got {self.step!r}")
            k = (self.high - self.low) / self.step
            if abs(k - round(k)) > 1e-9 * max(1.0, k):
                raise ValueError(f"{n}: high - low = {self.high - self.low:g} must be a whole "
                                 f"number of steps of {self.step:g}")
        for v in (self.low, self.high):
            try:
                apply_params(base or Config(), {n: v})
            except ValueError as exc:
                raise ValueError(f"{n}: the range [{self.low:g}, {self.high:g}] lies outside "
                                 f"what the configuration accepts ({exc})") from None

    def values(self) -> np.ndarray | None:
        """The grid, or ``None`` when continuous."""
        if self.step is None:
            return None
        k = int(round((self.high - self.low) / self.step))
        return np.round(self.low + self.step * np.arange(k + 1), 10)


TUNABLE = {"eta": "distance", "sigma": "distance", "d_min": "barrier", "kappa": "barrier",
           "mu": "barrier", "delta": "barrier"}
"""Tunable parameters and the part of :class:`~paper_repro.config.Config` each lives in."""


SEARCH_SPACE: dict[str, ParamRange] = {
    "eta": ParamRange(
        "eta", 0.1, 0.6, 0.05,
        "η, m (paper 0.3): below 0.1 m D is the Euclidean ½d² to within the cloud spacing "
        "(≈0.7 m) and chatters like it; above 0.6 m the offset η²·ln(V/W) of D over ½d² "
        "reaches the size of d_min and the smoothed safe set swallows narrow passages"),
    "sigma": ParamRange(
        "sigma", 0.4, 1.6, 0.05,
        "σ, m (paper 0.8): the η-sweep's range, half to twice the printed value; below the "
        "cloud spacing W_σ weighs single points, above 2 m it weighs every visible point alike"),
    "d_min": ParamRange(
        "d_min", 0.5, 2.0, 0.25,
        "m² (ours 1.0): d_min = ½r², r from 1 m to 2 m of smoothed clearance; the constraint "
        "asks 1 m of true clearance, and beyond 2 m windows and U-channels close"),
    "kappa": ParamRange(
        "kappa", 2.5, 40.0, 2.5,
        "κ, 1/m² (ours 10): the softplus is within ln2/κ of max(0, g), 0.28 m² at 2.5 (a "
        "quarter of d_min) to 0.017 m² at 40 (a near-kink, which can chatter)"),
    "mu": ParamRange(
        "mu", 1e4, 2e5, 1e4,
        "μ (paper 5·10⁴): a fifth to four times the printed weight, against the tracking "
        "weights T = 1000 and Q; below 10⁴ the penalty no longer holds d_min in our runs"),
    "delta": ParamRange(
        "delta", 0.55, 0.99, 0.04,
        "δ (paper 0.95), printed form g = (1−δ)β_j − β_{j+1}: β may shrink per step to "
        "between 45 % (δ = 0.55) and 1 % (δ = 0.99) of its value; (0, 1) is all the "
        "configuration accepts"),
}
"""The default search space; every range holds the printed (or our chosen) value on its grid,
so the printed set-up is trial 0 of every study."""


OBJECTIVES = {
    "hf_energy_fraction": "share of thrust power above 5 Hz",
    "tv_u_rate_N_per_s": "total variation of u per second, N/s",
    "time_to_complete_s": "time to complete the passage, s",
}
"""Objectives a study may minimise (columns of :func:`~paper_repro.analysis.metrics.summary_row`),
each
the mean over the trial's scenes."""


DEFAULT_OBJECTIVES = ("hf_energy_fraction", "time_to_complete_s")
"""Chattering (the measure the paper's Figs. 4 and 8 are about) against speed."""


CONSTRAINTS = ("clearance_shortfall_m", "collisions", "completions_lost")
"""Optuna constraints (≤ 0 is feasible): :data:`MIN_CLEARANCE` − the smallest clearance over the
scenes, m; the number of scenes with a collision (clearance < 0.35 m); the number of scenes the
printed set-up completes that the trial does not (stalled, step limit, raised). A training scene
on which the printed set-up itself stalls costs a trial only time (the step limit counts as its
time to complete), so a trial that gets through it gains."""


MIN_CLEARANCE = 1.0
"""m: the clearance every training scene must keep for a trial to be feasible.

Why 1 m. A collision is a clearance below 0.35 m. The first tuning asked 0.5 m on 3 training
scenes: its front point kept 0.58 m there and came down to 0.11 m on the held-out passages (6
of 20 collided), a drop of 0.47 m from training to held-out. The margin above the collision
radius must cover that drop: 0.35 + 0.47 = 0.82 m, rounded up to 1 m. The printed set-up keeps
1.22 m or more on every passage of the Monte Carlo study, so it stays feasible."""


SETUPS = ("printed", "best_chattering", "safest")
"""The three held-out set-ups, in the order of every table: the printed parameters, the front's
point best on chattering, and the front's safest point among those that chatter less than the
printed set-up (:func:`~paper_repro.studies.tuning_results.best_setups`)."""


def search_space(space=None, base: Config | None = None) -> dict[str, ParamRange]:
    """The search space, checked.

    ``space`` is ``None`` (all of :data:`SEARCH_SPACE`), a sequence of names (their default
    ranges) or a mapping ``{name: ParamRange | (low, high[, step]) | None}`` (exactly these
    parameters; ``None`` takes the default range). A parameter left out keeps ``base``'s value.
    Raises ``ValueError`` naming the parameter (unknown, empty range, low > high, off its step,
    outside what the configuration accepts).
    """
    if space is None:
        space = dict.fromkeys(SEARCH_SPACE)
    elif isinstance(space, str) or not isinstance(space, Mapping):
        space = dict.fromkeys(space)
    out = {}
    for n, r in space.items():
        if n not in TUNABLE:
            raise ValueError(f"parameter must be one of {sorted(TUNABLE)}, got {n!r}")
        if r is None:
            r = SEARCH_SPACE[n]
        elif not isinstance(r, ParamRange):
            r = tuple(r)
            if len(r) not in (2, 3):
                raise ValueError(f"{n}: a range is (low, high) or (low, high, step), got {r!r}")
            r = ParamRange(n, *r, why="given")
        elif r.name != n:
            raise ValueError(f"{n}: the range given is for {r.name!r}")
        out[n] = r
    if not out:
        raise ValueError("the search space must hold at least one parameter")
    for r in out.values():
        r.check(base)
    return out


def check_objectives(objectives: Sequence[str]) -> tuple[str, ...]:
    """``objectives`` as a tuple; ``ValueError`` naming an unknown or repeated one."""
    if isinstance(objectives, str):
        objectives = (objectives,)
    objectives = tuple(objectives)
    if not objectives:
        raise ValueError(f"objectives must name at least one of {sorted(OBJECTIVES)}")
    for o in objectives:
        if o not in OBJECTIVES:
            raise ValueError(f"objective must be one of {sorted(OBJECTIVES)}, got {o!r}")
    if len(set(objectives)) != len(objectives):
        raise ValueError(f"objectives must not repeat, got {objectives!r}")
    return objectives


def apply_params(base: Config, params: Mapping[str, float]) -> Config:
    """``base`` with the tuned parameters ``params`` (``{"eta": 0.3, "mu": 5e4, ...}``) set."""
    parts = {"distance": {}, "barrier": {}}
    for n, v in params.items():
        if n not in TUNABLE:
            raise ValueError(f"parameter must be one of {sorted(TUNABLE)}, got {n!r}")
        parts[TUNABLE[n]][n] = float(v)
    return dataclasses.replace(
        base, distance=dataclasses.replace(base.distance, **parts["distance"]),
        barrier=dataclasses.replace(base.barrier, **parts["barrier"]))


def printed_params(base: Config | None = None, names: Sequence[str] = tuple(TUNABLE)) -> dict:
    """The tuned parameters' values in ``base`` (default: printed + our chosen defaults)."""
    base = base or Config()
    return {n: float(getattr(getattr(base, TUNABLE[n]), n)) for n in names}


def suggest(trial, space: Mapping[str, ParamRange]) -> dict[str, float]:
    """The trial's parameter set (rounded to 10 decimals so grid values are exact)."""
    return {n: round(trial.suggest_float(n, r.low, r.high, step=r.step), 10)
            for n, r in space.items()}


def finished_trials(study) -> list:
    import optuna

    return study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))


def is_feasible(trial) -> bool:
    con = trial.user_attrs.get("constraints")
    return con is not None and all(c <= 0 for c in con) and all(
        math.isfinite(v) for v in trial.values)

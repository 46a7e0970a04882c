"""Automatic tuning of η, σ, d_min, κ, μ and δ with Optuna, flown on the study engine.

The paper names "automatic tuning of smoothing and penalty parameters" as its future work; its
parameters were hand-picked for one scene, and four of ours (κ, ε, d_min, λ) were chosen by us.
:func:`tune` runs a multi-objective Optuna study over the parameters of :data:`SEARCH_SPACE`:

* a *trial* is a parameter set flown on the training scenes, random passages
  (:func:`paper_repro.study.passage_config`). Its scenes are one small
  :class:`~paper_repro.study.Study` run by :func:`~paper_repro.study.run_study`, so every flight
  goes through the shared run cache and runs on the embedded Dask cluster or a real one;
  as many trials run at once as the cluster has workers;
* the *objectives* (:data:`OBJECTIVES`), both minimised, are measured per trial over its
  scenes (the mean over scenes): a chattering measure (share of thrust power above 5 Hz, or the
  total variation of u per second) and the time to complete the passage;
* the *constraints* are Optuna's (``constraints_func``, a value ≤ 0 is feasible), so an unsafe
  trial is infeasible to the sampler rather than merely penalised: minimum clearance ≥ 0.5 m
  over all scenes, no collision, and every scene completed (no stall, no step limit, no raised
  run); see :data:`CONSTRAINTS`;
* the storage is an RDB URL (SQLite in ``figures/tuning/tuning.db`` by default), so an
  interrupted study resumes where it stopped (:func:`tune` counts the finished trials and flies
  only the missing ones; the flights of an interrupted trial come back from the run cache), and
  ``optuna-dashboard sqlite:///figures/tuning/tuning.db`` opens it.

Then :func:`evaluate_heldout` flies three set-ups, the printed parameters (with our chosen
defaults), the Pareto point best on chattering and the one best on time, on held-out scenes
never used in tuning, and :func:`heldout_summary` compares them with confidence intervals.
``python -m paper_repro tune`` does all of it and executes notebook ``12_tuning``.

Training and held-out scenes. Under the printed parameters a good share of random passages
stall (the NMPC is local and deadlocks in front of some walls). Asking "no stall on any training
scene" of scenes where even the printed set-up stalls would make nearly every trial infeasible
and teach the sampler nothing, so the training scenes are the first ``scenes`` seeds of
:data:`TRAIN_CANDIDATES` on which the printed set-up completes with at least 0.5 m of
clearance (:func:`training_scenes`; the printed flights are shared with the Monte Carlo study's
cache). This favours the printed set-up on the training scenes, by design and in the open. The
held-out scenes (:data:`HELDOUT_SEEDS`) are taken whatever the printed set-up does on them,
and never overlap the candidates, so their stall rates are an unbiased comparison.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import metrics, paths
from .config import Config
from .runs import RunSpec
from .study import PASSAGE_STEPS, QUICK_STEPS, Study, passage_config, passage_spec, run_study

# --- the search space ----------------------------------------------------------------------


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
        "asks 0.5 m of true clearance, and beyond 2 m windows and U-channels close"),
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
"""Objectives a study may minimise (columns of :func:`~paper_repro.metrics.summary_row`), each
the mean over the trial's scenes."""

DEFAULT_OBJECTIVES = ("hf_energy_fraction", "time_to_complete_s")
"""Chattering (the measure the paper's Figs. 4 and 8 are about) against speed."""

CONSTRAINTS = ("clearance_shortfall_m", "collisions", "not_completed")
"""Optuna constraints (≤ 0 is feasible): 0.5 m − the smallest clearance over the scenes; the
number of scenes with a collision (clearance < 0.35 m); the number of scenes not completed
(stalled, step limit, raised)."""

MIN_CLEARANCE = 0.5
"""m: the clearance every training scene must keep for a trial to be feasible."""

TRAIN_CANDIDATES = tuple(range(0, 60))
"""Seeds from which the training scenes are drawn (the first where the printed set-up
completes), shared with the Monte Carlo study's cache."""

HELDOUT_SEEDS = tuple(range(60, 80))
"""The held-out scenes: 20 seeds never among the training candidates, taken whatever the
printed set-up does on them."""

QUICK = {"trials": 4, "scenes": 2, "heldout": 2, "max_steps": QUICK_STEPS}
"""``--quick``: a few trials of 400-step runs (every part exercised, nothing proved)."""

DEFAULT_TRIALS = 40
DEFAULT_SCENES = 4
STUDY_NAME = "cbf_nmpc"
SETUPS = ("printed", "best_chattering", "best_time")
"""The three held-out set-ups, in the order of every table."""


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


# --- runs of a trial -------------------------------------------------------------------------

def tuning_spec(params: Mapping[str, float], seed: int, max_steps: int = PASSAGE_STEPS,
                base: Config | None = None) -> RunSpec:
    """The passage through random scene ``seed`` under ``base`` with ``params`` set.

    When only η and σ differ from ``base`` this is :func:`~paper_repro.study.passage_spec`
    itself (same name, same cache folder as the Monte Carlo and η studies); otherwise the name
    lists all six values.
    """
    base = base or Config()
    cfg = passage_config(apply_params(base, params), seed, max_steps)
    labels = tuple((n, float(getattr(getattr(cfg, TUNABLE[n]), n))) for n in TUNABLE)
    if cfg.barrier == base.barrier:
        spec = passage_spec(seed, "smooth", cfg.distance.eta, cfg.distance.sigma, max_steps,
                            base)
        return dataclasses.replace(spec, labels=spec.labels + labels[2:])
    d, b = cfg.distance, cfg.barrier
    name = (f"passage-smooth-eta{d.eta:g}-sigma{d.sigma:g}-dmin{b.d_min:g}-kappa{b.kappa:g}"
            f"-mu{b.mu:g}-delta{b.delta:g}-s{seed:03d}")
    return RunSpec(name, cfg, int(max_steps),
                   (("metric", "smooth"), *labels, ("scene_seed", int(seed))))


def trial_study(params: Mapping[str, float], seeds: Sequence[int], max_steps: int,
                base: Config | None = None, name: str = "trial") -> Study:
    """One trial's flights as a :class:`~paper_repro.study.Study`: ``params`` on each seed."""
    return Study(name, tuple(tuning_spec(params, s, max_steps, base) for s in seeds),
                 f"tuning trial {params}")


def evaluate_table(table, objectives: Sequence[str] = DEFAULT_OBJECTIVES,
                   require_completion: bool = True, time_limit_s: float = PASSAGE_STEPS * 0.01
                   ) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A trial's objective values and constraint values from its study table.

    Parameters
    ----------
    table : one row per scene (:func:`~paper_repro.study.run_study`).
    objectives : names from :data:`OBJECTIVES`; each is the mean over scenes. A scene that did
        not complete counts ``time_limit_s`` as its time and a run that raised counts the worst
        chattering of the other scenes (or +inf): the trial is infeasible anyway, these only
        keep its values finite and ordered for the sampler.
    require_completion : a scene that reached its step limit counts as not completed (``False``
        for ``--quick`` runs, which all stop at their step limit: then only stalls and raised
        runs count).
    time_limit_s : s.

    Returns
    -------
    values : one per objective.
    constraints : one per :data:`CONSTRAINTS`, ≤ 0 when satisfied.
    """
    objectives = check_objectives(objectives)
    ok = table["status"] == "ok"
    values = []
    for o in objectives:
        if o == "time_to_complete_s":
            v = np.where(ok & table["completed"].fillna(False).astype(bool),
                         table[o].astype(float), time_limit_s)
        else:
            v = table[o].where(ok).astype(float).to_numpy()
            worst = np.nanmax(v) if np.any(np.isfinite(v)) else math.inf
            v = np.where(np.isfinite(v), v, worst)
        values.append(float(np.mean(v)))
    clear = table["min_clearance_m"].where(ok).astype(float)
    shortfall = MIN_CLEARANCE - (float(clear.min()) if clear.notna().any() else 0.0)
    collisions = int((ok & table["collision"].fillna(False).astype(bool)).sum())
    done = ok & (table["completed"].fillna(False).astype(bool) if require_completion
                 else ~table["stalled"].fillna(False).astype(bool))
    not_completed = int((~done).sum())
    return tuple(values), (float(shortfall), float(collisions), float(not_completed))


# --- the study ------------------------------------------------------------------------------

@dataclass
class TuningResult:
    """What :func:`tune` produced: the Optuna study, where it is stored, the training seeds."""

    study: object  # optuna.Study
    storage: str
    seeds: tuple
    directory: Path
    flown_trials: int
    wall_time_s: float

    def frame(self):
        """:func:`trials_frame` of the study."""
        return trials_frame(self.study)


def tune(trials: int = DEFAULT_TRIALS, quick: bool = False, workers: int | None = None,
         scheduler: str | None = None, client=None, storage: str | None = None,
         study_name: str = STUDY_NAME, space: Mapping | None = None,
         objectives: Sequence[str] = DEFAULT_OBJECTIVES, scenes: int | None = None,
         seeds: Sequence[int] | None = None, sampler: str = "tpe", seed: int = 0,
         max_steps: int | None = None, base: Config | None = None, out=None, runs_dir=None,
         log: Callable[[str], None] = print,
         callbacks: Sequence[Callable] = ()) -> TuningResult:
    """Run (or resume) the tuning study until it holds ``trials`` finished trials.

    Parameters
    ----------
    trials : finished trials the study should hold in all. A resumed study counts the ones it
        has and runs only the rest; trials left running by a killed driver are marked failed and
        their parameters queued again (their finished flights come back from the cache).
    quick : 400-step runs, 2 scenes, 4 trials by default (CI).
    workers, scheduler, client : as :func:`~paper_repro.study.run_study`; as many trials run at
        once as there are workers (``workers=0``: one at a time, in this process).
    storage : RDB URL (default ``sqlite:///<out>/tuning.db``).
    study_name : name of the Optuna study in the storage.
    space : ``{name: ParamRange | (low, high[, step])}``, or a sequence of names, or ``None``
        for :data:`SEARCH_SPACE` (see :func:`search_space`).
    objectives : names from :data:`OBJECTIVES` (all minimised).
    scenes : number of training scenes (4; 2 with ``quick``), chosen by
        :func:`training_scenes`; or ``seeds`` gives them explicitly.
    sampler : ``"tpe"`` (multi-objective TPE, the default) or ``"nsga2"``, both with the
        constraints of :data:`CONSTRAINTS`.
    seed : seed of the sampler (offset by the number of trials already stored, so a resumed
        study does not replay its first draws).
    max_steps : step limit per passage (15,000; 400 with ``quick``).
    base : configuration the tuned parameters are set in (default: printed).
    out : folder of ``tuning.json`` and the default storage (``figures/tuning``).
    runs_dir : the run cache (default ``results/runs``).
    callbacks : Optuna callbacks ``(study, frozen_trial)``, called after each trial.

    Everything is checked (space, objectives, counts, storage URL, sampler) before a scene is
    built or a run flown; a mismatch with what a resumed study stored raises ``ValueError``.
    """
    import optuna

    base = base or Config()
    spec = _check_tune_args(trials, quick, workers, scheduler, storage, space, objectives,
                            scenes, seeds, sampler, max_steps, base)
    out = Path(out) if out is not None else tuning_dir(quick)
    out.mkdir(parents=True, exist_ok=True)
    storage = storage or f"sqlite:///{out / 'tuning.db'}"
    runs_dir = Path(runs_dir) if runs_dir is not None else paths.results_dir() / "runs"
    trials_dir = runs_dir.parent / "tuning" / study_name  # per-trial tables (not committed)
    max_steps, objectives, space = spec["max_steps"], spec["objectives"], spec["space"]
    start = time.perf_counter()

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    directions = ["minimize"] * len(objectives)
    existing = _load_existing(study_name, storage)
    with _cluster(workers, scheduler, client, log) as dask_client:
        if existing is None:
            train = tuple(seeds) if seeds is not None else training_scenes(
                spec["scenes"], max_steps=max_steps, base=base, client=dask_client,
                runs_dir=runs_dir, require_completion=not quick, log=log)
            _check_disjoint(train)
        else:
            train = tuple(existing.user_attrs.get("seeds", ()))
        stored = {"objectives": list(objectives), "seeds": list(train),
                  "space": {n: [r.low, r.high, r.step] for n, r in space.items()},
                  "max_steps": max_steps, "require_completion": not quick,
                  "base": json.loads(json.dumps(base.to_dict(), default=str))}
        n_done = 0 if existing is None else len(_finished(existing))
        study = optuna.create_study(
            study_name=study_name, storage=storage, directions=directions,
            load_if_exists=True, sampler=_sampler(sampler, seed + n_done, len(objectives)))
        if existing is None:
            for k, v in stored.items():
                study.set_user_attr(k, v)
            # Trial 0 is the printed set-up: where it lies against the front is the question.
            study.enqueue_trial(printed_params(base, space))
        else:
            _check_stored(study, stored)
        for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
            study.tell(t.number, state=optuna.trial.TrialState.FAIL)
            study.enqueue_trial(t.params)
            log(f"tune: trial {t.number} was left running by an earlier driver: failed, its "
                "parameters queued again")
        _write_json(out / "tuning.json", {
            "study_name": study_name, "storage": _shown_storage(storage, out),
            "sampler": sampler, "seed": seed, **stored,
            "space_why": {n: r.why for n, r in space.items()}})
        remaining = trials - len(_finished(study))
        n_jobs = 1 if dask_client is None else max(
            1, len(dask_client.scheduler_info()["workers"]))
        log(f"tune: study {study_name!r} in {storage}: {len(_finished(study))} finished "
            f"trials, {max(remaining, 0)} to run on {n_jobs} worker(s); training scenes "
            f"{list(train)}")
        flown = [0]

        def objective(trial):
            params = suggest(trial, space)
            table = run_study(
                trial_study(params, train, max_steps, base, f"trial-{trial.number:04d}"),
                out=trials_dir / f"trial-{trial.number:04d}", client=dask_client,
                workers=0 if dask_client is None else None, runs_dir=runs_dir,
                progress=False, log=lambda line: None).table
            values, constraints = evaluate_table(table, objectives, not quick,
                                                 max_steps * base.nmpc.ts)
            trial.set_user_attr("constraints", list(constraints))
            if hasattr(trial, "set_constraint"):  # Optuna >= 5: constraints by name
                for name, c in zip(CONSTRAINTS, constraints):
                    trial.set_constraint(name, c)
            trial.set_user_attr("scenes", _scene_records(table))
            trial.set_user_attr("flown", int(table["simulated"].sum()))
            flown[0] += 1
            log(f"tune: trial {trial.number}: {_fmt_params(params)} -> "
                + ", ".join(f"{o} {v:.4g}" for o, v in zip(objectives, values))
                + ("" if max(constraints) <= 0 else
                   f" (infeasible: {dict(zip(CONSTRAINTS, constraints))})"))
            return values

        if remaining > 0:
            _ask_and_tell(study, objective, remaining, n_jobs, callbacks)
    wall = time.perf_counter() - start
    _write_json(out / "tuning.json", {
        "study_name": study_name, "storage": _shown_storage(storage, out), "sampler": sampler,
        "seed": seed, "trials": len(_finished(study)), **stored,
        "space_why": {n: r.why for n, r in space.items()}})
    # What the machine determines, apart (tuning.json is what the flights determine).
    _write_json(out / "timings.json", {"flown_trials_last_call": flown[0],
                                       "wall_time_s_last_call": wall})
    return TuningResult(study, storage, train, out, flown[0], wall)


def _ask_and_tell(study, objective, n_trials: int, n_jobs: int, callbacks) -> None:
    """Run ``n_trials`` trials, ``n_jobs`` at a time: asked and told in this thread (the
    sampler and the storage are never touched concurrently; ``Study.optimize(n_jobs=2)`` was
    seen to hand one queued trial to two threads), flown in worker threads that wait on Dask.
    A trial whose objective raises is told FAIL and the error propagates, as in ``optimize``.
    """
    from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

    import optuna

    running: dict = {}
    asked = 0
    with ThreadPoolExecutor(max_workers=n_jobs) as pool:
        while asked < n_trials or running:
            while asked < n_trials and len(running) < n_jobs:
                trial = study.ask()
                running[pool.submit(objective, trial)] = trial
                asked += 1
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                trial = running.pop(future)
                try:
                    values = future.result()
                except BaseException:
                    study.tell(trial, state=optuna.trial.TrialState.FAIL)
                    for f in running:  # let the others finish and record them, then stop
                        f.cancel()
                    raise
                frozen = study.tell(trial, values)
                for callback in callbacks:
                    callback(study, frozen)


def suggest(trial, space: Mapping[str, ParamRange]) -> dict[str, float]:
    """The trial's parameter set (rounded to 10 decimals so grid values are exact)."""
    return {n: round(trial.suggest_float(n, r.low, r.high, step=r.step), 10)
            for n, r in space.items()}


def training_scenes(n: int, candidates: Sequence[int] = TRAIN_CANDIDATES,
                    max_steps: int = PASSAGE_STEPS, base: Config | None = None, client=None,
                    runs_dir=None, require_completion: bool = True,
                    log: Callable[[str], None] = print) -> tuple[int, ...]:
    """The first ``n`` seeds of ``candidates`` on which ``base`` (printed) completes the passage
    with clearance ≥ :data:`MIN_CLEARANCE` and no collision.

    The candidates are flown in batches of ``n`` through the run cache (the Monte Carlo study's
    printed passages are the same runs). ``require_completion=False`` (quick runs) accepts
    any run that did not stall. Raises ``ValueError`` if fewer than ``n`` qualify.
    """
    base = base or Config()
    runs_dir = Path(runs_dir) if runs_dir is not None else paths.results_dir() / "runs"
    chosen: list[int] = []
    pool = list(candidates)
    while len(chosen) < n and pool:
        batch, pool = pool[:n], pool[n:]
        table = run_study(trial_study(printed_params(base), batch, max_steps, base,
                                      "training-screen"),
                          out=runs_dir.parent / "tuning" / "training-screen",
                          client=client, workers=0 if client is None else None,
                          runs_dir=runs_dir, progress=False, log=lambda line: None).table
        for i in range(len(table)):
            _, con = evaluate_table(table.iloc[[i]], ("hf_energy_fraction",),
                                    require_completion)
            if max(con) <= 0 and len(chosen) < n:
                chosen.append(int(table["scene_seed"].iloc[i]))
        log(f"tune: screened seeds {batch}: training scenes so far {chosen}")
    if len(chosen) < n:
        raise ValueError(f"scenes: only {len(chosen)} of the candidate seeds "
                         f"{list(candidates)[:3]}... complete under the printed set-up, "
                         f"{n} were asked")
    return tuple(chosen)


# --- reading a study ------------------------------------------------------------------------

def load_study(directory=None, quick: bool = False):
    """The Optuna study saved by :func:`tune` in ``directory`` (its ``tuning.json``)."""
    import optuna

    d = Path(directory) if directory is not None else tuning_dir(quick)
    meta = tuning_meta(d)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    # The default SQLite file travels with its folder (a clone, another machine).
    local = d / "tuning.db"
    storage = f"sqlite:///{local}" if local.is_file() else meta["storage"]
    return optuna.load_study(study_name=meta["study_name"], storage=storage)


def tuning_meta(directory=None, quick: bool = False) -> dict:
    """``tuning.json`` of a tuning folder (default ``figures/tuning``)."""
    d = Path(directory) if directory is not None else tuning_dir(quick)
    return json.loads((d / "tuning.json").read_text())


def trials_frame(study) -> object:
    """One row per finished trial: ``number``, the parameters, the objectives (named), the
    constraints (named, :data:`CONSTRAINTS`), ``feasible``, ``pareto`` (on the feasible front)
    and ``printed`` (the printed set-up).

    Feasibility is read from the constraints the trial stored, never from its values, so an
    infeasible trial can never be on the front however good its objectives.
    """
    import pandas as pd

    objectives = study.user_attrs.get("objectives", [f"value{i}" for i in
                                                     range(len(study.directions))])
    names = list(study.user_attrs.get("space", {}))
    base = Config.from_dict(study.user_attrs["base"]) if "base" in study.user_attrs else Config()
    printed = printed_params(base, names)
    rows = []
    for t in _finished(study):
        con = t.user_attrs.get("constraints")
        row = {"number": t.number, **{n: t.params.get(n, np.nan) for n in names},
               **dict(zip(objectives, t.values)),
               **dict(zip(CONSTRAINTS, con if con is not None else [np.inf] * 3)),
               "flown": t.user_attrs.get("flown", 0)}
        row["feasible"] = con is not None and all(c <= 0 for c in con) and all(
            math.isfinite(v) for v in t.values)
        row["printed"] = all(math.isclose(t.params.get(n, np.nan), printed[n],
                                          rel_tol=1e-9) for n in names)
        rows.append(row)
    frame = pd.DataFrame(rows)
    if frame.empty:
        return frame.assign(feasible=[], pareto=[], printed=[])
    values = frame[objectives].to_numpy(float)
    frame["pareto"] = False
    feas = frame.index[frame["feasible"]]
    if len(feas):
        front = _non_dominated(values[feas])
        frame.loc[feas[front], "pareto"] = True
    return frame


def best_setups(frame, objectives: Sequence[str] = DEFAULT_OBJECTIVES,
                base: Config | None = None) -> dict[str, dict]:
    """The three held-out set-ups: ``printed`` (``base``'s values), ``best_chattering`` and
    ``best_time`` (the Pareto points best on the first and on the last objective; ties broken
    by the other objective, then by trial number).

    Raises ``ValueError`` when no trial is feasible: there is no front to pick from.
    """
    front = frame[frame["pareto"]]
    if front.empty:
        raise ValueError("no feasible trial: the study has no Pareto front to pick from")
    names = [c for c in frame.columns if c in TUNABLE]
    chat, speed = objectives[0], objectives[-1]
    pick = {"best_chattering": front.sort_values([chat, speed, "number"]).iloc[0],
            "best_time": front.sort_values([speed, chat, "number"]).iloc[0]}
    out = {"printed": printed_params(base, names)}
    for k, row in pick.items():
        # Rounded as the trial's flights were (:func:`suggest`): the same configuration.
        out[k] = {n: round(float(row[n]), 10) for n in names}
        out[k]["trial"] = int(row["number"])
    return out


def printed_position(frame, objectives: Sequence[str] = DEFAULT_OBJECTIVES) -> dict:
    """Where the printed set-up (trial 0) lies against the feasible front.

    Returns ``feasible``, ``on_front``, ``dominated_by`` (feasible trials at least as good in
    every objective and better in one), the printed values, and for each objective the largest
    relative reduction a front point offers without being worse in any other objective
    (``gain_<objective>``, 0 when none): what moving along the front buys at no cost.
    """
    pr = frame[frame["printed"]]
    if pr.empty:
        raise ValueError("the study holds no trial with the printed parameters")
    p = pr.iloc[0]
    feas = frame[frame["feasible"]]
    v = feas[list(objectives)].to_numpy(float)
    pv = p[list(objectives)].to_numpy(float)
    dom = np.all(v <= pv, axis=1) & np.any(v < pv, axis=1)
    out = {"feasible": bool(p["feasible"]), "on_front": bool(p["pareto"]),
           "dominated_by": int(dom.sum()), **{f"printed_{o}": float(p[o]) for o in objectives}}
    front = frame[frame["pareto"]][list(objectives)].to_numpy(float)
    for i, o in enumerate(objectives):
        others = [j for j in range(len(objectives)) if j != i]
        ok = np.all(front[:, others] <= pv[others], axis=1) if len(front) else np.zeros(0, bool)
        best = front[ok, i].min() if ok.any() else pv[i]
        out[f"gain_{o}"] = float(max(0.0, (pv[i] - best) / pv[i])) if pv[i] > 0 else 0.0
    return out


def importances(study, objectives: Sequence[str] | None = None, seed: int = 0):
    """Optuna's ``get_param_importances`` (:func:`_evaluator`) for each objective over the feasible
    trials, and for the constraint violation (sum of the positive constraints) over all: a
    DataFrame with one row per parameter and one column per target."""
    import optuna
    import pandas as pd

    objectives = list(objectives or study.user_attrs.get("objectives"))
    trials = _finished(study)
    feasible = [t for t in trials if _feasible(t)]
    cols = {}
    targets = {o: (feasible, lambda t, i=i: t.values[i]) for i, o in enumerate(objectives)}
    targets["constraint_violation"] = (trials, lambda t: float(sum(
        max(c, 0.0) for c in t.user_attrs.get("constraints", [1e9]))))
    for name, (group, target) in targets.items():
        if len(group) < 2:
            continue  # nothing to explain
        try:
            with warnings.catch_warnings():  # PED-ANOVA's notes on tiny or tied studies
                warnings.simplefilter("ignore")
                cols[name] = optuna.importance.get_param_importances(
                    _in_memory(study, group), target=target, evaluator=_evaluator(seed))
        except (RuntimeError, ValueError):  # e.g. every trial with the same parameters
            continue
    return pd.DataFrame(cols).fillna(0.0)


# --- held-out evaluation --------------------------------------------------------------------

def evaluate_heldout(setups: Mapping[str, Mapping[str, float]],
                     seeds: Sequence[int] = HELDOUT_SEEDS, max_steps: int = PASSAGE_STEPS,
                     base: Config | None = None, train_seeds: Sequence[int] = (),
                     workers: int | None = None, scheduler: str | None = None, client=None,
                     out=None, runs_dir=None, log: Callable[[str], None] = print):
    """Fly each set-up of ``setups`` (``{name: params}``) on the held-out ``seeds``.

    Set-ups with the same parameters share their flights (and the printed one shares the
    Monte Carlo study's). Raises ``ValueError`` if a held-out seed is a training seed.
    Returns the table, one row per (set-up, seed), with a ``setup`` column.
    """
    import pandas as pd

    seeds = tuple(int(s) for s in seeds)
    overlap = sorted(set(seeds) & {int(s) for s in train_seeds})
    if overlap:
        raise ValueError(f"seeds: held-out scenes must never be training scenes, both hold "
                         f"{overlap}")
    if not seeds:
        raise ValueError("seeds must hold at least one held-out scene")
    base = base or Config()
    unique: dict[tuple, list[str]] = {}
    for name, params in setups.items():
        p = {n: float(v) for n, v in params.items() if n in TUNABLE}
        unique.setdefault(tuple(sorted(p.items())), []).append(name)
    specs = [tuning_spec(dict(key), s, max_steps, base) for key in unique for s in seeds]
    out = Path(out) if out is not None else paths.results_dir() / "tuning" / "heldout"
    result = run_study(Study("tuning_heldout", tuple(specs), "held-out set-ups"), out=out,
                       workers=workers, scheduler=scheduler, client=client,
                       runs_dir=runs_dir, progress=False, log=log)
    table = result.table
    parts = []
    for i, names in enumerate(unique.values()):
        rows = table.iloc[i * len(seeds):(i + 1) * len(seeds)]
        for name in names:
            parts.append(rows.assign(setup=name))
    order = {n: i for i, n in enumerate(setups)}
    full = pd.concat(parts, ignore_index=True)
    return full.sort_values(["setup", "scene_seed"], key=lambda c: c.map(order)
                            if c.name == "setup" else c, kind="stable").reset_index(drop=True)


HELDOUT_COLUMNS = ("hf_energy_fraction", "tv_u_rate_N_per_s", "time_to_complete_s",
                   "min_clearance_m")
"""Measures compared on the held-out scenes."""


def heldout_summary(table, n_resamples: int = 5000, seed: int = 0):
    """The held-out comparison, one tidy table (``kind`` column):

    * ``rate`` rows: completed / collision / stalled / step limit / failed per set-up with
      Clopper–Pearson 95 % intervals (:func:`paper_repro.analysis.rates`);
    * ``median`` rows: the median of each of :data:`HELDOUT_COLUMNS` per set-up over its
      flown scenes (completed ones for the time), with a bootstrap 95 % interval;
    * ``paired`` rows: each tuned set-up against ``printed`` on the scenes both flew (both
      completed, for the time), the
      median per-scene ratio (difference for clearance) with a bootstrap interval and the
      Wilcoxon signed-rank p-value (:func:`paper_repro.analysis.paired`).
    """
    import pandas as pd

    from . import analysis

    rates = analysis.rates(table, by="setup").assign(kind="rate")
    # Every run that flew: chattering and clearance of a stalled flight are measured too;
    # the time to complete is NaN unless the passage completed, so it is compared on the
    # scenes that completed (both set-ups', for the paired rows).
    done = table[table["status"] == "ok"]
    med = []
    for setup, group in done.groupby("setup", sort=False):
        for col in HELDOUT_COLUMNS:
            v = group[col].dropna().to_numpy(float)
            lo, hi = (analysis._bootstrap_median(v, n_resamples, 0.95, seed) if len(v) >= 3
                      else (np.nan, np.nan))
            med.append({"setup": setup, "measure": col, "n": len(v),
                        "median": float(np.median(v)) if len(v) else np.nan,
                        "low": lo, "high": hi, "kind": "median"})
    pairs = []
    for other in [s for s in table["setup"].unique() if s != "printed"]:
        p = analysis.paired(done, a="printed", b=other, columns=HELDOUT_COLUMNS,
                            group="setup", n_resamples=n_resamples, seed=seed)
        pairs.append(p.assign(setup=other, kind="paired"))
    med = pd.DataFrame(med, columns=["setup", "measure", "n", "median", "low", "high", "kind"])
    return pd.concat([rates, med, *pairs], ignore_index=True)


def presets_from_setups(setups: Mapping[str, Mapping[str, float]],
                        base: Config | None = None) -> dict:
    """``{name: {"distance": {...}, "barrier": {...}}}``: the set-ups as configuration
    overrides, ready for ``dataclasses.replace`` (:func:`preset_config`)."""
    base = base or Config()
    out = {}
    for name, params in setups.items():
        cfg = apply_params(base, {n: v for n, v in params.items() if n in TUNABLE})
        out[name] = {"distance": dataclasses.asdict(cfg.distance),
                     "barrier": dataclasses.asdict(cfg.barrier)}
        if "trial" in params:
            out[name]["trial"] = int(params["trial"])
    return out


def preset_config(name: str, directory=None, base: Config | None = None) -> Config:
    """The configuration of a tuned preset (``best_chattering``, ``best_time``, ``printed``)
    saved in ``<directory>/presets.json`` (default ``figures/tuning``)."""
    d = Path(directory) if directory is not None else tuning_dir()
    presets = json.loads((d / "presets.json").read_text())
    if name not in presets:
        raise ValueError(f"name must be one of {sorted(presets)}, got {name!r}")
    base = base or Config()
    p = presets[name]
    return dataclasses.replace(base, distance=dataclasses.replace(base.distance,
                                                                  **p["distance"]),
                               barrier=dataclasses.replace(base.barrier, **p["barrier"]))


# --- figures (drawn from the saved study and table) -----------------------------------------

def plot_front(frame, objectives: Sequence[str] = DEFAULT_OBJECTIVES, setups=None):
    """The trials in objective space: feasible (dots), infeasible (crosses), the feasible
    Pareto front (line), the printed set-up (star) and the held-out picks (circled)."""
    import matplotlib.pyplot as plt

    x, y = objectives[0], objectives[-1]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    feas, infeas = frame[frame["feasible"]], frame[~frame["feasible"]]
    fin = infeas[np.isfinite(infeas[x]) & np.isfinite(infeas[y])]
    ax.scatter(fin[x], fin[y], marker="x", color="0.6", label=f"infeasible ({len(infeas)})")
    ax.scatter(feas[x], feas[y], s=18, color="C0", label=f"feasible ({len(feas)})")
    front = frame[frame["pareto"]].sort_values(x)
    ax.step(front[x], front[y], where="post", color="C1", lw=1.5,
            label=f"Pareto front ({len(front)})")
    ax.scatter(front[x], front[y], s=30, color="C1", zorder=3)
    pr = frame[frame["printed"]]
    ax.scatter(pr[x], pr[y], marker="*", s=220, color="C3", zorder=4, edgecolor="k",
               label="printed (trial 0)")
    for k, (name, params) in enumerate((setups or {}).items()):
        if "trial" in params:
            row = frame[frame["number"] == params["trial"]]
            ax.scatter(row[x], row[y], s=160, facecolor="none", edgecolor=f"C{k + 4}",
                       lw=2, zorder=5, label=name.replace("_", " "))
    ax.set_xlabel(OBJECTIVES.get(x, x))
    ax.set_ylabel(OBJECTIVES.get(y, y))
    ax.set_title("Training scenes: mean over scenes per trial")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_importances(imp):
    """Parameter importances, one group of bars per target."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    imp.plot.barh(ax=ax)
    ax.set_xlabel("importance (Optuna get_param_importances, normalised per target)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_heldout(summary):
    """Held-out comparison: completion rate and the median of each measure with 95 %
    intervals, per set-up."""
    import matplotlib.pyplot as plt

    setups = list(dict.fromkeys(summary.loc[summary["kind"] == "rate", "setup"]))
    panels = [("completed", "completion rate")] + [(c, OBJECTIVES.get(c, c)) for c in
                                                   HELDOUT_COLUMNS]
    fig, axes = plt.subplots(1, len(panels), figsize=(3.0 * len(panels), 3.2))
    for ax, (col, label) in zip(axes, panels):
        if col == "completed":
            d = summary[(summary["kind"] == "rate") & (summary["event"] == "completed")]
            mid = d.set_index("setup")["rate"]
        else:
            d = summary[(summary["kind"] == "median") & (summary["measure"] == col)]
            mid = d.set_index("setup")["median"]
        d = d.set_index("setup").reindex(setups)
        mid = mid.reindex(setups)
        err = np.vstack([mid - d["low"], d["high"] - mid]).clip(min=0)
        ax.errorbar(range(len(setups)), mid, yerr=np.nan_to_num(err), fmt="o", capsize=4)
        ax.set_xticks(range(len(setups)), [s.replace("_", "\n") for s in setups], fontsize=8)
        ax.set_title(label if col != "min_clearance_m" else "min clearance, m", fontsize=9)
    fig.tight_layout()
    return fig


# --- the command ----------------------------------------------------------------------------

def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro tune``."""
    from .reproduce import positive_int

    parser.add_argument("--trials", type=positive_int, default=None,
                        help=f"finished trials the study should hold (default {DEFAULT_TRIALS}; "
                             f"{QUICK['trials']} with --quick); a resumed study runs the rest")
    parser.add_argument("--quick", action="store_true",
                        help="a few 400-step trials (what CI executes); output under "
                             "figures/quick/tuning/")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes of the embedded Dask cluster (default: one per "
                             "core; 0: no Dask, one trial at a time in this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="send the runs to an existing Dask scheduler (tcp://host:8786)")
    parser.add_argument("--storage", default=None, metavar="URL",
                        help="Optuna RDB storage (default sqlite:///figures/tuning/tuning.db)")
    parser.add_argument("--objectives", nargs="+", default=list(DEFAULT_OBJECTIVES),
                        metavar="NAME", help=f"objectives to minimise, of {sorted(OBJECTIVES)}")
    parser.add_argument("--scenes", type=positive_int, default=None,
                        help=f"training scenes (default {DEFAULT_SCENES}; "
                             f"{QUICK['scenes']} with --quick)")
    parser.add_argument("--heldout", type=int, default=None,
                        help=f"held-out scenes (default {len(HELDOUT_SEEDS)}; "
                             f"{QUICK['heldout']} with --quick; 0 skips the evaluation)")
    parser.add_argument("--sampler", choices=("tpe", "nsga2"), default="tpe")
    parser.add_argument("--seed", type=int, default=0, help="sampler seed")
    parser.add_argument("--out", default=None,
                        help="where the storage, tables and figures go (default "
                             "figures/tuning, or figures/quick/tuning)")
    parser.add_argument("--no-figures", action="store_true",
                        help="do not execute the notebook 12_tuning")


def main(args) -> int:
    """``python -m paper_repro tune``: the study (resumed if stored), the held-out evaluation,
    then notebook ``12_tuning``, which draws everything from the saved study and table."""
    from .reproduce import duration

    quick = args.quick
    trials = args.trials or (QUICK["trials"] if quick else DEFAULT_TRIALS)
    out = Path(args.out) if args.out else tuning_dir(quick)
    heldout = args.heldout if args.heldout is not None else (
        QUICK["heldout"] if quick else len(HELDOUT_SEEDS))
    if heldout > len(HELDOUT_SEEDS):
        raise ValueError(f"--heldout must be at most {len(HELDOUT_SEEDS)} (the held-out seeds "
                         f"{HELDOUT_SEEDS[0]}-{HELDOUT_SEEDS[-1]}), got {heldout}")
    log = lambda line: print(line, flush=True)  # noqa: E731
    # Everything is checked before a cluster is started or a scene flown.
    _check_tune_args(trials, quick, args.workers, args.scheduler, args.storage, None,
                     args.objectives, args.scenes, None, args.sampler, None, Config())
    for name in ("heldout", "seed"):
        if getattr(args, name) is not None and getattr(args, name) < 0:
            raise ValueError(f"--{name} must be an integer >= 0, got {getattr(args, name)}")
    t0 = time.perf_counter()
    with _cluster(args.workers, args.scheduler, None, log) as client:
        res = tune(trials, quick=quick, client=client, storage=args.storage,
                   objectives=args.objectives, scenes=args.scenes, sampler=args.sampler,
                   seed=args.seed, out=out, log=log)
        if heldout:
            run_heldout(res, heldout, client=client, log=log)
    print(f"tune: {len(_finished(res.study))} trials, {res.flown_trials} run now, in "
          f"{duration(time.perf_counter() - t0)} -> {out}", flush=True)
    if not args.no_figures:
        from .reproduce import execute_notebook, notebook_path

        execute_notebook(notebook_path("12_tuning"),
                         paths.executed_dir(quick) / "12_tuning.ipynb",
                         {"tuning_dir": str(out)})
        print(f"notebook 12_tuning: figures in {out}", flush=True)
        from .evidence import command_line, stamp

        stamp(out, command_line())  # last: the set is this code's
    return 0


def run_heldout(res: TuningResult, n: int = len(HELDOUT_SEEDS), client=None, runs_dir=None,
                log: Callable[[str], None] = print):
    """The held-out step of ``tune``: pick the set-ups from the front, fly them on the first
    ``n`` held-out seeds, write ``heldout_table.csv`` and ``presets.json`` into the tuning
    folder. Returns the table."""
    meta = res.study.user_attrs
    base = Config.from_dict(meta["base"])
    setups = best_setups(trials_frame(res.study), meta["objectives"], base)
    runs_dir = Path(runs_dir) if runs_dir is not None else paths.results_dir() / "runs"
    table = evaluate_heldout(setups, HELDOUT_SEEDS[:n], meta["max_steps"], base, res.seeds,
                             client=client, workers=0 if client is None else None,
                             out=runs_dir.parent / "tuning" / "heldout", runs_dir=runs_dir,
                             log=log)
    from .study import TIMING_COLUMNS

    keep = [c for c in table.columns if c != "traceback"]
    flight, timings = metrics.split_timings(table[keep], TIMING_COLUMNS)
    flight.to_csv(res.directory / "heldout_table.csv", index=False, float_format="%.6g")
    timings.insert(0, "name", table["name"])
    timings.to_csv(res.directory / "heldout_timings.csv", index=False, float_format="%.4g")
    _write_json(res.directory / "presets.json", presets_from_setups(setups, base))
    return table


def tuning_dir(quick: bool = False) -> Path:
    """Committed home of the tuning study and its figures: ``figures/tuning`` (or
    ``figures/quick/tuning``, git-ignored)."""
    return paths.figures_dir(quick) / "tuning"


# --- helpers --------------------------------------------------------------------------------

def _shown_storage(storage: str, out: Path) -> str:
    """The storage URL as recorded in ``tuning.json``: relative to the tuning folder when the
    database lives in it (the same on every machine), else as given."""
    prefix = f"sqlite:///{out}/"
    return "sqlite:///" + storage[len(prefix):] if storage.startswith(prefix) else storage


def _check_tune_args(trials, quick, workers, scheduler, storage, space, objectives, scenes,
                     seeds, sampler, max_steps, base) -> dict:
    if not (isinstance(trials, int) and not isinstance(trials, bool) and trials >= 1):
        raise ValueError(f"trials must be an integer >= 1, got {trials!r}")
    objectives = check_objectives(objectives)
    space = search_space(space, base)
    if sampler not in ("tpe", "nsga2"):
        raise ValueError(f"sampler must be one of ('tpe', 'nsga2'), got {sampler!r}")
    if workers is not None and not (isinstance(workers, int) and workers >= 0):
        raise ValueError(f"workers must be an integer >= 0, got {workers!r}")
    if scheduler is not None and not (isinstance(scheduler, str) and "://" in scheduler):
        raise ValueError(f"scheduler must be an address like 'tcp://host:8786', got "
                         f"{scheduler!r}")
    if storage is not None:
        _check_storage(storage)
    n = scenes if scenes is not None else (QUICK["scenes"] if quick else DEFAULT_SCENES)
    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"scenes must be an integer >= 1, got {n!r}")
    if seeds is not None:
        if not seeds or not all(isinstance(s, (int, np.integer)) and s >= 0 for s in seeds):
            raise ValueError(f"seeds must be a non-empty sequence of integers >= 0, got "
                             f"{seeds!r}")
        _check_disjoint(seeds)
    steps = max_steps if max_steps is not None else (QUICK["max_steps"] if quick
                                                     else PASSAGE_STEPS)
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"max_steps must be an integer >= 1, got {steps!r}")
    return {"objectives": objectives, "space": space, "scenes": n, "max_steps": steps}


def _check_storage(url: str) -> None:
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        make_url(url)
    except (ArgumentError, ValueError, TypeError):
        raise ValueError(f"storage must be an RDB URL like 'sqlite:///tuning.db', got "
                         f"{url!r}") from None


def _check_disjoint(seeds) -> None:
    overlap = sorted(set(int(s) for s in seeds) & set(HELDOUT_SEEDS))
    if overlap:
        raise ValueError(f"seeds: training scenes must not be held-out scenes "
                         f"({HELDOUT_SEEDS[0]}-{HELDOUT_SEEDS[-1]}), got {overlap}")


def _check_stored(study, stored: dict) -> None:
    """A resumed study must be the same study: same objectives, space, step limit and base."""
    for k in ("objectives", "space", "max_steps", "require_completion", "base"):
        if k in study.user_attrs and json.loads(json.dumps(study.user_attrs[k])) != \
                json.loads(json.dumps(stored[k])):
            raise ValueError(f"{k}: the stored study {study.study_name!r} was run with "
                             f"{study.user_attrs[k]!r}, not {stored[k]!r}; use another "
                             "--storage or study name")


def _load_existing(name: str, storage: str):
    import optuna

    try:
        return optuna.load_study(study_name=name, storage=storage)
    except KeyError:  # no such study in the storage yet
        return None


def _sampler(name: str, seed: int, n_objectives: int):
    """The sampler, constrained. Optuna >= 5 reads the constraints each trial sets by name
    (``Trial.set_constraint``, its replacement for ``constraints_func``); Optuna 4 gets them
    through ``constraints_func``. Either way a value > 0 makes the trial infeasible to the
    sampler, which ranks it behind every feasible trial."""
    import optuna

    native = hasattr(optuna.trial.Trial, "set_constraint")
    con = {} if native else {"constraints_func": _constraints}
    if name == "nsga2":
        return optuna.samplers.NSGAIISampler(population_size=10, seed=seed, **con)
    # Multi-objective TPE: 10 random trials, then TPE; the constant liar keeps concurrent
    # trials from all sampling the same point.
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=10, multivariate=True,
                                      constant_liar=True, **con)


def _constraints(trial) -> list[float]:
    """``constraints_func``: what the objective stored (≤ 0 feasible)."""
    return list(trial.user_attrs.get("constraints", [math.inf] * len(CONSTRAINTS)))


def _finished(study) -> list:
    import optuna

    return study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))


def _feasible(trial) -> bool:
    con = trial.user_attrs.get("constraints")
    return con is not None and all(c <= 0 for c in con) and all(
        math.isfinite(v) for v in trial.values)


def _evaluator(seed: int):
    """fANOVA when scikit-learn is installed (Optuna's default), else PED-ANOVA, which Optuna
    ships without extra dependencies."""
    import optuna

    try:
        import sklearn  # noqa: F401
    except ImportError:
        # The top quarter of the trials (not the default tenth): a few dozen trials leave
        # too few in a tenth to compare distributions.
        return optuna.importance.PedAnovaImportanceEvaluator(target_quantile=0.25)
    return optuna.importance.FanovaImportanceEvaluator(seed=seed)


def _in_memory(study, trials):
    import optuna

    s = optuna.create_study(directions=study.directions)
    s.add_trials(trials)
    return s


def _non_dominated(values: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``values`` (n, k) that no other row dominates (all minimised)."""
    keep = []
    for i, v in enumerate(values):
        dominated = np.any(np.all(values <= v, axis=1) & np.any(values < v, axis=1))
        if not dominated:
            keep.append(i)
    return np.asarray(keep, int)


def _scene_records(table) -> list[dict]:
    cols = ["scene_seed", "status", "outcome", "completed", "stalled", "collision",
            "min_clearance_m", "time_to_complete_s", "hf_energy_fraction",
            "tv_u_rate_N_per_s", "steps"]
    recs = []
    for _, row in table.iterrows():
        rec = {}
        for c in cols:
            v = row.get(c)
            if isinstance(v, (np.generic,)):
                v = v.item()
            if isinstance(v, float) and not math.isfinite(v):
                v = None
            rec[c] = v
        recs.append(rec)
    return recs


class _cluster:
    """Context: a Dask client for the whole tuning (the embedded cluster is started once, not
    per trial); ``None`` for ``workers=0``; an outside ``client`` is passed through."""

    def __init__(self, workers, scheduler, client, log):
        self.args = workers, scheduler, client, log
        self.own = self.cluster = None

    def __enter__(self):
        workers, scheduler, client, log = self.args
        if client is not None:
            return client
        if scheduler is None and workers == 0:
            return None
        import os

        from distributed import Client, LocalCluster

        if scheduler is not None:
            self.own = Client(scheduler)
        else:
            self.cluster = LocalCluster(n_workers=workers or (os.cpu_count() or 1),
                                        threads_per_worker=1, processes=True,
                                        dashboard_address=":0", silence_logs=40)
            self.own = Client(self.cluster)
        log(f"dask: {len(self.own.scheduler_info()['workers'])} worker(s), dashboard "
            f"{self.own.dashboard_link}")
        return self.own

    def __exit__(self, *exc):
        if self.own is not None:
            self.own.close()
        if self.cluster is not None:
            self.cluster.close()
        return False


def _fmt_params(params: Mapping[str, float]) -> str:
    return ", ".join(f"{n} {v:g}" for n, v in params.items())


def _write_json(path: Path, data: dict) -> None:
    import os

    tmp = path.with_name(f".{path.name}.{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=1, default=str) + "\n")
    os.replace(tmp, path)

"""Automatic tuning of η, σ, d_min, κ, μ and δ with Optuna, flown on the study engine.

The paper names "automatic tuning of smoothing and penalty parameters" as its future work; its
parameters were hand-picked for one scene, and four of ours (κ, ε, d_min, λ) were chosen by us.
:func:`tune` runs a multi-objective Optuna study over the parameters of :data:`SEARCH_SPACE`:

* a *trial* is a parameter set flown on the training scenes, random passages
  (:func:`paper_repro.studies.catalogue.passage_config`). Its scenes are one small
  :class:`~paper_repro.studies.catalogue.Study` run by
  :func:`~paper_repro.studies.engine.run_study`, so every flight
  goes through the shared run cache and runs on the embedded Dask cluster or a real one;
  as many trials run at once as the cluster has workers;
* the *objectives* (:data:`OBJECTIVES`), both minimised, are measured per trial over its
  scenes (the mean over scenes): a chattering measure (share of thrust power above 5 Hz, or the
  total variation of u per second) and the time to complete the passage;
* the *constraints* are Optuna's (``constraints_func``, a value ≤ 0 is feasible), so an unsafe
  trial is infeasible to the sampler rather than merely penalised: minimum clearance ≥ 1 m
  over all scenes (:data:`~paper_repro.studies.tuning_space.MIN_CLEARANCE` says why 1 m), no
  collision, and every scene the printed set-up completes completed (no stall, no step limit,
  no raised run); see :data:`CONSTRAINTS`;
* the storage is an RDB URL (SQLite in ``figures/tuning/tuning.db`` by default), so an
  interrupted study resumes where it stopped (:func:`tune` counts the finished trials and flies
  only the missing ones; the flights of an interrupted trial come back from the run cache), and
  ``optuna-dashboard sqlite:///figures/tuning/tuning.db`` opens it.

Then :func:`~paper_repro.studies.tuning_results.evaluate_heldout` flies three set-ups, the
printed parameters (with our chosen defaults), the Pareto point best on chattering and the
front's safest point that chatters less than the printed set-up, on 30 held-out scenes never
used in tuning, and :func:`~paper_repro.studies.tuning_results.heldout_summary` compares them
with confidence intervals. A tuned set-up is offered as a preset only when it has no held-out
collision and completes at least as many held-out passages as the printed set-up.
``python -m paper_repro tune`` does all of it and executes notebook ``12_tuning``.

Training and held-out scenes. Under the printed parameters a good share of random passages
stall (the NMPC is local and deadlocks in front of some walls) or chatter (a share of thrust
power above 5 Hz near 1). A training set of easy scenes only would teach the sampler nothing
about either, and one where every trial must complete a scene the printed set-up stalls on
would make nearly every trial infeasible. So
:func:`~paper_repro.studies.tuning_scenes.training_scenes` takes, in candidate order,
``scenes − hard`` scenes the printed set-up flies cleanly (completed, clearance ≥ 1 m, share
above 5 Hz below :data:`~paper_repro.studies.tuning_scenes.CHATTERING`), and ``hard`` scenes
where it does not: half where it stalls or reaches the step limit, half where it completes but
chatters. A trial must complete the scenes the printed set-up completes; on the ones it stalls
on, a trial that gets through gains time. The printed flights are shared with the Monte Carlo
study's cache. The held-out scenes are taken whatever the printed set-up does on them, and
never overlap the candidates, so their rates are an unbiased comparison.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from paper_repro import paths
from paper_repro.config import Config
from paper_repro.paths import atomic_text, tuning_dir
from paper_repro.studies.catalogue import (
    PASSAGE_STEPS,
    QUICK_STEPS,
)
from paper_repro.studies.cluster import dask_client
from paper_repro.studies.engine import run_study
from paper_repro.studies.tuning_scenes import (
    check_disjoint,
    evaluate_table,
    training_scenes,
    trial_study,
)
from paper_repro.studies.tuning_space import (
    CONSTRAINTS,
    DEFAULT_OBJECTIVES,
    check_objectives,
    finished_trials,
    printed_params,
    search_space,
    suggest,
)

# --- the search space ----------------------------------------------------------------------


QUICK = {"trials": 4, "scenes": 2, "hard": 0, "heldout": 2, "max_steps": QUICK_STEPS}
"""``--quick``: a few trials of 400-step runs (every part exercised, nothing proved)."""

DEFAULT_TRIALS = 60
DEFAULT_SCENES = 12
DEFAULT_HARD = 4
STUDY_NAME = "cbf_nmpc"


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


@dataclass(frozen=True)
class TuningSettings:
    """What a tuning is: the study it runs (or resumes), on which scenes, towards what.

    Attributes
    ----------
    trials : finished trials the study should hold in all. A resumed study counts the ones it
        has and runs only the rest; trials left running by a killed driver are marked failed
        and their parameters queued again (their finished flights come back from the cache).
    quick : 400-step runs, 2 scenes, 4 trials by default (CI).
    space : ``{name: ParamRange | (low, high[, step])}``, or a sequence of names, or ``None``
        for :data:`~paper_repro.studies.tuning_space.SEARCH_SPACE` (see ``search_space``).
    objectives : names from :data:`~paper_repro.studies.tuning_space.OBJECTIVES` (all
        minimised).
    scenes : number of training scenes (12; 2 with ``quick``), chosen by
        :func:`training_scenes`; or ``seeds`` gives them explicitly.
    hard : how many of them are scenes where the printed set-up stalls or chatters (4; 0 with
        ``quick``); at most ``scenes``.
    seeds : the training scenes' seeds, instead of ``scenes`` (then every one must be
        completed).
    sampler : ``"tpe"`` (multi-objective TPE, the default) or ``"nsga2"``, both with the
        constraints of :data:`~paper_repro.studies.tuning_space.CONSTRAINTS`.
    seed : seed of the sampler (offset by the number of trials already stored, so a resumed
        study does not replay its first draws).
    max_steps : step limit per passage (15,000; 400 with ``quick``).
    base : configuration the tuned parameters are set in (default: printed).
    study_name : name of the Optuna study in the storage.
    storage : RDB URL (default ``sqlite:///<out>/tuning.db``).
    out : folder of ``tuning.json`` and the default storage (``figures/tuning``).
    runs_dir : the run cache (default ``results/runs``).
    """

    trials: int = DEFAULT_TRIALS
    quick: bool = False
    space: Mapping | Sequence[str] | None = None
    objectives: Sequence[str] = DEFAULT_OBJECTIVES
    scenes: int | None = None
    hard: int | None = None
    seeds: Sequence[int] | None = None
    sampler: str = "tpe"
    seed: int = 0
    max_steps: int | None = None
    base: Config | None = None
    study_name: str = STUDY_NAME
    storage: str | None = None
    out: str | Path | None = None
    runs_dir: str | Path | None = None


def tune(settings: TuningSettings | None = None, *, workers: int | None = None,
         scheduler: str | None = None, client=None, log: Callable[[str], None] = print,
         callbacks: Sequence[Callable] = ()) -> TuningResult:
    """Run (or resume) the tuning study ``settings`` describe until it holds
    ``settings.trials`` finished trials.

    Parameters
    ----------
    settings : :class:`TuningSettings` (default: the full tuning, 40 trials on 4 scenes).
    workers, scheduler, client : where the flights run, as
        :func:`~paper_repro.studies.engine.run_study`; as many trials run at once as there
        are workers (``workers=0``: one at a time, in this process).
    log : where progress lines go.
    callbacks : Optuna callbacks ``(study, frozen_trial)``, called after each trial.

    Everything is checked (space, objectives, counts, storage URL, sampler) before a scene is
    built or a run flown; a mismatch with what a resumed study stored raises ``ValueError``.
    """
    import optuna

    st = settings if settings is not None else TuningSettings()
    if not isinstance(st, TuningSettings):
        raise ValueError(f"settings must be a TuningSettings, got {type(st).__name__}")
    trials, quick, storage, study_name = st.trials, st.quick, st.storage, st.study_name
    space, objectives, scenes, seeds = st.space, st.objectives, st.scenes, st.seeds
    sampler, seed, max_steps, out, runs_dir = (st.sampler, st.seed, st.max_steps, st.out,
                                               st.runs_dir)
    base = st.base or Config()
    spec = check_tune_args(trials, quick, workers, scheduler, storage, space, objectives,
                            scenes, seeds, sampler, max_steps, base, st.hard)
    out = Path(out) if out is not None else tuning_dir(quick)
    out.mkdir(parents=True, exist_ok=True)
    storage = storage or f"sqlite:///{out / 'tuning.db'}"
    runs_dir = Path(runs_dir) if runs_dir is not None else paths.results_dir() / "runs"
    trials_dir = runs_dir.parent / "tuning" / study_name  # per-trial tables (not committed)
    max_steps, objectives, space = spec["max_steps"], spec["objectives"], spec["space"]
    start = time.perf_counter()

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    existing = _load_existing(study_name, storage, log)
    with tuning_client(workers, scheduler, client, log) as cluster_client:
        train, must = _scenes_of(existing, seeds, spec, max_steps, base, cluster_client,
                                 runs_dir, quick, log)
        stored = {"objectives": list(objectives), "seeds": list(train),
                  "must_complete": list(must),
                  "space": {n: [r.low, r.high, r.step] for n, r in space.items()},
                  "max_steps": max_steps, "require_completion": not quick,
                  "base": json.loads(json.dumps(base.key_dict(), default=str))}
        study = _open_study(optuna, existing, study_name, storage, sampler, seed, stored,
                            base, space, log)
        write_json(out / "tuning.json", {
            "study_name": study_name, "storage": _shown_storage(storage, out),
            "sampler": sampler, "seed": seed, **stored,
            "space_why": {n: r.why for n, r in space.items()}})
        remaining = trials - len(finished_trials(study))
        n_jobs = 1 if cluster_client is None else max(
            1, len(cluster_client.scheduler_info()["workers"]))
        log(f"tune: study {study_name!r} in {storage}: {len(finished_trials(study))} finished "
            f"trials, {max(remaining, 0)} to run on {n_jobs} worker(s); training scenes "
            f"{list(train)}")
        flown = [0]
        objective = _objective(space, train, must, max_steps, base, objectives, quick,
                               trials_dir, runs_dir, cluster_client, flown, log)
        if remaining > 0:
            _ask_and_tell(study, objective, remaining, n_jobs, callbacks)
    wall = time.perf_counter() - start
    write_json(out / "tuning.json", {
        "study_name": study_name, "storage": _shown_storage(storage, out), "sampler": sampler,
        "seed": seed, "trials": len(finished_trials(study)), **stored,
        "space_why": {n: r.why for n, r in space.items()}})
    # What the machine determines, apart (tuning.json is what the flights determine). A call
    # that ran no trial keeps the timings of the call that did (as a cached study does).
    if flown[0] > 0 or not (out / "timings.json").is_file():
        write_json(out / "timings.json", {"flown_trials_last_call": flown[0],
                                           "wall_time_s_last_call": wall})
    return TuningResult(study, storage, train, out, flown[0], wall)


def _scenes_of(existing, seeds, spec: dict, max_steps: int, base: Config, cluster_client,
               runs_dir: Path, quick: bool, log) -> tuple[tuple, tuple]:
    """The training scenes and those every trial must complete: a resumed study's own, the
    ``seeds`` given, or chosen by :func:`training_scenes`."""
    if existing is not None:
        train = tuple(existing.user_attrs.get("seeds", ()))
        return train, tuple(existing.user_attrs.get("must_complete", train))
    if seeds is not None:
        train, must = tuple(seeds), tuple(seeds)
    else:
        train, must = training_scenes(
            spec["scenes"], spec["hard"], max_steps=max_steps, base=base,
            client=cluster_client, runs_dir=runs_dir, require_completion=not quick, log=log)
    check_disjoint(train)
    return train, must


def _open_study(optuna, existing, study_name: str, storage: str, sampler: str, seed: int,
                stored: dict, base: Config, space: dict, log):
    """The Optuna study, created (with the printed set-up as trial 0) or resumed (its stored
    settings checked); a trial an earlier driver left running is failed and queued again."""
    n_done = 0 if existing is None else len(finished_trials(existing))
    objectives = stored["objectives"]
    study = optuna.create_study(
        study_name=study_name, storage=storage, directions=["minimize"] * len(objectives),
        load_if_exists=True, sampler=_sampler(sampler, seed + n_done, len(objectives)))
    if existing is None:
        for k, v in stored.items():
            study.set_user_attr(k, v)
        # Trial 0 is the printed set-up: where it lies against the front is the question.
        study.enqueue_trial(printed_params(base, space))
    else:
        _check_stored(study, stored)
        study.set_user_attr("base", stored["base"])  # the same base, in today's layout
    for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        study.tell(t.number, state=optuna.trial.TrialState.FAIL)
        study.enqueue_trial(t.params)
        log(f"tune: trial {t.number} was left running by an earlier driver: failed, its "
            "parameters queued again")
    return study


def _objective(space: dict, train: tuple, must: tuple, max_steps: int, base: Config,
               objectives, quick: bool, trials_dir: Path, runs_dir: Path, cluster_client,
               flown: list, log):
    """The trial's objective: fly the training scenes with the suggested parameters (one
    study each, through the run cache), and score the table; ``flown[0]`` counts the
    trials."""
    def objective(trial):
        params = suggest(trial, space)
        table = run_study(
            trial_study(params, train, max_steps, base, f"trial-{trial.number:04d}"),
            out=trials_dir / f"trial-{trial.number:04d}", client=cluster_client,
            workers=0 if cluster_client is None else None, runs_dir=runs_dir,
            progress=False, log=lambda line: None).table
        values, constraints = evaluate_table(table, objectives, not quick,
                                             max_steps * base.nmpc.ts, must)
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
    return objective


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


# --- helpers --------------------------------------------------------------------------------

def _shown_storage(storage: str, out: Path) -> str:
    """The storage URL as recorded in ``tuning.json``: relative to the tuning folder when the
    database lives in it (the same on every machine), else as given."""
    prefix = f"sqlite:///{out}/"
    return "sqlite:///" + storage[len(prefix):] if storage.startswith(prefix) else storage


def check_tune_args(trials, quick, workers, scheduler, storage, space, objectives, scenes,
                     seeds, sampler, max_steps, base, hard=None) -> dict:
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
    k = hard if hard is not None else (QUICK["hard"] if quick else min(DEFAULT_HARD, n))
    if not (isinstance(k, int) and not isinstance(k, bool) and 0 <= k <= n):
        raise ValueError(f"hard must be an integer in [0, scenes = {n}], got {k!r}")
    if seeds is not None:
        if not seeds or not all(isinstance(s, (int, np.integer)) and s >= 0 for s in seeds):
            raise ValueError(f"seeds must be a non-empty sequence of integers >= 0, got "
                             f"{seeds!r}")
        check_disjoint(seeds)
    steps = max_steps if max_steps is not None else (QUICK["max_steps"] if quick
                                                     else PASSAGE_STEPS)
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"max_steps must be an integer >= 1, got {steps!r}")
    return {"objectives": objectives, "space": space, "scenes": n, "hard": k,
            "max_steps": steps}


def _check_storage(url: str) -> None:
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        make_url(url)
    except (ArgumentError, ValueError, TypeError):
        raise ValueError(f"storage must be an RDB URL like 'sqlite:///tuning.db', got "
                         f"{url!r}") from None


def _check_stored(study, stored: dict) -> None:
    """A resumed study must be the same study: same objectives, space, step limit and base (a
    base stored before a setting moved, :data:`~paper_repro.config_history.MOVED`, is read in the
    current layout)."""
    for k in ("objectives", "space", "max_steps", "require_completion", "base"):
        if k not in study.user_attrs:
            continue
        was = study.user_attrs[k]
        if k == "base":
            was = Config.from_dict(was).key_dict()
        if json.loads(json.dumps(was, default=str)) != json.loads(json.dumps(stored[k])):
            raise ValueError(f"{k}: the stored study {study.study_name!r} was run with "
                             f"{study.user_attrs[k]!r}, not {stored[k]!r}; use another "
                             "--storage or study name")


def _load_existing(name: str, storage: str, log=print):
    """The stored study, or ``None``. A SQLite file that is not a database (truncated,
    overwritten) is moved to ``<file>.damaged`` with one line naming it, and the study starts
    anew; its flights come back from the run cache."""
    import optuna
    import sqlalchemy.exc

    try:
        return optuna.load_study(study_name=name, storage=storage)
    except KeyError:  # no such study in the storage yet
        return None
    except sqlalchemy.exc.DatabaseError as exc:
        path = Path(storage.removeprefix("sqlite:///"))
        if not (storage.startswith("sqlite:///") and path.is_file()):
            raise
        aside = path.with_name(f"{path.name}.damaged")
        os.replace(path, aside)
        log(f"tune: damaged storage {path} ({type(exc.orig).__name__}: {exc.orig}); moved to "
            f"{aside.name}, starting the study anew")
        return None


def _sampler(name: str, seed: int, n_objectives: int):
    """The sampler, constrained. Optuna >= 5 reads the constraints each trial sets by name
    (``Trial.set_constraint``, its replacement for ``constraints_func``); Optuna 4 gets them
    through ``constraints_func``. Either way a value > 0 makes the trial infeasible to the
    sampler, which ranks it behind every feasible trial."""
    import optuna

    native = hasattr(optuna.trial.Trial, "set_constraint")
    con = {} if native else {"constraints_func": trial_constraints}
    if name == "nsga2":
        return optuna.samplers.NSGAIISampler(population_size=10, seed=seed, **con)
    # Multi-objective TPE: 10 random trials, then TPE; the constant liar keeps concurrent
    # trials from all sampling the same point.
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=10, multivariate=True,
                                      constant_liar=True, **con)


def trial_constraints(trial) -> list[float]:
    """``constraints_func``: what the objective stored (≤ 0 feasible)."""
    return list(trial.user_attrs.get("constraints", [math.inf] * len(CONSTRAINTS)))


def _fmt_params(params: Mapping[str, float]) -> str:
    return ", ".join(f"{n} {v:g}" for n, v in params.items())


def write_json(path: Path, data: dict) -> None:
    atomic_text(path, json.dumps(data, indent=1, default=str) + "\n")


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


def tuning_client(workers, scheduler, client, log):
    """Context: the Dask client of a whole tuning (``cluster.dask_client``, started once,
    not per trial), or ``None`` for ``workers=0``: the trials fly in this process."""
    if client is None and scheduler is None and workers == 0:
        return contextlib.nullcontext(None)
    return dask_client(workers, scheduler, client, log)

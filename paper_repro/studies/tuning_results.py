"""Reading a tuning study: trials as a table, the Pareto front, importances, and the held-out
comparison of the chosen set-ups against the printed parameters."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from paper_repro import paths
from paper_repro.analysis import metrics
from paper_repro.config import Config
from paper_repro.paths import tuning_dir
from paper_repro.studies.catalogue import (
    PASSAGE_STEPS,
    Study,
)
from paper_repro.studies.engine import run_study
from paper_repro.studies.tuning import TuningResult, write_json
from paper_repro.studies.tuning_scenes import HELDOUT_SEEDS, tuning_spec
from paper_repro.studies.tuning_space import (
    CONSTRAINTS,
    DEFAULT_OBJECTIVES,
    MIN_CLEARANCE,
    TUNABLE,
    apply_params,
    finished_trials,
    is_feasible,
    printed_params,
)

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
    constraints (named, :data:`CONSTRAINTS`), ``min_clearance_m`` (the smallest over the
    training scenes), ``feasible``, ``pareto`` (on the feasible front)
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
    for t in finished_trials(study):
        con = t.user_attrs.get("constraints")
        row = {"number": t.number, **{n: t.params.get(n, np.nan) for n in names},
               **dict(zip(objectives, t.values)),
               **dict(zip(CONSTRAINTS, con if con is not None else [np.inf] * 3)),
               "flown": t.user_attrs.get("flown", 0)}
        # The smallest clearance over the training scenes, m (from the shortfall below it).
        row["min_clearance_m"] = MIN_CLEARANCE - row["clearance_shortfall_m"]
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
    """The three held-out set-ups of :data:`~paper_repro.studies.tuning_space.SETUPS`:

    * ``printed``: ``base``'s values;
    * ``best_chattering``: the Pareto point best on the first objective (ties broken by the
      last objective, then by trial number);
    * ``safest``: among the Pareto points that chatter less than the printed set-up (the
      whole front when none does, or when the study holds no printed trial), the one with
      the largest clearance over the training scenes (ties broken by chattering, then by
      trial number).

    The two tuned set-ups may be the same trial; their flights are then shared.
    Raises ``ValueError`` when no trial is feasible: there is no front to pick from.
    """
    front = frame[frame["pareto"]]
    if front.empty:
        raise ValueError("no feasible trial: the study has no Pareto front to pick from")
    names = [c for c in frame.columns if c in TUNABLE]
    chat, speed = objectives[0], objectives[-1]
    printed = frame[frame["printed"]]
    calm = front if printed.empty else front[front[chat] < float(printed[chat].iloc[0])]
    calm = front if calm.empty else calm
    pick = {"best_chattering": front.sort_values([chat, speed, "number"]).iloc[0],
            "safest": calm.sort_values(["clearance_shortfall_m", chat, "number"]).iloc[0]}
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
    """Optuna's ``get_param_importances`` (PED-ANOVA, :func:`_evaluator`) for each objective
    over the feasible trials, and for the constraint violation (sum of the positive
    constraints) over all: a DataFrame with one row per parameter and one column per target."""
    import optuna
    import pandas as pd

    objectives = list(objectives or study.user_attrs.get("objectives"))
    trials = finished_trials(study)
    feasible = [t for t in trials if is_feasible(t)]
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
      Clopper–Pearson 95 % intervals (:func:`paper_repro.analysis.statistics.rates`);
    * ``median`` rows: the median of each of :data:`HELDOUT_COLUMNS` per set-up over its
      flown scenes (completed ones for the time), with a bootstrap 95 % interval;
    * ``paired`` rows: each tuned set-up against ``printed`` on the scenes both flew (both
      completed, for the time), the
      median per-scene ratio (difference for clearance) with a bootstrap interval and the
      Wilcoxon signed-rank p-value (:func:`paper_repro.analysis.statistics.paired`).
    """
    import pandas as pd

    from paper_repro.analysis import statistics as analysis

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


def verdicts(table) -> dict[str, dict]:
    """Whether each tuned set-up of a held-out table may be offered as a preset:
    ``{setup: {"offered": bool, "why": str}}``.

    A set-up is offered only when it has **no** held-out collision and completes at least as
    many held-out passages as the printed set-up (the same scenes, so the same count is the
    same rate). The printed set-up is the reference and always offered.
    """
    ok = table["status"] == "ok"
    out = {}
    counts = {}
    for setup, g in table.groupby("setup", sort=False):
        good = ok.loc[g.index]
        counts[setup] = (int((good & g["collision"].fillna(False).astype(bool)).sum()),
                         int((good & g["completed"].fillna(False).astype(bool)).sum()), len(g))
    ref = counts.get("printed")
    for setup, (collided, done, n) in counts.items():
        if setup == "printed":
            out[setup] = {"offered": True, "why": f"the reference: completed {done}/{n}, "
                          f"{collided} collisions"}
            continue
        reasons = []
        if collided:
            reasons.append(f"{collided}/{n} held-out collisions")
        if ref is not None and done < ref[1]:
            reasons.append(f"completed {done}/{n}, fewer than the printed set-up's {ref[1]}/{n}")
        out[setup] = {"offered": not reasons,
                      "why": "; ".join(reasons) if reasons else
                      f"0/{n} held-out collisions, completed {done}/{n} (printed: "
                      f"{ref[1] if ref else '?'}/{n})"}
    return out


def presets_from_setups(setups: Mapping[str, Mapping[str, float]],
                        base: Config | None = None,
                        verdict: Mapping[str, Mapping] | None = None) -> dict:
    """``{name: {"distance": {...}, "barrier": {...}, "offered": bool, "why": str}}``: the
    set-ups as configuration overrides, ready for ``dataclasses.replace``
    (:func:`preset_config`), with the held-out :func:`verdicts` when given."""
    base = base or Config()
    out = {}
    for name, params in setups.items():
        stored = apply_params(base, {n: v for n, v in params.items()
                                     if n in TUNABLE}).key_dict()  # as a run's key sees it
        out[name] = {"distance": stored["distance"], "barrier": stored["barrier"]}
        if "trial" in params:
            out[name]["trial"] = int(params["trial"])
        if verdict is not None and name in verdict:
            out[name].update(verdict[name])
    return out


def preset_config(name: str, directory=None, base: Config | None = None) -> Config:
    """The configuration of a tuned preset saved in ``<directory>/presets.json`` (default
    ``figures/tuning``): ``printed``, or a tuned set-up that the held-out evaluation offered
    (:func:`verdicts`). A set-up it did not offer raises ``ValueError`` saying why."""
    d = Path(directory) if directory is not None else tuning_dir()
    presets = json.loads((d / "presets.json").read_text())
    if name not in presets:
        raise ValueError(f"name must be one of {sorted(presets)}, got {name!r}")
    p = presets[name]
    if not p.get("offered", True):
        raise ValueError(f"name: the tuned set-up {name!r} is not offered as a preset "
                         f"({p.get('why', 'it failed the held-out evaluation')})")
    base = base or Config()
    return dataclasses.replace(base, distance=dataclasses.replace(base.distance,
                                                                  **p["distance"]),
                               barrier=dataclasses.replace(base.barrier, **p["barrier"]))


def run_heldout(res: TuningResult, n: int = len(HELDOUT_SEEDS), client=None, runs_dir=None,
                log: Callable[[str], None] = print):
    """The held-out step of ``tune``: pick the set-ups from the front, fly them on the first
    ``n`` held-out seeds, write ``heldout_table.csv`` and ``presets.json`` (with each set-up's
    :func:`verdicts`) into the tuning folder. Returns the table."""
    meta = res.study.user_attrs
    base = Config.from_dict(meta["base"])
    setups = best_setups(trials_frame(res.study), meta["objectives"], base)
    runs_dir = Path(runs_dir) if runs_dir is not None else paths.results_dir() / "runs"
    table = evaluate_heldout(setups, HELDOUT_SEEDS[:n], meta["max_steps"], base, res.seeds,
                             client=client, workers=0 if client is None else None,
                             out=runs_dir.parent / "tuning" / "heldout", runs_dir=runs_dir,
                             log=log)
    from paper_repro.studies.engine import TIMING_COLUMNS

    keep = [c for c in table.columns if c != "traceback"]
    flight, timings = metrics.split_timings(table[keep], TIMING_COLUMNS)
    flight.to_csv(res.directory / "heldout_table.csv", index=False, float_format="%.6g")
    timings.insert(0, "name", table["name"])
    timings.to_csv(res.directory / "heldout_timings.csv", index=False, float_format="%.4g")
    write_json(res.directory / "presets.json",
               presets_from_setups(setups, base, verdicts(flight)))
    return table


def _evaluator(seed: int):
    """PED-ANOVA on the best quarter of the trials (not Optuna's default tenth: a few dozen
    trials leave too few in a tenth to compare distributions). It ships with Optuna and needs no
    other library, so the importances are the same on every machine; fANOVA, Optuna's default,
    needs scikit-learn. ``seed`` is kept for an evaluator that samples."""
    import optuna

    del seed
    return optuna.importance.PedAnovaImportanceEvaluator(target_quantile=0.25)


def _non_dominated(values: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``values`` (n, k) that no other row dominates (all minimised)."""
    keep = []
    for i, v in enumerate(values):
        dominated = np.any(np.all(values <= v, axis=1) & np.any(values < v, axis=1))
        if not dominated:
            keep.append(i)
    return np.asarray(keep, int)


def _in_memory(study, trials):
    import optuna

    s = optuna.create_study(directions=study.directions)
    s.add_trials(trials)
    return s

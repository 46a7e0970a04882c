"""Which passages a tuning flies and how a trial is scored: the training and held-out scenes,
a trial's runs, and its objectives and constraints from its study table
(:mod:`paper_repro.studies.tuning` runs the study on them)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from paper_repro import paths
from paper_repro.config import Config
from paper_repro.studies.catalogue import PASSAGE_STEPS, Study, passage_config, passage_spec
from paper_repro.studies.engine import run_study
from paper_repro.studies.runs import RunSpec
from paper_repro.studies.tuning_space import (
    DEFAULT_OBJECTIVES,
    MIN_CLEARANCE,
    TUNABLE,
    apply_params,
    check_objectives,
    printed_params,
)

# --- the scenes -------------------------------------------------------------------------------

TRAIN_CANDIDATES = tuple(range(0, 60))
"""Seeds from which the training scenes are drawn (the first where the printed set-up
completes), shared with the Monte Carlo study's cache."""

HELDOUT_SEEDS = tuple(range(60, 90))
"""The held-out scenes: 30 seeds never among the training candidates, taken whatever the
printed set-up does on them."""

CHATTERING = 0.5
"""Share of thrust power above 5 Hz from which a printed flight counts as chattering. On the
Monte Carlo study's passages the printed set-up's share is bimodal, below 0.2 or above 0.75,
so any threshold between the two modes picks the same scenes."""

# --- runs of a trial -------------------------------------------------------------------------

def tuning_spec(params: Mapping[str, float], seed: int, max_steps: int = PASSAGE_STEPS,
                base: Config | None = None) -> RunSpec:
    """The passage through random scene ``seed`` under ``base`` with ``params`` set.

    When only η and σ differ from ``base`` this is
    :func:`~paper_repro.studies.catalogue.passage_spec`
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
    """One trial's flights as a :class:`~paper_repro.studies.catalogue.Study`: ``params`` on each
    seed."""
    return Study(name, tuple(tuning_spec(params, s, max_steps, base) for s in seeds),
                 f"tuning trial {params}")


def evaluate_table(table, objectives: Sequence[str] = DEFAULT_OBJECTIVES,
                   require_completion: bool = True, time_limit_s: float = PASSAGE_STEPS * 0.01,
                   must_complete: Sequence[int] | None = None
                   ) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A trial's objective values and constraint values from its study table.

    Parameters
    ----------
    table : one row per scene (:func:`~paper_repro.studies.engine.run_study`).
    objectives : names from :data:`OBJECTIVES`; each is the mean over scenes. A scene that did
        not complete counts ``time_limit_s`` as its time and a run that raised counts the worst
        chattering of the other scenes (or +inf): the trial is infeasible anyway, these only
        keep its values finite and ordered for the sampler.
    require_completion : a scene that reached its step limit counts as not completed (``False``
        for ``--quick`` runs, which all stop at their step limit: then only stalls and raised
        runs count).
    time_limit_s : s.
    must_complete : seeds of the scenes a trial must complete (those the printed set-up
        completes); ``None``: every scene.

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
    required = (np.ones(len(table), bool) if must_complete is None else
                table["scene_seed"].astype(int).isin([int(s) for s in must_complete]).to_numpy())
    lost = int((~done.to_numpy(bool) & required).sum())
    return tuple(values), (float(shortfall), float(collisions), float(lost))


# --- choosing the training scenes ---------------------------------------------------------

def training_scenes(n: int, hard: int = 0, candidates: Sequence[int] = TRAIN_CANDIDATES,
                    max_steps: int = PASSAGE_STEPS, base: Config | None = None, client=None,
                    runs_dir=None, require_completion: bool = True,
                    log: Callable[[str], None] = print
                    ) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The training scenes: ``n − hard`` seeds of ``candidates`` that ``base`` (printed) flies
    cleanly and ``hard`` seeds where it does not, each group the first in candidate order.

    * clean: completed, no collision, clearance ≥ :data:`MIN_CLEARANCE`, share of thrust
      power above 5 Hz below :data:`CHATTERING`;
    * hard: ``hard − hard // 2`` where the printed set-up stalls or reaches the step limit
      (with no collision), and ``hard // 2`` where it completes with no collision but chatters.

    The candidates are flown in batches of ``n`` through the run cache (the Monte Carlo study's
    printed passages are the same runs). ``require_completion=False`` (quick runs, which all
    stop at their step limit) counts any run that did not stall as clean.

    Returns
    -------
    seeds : the training seeds, sorted.
    must_complete : those of them the printed set-up completes (the clean and the chattering
        ones), which a trial must complete too.

    Raises ``ValueError`` if fewer scenes of a kind qualify than are asked.
    """
    if not (isinstance(hard, int) and 0 <= hard <= n):
        raise ValueError(f"hard must be an integer in [0, scenes = {n}], got {hard!r}")
    base = base or Config()
    runs_dir = Path(runs_dir) if runs_dir is not None else paths.results_dir() / "runs"
    wanted = {"clean": n - hard, "stalling": hard - hard // 2, "chattering": hard // 2}
    chosen: dict[str, list[int]] = {k: [] for k in wanted}
    pool = list(candidates)
    while any(len(chosen[k]) < wanted[k] for k in wanted) and pool:
        batch, pool = pool[:n], pool[n:]
        table = run_study(trial_study(printed_params(base), batch, max_steps, base,
                                      "training-screen"),
                          out=runs_dir.parent / "tuning" / "training-screen",
                          client=client, workers=0 if client is None else None,
                          runs_dir=runs_dir, progress=False, log=lambda line: None).table
        for i in range(len(table)):
            kind = _scene_kind(table.iloc[[i]], require_completion)
            if kind is not None and len(chosen[kind]) < wanted[kind]:
                chosen[kind].append(int(table["scene_seed"].iloc[i]))
        log(f"tune: screened seeds {batch}: training scenes so far {chosen}")
    short = {k: f"{len(chosen[k])} of {wanted[k]}" for k in wanted
             if len(chosen[k]) < wanted[k]}
    if short:
        raise ValueError(f"scenes: too few candidate seeds ({list(candidates)[0]}-"
                         f"{list(candidates)[-1]}) of each kind under the printed set-up: "
                         f"{short}")
    seeds = tuple(sorted(s for group in chosen.values() for s in group))
    must = tuple(sorted(chosen["clean"] + chosen["chattering"]))
    return seeds, must


def _scene_kind(row, require_completion: bool) -> str | None:
    """``clean``, ``stalling``, ``chattering`` or ``None`` (a collision, too close, raised) for
    one printed flight (a one-row table)."""
    _, (shortfall, collisions, lost) = evaluate_table(row, ("hf_energy_fraction",),
                                                      require_completion)
    r = row.iloc[0]
    if r["status"] != "ok" or collisions > 0:
        return None
    if lost > 0:
        return "stalling"
    if require_completion and float(r["hf_energy_fraction"]) >= CHATTERING:
        return "chattering"
    return "clean" if shortfall <= 0 else None


def check_disjoint(seeds) -> None:
    overlap = sorted(set(int(s) for s in seeds) & set(HELDOUT_SEEDS))
    if overlap:
        raise ValueError(f"seeds: training scenes must not be held-out scenes "
                         f"({HELDOUT_SEEDS[0]}-{HELDOUT_SEEDS[-1]}), got {overlap}")



"""Why the QPs of the moving studies fail, and what the relaxed QP and the floor change.

    python benchmarks/qp_failures.py [--min-solves 10] [--runs NAME ...] [--workers 2] [--save]

Picks the runs of the committed moving studies (``moving_obstacles``, ``moving_heldout``)
whose failed and relaxed solves add up to more than ``--min-solves``, and the runs named by
``--runs`` (by default :data:`HARD_QP_RUNS`). Flies each one twice:

* ``as designed``: the study's own configuration (the relaxed QP on, the design's floor);
* ``hard QP``: the relaxed QP off and the lowest altitude of 𝒳 back to the paper's
  (``QuadrotorParams().state_lower``), the controller the studies flew before either remedy.

Every solve whose hard QP no backend solved is recorded with its cause, whether the relaxed
QP then stepped in (``path`` ``relaxed``) or the solve failed (``failed``)
(:attr:`~paper_repro.solvers.rti.RealTimeNMPC.last_failure`,
:attr:`~paper_repro.solvers.rti.RealTimeNMPC.last_relaxation`):

* ``active_set``: the warm-started Riccati active set's status (``None``: skipped, the
  interior point was called first);
* ``interior_point``: the interior point's status (``solved``, ``iteration_limit``,
  ``not_positive_definite``);
* ``hpipm``: HPIPM's return status (:data:`HPIPM_STATUS`);
* ``finite_data``: the linearisation's numbers were all finite;
* ``outside_state_box``: the state was outside 𝒳, so the relaxed box was imposed.

Per run and variant it also gives where those solves were: with points in view, with the
vehicle inside the barrier's margin (clearance below √(2 d_min), the ½d² reading of d_min),
and the longest streak in a row; and whether the vehicle left the workspace (below the
ground, z < 0, say), the first step it did and its lowest altitude. ``--save`` writes
``figures/studies/qp_failures/`` (``runs.csv``, ``causes.csv``), stamped.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pandas as pd
from moving_heldout import heldout_study

from paper_repro import QuadrotorParams, paths
from paper_repro import studies as S
from paper_repro.evidence.golden import layer_of, stamp
from paper_repro.studies.runs import fly
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER

STUDIES = ("moving_obstacles", "moving_heldout")
"""The committed studies whose failed solves are explained."""

HPIPM_STATUS = {"0": "success", "1": "max_iter", "2": "min_step", "3": "nan_sol",
                "4": "incons_eq"}
"""HPIPM's return statuses (``enum hpipm_status`` of its headers)."""


def specs_by_name() -> dict:
    """Every run spec of the two studies, by name."""
    return {s.name: s for study in (S.moving_obstacles(), heldout_study(range(50, 150)))
            for s in study.specs}


def longest_streak(failed: np.ndarray) -> int:
    """The longest run of consecutive ``True`` in ``failed``."""
    best = run = 0
    for f in failed:
        run = run + 1 if f else 0
        best = max(best, run)
    return best


HARD_QP_RUNS = (
    "passage-euclidean-crossing-static-s032",
    "passage-smooth-eta0.3-sigma0.8-crossing-kalman-design-s041",
    "passage-euclidean-crossing-oracle-design-s057",
    "passage-euclidean-crossing-oracle-design-s139",
    "passage-smooth-eta0.3-sigma0.8-crossing-kalman-design-s063",
    "passage-smooth-eta0.3-sigma0.8-crossing-kalman-design-s066",
    "passage-smooth-eta0.3-sigma0.8-crossing-kalman-design-s083",
    "passage-smooth-eta0.3-sigma0.8-crossing-kalman-design-s096",
    "passage-euclidean-crossing-kalman-design-s145")
"""The runs whose hard QP fails most without the floor: more than 10 failed solves each in
the ``hard QP`` variant (its rows in ``runs.csv`` show the count). Flown by default."""

VARIANTS = ("as designed", "hard QP")
"""The two controllers each chosen run is flown with (see the module's text)."""


def hard_qp(spec):
    """``spec`` with the relaxed QP off and the paper's 𝒳 (no floor above the ground)."""
    cfg = spec.config
    lower = list(cfg.quadrotor.state_lower)
    lower[2] = QuadrotorParams().state_lower[2]
    return dataclasses.replace(spec, config=dataclasses.replace(
        cfg, solver=dataclasses.replace(cfg.solver, relaxed_qp=False),
        quadrotor=dataclasses.replace(cfg.quadrotor, state_lower=tuple(lower))))


def explain(job) -> tuple[dict, list[dict]]:
    """Fly ``job`` (a variant's name and a spec); its row and its hard QPs' causes."""
    variant, spec = job
    r = fly(spec, progress=False)
    hard = np.isin(r.status, ["qp_failed", "relaxed"])  # solves whose hard QP failed
    margin = float(np.sqrt(2 * r.config.barrier.d_min))
    outside = np.flatnonzero(((r.positions < WORKSPACE_LOWER) |
                              (r.positions > WORKSPACE_UPPER)).any(axis=1))
    row = {"name": spec.name, "variant": variant, "steps": r.steps, "outcome": r.outcome,
           "failed_solves": int(np.sum(~r.success)),
           "relaxed_solves": int(np.sum(r.status == "relaxed")),
           "hard_qp_failed": int(hard.sum()),
           "hard_qp_failed_in_view": int(np.sum(hard & (r.visible_points > 0))),
           "hard_qp_failed_inside_margin": int(np.sum(hard & (r.clearance < margin))),
           "longest_streak": longest_streak(hard),
           "min_clearance_m": float(r.clearance.min()),
           "left_workspace_step": int(outside[0]) if len(outside) else -1,
           "min_altitude_m": float(r.positions[:, 2].min())}
    causes = [{"name": spec.name, "variant": variant, "path": path, **_fields(cause),
               "count": n}
              for path, entry in (("failed", "qp_failures"), ("relaxed", "qp_relaxations"))
              for cause, n in r.meta.get(entry, {}).items()]
    return row, causes


def _fields(cause: str) -> dict:
    """The cause's text (``key value, key value``) as columns; HPIPM's status named."""
    fields = dict(part.split(" ", 1) for part in cause.split(", "))
    fields["hpipm"] = HPIPM_STATUS.get(fields["hpipm"], fields["hpipm"])
    return fields


def chosen_runs(min_solves: int, names: list[str]) -> pd.DataFrame:
    """The committed runs with more than ``min_solves`` failed and relaxed solves, and those
    named; columns ``name``, ``study``, ``failed_solves``, ``relaxed_solves``."""
    committed = pd.concat([pd.read_csv(paths.figures_dir() / "studies" / s / "table.csv")
                           .assign(study=s) for s in STUDIES])
    unknown = sorted(set(names) - set(committed["name"]))
    if unknown:
        raise SystemExit(f"--runs: no run of {STUDIES} is named {', '.join(unknown)}")
    many = committed["failed_solves"] + committed["relaxed_solves"] > min_solves
    return committed[many | committed["name"].isin(names)][
        ["name", "study", "failed_solves", "relaxed_solves"]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--min-solves", type=int, default=10)
    parser.add_argument("--runs", nargs="*", default=list(HARD_QP_RUNS))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    chosen = chosen_runs(args.min_solves, args.runs)
    specs = specs_by_name()
    todo = [(v, s if v == VARIANTS[0] else hard_qp(s))
            for s in (specs[n] for n in chosen["name"]) for v in VARIANTS]
    with ProcessPoolExecutor(args.workers) as pool:
        done = list(pool.map(explain, todo))
    study = dict(zip(chosen["name"], chosen["study"]))
    runs = pd.DataFrame([row for row, _ in done])
    runs.insert(1, "study", runs["name"].map(study))
    causes = pd.DataFrame([c for _, cs in done for c in cs],
                          columns=["name", "variant", "path", "active_set", "interior_point",
                                   "hpipm", "relaxed", "finite_data", "finite_step",
                                   "outside_state_box", "count"])
    pd.set_option("display.width", 250)
    print(runs.to_string(index=False))
    by = [c for c in causes.columns if c not in ("name", "count")]
    print(causes.groupby(by, dropna=False)["count"].sum().sort_values(ascending=False)
          .to_string() if len(causes) else "no hard QP failed")
    if args.save:
        out = paths.figures_dir() / "studies" / "qp_failures"
        out.mkdir(parents=True, exist_ok=True)
        runs.to_csv(out / "runs.csv", index=False, float_format="%.6g")
        causes.to_csv(out / "causes.csv", index=False)
        runs_arg = ("" if args.runs == list(HARD_QP_RUNS)
                    else f" --runs {' '.join(args.runs)}")
        stamp(out, f"python benchmarks/qp_failures.py --save --min-solves {args.min_solves}"
              + runs_arg,
              layer_of(*(s.config for _, s in todo)))


if __name__ == "__main__":
    main()

"""Why the QPs of the moving studies fail: each failed solve's cause, measured.

    python benchmarks/qp_failures.py [--min-failed 10] [--workers 2] [--save] [--relaxed-qp]

Flies again the runs of the committed moving studies (``moving_obstacles``,
``moving_heldout``) with more than ``--min-failed`` failed solves, and records for every
failed QP what each backend of the chain said
(:attr:`~paper_repro.solvers.rti.RealTimeNMPC.last_failure`):

* ``active_set``: the warm-started Riccati active set's status (``None``: skipped, the
  interior point was called first);
* ``interior_point``: the interior point's status (``solved``, ``iteration_limit``,
  ``not_positive_definite``);
* ``hpipm``: HPIPM's return status (:data:`HPIPM_STATUS`);
* ``finite_data``: the linearisation's numbers were all finite;
* ``outside_state_box``: the state was outside 𝒳, so the relaxed box was imposed.

Per run it also gives where the failed steps were: with points in view, with the vehicle
inside the barrier's margin (clearance below √(2 d_min), the ½d² reading of d_min), and the
longest streak of failures in a row; and whether the vehicle left the workspace (below its
floor, z < 0, say), the first step it did and its lowest altitude. ``--save`` writes
``figures/studies/qp_failures/`` (``runs.csv``, ``causes.csv``), stamped.

``--relaxed-qp`` flies the same runs with ``SolverParams(relaxed_qp=True)``
(:mod:`~paper_repro.solvers.relaxed_qp`) and prints what changed: the failed and the relaxed
solves, the outcome, the lowest altitude and the clearance.
"""

from __future__ import annotations

import argparse
import dataclasses
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pandas as pd
from moving_heldout import heldout_study

from paper_repro import paths
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


def explain(spec) -> tuple[dict, list[dict]]:
    """Fly ``spec``; its row and its causes."""
    r = fly(spec, progress=False)
    failed = ~r.success & (r.status == "qp_failed")
    margin = float(np.sqrt(2 * r.config.barrier.d_min))
    outside = np.flatnonzero(((r.positions < WORKSPACE_LOWER) |
                              (r.positions > WORKSPACE_UPPER)).any(axis=1))
    row = {"name": spec.name, "steps": r.steps, "outcome": r.outcome,
           "failed_solves": int(np.sum(~r.success)), "qp_failed": int(failed.sum()),
           "relaxed_solves": int(r.meta.get("qp_counts", {}).get("relaxed", 0)),
           "failed_in_view": int(np.sum(failed & (r.visible_points > 0))),
           "failed_inside_margin": int(np.sum(failed & (r.clearance < margin))),
           "longest_streak": longest_streak(failed),
           "min_clearance_m": float(r.clearance.min()),
           "left_workspace_step": int(outside[0]) if len(outside) else -1,
           "min_altitude_m": float(r.positions[:, 2].min())}
    causes = [{"name": spec.name, **_fields(cause), "count": n}
              for cause, n in r.meta.get("qp_failures", {}).items()]
    return row, causes


def _fields(cause: str) -> dict:
    """The cause's text (``key value, key value``) as columns; HPIPM's status named."""
    fields = dict(part.split(" ", 1) for part in cause.split(", "))
    fields["hpipm"] = HPIPM_STATUS.get(fields["hpipm"], fields["hpipm"])
    return fields


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--min-failed", type=int, default=10)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--save", action="store_true")
    parser.add_argument("--relaxed-qp", action="store_true")
    args = parser.parse_args()
    if args.save and args.relaxed_qp:
        parser.error("--save writes the committed flights' causes: it takes no --relaxed-qp")
    committed = pd.concat([pd.read_csv(paths.figures_dir() / "studies" / s / "table.csv")
                           .assign(study=s) for s in STUDIES])
    chosen = committed[committed["failed_solves"] > args.min_failed]
    specs = specs_by_name()
    todo = [specs[n] for n in chosen["name"]]
    if args.relaxed_qp:
        todo = [dataclasses.replace(s, config=dataclasses.replace(
            s.config, solver=dataclasses.replace(s.config.solver, relaxed_qp=True)))
            for s in todo]
    with ProcessPoolExecutor(args.workers) as pool:
        done = list(pool.map(explain, todo))
    runs = pd.DataFrame([row for row, _ in done])
    runs.insert(1, "study", chosen["study"].to_numpy())
    runs.insert(2, "committed_failed_solves", chosen["failed_solves"].to_numpy())
    causes = pd.DataFrame([c for _, cs in done for c in cs])
    pd.set_option("display.width", 250)
    print(runs.to_string(index=False))
    by = [c for c in causes.columns if c not in ("name", "count")]
    print(causes.groupby(by, dropna=False)["count"].sum().sort_values(ascending=False)
          .to_string() if len(causes) else "no failed QP")
    if args.save:
        out = paths.figures_dir() / "studies" / "qp_failures"
        out.mkdir(parents=True, exist_ok=True)
        runs.to_csv(out / "runs.csv", index=False, float_format="%.6g")
        causes.to_csv(out / "causes.csv", index=False)
        stamp(out, f"python benchmarks/qp_failures.py --save --min-failed {args.min_failed}",
              layer_of(*(dataclasses.replace(s).config for s in todo)))


if __name__ == "__main__":
    main()

"""The design barrier for moving regions on crossings it was not chosen on.

    python benchmarks/moving_heldout.py [--seeds 50-99] [--workers 2] [--save]

The design (``studies.catalogue.MOVING_DESIGN``) was chosen on the moving study's crossings
(seeds 0-49, ``benchmarks/moving_levers.py``). This flies it, in the study's configuration
(the damped RTI on the ``riccati-ipm`` QP chain, prediction oracle and Kalman, both metrics),
on fresh random crossings, and prints per prediction and metric the collisions (clearance
< 0.35 m) with 95 % Clopper-Pearson intervals, the closest approach, the completions and the
failed solves. ``--save`` writes ``figures/studies/moving_heldout/`` (the table, its
``study.json`` and the summary ``heldout.csv``), stamped.
"""

from __future__ import annotations

import argparse

import pandas as pd

from paper_repro import paths
from paper_repro import studies as S
from paper_repro.analysis import statistics
from paper_repro.cli.args import seed_list
from paper_repro.evidence.golden import layer_of, stamp
from paper_repro.studies.catalogue import MOVING_DESIGN

BY = ["prediction", "metric"]


def heldout_study(seeds) -> S.Study:
    """The moving study's design rows (its configuration, labels and names) on ``seeds``."""
    study = S.moving_obstacles(scenes=max(seeds) + 1)
    specs = tuple(s for s in study.specs if dict(s.labels)["barrier"] == "design"
                  and dict(s.labels)["scene_seed"] in set(seeds))
    return S.Study("moving_heldout", specs,
                   f"the design barrier {MOVING_DESIGN} on crossings {seeds[0]}-"
                   f"{seeds[-1]}, oracle and kalman, both metrics")


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per prediction and metric: collisions and completions with their intervals, the
    closest approach and the failed solves."""
    r = statistics.rates(table, by=BY).set_index([*BY, "event"])
    rows = []
    for key, g in table.groupby(BY, sort=False):
        col, done = r.loc[(*key, "collision")], r.loc[(*key, "completed")]
        rows.append({**dict(zip(BY, key)), "runs": len(g), "collisions": int(col["k"]),
                     "collision_low": col["low"], "collision_high": col["high"],
                     "completed": int(done["k"]), "min_clearance_m": g["min_clearance_m"].min(),
                     "failed_solves": int(g["failed_solves"].sum())})
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="50-99", help="crossing seeds, e.g. 50-99")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    try:
        seeds = sorted(seed_list(args.seeds))
    except argparse.ArgumentTypeError as exc:
        parser.error(f"--seeds {exc}")
    study = heldout_study(seeds)
    out = (paths.figures_dir() / "studies" / "moving_heldout" if args.save
           else paths.results_dir() / "moving_heldout")
    result = S.run_study(study, out=out, workers=args.workers,
                         runs_dir=paths.results_dir() / "runs", progress=False)
    table = summary(result.table)
    print(table.to_string(index=False))
    if args.save:
        table.to_csv(out / "heldout.csv", index=False, float_format="%.6g")
        stamp(out, f"python benchmarks/moving_heldout.py --save --seeds {args.seeds}",
              layer_of(*(s.config for s in study.specs)))


if __name__ == "__main__":
    main()

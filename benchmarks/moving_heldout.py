"""The design barrier for moving regions on crossings it was not chosen on.

    python benchmarks/moving_heldout.py [--seeds 50-149] [--workers 2] [--save]

The design (``studies.catalogue.moving_design``: the barrier of ``MOVING_DESIGN``, the longer
prediction step, crossings timed to its pace) was chosen looking at crossings 0-99: the
study's 0-49, and 50-99, the held-out set of the first design, which collided on 5 of its 200
runs. This flies it, in the study's configuration (the damped RTI on the ``riccati-ipm`` QP
chain, prediction oracle and Kalman, both metrics), on crossings 50-99 (label ``set``
``"seen"``) and 100-149, which no design has seen (``"held out"``, from :data:`HELD_OUT_FROM`
on), and prints per set, prediction and metric the collisions (clearance < 0.35 m) with 95 %
Clopper-Pearson intervals, the closest approach, the completions, the failed solves and the
runs in which a region came within the LiDAR's range (``encounters``). ``--save`` writes
``figures/studies/moving_heldout/`` (the table, its ``study.json`` and the summary
``heldout.csv``), stamped.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses

import pandas as pd

from paper_repro import Config, paths
from paper_repro import studies as S
from paper_repro.analysis import metrics, statistics
from paper_repro.cli.args import seed_list
from paper_repro.evidence.golden import layer_of, stamp
from paper_repro.studies.catalogue import MOVING_DESIGN

BY = ["set", "prediction", "metric"]

HELD_OUT_FROM = 100
"""The first crossing no design was chosen on."""


def heldout_study(seeds) -> S.Study:
    """The moving study's design rows (its configuration, labels and names) on ``seeds``."""
    study = S.moving_obstacles(scenes=max(seeds) + 1)
    specs = tuple(dataclasses.replace(s, labels=s.labels + (
                      ("set", "held out" if dict(s.labels)["scene_seed"] >= HELD_OUT_FROM
                       else "seen"),))
                  for s in study.specs if dict(s.labels)["barrier"] == "design"
                  and dict(s.labels)["scene_seed"] in set(seeds))
    return S.Study("moving_heldout", specs,
                   f"the design barrier {MOVING_DESIGN} on crossings {seeds[0]}-"
                   f"{seeds[-1]}, oracle and kalman, both metrics")


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per set, prediction and metric: collisions and completions with their intervals, the
    closest approach and the failed solves."""
    r = statistics.rates(table, by=BY).set_index([*BY, "event"])
    rows = []
    for key, g in table.groupby(BY, sort=False):
        col, done = r.loc[(*key, "collision")], r.loc[(*key, "completed")]
        rows.append({**dict(zip(BY, key)), "runs": len(g), "collisions": int(col["k"]),
                     "collision_low": col["low"], "collision_high": col["high"],
                     "completed": int(done["k"]), "min_clearance_m": g["min_clearance_m"].min(),
                     "failed_solves": int(g["failed_solves"].sum()),
                     "relaxed_solves": int(g["relaxed_solves"].sum()),
                     "encounters": metrics.encounters(g["min_clearance_m"], Config().sensor.range)})
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="50-149", help="crossing seeds, e.g. 50-149")
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

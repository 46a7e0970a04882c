"""Which moving crossings could be flown clear at all? The avoidability check on each crossing.

    python benchmarks/avoidability.py [--seeds 0-49,100-149] [--save]

For each random crossing the moving studies fly (:data:`FLOWN`: the crossings of the paper's
barrier, timed to the printed set-up's pace, and those of the design, timed to its own;
``make_scene("random-crossing", seed, approach_time)``), a point mass with the
quadrotor's velocity and tilt-limited acceleration bounds and full foresight searches for a
passage from the start to the finish line within the study's step limit that keeps 0.35 m from
every region, the regions solid (:func:`paper_repro.analysis.avoidability.find_passage`).
The same search is repeated within the time the fastest predicted run of the crossing took, in
the moving study or the design's held-out crossings (``at_pace_*``): could it have been flown
clear without being slower than the controller?
Prints one row per crossing and the share of avoidable ones; ``--save`` writes
``figures/studies/avoidability/avoidability.csv``, stamped.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import time

import pandas as pd
from scipy import stats

from paper_repro import Config, make_scene, paths
from paper_repro.analysis.avoidability import find_passage, passage_row
from paper_repro.cli.args import seed_list
from paper_repro.evidence.golden import stamp, stamped_layer
from paper_repro.studies.catalogue import MOVING_APPROACH_TIME, PASSAGE_STEPS

FLOWN = ((150.0, "0-49"), (MOVING_APPROACH_TIME, "0-149"))
"""(pace ``approach_time`` s, seeds) of the crossings the moving studies fly: the study's 50
with the paper's barrier; the design's, the study's 50 and the 100 of its held-out set."""

_STUDIES = [paths.figures_dir() / "studies" / name
            for name in ("moving_obstacles", "moving_heldout")]
"""The moving study and the design's held-out crossings, whose runs set the pace."""


def _study_pace() -> dict:
    """Crossing (its scene's name, which carries its pace) → the shortest time to the finish
    line among the oracle and Kalman runs of it (s) in the committed tables of
    :data:`_STUDIES`."""
    tables = [pd.read_parquet(f / "table.parquet") for f in _STUDIES
              if (f / "table.parquet").is_file()]
    if not tables:
        return {}
    t = pd.concat(tables, ignore_index=True)
    t = t[t["prediction"].isin(("oracle", "kalman")) & t["completed"].astype(bool)]
    return {str(k): float(v) for k, v in t.groupby("scene")["time_to_complete_s"].min().items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default=None,
                        help="crossing seeds at both paces, e.g. 0-49 or 2,3,5 (default: the "
                             "crossings the studies fly)")
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    try:
        crossings = [(pace, seed) for pace, seeds in FLOWN
                     for seed in seed_list(seeds if args.seeds is None else args.seeds)]
    except argparse.ArgumentTypeError as exc:
        parser.error(f"--seeds {exc}")
    horizon = PASSAGE_STEPS * Config().nmpc.ts
    pace = _study_pace()
    rows = []
    for approach_time, seed in crossings:
        t0 = time.perf_counter()
        scene = make_scene("random-crossing", seed, approach_time)
        passage = find_passage(scene, horizon)
        row = {"approach_time_s": approach_time, **passage_row(seed, passage)}
        # The same question at the controller's own pace: finish no later than the fastest of
        # the study's predicted runs of this crossing did.
        row["study_time_s"] = pace.get(scene.name, float("nan"))
        if scene.name in pace:
            at_pace = find_passage(scene, pace[scene.name])
            row.update(at_pace_outcome=at_pace.outcome, at_pace_clearance_m=at_pace.clearance)
        rows.append(row)
        print(f"{scene.name:24s}: {passage.outcome:17s} clearance {passage.clearance:6.3f} m, "
              f"finish at {passage.time:6.1f} s, guess {passage.guess or '-'}; within "
              f"{row['study_time_s']:.1f} s: {row.get('at_pace_outcome', '-')} "
              f"({time.perf_counter() - t0:.1f} s)", flush=True)
    table = pd.DataFrame(rows)
    k, n = int(table["avoidable"].sum()), len(table)
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    print(f"avoidable: {k}/{n} [{ci.low:.2f}, {ci.high:.2f}] (95 % Clopper-Pearson)")
    if args.save:
        out = paths.figures_dir() / "studies" / "avoidability"
        out.mkdir(parents=True, exist_ok=True)
        table.to_csv(out / "avoidability.csv", index=False, float_format="%.6g")
        # Its pace column reads the moving studies' tables: the set carries their layer.
        layers = {stamped_layer(f) for f in _STUDIES if f.is_dir()}
        if len(layers) > 1:
            raise SystemExit(f"the moving studies carry different golden layers {layers}")
        stamp(out, "python benchmarks/avoidability.py --save"
              + ("" if args.seeds is None else f" --seeds {args.seeds}"),
              layers.pop() if layers else "")


if __name__ == "__main__":
    main()

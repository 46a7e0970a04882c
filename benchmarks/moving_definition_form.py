"""The moving_obstacles study's smooth runs with the barrier in Definition 1's form (c = δ).

    python benchmarks/moving_definition_form.py [--scenes 30] [--workers 2] [--force]

Writes ``figures/studies/moving_obstacles_definition/`` (table and study.json, runs cached in
``results/runs/``) and prints the collision, completion and stall rates and the median
clearance and thrust variation per barrier (the paper's margin, the design's) and prediction.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses

from paper_repro import Config, paths
from paper_repro import studies as S
from paper_repro.config import PREDICTIONS, BarrierParams
from paper_repro.evidence.golden import layer_of, stamp
from paper_repro.studies.catalogue import Study


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", type=int, default=30)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--force", action="store_true", help="fly every run again")
    args = parser.parse_args()
    base = Config(barrier=BarrierParams(form="definition"))
    specs = tuple(
        dataclasses.replace(s, name=s.name.replace("crossing-", "crossing-definition-"))
        for s in S.moving_obstacles(scenes=args.scenes, base=base).specs
        if dict(s.labels)["metric"] == "smooth")
    study = Study("moving_obstacles_definition", specs,
                    "random crossings, smooth metric, barrier in Definition 1's form (c = δ), "
                    f"prediction in {PREDICTIONS}, {args.scenes} passages")
    result = S.run_study(study, out=paths.figures_dir() / "studies" / study.name,
                         workers=args.workers, runs_dir=paths.results_dir() / "runs",
                         force=args.force)
    stamp(result.directory, "python benchmarks/moving_definition_form.py",
          layer_of(*(s.config for s in specs)))
    table = result.table.groupby(["barrier", "prediction"])
    print(table[["collision", "completed", "stalled"]].mean())
    print(table[["min_clearance_m", "tv_u_rate_N_per_s"]].median())


if __name__ == "__main__":
    main()

"""What the local map and the guide cost per closed-loop step.

    python benchmarks/guidance_cost.py --passages 5 [--save]

Flies the first ``--passages`` random passages of the ``guidance`` study with the smoothed
metric, in one process: with the map and the guide (perfect LiDAR, as the guidance study
flies), with the map alone on the noisy LiDAR of the sensor-noise study, and with both on the
noisy LiDAR. The map's update and read-out
(:class:`~paper_repro.world.local_map.VoxelMap` ``update`` and ``regions``) and the guide
(:meth:`~paper_repro.world.guide.Guide.set_point`, its plans included) are timed around each
call, and their sums are divided by the steps flown: the cost per step, the planner
amortised. Beside them, the all-in step (wall time over steps) and the controller call.

``--save`` writes ``figures/guidance_cost/cost.csv`` (this machine's times, expected to move
by tens of percent between runs) and the stamp. Numbers only, no thresholds.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
import functools
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from paper_repro import Config  # noqa: E402
from paper_repro.paths import figures_dir  # noqa: E402
from paper_repro.sim.loop import simulate  # noqa: E402
from paper_repro.studies.catalogue import (  # noqa: E402
    NOISY_LIDAR,
    passage_config,
    with_guide,
    with_map,
)
from paper_repro.world.guide import Guide  # noqa: E402
from paper_repro.world.local_map import VoxelMap  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from _table import print_table  # noqa: E402

PARTS = {"map_update": (VoxelMap, "update"), "map_readout": (VoxelMap, "regions"),
         "guide": (Guide, "set_point")}
"""The timed parts, by the column stem of their cost (``map_update_ms``)."""

COLUMNS = [("setup", "setup", "s"), ("passages", "passages", "d"), ("steps", "steps", "d"),
           ("all_in_ms", "all-in ms", ".3f"), ("controller_ms", "control ms", ".3f"),
           ("map_update_ms", "map upd ms", ".4f"), ("map_readout_ms", "map read ms", ".4f"),
           ("guide_ms", "guide ms", ".4f"), ("map_and_guide_ms", "map+guide", ".4f")]


def timed_parts() -> dict[str, float]:
    """Wrap the timed methods once; returns the dict their seconds accumulate in."""
    spent = dict.fromkeys(PARTS, 0.0)
    for part, (cls, name) in PARTS.items():
        method = getattr(cls, name)

        @functools.wraps(method)
        def wrapper(self, *args, _method=method, _part=part, **kwargs):
            start = time.perf_counter()
            try:
                return _method(self, *args, **kwargs)
            finally:
                spent[_part] += time.perf_counter() - start

        setattr(cls, name, wrapper)
    return spent


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--passages", type=int, default=5)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args(argv)
    if args.passages < 1:
        parser.error(f"--passages must be >= 1, got {args.passages}")
    spent = timed_parts()
    noisy = dataclasses.replace(Config(), sensor=NOISY_LIDAR)
    setups = {"map + guide, perfect LiDAR": with_guide(Config()),
              "map, noisy LiDAR": with_map(noisy),
              "map + guide, noisy LiDAR": with_guide(noisy)}
    rows = []
    simulate(passage_config(setups["map + guide, perfect LiDAR"], 0), max_steps=50,
             progress=False)  # builds and warms the compiled parts
    for setup, base in setups.items():
        before, steps, wall, solve = dict(spent), 0, 0.0, 0.0
        for seed in range(args.passages):
            cfg = passage_config(base, seed)
            if not cfg.sensor.perfect:
                cfg = dataclasses.replace(cfg, sensor=dataclasses.replace(cfg.sensor, seed=seed))
            start = time.perf_counter()
            result = simulate(cfg, progress=False)
            wall += time.perf_counter() - start
            steps += result.steps
            solve += float(np.sum(result.solve_time))
        row = {"setup": setup, "passages": args.passages, "steps": steps,
               "all_in_ms": 1e3 * wall / steps, "controller_ms": 1e3 * solve / steps}
        row.update({f"{part}_ms": 1e3 * (spent[part] - before[part]) / steps
                    for part in PARTS})
        row["map_and_guide_ms"] = sum(row[f"{part}_ms"] for part in PARTS)
        rows.append(row)
    print_table(rows, COLUMNS, width=14)
    table = pd.DataFrame(rows)
    if args.save:
        from paper_repro.evidence.golden import command_line, stamp

        out = figures_dir() / "guidance_cost"
        out.mkdir(parents=True, exist_ok=True)
        table.to_csv(out / "cost.csv", index=False, float_format="%.4g")
        stamp(out, command_line(), "guide")
        print(f"wrote {out / 'cost.csv'}")


if __name__ == "__main__":
    main()

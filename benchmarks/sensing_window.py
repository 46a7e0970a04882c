"""Thrust steps where the LiDAR's visible set changes, with and without the sensing window.

    python benchmarks/sensing_window.py --scenario paper --windows 0 0.25 0.5 1.0 --out DIR

Flies the mission once per window width w (``DistanceParams.window``; 0 is the paper's hard
cut-off), saves each result in ``DIR/w<w>/``, and prints per width: the steps at which the
number of visible points changed ("events"), the median and 90th percentile of |Δu| (the
largest of the four rotors' thrust steps, N) at events and at the other steps within 0.2 s of
an event (the same phase of flight; :func:`paper_repro.analysis.metrics.scan_change_steps`), the
share
of events with a step above 0.01 N, the Mann-Whitney p-value of "|Δu| at events and around
them come from the same distribution", the minimum clearance and the mission's outcome. With
``--from-saved`` it only reads the results in DIR. The last line is the table as JSON.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
from _table import print_table  # benchmarks/_table.py (the script's folder)
from scipy.stats import mannwhitneyu

from paper_repro import Config
from paper_repro.analysis.metrics import scan_change_steps
from paper_repro.sim.loop import simulate
from paper_repro.sim.result import SimulationResult


def row(width: float, result) -> dict:
    at, other = scan_change_steps(result)
    p = float(mannwhitneyu(at, other).pvalue) if len(at) and len(other) else float("nan")
    return {"window_m": width, "steps": int(result.steps), "events": int(len(at)),
            "median_du_events_N": float(np.median(at)) if len(at) else float("nan"),
            "p90_du_events_N": float(np.percentile(at, 90)) if len(at) else float("nan"),
            "median_du_other_N": float(np.median(other)),
            "p90_du_other_N": float(np.percentile(other, 90)),
            "share_events_above_10mN": float(np.mean(at > 0.01)) if len(at) else float("nan"),
            "mannwhitney_p": p, "min_clearance_m": float(result.clearance.min()),
            "outcome": result.outcome}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="paper")
    parser.add_argument("--windows", type=float, nargs="+", default=[0.0, 0.25, 0.5, 1.0])
    parser.add_argument("--max-steps", type=int, default=200_000)
    parser.add_argument("--out", type=Path, default=Path("results/sensing_window"))
    parser.add_argument("--from-saved", action="store_true")
    args = parser.parse_args()
    rows = []
    for w in args.windows:
        folder = args.out / f"w{w:g}"
        if args.from_saved:
            result = SimulationResult.load(folder)
        else:
            base = Config()
            cfg = dataclasses.replace(
                base, distance=dataclasses.replace(base.distance, window=w),
                simulation=dataclasses.replace(base.simulation, scenario=args.scenario))
            result = simulate(cfg, max_steps=args.max_steps, progress=False)
            result.save(folder)
        rows.append(row(w, result))
        print(json.dumps(rows[-1]), flush=True)
    print(f"\n{args.scenario}: |Δu| (max over rotors, N) at changes of the visible set")
    print_table(rows, [("window_m", "w m", ".2f"), ("events", "events", "d"),
                       ("median_du_events_N", "med ev", ".4f"),
                       ("p90_du_events_N", "p90 ev", ".4f"),
                       ("median_du_other_N", "med around", ".5f"),
                       ("p90_du_other_N", "p90 around", ".5f"),
                       ("share_events_above_10mN", ">10 mN", ".2f"),
                       ("mannwhitney_p", "MW p", ".2g"), ("min_clearance_m", "min clear", ".3f"),
                       ("outcome", "outcome", "s")], width=11)


if __name__ == "__main__":
    main()

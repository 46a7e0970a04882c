"""The unicycle through both solvers: speed, agreement with IPOPT, clearance, chattering.

    python benchmarks/ground_robot.py --steps 500

Flies the planar L-wall scene (:func:`paper_repro.world.planar.planar_scene`) with the smooth
and the Euclidean metric, each with IPOPT (the reference), the real-time iteration (one SQP
step per instant) and two SQP steps, then prints per run: median / p99 wall time of one
controller call in ms, failed solves, the largest position deviation from IPOPT's path, the
minimum clearance, whether the robot got past the wall, and the chattering of (v, ω): total
variation per second, max |Δu| and sign changes of Δu. The last line is the same table as
JSON.

The runs are flown by :func:`~paper_repro.sim.loop.simulate`, the quadrotor's closed loop: a
run ends when the robot reaches its target, or when it stalls. What the flights determine
goes to ``figures/ground_robot/ground_robot.csv`` (byte-stable; the book's table is
formatted from it), the solve times to ``ground_robot_timings.csv`` (this machine's).
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import sys

import numpy as np
import pandas as pd
from _table import print_table  # benchmarks/_table.py (the script's folder)

from paper_repro.analysis.metrics import chattering_metrics
from paper_repro.evidence.golden import stamp
from paper_repro.paths import figures_dir
from paper_repro.sim.loop import simulate
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.unicycle import unicycle_config, unicycle_model
from paper_repro.world.planar import planar_scene

VARIANTS = {"reference": ("reference", {}), "rti": ("rti", {"max_iter": 1}),
            "sqp-2": ("rti", {"max_iter": 2})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--no-save", action="store_true",
                        help="print only (the committed tables are written for 500 steps)")
    args = parser.parse_args()
    scene, model = planar_scene(), unicycle_model()
    wall = scene.clouds[0][:, 0].max()
    rows = []
    for metric in ("smooth", "euclidean"):
        runs = {}
        for name, (solver, options) in VARIANTS.items():
            cfg = unicycle_config(metric, solver)
            runs[name] = simulate(cfg, make_controller(cfg, model, **options), scene=scene,
                                  max_steps=args.steps, progress=False)
        ref = runs["reference"]
        for name, r in runs.items():
            ms = r.solve_time * 1e3
            # 2 Hz: the horizon is 1.5 s, so faster content is switching, not a manoeuvre.
            chat = chattering_metrics(r.u, cfg.nmpc.ts, cutoff_hz=2.0)
            rows.append({
                "metric": metric, "solver": name, "steps": len(r.t),
                "median_ms": float(np.median(ms)),
                "p99_ms": float(np.percentile(ms, 99)), "failures": int((~r.success).sum()),
                "max_dev_m": _deviation(r.x, ref.x),
                "min_clearance_m": float(r.clearance.min()),
                "passed": bool(r.x[-1, 0] > wall), "outcome": r.outcome,
                "tv_per_s": chat["total_variation"] / (len(r.u) * cfg.nmpc.ts),
                "max_abs_du": chat["max_abs_du"], "sign_changes": chat["du_sign_changes"]})
    print(f"\nunicycle, planar L wall, {args.steps} steps of {cfg.nmpc.ts} s")
    print_table(rows, [("metric", "metric", "s"), ("solver", "solver", "s"),
                       ("median_ms", "median ms", ".2f"), ("p99_ms", "p99 ms", ".2f"),
                       ("failures", "failures", "d"), ("max_dev_m", "max dev m", ".2e"),
                       ("min_clearance_m", "min clear m", ".3f"), ("passed", "passed", "s"),
                       ("outcome", "outcome", "s"),
                       ("tv_per_s", "TV/s", ".3f"), ("max_abs_du", "max|du|", ".3f"),
                       ("sign_changes", "reversals", "d")])
    if not args.no_save:
        _save(rows)


TIMINGS = ("median_ms", "p99_ms")


def _save(rows: list[dict]) -> None:
    """The flight columns (rounded, byte-stable) and the timings, apart; then the stamp."""
    out = figures_dir() / "ground_robot"
    out.mkdir(parents=True, exist_ok=True)
    table = pd.DataFrame(rows)
    flight = table.drop(columns=list(TIMINGS))
    flight.to_csv(out / "ground_robot.csv", index=False, float_format="%.6g")
    table[["metric", "solver", *TIMINGS]].to_csv(out / "ground_robot_timings.csv", index=False,
                                                 float_format="%.4g")
    stamp(out, " ".join(["python", "benchmarks/ground_robot.py", *sys.argv[1:]]))


def _deviation(x, ref) -> float:
    """m, the largest distance between two flights over the steps both flew."""
    n = min(len(x), len(ref))
    return float(np.linalg.norm(x[:n, :2] - ref[:n, :2], axis=1).max())


if __name__ == "__main__":
    main()

"""The unicycle through both solvers: speed, agreement with IPOPT, clearance, chattering.

    python benchmarks/ground_robot.py --steps 500

Flies the planar L-wall scene (:func:`paper_repro.world.planar.planar_scene`) with the smooth
and the Euclidean metric, each with IPOPT (the reference), the real-time iteration (one SQP
step per instant) and two SQP steps, then prints per run: median / p99 wall time of one
controller call in ms, failed solves, the largest position deviation from IPOPT's path, the
minimum clearance, whether the robot got past the wall, and the chattering of (v, ω): total
variation per second, max |Δu| and sign changes of Δu. The last line is the same table as
JSON.
"""

from __future__ import annotations

import argparse

import numpy as np
from _table import print_table  # benchmarks/_table.py (the script's folder)

from paper_repro.analysis.metrics import chattering_metrics
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.unicycle import unicycle_config, unicycle_model
from paper_repro.world.planar import fly, planar_scene

VARIANTS = {"reference": ("reference", {}), "rti": ("rti", {"max_iter": 1}),
            "sqp-2": ("rti", {"max_iter": 2})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=500)
    args = parser.parse_args()
    scene, model = planar_scene(), unicycle_model()
    wall = scene.cloud[:, 0].max()
    rows = []
    for metric in ("smooth", "euclidean"):
        runs = {}
        for name, (solver, options) in VARIANTS.items():
            cfg = unicycle_config(metric, solver)
            runs[name] = fly(make_controller(cfg, model, **options), scene, steps=args.steps)
        ref = runs["reference"]
        for name, r in runs.items():
            ms = r.solve_time * 1e3
            # 2 Hz: the horizon is 1.5 s, so faster content is switching, not a manoeuvre.
            chat = chattering_metrics(r.u, cfg.nmpc.ts, cutoff_hz=2.0)
            rows.append({
                "metric": metric, "solver": name, "median_ms": float(np.median(ms)),
                "p99_ms": float(np.percentile(ms, 99)), "failures": int((~r.success).sum()),
                "max_dev_m": float(np.linalg.norm(r.x[:, :2] - ref.x[:, :2], axis=1).max()),
                "min_clearance_m": float(r.clearance.min()),
                "passed": bool(r.x[-1, 0] > wall),
                "tv_per_s": chat["total_variation"] / (len(r.u) * cfg.nmpc.ts),
                "max_abs_du": chat["max_abs_du"], "sign_changes": chat["du_sign_changes"]})
    print(f"\nunicycle, planar L wall, {args.steps} steps of {cfg.nmpc.ts} s")
    print_table(rows, [("metric", "metric", "s"), ("solver", "solver", "s"),
                       ("median_ms", "median ms", ".2f"), ("p99_ms", "p99 ms", ".2f"),
                       ("failures", "failures", "d"), ("max_dev_m", "max dev m", ".2e"),
                       ("min_clearance_m", "min clear m", ".3f"), ("passed", "passed", "s"),
                       ("tv_per_s", "TV/s", ".3f"), ("max_abs_du", "max|du|", ".3f"),
                       ("sign_changes", "reversals", "d")])


if __name__ == "__main__":
    main()

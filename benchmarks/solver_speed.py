"""Closed-loop solve time and agreement of the NMPC solvers.

    python benchmarks/solver_speed.py --scenario encounter --steps 2000
    python benchmarks/solver_speed.py --scenario crossing --steps 3000   # a moving region

Flies the same mission with the IPOPT reference and with the structure-exploiting solver
(several SQP iteration counts; its QPs by the warm-started Riccati solver, ``rti-hpipm`` by
HPIPM, ``*-ipm`` by the chain ``riccati-ipm``: the active set within a budget, then the
interior point on the same kernels), then prints, per solver: median / p95 / p99 / max wall
time of one controller call in ms (Python overhead included: packing the scan, building the
QP, solving), the median iteration count, the failed solves, the QPs that went to the interior
point and to HPIPM, the minimum clearance, and the largest
position deviation from the reference trajectory. The last line is the same table as JSON.

With ``--save`` the table is also written to ``figures/solver_speed/<scenario>/``: what the
flights determine in ``speed.csv`` (byte-stable), the times in ``speed_timings.csv`` (this
machine's), then the stamp; the book's speed tables are formatted from them.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
import platform
import sys
import time

import numpy as np
import pandas as pd
from _table import print_table  # benchmarks/_table.py (the script's folder)

from paper_repro import Config
from paper_repro.evidence.golden import stamp
from paper_repro.paths import figures_dir
from paper_repro.sim.loop import simulate
from paper_repro.solvers.factory import make_controller

VARIANTS = {  # name -> (solver, controller options)
    "reference": ("reference", {}),
    "rti": ("rti", {"max_iter": 1}),
    "rti-damped": ("rti", {"max_iter": 1, "line_search": True}),
    "rti-hpipm": ("rti", {"max_iter": 1, "qp_solver": "hpipm"}),
    "rti-riccati": ("rti", {"max_iter": 1, "qp_solver": "riccati"}),
    "rti-damped-riccati": ("rti", {"max_iter": 1, "line_search": True,
                                   "qp_solver": "riccati"}),
    "sqp-2": ("rti", {"max_iter": 2}),
    "sqp-converged": ("rti", {"max_iter": 30, "step_tol": 1e-9}),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="encounter",
                        choices=("encounter", "paper", "crossing", "oncoming"))
    parser.add_argument("--prediction", default=None, choices=("static", "oracle", "kalman"),
                        help="how moving regions are predicted (default: oracle for the "
                             "moving scenes, static otherwise)")
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--metric", default="smooth", choices=("smooth", "euclidean"))
    parser.add_argument("--solvers", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--save", action="store_true",
                        help="write the table to figures/solver_speed/<scenario>/ (committed)")
    args = parser.parse_args()

    base = Config()
    prediction = args.prediction or ("static" if args.scenario in ("encounter", "paper")
                                     else "oracle")
    base = dataclasses.replace(
        base, simulation=dataclasses.replace(base.simulation, scenario=args.scenario),
        nmpc=dataclasses.replace(base.nmpc, prediction=prediction),
        distance=dataclasses.replace(base.distance, metric=args.metric))
    runs = {}
    for name in args.solvers:
        solver, options = VARIANTS[name]
        cfg = dataclasses.replace(base, solver=dataclasses.replace(base.solver, nlp_solver=solver))
        t0 = time.perf_counter()
        ctl = make_controller(cfg, **options)
        build = time.perf_counter() - t0
        runs[name] = simulate(cfg, controller=ctl, max_steps=args.steps, progress=False)
        print(f"# {name}: built in {build:.1f} s, flew {runs[name].steps} steps in "
              f"{runs[name].meta['wall_time_s']:.1f} s", flush=True)

    ref = runs.get("reference")
    rows = []
    for name, r in runs.items():
        ms = r.solve_time * 1e3
        dev = np.nan
        if ref is not None:
            k = min(len(ref.x), len(r.x))
            dev = float(np.max(np.linalg.norm(r.x[:k, :3] - ref.x[:k, :3], axis=1)))
        rows.append({"solver": name, "steps": r.steps, "outcome": r.outcome,
                     "median_ms": float(np.median(ms)),
                     "p95_ms": float(np.percentile(ms, 95)),
                     "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max()),
                     "iterations_median": float(np.median(r.iterations)),
                     "failures": r.failures, "max_dev_m": dev,
                     "ipm_qps": r.meta.get("qp_counts", {}).get("ipm", 0),
                     "hpipm_qps": r.meta.get("qp_counts", {}).get("hpipm", 0),
                     "shortened": r.meta.get("step_counts", {}).get("shortened", 0),
                     "min_clearance_m": float(r.clearance.min())})

    print(f"\n{args.scenario} ({prediction} prediction), {args.metric} metric, {args.steps} steps, "
          f"{platform.processor() or platform.machine()} ({_cpu_name()}), "
          f"{__import__('os').cpu_count()} cores")
    print_table(rows, [("solver", "solver", "s"), ("outcome", "outcome", "s"),
                       ("median_ms", "median ms", ".2f"),
                       ("p95_ms", "p95 ms", ".2f"), ("p99_ms", "p99 ms", ".2f"),
                       ("max_ms", "max ms", ".2f"), ("iterations_median", "iters", ".0f"),
                       ("failures", "failures", "d"), ("ipm_qps", "ipm QPs", "d"),
                       ("hpipm_qps", "hpipm QPs", "d"),
                       ("shortened", "short steps", "d"),
                       ("max_dev_m", "max dev m", ".2e"),
                       ("min_clearance_m", "min clear m", ".3f")], width=14)
    if args.save:
        _save(rows, args.scenario)


TIMINGS = ("median_ms", "p95_ms", "p99_ms", "max_ms")


def _save(rows: list[dict], scenario: str) -> None:
    """The flight columns (byte-stable) and the timings, apart; then the stamp (of the
    ``"riccati-ipm"`` layer when a variant flies that chain)."""
    out = figures_dir() / "solver_speed" / scenario
    out.mkdir(parents=True, exist_ok=True)
    table = pd.DataFrame(rows)
    table.drop(columns=list(TIMINGS)).to_csv(out / "speed.csv", index=False,
                                             float_format="%.6g")
    table[["solver", *TIMINGS]].to_csv(out / "speed_timings.csv", index=False,
                                       float_format="%.4g")
    ipm = any(VARIANTS[row["solver"]][1].get("qp_solver") == "riccati-ipm" for row in rows)
    stamp(out, " ".join(["python", "benchmarks/solver_speed.py", *sys.argv[1:]]),
          "riccati-ipm" if ipm else "")


def _cpu_name() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


if __name__ == "__main__":
    main()

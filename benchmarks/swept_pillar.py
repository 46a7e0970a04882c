"""Solve-time tails with a moving region in view: a pillar swept across a hovering UAV.

    python benchmarks/swept_pillar.py [--steps 1200] [--save]

A 0.8 × 0.8 × 20 m column moves along +y at 1 m/s through the point where the UAV hovers
(x = 0, z = 3 m), reaching it at t = 6 s; the UAV holds its position (its target is its start;
the passage's finish line is never reached). Each variant flies it :data:`PASSES` times with
one controller, reset before each pass, and the controller's own clock (``solve_time`` per
call). The passes fly the same states bit for bit (checked), so they make the same calls: the
tail of the first pass against T_s = 10 ms (median, p99, max, the calls over T_s) is printed
beside each call's least time over the passes (p99, max, over T_s), which is the controller's
own cost (a call slow in one pass only was slowed by the machine), with the clearance, the QPs
sent to the interior point (the ``riccati-ipm`` chain) and to HPIPM, and the interior point's
iterations per QP (median, p99, max). The machine is shared and noisy (±50 % between runs):
read the tail, not one number. ``--save`` writes ``figures/solver_speed/swept_pillar/``:
``pillar.csv`` (what the flight determines: steps, clearance, the QPs per solver and the
interior point's iterations) and ``tails.csv`` (the timings), stamped.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses

import numpy as np
import pandas as pd
from _passes import PASSES, fly_passes  # benchmarks/_passes.py (the script's folder)

from paper_repro import Config, make_controller, paths, simulate
from paper_repro.evidence.golden import layer_of, stamp
from paper_repro.studies.catalogue import moving_design_controller
from paper_repro.world.motion import Motion
from paper_repro.world.scene import Region, Scene
from paper_repro.world.shapes import Box

START = (0.0, 0.0, 3.0)
SPEED = 1.0
MEETING_TIME = 6.0


def pillar_scene() -> Scene:
    """The hovering UAV and the swept pillar (its cloud where its offset is zero, at t = 0)."""
    pillar = Region("pillar", Box((0.0, -SPEED * MEETING_TIME, 10.0), (0.8, 0.8, 20.0)))
    finish = ((0.0, 0.0, 24.0), (0.0, 0.0, 1.0))  # 21 m above: never reached
    return Scene("swept-pillar", (pillar,), START, (START,), 7, finish,
                 motions=(Motion.constant((0.0, SPEED, 0.0)),))


VARIANTS = {  # name -> (prediction, damped RTI, QP chain, the moving design's controller)
    "static (the paper's prediction)": ("static", False, "riccati-ipm", False),
    "oracle, full steps (the default solver)": ("oracle", False, "riccati-ipm", False),
    "oracle, damped RTI (the moving study's paper rows)": ("oracle", True, "riccati-ipm", False),
    "oracle, damped RTI, the design (the moving study's design rows)":
        ("oracle", True, "riccati-ipm", True),
    "static, riccati (HPIPM in the tail)": ("static", False, "riccati", False),
    "oracle, full steps, riccati": ("oracle", False, "riccati", False),
    "oracle, damped RTI, riccati": ("oracle", True, "riccati", False),
}


class _Counting:
    """The controller, reading after each call how many iterations its QP took in the
    interior point (0: the active-set method alone)."""

    def __init__(self, controller):
        self.controller, self.ipm_iterations = controller, []

    def solve(self, *args, **kwargs):
        solution = self.controller.solve(*args, **kwargs)
        self.ipm_iterations.append(self.controller.qp.last_ipm_iterations)
        return solution

    def __getattr__(self, name):
        return getattr(self.controller, name)


def _fly(cfg, scene) -> dict:
    """One variant's row: its flight, :data:`PASSES` times with one controller."""
    controller = make_controller(cfg)
    counted = []

    def fly():
        controller.reset()
        counted.append(_Counting(controller))
        return simulate(cfg, scene=scene, controller=counted[-1], progress=False)

    (result, *_), least = fly_passes(fly, PASSES)
    ms = 1e3 * np.asarray(result.solve_time, float)
    ts_ms = 1e3 * cfg.nmpc.ts
    iterations = np.asarray(counted[0].ipm_iterations)
    iterations = iterations[iterations > 0]
    counts = result.meta.get("qp_counts", {})
    return {"steps": result.steps, "outcome": result.outcome, "passes": PASSES,
            "median_ms": float(np.median(ms)), "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max()), "over_ts": int((ms > ts_ms).sum()),
            "least_p99_ms": float(np.percentile(least, 99)),
            "least_max_ms": float(least.max()), "least_over_ts": int((least > ts_ms).sum()),
            "min_clearance_m": float(result.clearance.min()),
            "ipm_qps": int(counts.get("ipm", 0)), "hpipm_qps": int(counts.get("hpipm", 0)),
            "ipm_iterations_median": float(np.median(iterations)) if iterations.size else 0.0,
            "ipm_iterations_p99": float(np.percentile(iterations, 99)) if iterations.size
            else 0.0,
            "ipm_iterations_max": int(iterations.max()) if iterations.size else 0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=1200)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    scene, rows, configs = pillar_scene(), [], []
    for name, (prediction, damped, qp_solver, design) in VARIANTS.items():
        base = Config()
        cfg = dataclasses.replace(
            base, nmpc=dataclasses.replace(base.nmpc, prediction=prediction),
            solver=dataclasses.replace(base.solver, line_search=damped, qp_solver=qp_solver),
            simulation=dataclasses.replace(base.simulation, kind="passage",
                                           max_steps=args.steps))
        if design:  # the smoothed metric's: its swept margin and its longer prediction
            cfg = moving_design_controller(cfg, "smooth")
        configs.append(cfg)
        rows.append({"variant": name, **_fly(cfg, scene)})
        print(pd.DataFrame(rows[-1:]).to_string(index=False), flush=True)
    table = pd.DataFrame(rows)
    print(table.to_string(index=False))
    if args.save:
        out = paths.figures_dir() / "solver_speed" / "swept_pillar"
        out.mkdir(parents=True, exist_ok=True)
        flight = ["variant", "steps", "outcome", "min_clearance_m", "ipm_qps", "hpipm_qps",
                  "ipm_iterations_median", "ipm_iterations_p99", "ipm_iterations_max"]
        table[flight].to_csv(out / "pillar.csv", index=False, float_format="%.6g")
        table.drop(columns=flight[1:]).to_csv(out / "tails.csv", index=False,
                                              float_format="%.4g")
        stamp(out, f"python benchmarks/swept_pillar.py --save --steps {args.steps}",
              layer_of(*configs))


if __name__ == "__main__":
    main()

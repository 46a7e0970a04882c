"""Solve-time tails with a moving region in view: a pillar swept across a hovering UAV.

    python benchmarks/swept_pillar.py [--steps 1200] [--save]

A 0.8 × 0.8 × 20 m column moves along +y at 1 m/s through the point where the UAV hovers
(x = 0, z = 3 m), reaching it at t = 6 s; the UAV holds its position (its target is its start;
the passage's finish line is never reached). Each variant flies it once with the controller's
own clock (``solve_time`` per call) and prints the per-call tail against T_s = 10 ms: median,
p99, max and the calls over T_s, with the clearance and the QPs sent to the interior point
(the ``riccati-ipm`` chain) and to HPIPM. The machine is shared and noisy (±50 % between
runs): read the tail, not one number. ``--save`` writes ``figures/solver_speed/swept_pillar/``:
``pillar.csv`` (what the flight determines: steps, clearance, the QPs per solver) and
``tails.csv`` (the timings), stamped.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import pandas as pd

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
        controller = make_controller(cfg)
        result = simulate(cfg, scene=scene, controller=controller, progress=False)
        ms = 1e3 * np.asarray(result.solve_time, float)
        ts_ms = 1e3 * cfg.nmpc.ts
        rows.append({"variant": name, "steps": result.steps,
                     "median_ms": float(np.median(ms)), "p99_ms": float(np.percentile(ms, 99)),
                     "max_ms": float(ms.max()), "over_ts": int((ms > ts_ms).sum()),
                     "min_clearance_m": float(result.clearance.min()),
                     "ipm_qps": int(result.meta.get("qp_counts", {}).get("ipm", 0)),
                     "hpipm_qps": int(result.meta.get("qp_counts", {}).get("hpipm", 0))})
        print(pd.DataFrame(rows[-1:]).to_string(index=False), flush=True)
    table = pd.DataFrame(rows)
    print(table.to_string(index=False))
    if args.save:
        out = paths.figures_dir() / "solver_speed" / "swept_pillar"
        out.mkdir(parents=True, exist_ok=True)
        flight = ["variant", "steps", "min_clearance_m", "ipm_qps", "hpipm_qps"]
        table[flight].to_csv(out / "pillar.csv", index=False, float_format="%.6g")
        table.drop(columns=flight[1:]).to_csv(out / "tails.csv", index=False,
                                              float_format="%.4g")
        stamp(out, f"python benchmarks/swept_pillar.py --save --steps {args.steps}",
              layer_of(*configs))


if __name__ == "__main__":
    main()

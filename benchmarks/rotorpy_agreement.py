"""RotorPy with every effect off against our plant: the same closed loop, another integrator.

    python benchmarks/rotorpy_agreement.py [--scenes encounter paper] [--no-save]

Flies each scene twice with the default controller (the smoothed metric): against our plant
(:class:`~paper_repro.sim.plant.QuadrotorPlant`, the NMPC's own model integrated by RK45) and
against RotorPy's multirotor with every effect of ``PlantParams`` off
(:class:`~paper_repro.sim.rotorpy_plant.RotorpyPlant`, the ``hardware`` extra). Both model the
same rigid body with the same thrusts, so what differs is the integration. Per scene it
prints the steps each flew, the largest distance between the two paths over the steps both
flew, the largest difference of the thrusts, both outcomes and both closest approaches.

The studies towards hardware read any later difference as the effects' only if this one is
small: under 1 cm over a whole mission. ``figures/hardware/agreement.csv`` (byte-stable) is
what the book's table is formatted from.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
import sys

import numpy as np
import pandas as pd
from _table import print_table  # benchmarks/_table.py (the script's folder)

from paper_repro.config import Config, PlantParams, SimulationParams
from paper_repro.evidence.golden import stamp
from paper_repro.paths import figures_dir
from paper_repro.sim.loop import simulate

SCENES = ("encounter", "paper")
"""The scenes flown: the encounter (one cloud, about 50 s) and the paper's mission."""


def agreement(scenario: str, max_steps: int | None = None) -> dict:
    """One scene flown against both plants; its row."""
    base = Config(simulation=SimulationParams(scenario=scenario))
    kw = {} if max_steps is None else {"max_steps": max_steps}
    ours = simulate(base, progress=False, **kw)
    theirs = simulate(dataclasses.replace(base, plant=PlantParams(simulator="rotorpy")),
                      progress=False, **kw)
    n = min(len(ours.u), len(theirs.u))
    return {"scene": scenario, "steps_ours": len(ours.u), "steps_rotorpy": len(theirs.u),
            "max_position_difference_m": float(np.linalg.norm(
                ours.positions[:n + 1] - theirs.positions[:n + 1], axis=1).max()),
            "max_thrust_difference_N": float(np.abs(ours.u[:n] - theirs.u[:n]).max()),
            "outcome_ours": ours.outcome, "outcome_rotorpy": theirs.outcome,
            "min_clearance_ours_m": float(ours.clearance.min()),
            "min_clearance_rotorpy_m": float(theirs.clearance.min())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    parser.add_argument("--max-steps", type=int, default=None,
                        help="a step limit (the committed table flies each scene whole)")
    parser.add_argument("--no-save", action="store_true")
    args = parser.parse_args()
    if args.max_steps is not None and not args.no_save:
        parser.error("--max-steps flies part of a scene: it needs --no-save")
    rows = [agreement(s, args.max_steps) for s in args.scenes]
    print_table(rows, [("scene", "scene", "s"), ("steps_ours", "steps, ours", "d"),
                       ("steps_rotorpy", "steps, RotorPy", "d"),
                       ("max_position_difference_m", "max |Δp| m", ".2e"),
                       ("max_thrust_difference_N", "max |Δf| N", ".2e"),
                       ("outcome_ours", "ours", "s"), ("outcome_rotorpy", "RotorPy", "s")])
    if not args.no_save:
        out = figures_dir() / "hardware"
        out.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(rows).to_csv(out / "agreement.csv", index=False, float_format="%.6g")
        stamp(out, " ".join(["python", "benchmarks/rotorpy_agreement.py", *sys.argv[1:]]))


if __name__ == "__main__":
    main()

"""How fast the UAV moves sideways on the moving crossings, and how each collision came about.

    python benchmarks/moving_speeds.py [--save]

Reads the flights of the moving study and of the design's held-out crossings from the run
cache (``results/runs``; fly them first: ``python -m paper_repro study moving_obstacles`` and
``python benchmarks/moving_heldout.py``), and never flies. Prints:

* per set, barrier, prediction and metric (``speeds.csv``): the runs' largest horizontal
  speed (m/s; median and 90th percentile over the runs) and how many runs met a region
  faster than that (the regions cross at 0.5-1.5 m/s). Every
  prediction ends at rest at the artificial equilibrium N·h after the instant, and lateral
  motion passes through four integrations, so the prediction's span caps how fast the UAV can
  move sideways; a region faster than that cap cannot be outrun, only stepped aside from;
* every collision (``collisions.csv``): the region that came closest, its speed, the UAV's mean
  horizontal velocity over the 3 s before the closest approach, and the cosine between the
  two: near 1, the UAV was fleeing along the region's own path, the way ∇D = y − Π points
  when a region closes from the side.

``--save`` writes ``figures/studies/moving_speeds/``, stamped with the studies' layer.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse

import numpy as np
import pandas as pd

from paper_repro import paths
from paper_repro.evidence.golden import stamp, stamped_layer
from paper_repro.sim.result import SimulationResult
from paper_repro.studies.runs import HASH_LENGTH

SETS = {"study": "moving_obstacles", "held out": "moving_heldout"}
"""Set label → folder under ``figures/studies`` whose ``table.parquet`` lists the flights (the
held-out table's own ``set`` column, ``seen`` or ``held out``, takes precedence)."""

BEFORE_S = 3.0
"""s, the span before the closest approach over which the UAV's mean velocity is taken."""

BY = ["set", "barrier", "prediction", "metric"]


def region_speeds(result: SimulationResult) -> np.ndarray:
    """(n_regions,) m/s, each region's constant speed."""
    return np.array([np.linalg.norm(m.velocity(0.0)) for m in result.scene.motions])


def closest_approach(result: SimulationResult) -> dict:
    """The closest approach of a run: which region, its speed and the UAV's motion before."""
    k = int(np.nanargmin(result.clearance))
    t, y = float(result.t[k]), result.x[k, :3]
    clouds = result.scene.clouds_at(t)
    region = int(np.argmin([np.linalg.norm(c - y, axis=1).min() for c in clouds]))
    v_region = np.asarray(result.scene.motions[region].velocity(t))[:2]
    k0 = int(np.searchsorted(result.t, t - BEFORE_S))
    v_uav = (result.x[k, :2] - result.x[k0, :2]) / max(t - float(result.t[k0]), 1e-9)
    return {"t_closest_s": t, "region": region,
            "region_speed_m_s": float(np.linalg.norm(v_region)),
            "uav_speed_before_m_s": float(np.linalg.norm(v_uav)),
            "cos_uav_region": float(v_uav @ v_region / max(np.linalg.norm(v_uav)
                                                            * np.linalg.norm(v_region), 1e-12))}


def read_runs() -> pd.DataFrame:
    """One row per flight of :data:`SETS`: its labels, outcome, clearance, largest horizontal
    speed and, for a collision, its closest approach."""
    runs_dir = paths.results_dir() / "runs"
    rows = []
    for label, folder in SETS.items():
        table = pd.read_parquet(paths.figures_dir() / "studies" / folder / "table.parquet")
        for r in table.itertuples():
            result = SimulationResult.load(runs_dir / f"{r.name}-{r.key[:HASH_LENGTH]}")
            speed = np.linalg.norm(result.x[:, 6:8], axis=1)
            row = {"set": getattr(r, "set", label), "barrier": r.barrier,
                   "prediction": r.prediction, "metric": r.metric, "scene": r.scene,
                   "scene_seed": int(r.scene_seed),
                   "collision": bool(r.collision), "min_clearance_m": float(r.min_clearance_m),
                   "max_horizontal_speed_m_s": float(np.nanmax(speed)),
                   "fastest_region_m_s": float(region_speeds(result).max())}
            if r.collision:
                row.update(closest_approach(result))
            rows.append(row)
    return pd.DataFrame(rows)


def speeds(runs: pd.DataFrame) -> pd.DataFrame:
    """Per set, barrier, prediction and metric: the runs' largest horizontal speeds, their
    median and 90th percentile (not their largest: a run whose solves fail for seconds can
    leave 𝒳 at any speed, and is counted in the study's tables, not here)."""
    g = runs.groupby(BY, sort=False)
    return g.agg(runs=("scene", "size"),
                 max_horizontal_speed_median_m_s=("max_horizontal_speed_m_s", "median"),
                 max_horizontal_speed_p90_m_s=("max_horizontal_speed_m_s",
                                               lambda s: s.quantile(0.9)),
                 runs_with_a_region_faster=("fastest_region_m_s", lambda s: int(
                     (s > runs.loc[s.index, "max_horizontal_speed_m_s"]).sum())),
                 collisions=("collision", "sum")).reset_index()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    runs = read_runs()
    table = speeds(runs)
    collisions = runs[runs["collision"]].drop(columns=["collision"])
    with pd.option_context("display.width", 200):
        print(table.to_string(index=False))
        print(collisions.to_string(index=False))
    if args.save:
        out = paths.figures_dir() / "studies" / "moving_speeds"
        out.mkdir(parents=True, exist_ok=True)
        table.to_csv(out / "speeds.csv", index=False, float_format="%.6g")
        collisions.to_csv(out / "collisions.csv", index=False, float_format="%.6g")
        layers = {stamped_layer(paths.figures_dir() / "studies" / f) for f in SETS.values()}
        if len(layers) > 1:
            raise SystemExit(f"the moving studies carry different golden layers {layers}")
        stamp(out, "python benchmarks/moving_speeds.py --save", layers.pop())


if __name__ == "__main__":
    main()

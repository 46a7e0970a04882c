"""The guide's set-point filter: chattering, time and clearance with and without it.

    python benchmarks/guide_filter.py [--passages 20] [--taus 0,1] [--workers 2] [--save]

The guide moves its set-point in small steps at every check (0.1 s), and those steps reach the
thrusts: on the guidance study's passages the smoothed metric's share of thrust power above
5 Hz is several times the paper controller's. ``guide.set_point_filter`` (τ, s; 0.5 by
default) hands the NMPC a first-order filter of the set-point instead. This flies the first
``--passages`` passages of the guidance study's smoothed "local map + guide" arm once per τ
of ``--taus`` (0 among them: no filter), and pairs each flight with the unfiltered flight of
the same passage; the study's own runs (the default τ) are read from its committed table:
outcome, time to complete, minimum clearance, the share of thrust power above 5 Hz and the
total variation rate of the thrusts.

``--save`` writes ``figures/guide_filter/flights.csv`` (one row per passage and τ, what the
flights determine, byte-stable) and ``summary.csv`` (per τ: completed, collisions, and the
medians of the ratios to no filter), stamped with the guide layer's golden hash.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
import functools
import os
from concurrent.futures import ProcessPoolExecutor

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from paper_repro import paths  # noqa: E402
from paper_repro.analysis.metrics import COLLISION_CLEARANCE, summary_row  # noqa: E402
from paper_repro.config import GuideParams  # noqa: E402
from paper_repro.evidence.golden import stamp  # noqa: E402
from paper_repro.sim.loop import simulate  # noqa: E402
from paper_repro.studies.catalogue import make_study  # noqa: E402

ARM = "passage-smooth-eta0.3-sigma0.8-guide-s{seed:03d}"
"""The guidance study's smoothed map-and-guide runs, by passage."""

COLUMNS = ["outcome", "time_to_complete_s", "min_clearance_m", "hf_energy_fraction",
           "tv_u_rate_N_per_s"]
"""What each flight is compared by (``summary_row``'s names)."""


def _fly(job: tuple[int, float]) -> dict:
    """One passage with the set-point filter τ: its row of :data:`COLUMNS`."""
    seed, tau = job
    spec = _specs()[ARM.format(seed=seed)]
    cfg = dataclasses.replace(spec.config, guide=dataclasses.replace(
        spec.config.guide, set_point_filter=tau))
    row = summary_row(simulate(cfg, max_steps=spec.max_steps, progress=False))
    return {"seed": seed, "tau_s": tau, **{c: row[c] for c in COLUMNS}}


@functools.cache
def _specs() -> dict:
    """The guidance study's runs, by name."""
    return {s.name: s for s in make_study("guidance").specs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--passages", type=int, default=20)
    parser.add_argument("--taus", default="0,1")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    taus = [float(v) for v in args.taus.split(",")]
    default = GuideParams().set_point_filter
    if (args.passages < 1 or 0.0 not in taus or default in taus
            or any(not (np.isfinite(t) and t >= 0) for t in taus)):
        parser.error(f"--passages must be >= 1, and --taus numbers >= 0 (s) that hold 0 (no "
                     f"filter, what the ratios divide by) and not {default} (the study's)")
    study = pd.read_csv(paths.figures_dir() / "studies" / "guidance" / "table.csv")
    study = study.set_index("name")
    base = [{"seed": seed, "tau_s": default,
             **study.loc[ARM.format(seed=seed), COLUMNS].to_dict()}
            for seed in range(args.passages)]
    jobs = [(seed, tau) for tau in taus for seed in range(args.passages)]
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        flown = list(pool.map(_fly, jobs))
    flights = pd.DataFrame(flown + base).sort_values(["tau_s", "seed"], kind="stable")
    summary = pd.DataFrame([_summary(flights, tau) for tau in sorted({*taus, default})])
    print(summary.to_string(index=False))
    if args.save:
        out = paths.figures_dir() / "guide_filter"
        out.mkdir(parents=True, exist_ok=True)
        flights.to_csv(out / "flights.csv", index=False, float_format="%.6g")
        summary.to_csv(out / "summary.csv", index=False, float_format="%.4g")
        stamp(out, f"python benchmarks/guide_filter.py --save --passages {args.passages} "
                   f"--taus {args.taus}", layer="guide")


def _summary(flights: pd.DataFrame, tau: float) -> dict:
    """Per τ: passages completed and colliding, and the medians over the passages of the
    ratios to the unfiltered flight of the same passage (time over the passages both
    complete)."""
    base = flights[flights.tau_s == 0.0].set_index("seed")
    arm = flights[flights.tau_s == tau].set_index("seed")
    both = (arm.outcome == "completed") & (base.outcome == "completed")
    return {"tau_s": tau, "passages": len(arm),
            "completed": int((arm.outcome == "completed").sum()),
            "collisions": int((arm.min_clearance_m < COLLISION_CLEARANCE).sum()),
            "hf_share_median": float(arm.hf_energy_fraction.median()),
            "hf_share_ratio_median": float((arm.hf_energy_fraction
                                            / base.hf_energy_fraction).median()),
            "tv_rate_ratio_median": float((arm.tv_u_rate_N_per_s
                                           / base.tv_u_rate_N_per_s).median()),
            "time_ratio_median": float((arm.time_to_complete_s[both]
                                        / base.time_to_complete_s[both]).median()),
            "min_clearance_m": float(arm.min_clearance_m.min())}


if __name__ == "__main__":
    main()

"""Levers against collisions with moving regions, measured on the moving-obstacle crossings.

    python benchmarks/moving_levers.py [--seeds 0-29] [--levers NAME ...] [--workers 2] [--save]

Each lever is a change of the moving study's configuration (the damped RTI, prediction oracle
and kalman, both metrics), on the default QP chain (the study flies ``riccati-ipm``; the
screening was not flown again); every lever flies the same random crossings through the run
cache. Each group of runs is saved whole under ``results/levers/`` and read back by a later
call (``studies.saved_table``), so a long call carried over machines flies only the rest.
Prints, per lever, prediction and metric: collisions (clearance < 0.35 m), minimum clearance,
completion, chattering (total variation of u per second) and the solve-time tail. ``--save``
writes ``figures/studies/moving_levers/levers.csv`` (what the flights determine) and
``timings.csv`` (the machine's), stamped.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses

import pandas as pd

from paper_repro import Config, paths
from paper_repro import studies as S
from paper_repro.analysis import metrics, statistics
from paper_repro.cli.args import seed_list
from paper_repro.evidence.golden import layer_of, stamp
from paper_repro.studies.catalogue import PASSAGE_STEPS, Study, passage_spec

PREDICTED = ("oracle", "kalman")

MOVING_ONLY = {"reaction_time", "sweep_time", "moving_d_min", "equilibrium_lookahead"}
"""Barrier levers that act on a region's predicted velocity: refused with the static
prediction, and the paper's barrier for a region at rest (tests/test_moving_prediction.py)."""


def _with(nmpc=None, barrier=None):
    def make(base: Config) -> Config:
        return dataclasses.replace(
            base, nmpc=dataclasses.replace(base.nmpc, **(nmpc or {})),
            barrier=dataclasses.replace(base.barrier, **(barrier or {})))
    return make


LEVERS = {
    "none": _with(),
    "reaction-0.5s": _with(barrier={"reaction_time": 0.5}),
    "reaction-1s": _with(barrier={"reaction_time": 1.0}),
    "reaction-2s": _with(barrier={"reaction_time": 2.0}),
    "h-0.03s": _with(nmpc={"prediction_ts": 0.03}),
    "d_min-2": _with(barrier={"d_min": 2.0}),
    "d_min-3": _with(barrier={"d_min": 3.0}),
    "d_min-2+reaction-0.5s": _with(barrier={"d_min": 2.0, "reaction_time": 0.5}),
    "sweep-0.5s": _with(barrier={"sweep_time": 0.5}),
    "sweep-1s": _with(barrier={"sweep_time": 1.0}),
    "moving-d_min-3": _with(barrier={"moving_d_min": 3.0}),
    "moving-d_min-3+sweep-0.5s": _with(barrier={"moving_d_min": 3.0, "sweep_time": 0.5}),
    "moving-d_min-3+sweep-1s": _with(barrier={"moving_d_min": 3.0, "sweep_time": 1.0}),
    "lookahead-3s": _with(barrier={"equilibrium_lookahead": 3.0}),
    "lookahead-5s": _with(barrier={"equilibrium_lookahead": 5.0}),
    "moving-d_min-3+lookahead-4s": _with(barrier={"moving_d_min": 3.0,
                                                  "equilibrium_lookahead": 4.0}),
    # The Euclidean barrier of the first design; the design now adds a sweep and a longer
    # prediction (studies.catalogue.MOVING_DESIGN), flown by the moving study itself.
    "moving-d_min-2+lookahead-3s": _with(barrier={"moving_d_min": 2.0,
                                                  "equilibrium_lookahead": 3.0}),
}
"""Lever name → change of the moving study's base configuration."""


def lever_study(name: str, seeds, max_steps: int = PASSAGE_STEPS) -> Study:
    """The crossings of ``seeds`` × {oracle, kalman} × both metrics under lever ``name``."""
    base = Config()
    base = dataclasses.replace(base, solver=dataclasses.replace(base.solver, line_search=True))
    specs = []
    for prediction in PREDICTED:
        cfg = LEVERS[name](dataclasses.replace(
            base, nmpc=dataclasses.replace(base.nmpc, prediction=prediction)))
        tag = f"crossing-{prediction}" + ("" if name == "none" else f"-{name}")
        for metric in ("smooth", "euclidean"):
            for seed in seeds:
                spec = passage_spec(seed, metric, max_steps=max_steps, base=cfg, tag=tag,
                                    scenario="random-crossing")
                specs.append(dataclasses.replace(spec, labels=spec.labels + (
                    ("prediction", prediction), ("lever", name))))
    return Study(f"moving-levers-{name}", tuple(specs), f"lever {name} on the crossings")


def static_study(name: str, seeds, max_steps: int = PASSAGE_STEPS) -> Study:
    """Lever ``name`` on the static random passages of ``seeds`` (the Monte Carlo study's
    scenes), with the default solver and the paper's static prediction: does it keep the
    static scenes clear, and does it stall them? ``none`` is the Monte Carlo study's runs."""
    cfg, tag = LEVERS[name](Config()), ("" if name == "none" else f"lever-{name}")
    specs = []
    for metric in ("smooth", "euclidean"):
        for seed in seeds:
            spec = passage_spec(seed, metric, max_steps=max_steps, base=cfg, tag=tag)
            specs.append(dataclasses.replace(spec, labels=spec.labels + (
                ("prediction", "static"), ("lever", name))))
    return Study(f"static-levers-{name}", tuple(specs), f"lever {name} on static passages")


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per lever, prediction and metric: collisions and completions with 95 % Clopper–Pearson
    intervals, the minimum clearance, the median chattering and the failed solves."""
    by = ["scenes", "lever", "prediction", "metric"]
    r = statistics.rates(table, by=by).set_index([*by, "event"])
    rows = []
    for key, g in table.groupby(by, sort=False):
        col, done = r.loc[(*key, "collision")], r.loc[(*key, "completed")]
        rows.append({**dict(zip(by, key)), "runs": len(g),
                     # runs in which a region came into the LiDAR's range at all: a lever that
                     # changes the pace can pass before the regions arrive (the crossings are
                     # timed for the printed pace), which is no avoidance
                     "encounters": metrics.encounters(g["min_clearance_m"], Config().sensor.range),
                     "collisions": int(col["k"]),
                     "collision_low": col["low"], "collision_high": col["high"],
                     "completed": int(done["k"]), "stalled": int(g["stalled"].sum()),
                     "min_clearance_m": g["min_clearance_m"].min(),
                     "tv_u_rate_median_N_per_s": g["tv_u_rate_N_per_s"].median(),
                     "failed_solves": int(g["failed_solves"].sum()),
                     "relaxed_solves": int(g["relaxed_solves"].sum()),
                     "cbf_condition_violated_share_median":
                         g["cbf_condition_violated_share"].median(),
                     "time_to_complete_median_s": g["time_to_complete_s"].median()})
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-29", help="crossing seeds, e.g. 0-49 or 2,3,5")
    parser.add_argument("--levers", nargs="+", default=list(LEVERS), choices=list(LEVERS))
    parser.add_argument("--full-seeds", default=None,
                        help="a second set of crossing seeds (e.g. all the study's, 0-29) for "
                             "the --full-levers; the table's `scenes` column tells the sets")
    parser.add_argument("--full-levers", nargs="+", default=[], choices=list(LEVERS),
                        help="the levers flown on --full-seeds and --static-seeds")
    parser.add_argument("--static-seeds", default=None,
                        help="static random passages (the Monte Carlo study's scenes) on which "
                             "the --full-levers fly too, with the paper's static prediction")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    if bool(args.full_levers) != bool(args.full_seeds or args.static_seeds):
        parser.error("--full-levers and --full-seeds (or --static-seeds) go together")
    for option in ("seeds", "full_seeds", "static_seeds"):
        try:
            if getattr(args, option):
                seed_list(getattr(args, option))
        except argparse.ArgumentTypeError as exc:
            parser.error(f"--{option.replace('_', '-')} {exc}")
    # Every study is built (and so every configuration checked) before anything flies.
    groups = [(args.seeds, name, lever_study(name, seed_list(args.seeds)))
              for name in args.levers]
    if args.full_seeds:
        groups += [(args.full_seeds, name, lever_study(name, seed_list(args.full_seeds)))
                   for name in args.full_levers]
    if args.static_seeds:
        predicted = Config(nmpc=dataclasses.replace(Config().nmpc, prediction="oracle"))
        for name in args.full_levers:
            if any(getattr(LEVERS[name](predicted).barrier, f) for f in MOVING_ONLY):
                print(f"{name}: acts on regions predicted to move only (refused under the "
                      "static prediction, the plain barrier at rest): no static rows")
                continue
            groups.append((f"static {args.static_seeds}", name,
                           static_study(name, seed_list(args.static_seeds))))
    tables, timings = [], []
    for scenes, name, study in groups:
        folder = paths.results_dir() / "levers" / f"{name}-{scenes}".replace(" ", "-")
        # A group saved whole by an earlier call (here or on another machine) is read back.
        saved = S.saved_table(study, folder)
        if saved is None:
            saved = S.run_study(study, out=folder, workers=args.workers,
                                runs_dir=paths.results_dir() / "runs", progress=False).table
        t = saved.assign(scenes=scenes)
        tables.append(t)
        timings.append(t[["scenes", "name", "lever", "prediction", "metric", "solve_p99_ms",
                          "solve_max_ms"]])
        print(summary(t).to_string(index=False), flush=True)
    table = pd.concat(tables, ignore_index=True)
    if args.save:
        out = paths.figures_dir() / "studies" / "moving_levers"
        out.mkdir(parents=True, exist_ok=True)
        summary(table).to_csv(out / "levers.csv", index=False, float_format="%.6g")
        pd.concat(timings).to_csv(out / "timings.csv", index=False, float_format="%.4g")
        full = (f" --full-seeds {args.full_seeds} --full-levers {' '.join(args.full_levers)}"
                if args.full_seeds else "")
        full += f" --static-seeds {args.static_seeds}" if args.static_seeds else ""
        stamp(out, f"python benchmarks/moving_levers.py --save --seeds {args.seeds} --levers "
                   f"{' '.join(args.levers)}{full}",
              layer_of(*(s.config for _, _, study in groups for s in study.specs)))


if __name__ == "__main__":
    main()

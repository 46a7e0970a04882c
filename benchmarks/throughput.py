"""All-in cost of one closed-loop step, on one core and with two workers.

    python benchmarks/throughput.py --steps 20000 --scenario paper

Flies ``paper_repro.sim.loop.simulate`` for ``--steps`` steps (or until the mission ends) on
one core, then two such flights at once in two processes (``multiprocessing``, spawn). One
step is everything the loop does: LiDAR scan, controller, plant integration, logging. The
compile caches are warmed and the controllers built before any timing; each flight starts
import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

from a controller that has flown a few steps and was then reset.

The table gives, per run: steps, wall time, steps/s, ms per step, CPU ms per step (the
process's CPU time: what the step costs when other jobs share the cores), and the parts of a
step: the plant
(the flight's logged states and inputs integrated again by the integrator ``simulate`` uses,
timed alone; the replay must reproduce the logged states), the controller (mean of
``result.solve_time``, the whole ``solve`` call) and the rest (LiDAR scan, truth distance,
logging, the loop itself). The last line is JSON with ``steps_per_core_s`` (one worker),
``steps_per_s_2_workers`` (both flights' steps over the span from the first start to the last
end), ``parallel_efficiency`` (= the latter / 2 / the former), ``all_in_ms_per_step``,
``plant_ms_per_step`` and ``controller_ms_per_step`` (one worker).

Then, one process, the scene families of the studies (``--families``): the paper mission
(``--steps`` steps), random passages (the first ``--passages`` of ``monte_carlo``) and random
crossings (the first ``--crossings`` of ``moving_obstacles`` with the oracle prediction and
the damped RTI on the ``riccati-ipm`` QP chain they fly), each with both metrics, each scene
flown twice (``PASSES``). Per family and metric: runs, steps (of one pass), all-in steps per
second and ms per step (over both passes), and the controller call's median, p99, p99.9 and
max against T_s (wall clock, ``result.solve_time``, first pass); then p99.9, max and the calls
over T_s of each call's least time over the passes. The flights are deterministic, so both
passes make the same calls: a call slow in one pass only was slowed by the machine (another
process, or the host of this virtual machine, held the core; the thread's CPU time counts
that too here, so it cannot tell them apart), and the least time is the controller's. The
JSON line gains ``families`` (one entry per row).

``--save`` writes both tables to ``figures/throughput/`` (``parallel.csv``, ``families.csv``:
this machine's times, expected to change), then the stamp; ``environment.md`` formats its
throughput section from them and from ``benchmarks/profile_step.py``'s profile.

Numbers only, no thresholds: on a shared machine they move by tens of percent between runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

# One core per flight: BLAS threads would compete with the other worker (set before NumPy
# loads; spawned workers inherit it).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from _passes import PASSES, fly_passes  # noqa: E402  benchmarks/_passes.py (the script's folder)

from paper_repro import Config
from paper_repro.paths import figures_dir
from paper_repro.sim.loop import simulate
from paper_repro.sim.plant import QuadrotorPlant, plant_for
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.quadrotor import quadrotor_model

WARMUP_STEPS = 50


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=20_000,
                        help="closed-loop steps per flight (default 20000)")
    parser.add_argument("--scenario", default="paper", choices=("paper", "encounter"))
    parser.add_argument("--workers", type=int, default=2,
                        help="concurrent flights of the parallel run (default 2)")
    parser.add_argument("--families", nargs="*", default=list(FAMILIES), choices=list(FAMILIES),
                        help="scene families flown after the parallel run (default: all)")
    parser.add_argument("--passages", type=int, default=20,
                        help="random passages per metric (default 20)")
    parser.add_argument("--crossings", type=int, default=5,
                        help="random crossings per metric (default 5)")
    parser.add_argument("--save", action="store_true",
                        help="write figures/throughput/ (this machine's times) and its stamp")
    args = parser.parse_args()
    if min(args.steps, args.workers, args.passages, args.crossings) < 1:
        parser.error("--steps, --workers, --passages and --crossings must be >= 1")

    cfg = _config(args.scenario)
    ctl = _warm_controller(cfg)  # also fills the compile caches the workers will load from
    QuadrotorPlant(cfg.quadrotor, cfg.nmpc.ts)

    t0, c0 = time.perf_counter(), time.process_time()
    result = simulate(cfg, controller=ctl, max_steps=args.steps, progress=False)
    outer, cpu = time.perf_counter() - t0, time.process_time() - c0
    wall = result.meta.get("wall_time_s", outer)
    plant_name, plant_ms, replay_error = _plant_cost(result, cfg)
    one = _row("1 worker", result.steps, wall, float(np.mean(result.solve_time)) * 1e3,
               plant_ms, cpu)

    rows, together = _parallel_rows(one, args.scenario, args.steps, args.workers)
    print(f"# {args.scenario} mission, {cfg.distance.metric} metric; plant: {plant_name} "
          f"(replay reproduces the logged states to {replay_error:.1e} m)")
    print_parallel(rows)
    families = [row for name in args.families
                for row in FAMILIES[name](args.steps, args.passages, args.crossings)]
    cluster = None
    if families:
        print_families(families)
        cluster = cluster_cost(families)
        print("# a 10,000-scene Monte Carlo (x 2 metrics) at this speed: "
              + ", ".join(f"{k} {v:,.4g}" for k, v in cluster.items()))
    if args.save:
        save(rows, families, cluster, args.scenario, "crossings" in args.families)
    print(json.dumps({
        "steps_per_core_s": round(one["steps_per_s"], 1),
        "steps_per_s_2_workers": round(together, 1),
        "parallel_efficiency": round(together / args.workers / one["steps_per_s"], 3),
        "all_in_ms_per_step": round(one["ms"], 4),
        "plant_ms_per_step": round(plant_ms, 4),
        "controller_ms_per_step": round(one["controller_ms"], 4),
        "families": families,
    }))


def _parallel_rows(one: dict, scenario: str, steps: int, workers: int):
    """The rows of the parallel run (``one``, the single flight, first; then each of
    ``workers`` flights started at once in its own process; then all of them together) and
    the steps per second of all together."""
    ctx = mp.get_context("spawn")
    barrier = ctx.Barrier(workers)
    queue = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(scenario, steps, barrier, queue))
             for _ in range(workers)]
    for p in procs:
        p.start()
    reports = [queue.get() for _ in procs]
    for p in procs:
        p.join()
    rows = [one]
    for i, r in enumerate(reports):
        rows.append(_row(f"worker {i + 1}/{workers}", r["steps"], r["wall"],
                         r["controller_ms"], float("nan"), r["cpu"]))
    span = max(r["end"] for r in reports) - min(r["start"] for r in reports)
    total = sum(r["steps"] for r in reports)
    rows.append(_row(f"{workers} workers, together", total, span, float("nan"),
                     float("nan"), sum(r["cpu"] for r in reports)))
    return rows, total / span


def print_parallel(rows: list[dict]) -> None:
    """The parallel run's table: steps, wall time and the cost of a step by part."""
    header = ("run", "steps", "wall s", "steps/s", "ms/step", "cpu ms", "plant ms",
              "ctrl ms", "rest ms")
    print("{:<22}{:>8}{:>9}{:>9}{:>9}{:>9}{:>10}{:>9}{:>9}".format(*header))
    for r in rows:
        print("{:<22}{:>8d}{:>9.2f}{:>9.0f}{:>9.3f}{:>9.3f}{:>10.3f}{:>9.3f}{:>9.3f}".format(
            r["run"], r["steps"], r["wall"], r["steps_per_s"], r["ms"], r["cpu_ms"],
            r["plant_ms"], r["controller_ms"], r["rest_ms"]))


def save(rows: list[dict], families: list[dict], cluster: dict | None, scenario: str,
         crossings: bool) -> None:
    """Write ``figures/throughput/`` (this machine's times) and its stamp; with ``crossings``
    the set carries the moving study's layer (its crossings fly that configuration)."""
    from paper_repro.evidence.golden import layer_of, stamp
    from paper_repro.studies.catalogue import make_study

    out = figures_dir() / "throughput"
    out.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).assign(scenario=scenario).to_csv(
        out / "parallel.csv", index=False, float_format="%.4g")
    pd.DataFrame(families).to_csv(out / "families.csv", index=False, float_format="%.4g")
    if cluster is not None:
        pd.DataFrame([cluster]).to_csv(out / "cluster.csv", index=False, float_format="%.4g")
    layer = (layer_of(*(s.config for s in make_study("moving_obstacles", scenes=1).specs))
             if crossings else "")
    stamp(out, " ".join(["python", "benchmarks/throughput.py", *sys.argv[1:]]), layer)


# --- the scene families ------------------------------------------------------------------------

def _fly_family(family: str, metric: str, specs) -> dict:
    """Fly ``specs`` (RunSpecs of one configuration but the scene) in this process with one
    controller, reset before each flight, :data:`PASSES` times over (``_passes``); the row of
    the families table."""
    ctl = _warm_controller(specs[0].config)
    steps, wall, first, least = 0, 0.0, [], []
    for spec in specs:
        def fly(spec=spec):
            ctl.reset()
            return simulate(spec.config, controller=ctl, max_steps=spec.max_steps,
                            progress=False)

        results, floor = fly_passes(fly, PASSES, spec.name)
        steps += sum(r.steps for r in results)
        wall += sum(r.meta["wall_time_s"] for r in results)
        first.append(1e3 * np.asarray(results[0].solve_time, float))
        least.append(floor)
    ms, floor = np.concatenate(first), np.concatenate(least)
    ts_ms = specs[0].config.nmpc.ts * 1e3
    return {"family": family, "metric": metric, "runs": len(specs), "steps": len(ms),
            "passes": PASSES, "steps_per_s": steps / wall, "all_in_ms": wall / steps * 1e3,
            "controller_ms": float(ms.mean()), "median_ms": float(np.median(ms)),
            "p99_ms": float(np.percentile(ms, 99)), "p999_ms": float(np.percentile(ms, 99.9)),
            "max_ms": float(ms.max()), "over_ts": int(np.sum(ms > ts_ms)), "ts_ms": ts_ms,
            "least_p999_ms": float(np.percentile(floor, 99.9)),
            "least_max_ms": float(floor.max()), "least_over_ts": int(np.sum(floor > ts_ms))}


def _paper_family(steps: int, passages: int, crossings: int) -> list[dict]:
    from paper_repro.studies.runs import RunSpec

    out = []
    for metric in ("smooth", "euclidean"):
        base = Config()
        cfg = dataclasses.replace(base, distance=dataclasses.replace(base.distance,
                                                                     metric=metric))
        out.append(_fly_family("paper mission", metric, [RunSpec(f"paper-{metric}", cfg,
                                                                 steps)]))
    return out


def _passage_family(steps: int, passages: int, crossings: int) -> list[dict]:
    from paper_repro.studies.catalogue import make_study

    specs = make_study("monte_carlo", scenes=passages).specs
    return [_fly_family("random passages", m, [s for s in specs
                                               if s.config.distance.metric == m])
            for m in ("smooth", "euclidean")]


def _crossing_family(steps: int, passages: int, crossings: int) -> list[dict]:
    from paper_repro.studies.catalogue import make_study

    specs = [s for s in make_study("moving_obstacles", scenes=crossings).specs
             if s.config.nmpc.prediction == "oracle"]
    return [_fly_family("random crossings (oracle)", m,
                        [s for s in specs if s.config.distance.metric == m])
            for m in ("smooth", "euclidean")]


def cluster_cost(families: list[dict], scenes: int = 10_000) -> dict:
    """What ``scenes`` random passages per metric cost on a cluster at the measured speed:
    core-hours (mean steps per passage × all-in ms per step, both metrics), the resident
    memory of this process (a single-threaded worker holds the same: CasADi, the compiled
    libraries, its controllers) and the size of one saved result."""
    import resource
    import tempfile

    from paper_repro.studies.catalogue import make_study

    passages = [r for r in families if r["family"] == "random passages"]
    if not passages:
        return {}
    seconds = sum(r["steps"] / r["runs"] * r["all_in_ms"] * 1e-3 for r in passages)
    spec = make_study("monte_carlo", scenes=1).specs[0]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "run"
        simulate(spec.config, max_steps=spec.max_steps, progress=False).save(folder)
        result_mb = sum(f.stat().st_size for f in folder.iterdir()) / 1e6
    return {"scenes_per_metric": scenes,
            "steps_per_passage": sum(r["steps"] for r in passages)
            / sum(r["runs"] for r in passages),
            "core_hours": seconds * scenes / 3600,
            "worker_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3,
            "result_mb_per_run": result_mb,
            "results_gb": result_mb * scenes * len(passages) / 1e3}


FAMILIES = {"paper": _paper_family, "passages": _passage_family, "crossings": _crossing_family}


def print_families(rows: list[dict]) -> None:
    print("# scene families, one process: all-in steps/s and the controller call (ms) "
          "against T_s")
    header = ("family", "metric", "runs", "steps", "steps/s", "ms/step", "median", "p99",
              "p99.9", "max", "> T_s", "least p99.9", "max", "> T_s")
    print("{:<27}{:>10}{:>6}{:>9}{:>9}{:>9}{:>8}{:>8}{:>8}{:>8}{:>7}{:>12}{:>8}{:>7}"
          .format(*header))
    for r in rows:
        print("{:<27}{:>10}{:>6d}{:>9d}{:>9.0f}{:>9.3f}{:>8.3f}{:>8.3f}{:>8.3f}{:>8.2f}{:>7d}"
              "{:>12.3f}{:>8.2f}{:>7d}".format(
                  r["family"], r["metric"], r["runs"], r["steps"], r["steps_per_s"],
                  r["all_in_ms"], r["median_ms"], r["p99_ms"], r["p999_ms"], r["max_ms"],
                  r["over_ts"], r["least_p999_ms"], r["least_max_ms"], r["least_over_ts"]))


def _config(scenario: str) -> Config:
    base = Config()
    return dataclasses.replace(
        base, simulation=dataclasses.replace(base.simulation, scenario=scenario))


def _warm_controller(cfg: Config):
    """A built controller that has flown a few steps, then reset to a clean slate."""
    ctl = make_controller(cfg)
    ctl.ready()
    simulate(cfg, controller=ctl, max_steps=WARMUP_STEPS, progress=False)
    ctl.reset()
    return ctl


def _worker(scenario: str, steps: int, barrier, queue) -> None:
    """One flight of the parallel run; every worker starts flying at the same moment."""
    cfg = _config(scenario)
    ctl = _warm_controller(cfg)
    barrier.wait()
    start = time.perf_counter()  # CLOCK_MONOTONIC: comparable between processes
    cpu = time.process_time()
    result = simulate(cfg, controller=ctl, max_steps=steps, progress=False)
    end, cpu = time.perf_counter(), time.process_time() - cpu
    queue.put({"steps": result.steps, "wall": result.meta.get("wall_time_s", end - start),
               "start": start, "end": end, "cpu": cpu,
               "controller_ms": float(np.mean(result.solve_time)) * 1e3})


def _plant_cost(result, cfg: Config):
    """ms per step of the integrator ``simulate`` uses (:func:`paper_repro.sim.plant.plant_for`),
    replaying the flight's logged states and inputs, and the largest deviation of the replay
    from the logged next states (m)."""
    plant = plant_for(quadrotor_model(cfg), cfg)
    name = type(plant).__name__ + (", compiled DP45" if getattr(plant, "native", False) else "")
    x, u = result.x, result.u
    out = []
    t0 = time.perf_counter()
    for k in range(len(u)):
        out.append(plant.step(x[k], u[k]))
    elapsed = time.perf_counter() - t0
    error = float(np.max(np.abs(np.array(out)[:, :3] - x[1:len(u) + 1, :3])))
    return name, elapsed / len(u) * 1e3, error


def _row(run, steps, wall, controller_ms, plant_ms, cpu):
    ms = wall / steps * 1e3
    return {"run": run, "steps": steps, "wall": wall, "steps_per_s": steps / wall, "ms": ms,
            "cpu_ms": cpu / steps * 1e3, "plant_ms": plant_ms, "controller_ms": controller_ms,
            "rest_ms": ms - controller_ms - plant_ms}


if __name__ == "__main__":
    main()

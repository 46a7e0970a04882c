"""All-in cost of one closed-loop step, on one core and with two workers.

    python benchmarks/throughput.py --steps 20000 --scenario paper

Flies ``paper_repro.sim.loop.simulate`` for ``--steps`` steps (or until the mission ends) on
one core, then two such flights at once in two processes (``multiprocessing``, spawn). One
step is everything the loop does: LiDAR scan, controller, plant integration, logging. The
compile caches are warmed and the controllers built before any timing; each flight starts
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

Numbers only, no thresholds: on a shared machine they move by tens of percent between runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import os
import time

# One core per flight: BLAS threads would compete with the other worker (set before NumPy
# loads; spawned workers inherit it).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from paper_repro import Config
from paper_repro.sim import loop as sim_module
from paper_repro.sim.loop import simulate
from paper_repro.sim.plant import Plant
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.quadrotor import plant_step

WARMUP_STEPS = 50


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=20_000,
                        help="closed-loop steps per flight (default 20000)")
    parser.add_argument("--scenario", default="paper", choices=("paper", "encounter"))
    parser.add_argument("--workers", type=int, default=2,
                        help="concurrent flights of the parallel run (default 2)")
    args = parser.parse_args()
    if args.steps < 1 or args.workers < 1:
        parser.error("--steps and --workers must be >= 1")

    cfg = _config(args.scenario)
    ctl = _warm_controller(cfg)  # also fills the compile caches the workers will load from
    Plant(cfg.quadrotor, cfg.nmpc.ts)

    t0, c0 = time.perf_counter(), time.process_time()
    result = simulate(cfg, controller=ctl, max_steps=args.steps, progress=False)
    outer, cpu = time.perf_counter() - t0, time.process_time() - c0
    wall = result.meta.get("wall_time_s", outer)
    plant_name, plant_ms, replay_error = _plant_cost(result, cfg)
    one = _row("1 worker", result.steps, wall, float(np.mean(result.solve_time)) * 1e3,
               plant_ms, cpu)

    ctx = mp.get_context("spawn")
    barrier = ctx.Barrier(args.workers)
    queue = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(args.scenario, args.steps, barrier, queue))
             for _ in range(args.workers)]
    for p in procs:
        p.start()
    reports = [queue.get() for _ in procs]
    for p in procs:
        p.join()
    rows = [one]
    for i, r in enumerate(reports):
        rows.append(_row(f"worker {i + 1}/{args.workers}", r["steps"], r["wall"],
                         r["controller_ms"], float("nan"), r["cpu"]))
    span = max(r["end"] for r in reports) - min(r["start"] for r in reports)
    total = sum(r["steps"] for r in reports)
    rows.append(_row(f"{args.workers} workers, together", total, span, float("nan"),
                     float("nan"), sum(r["cpu"] for r in reports)))

    print(f"# {args.scenario} mission, {cfg.distance.metric} metric; plant: {plant_name} "
          f"(replay reproduces the logged states to {replay_error:.1e} m)")
    header = ("run", "steps", "wall s", "steps/s", "ms/step", "cpu ms", "plant ms",
              "ctrl ms", "rest ms")
    print("{:<22}{:>8}{:>9}{:>9}{:>9}{:>9}{:>10}{:>9}{:>9}".format(*header))
    for r in rows:
        print("{:<22}{:>8d}{:>9.2f}{:>9.0f}{:>9.3f}{:>9.3f}{:>10.3f}{:>9.3f}{:>9.3f}".format(
            r["run"], r["steps"], r["wall"], r["steps_per_s"], r["ms"], r["cpu_ms"],
            r["plant_ms"], r["controller_ms"], r["rest_ms"]))
    together = total / span
    print(json.dumps({
        "steps_per_core_s": round(one["steps_per_s"], 1),
        "steps_per_s_2_workers": round(together, 1),
        "parallel_efficiency": round(together / args.workers / one["steps_per_s"], 3),
        "all_in_ms_per_step": round(one["ms"], 4),
        "plant_ms_per_step": round(plant_ms, 4),
        "controller_ms_per_step": round(one["controller_ms"], 4),
    }))


def _config(scenario: str) -> Config:
    base = Config()
    return dataclasses.replace(
        base, simulation=dataclasses.replace(base.simulation, scenario=scenario))


def _warm_controller(cfg: Config):
    """A built controller that has flown a few steps, then reset to a clean slate."""
    ctl = make_controller(cfg)
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
    """ms per step of the integrator ``simulate`` uses, replaying the flight's logged states
    and inputs, and the largest deviation of the replay from the logged next states (m)."""
    ts, params = cfg.nmpc.ts, cfg.quadrotor
    if hasattr(sim_module, "Plant"):
        plant = Plant(params, ts)
        step = plant.step
        name = "Plant, compiled DP45" if plant.native else "Plant, solve_ivp fallback"
    else:
        def step(x, u):
            return plant_step(x, u, ts, params)
        name = "model.plant_step (solve_ivp)"
    x, u = result.x, result.u
    out = []
    t0 = time.perf_counter()
    for k in range(len(u)):
        out.append(step(x[k], u[k]))
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

"""Where one closed-loop step goes, by sampling, and the floor of each part.

    python benchmarks/profile_step.py --steps 20000 [--save]

Flies the first ``--steps`` steps of the paper mission (smoothed metric, the default real-time
iteration) in a child process under ``py-spy`` (a sampling profiler: it adds no cost per call,
unlike cProfile), and sorts every sample of the closed loop into the part of the step it was
in, by the frames of its stack:

* ``QP (C)``: the Riccati QP's compiled solve; ``QP (Python)``: its wrapper;
* ``linearisation (C)``: the generated linearisation; ``linearisation (Python)``: filling its
  buffers, packing the scan;
* ``controller (Python)``: the rest of the controller call (guess, bounds, update);
* ``LiDAR``, ``plant``, ``clearance`` (the true distance the loop logs, measured for
  every step at once after the flight), ``logging``;
* ``loop``: the rest of ``simulate``'s step.

ms per step = share of the loop's samples × the flight's wall time per step, counting only the
samples of the span that wall time measures (the step loop of the measured flight: not the
controller's build, which is done before it, nor the warm-up or the set-up). Then, in the same
process without the profiler, the floor of the compiled parts: one linearisation and one QP
solve, each repeated on the inputs of a step with a region in view (the QP warm-started with its
own active set, so one factorisation; its thin Python wrapper included), one LiDAR scan and one
plant step there. Their sum is
the floor of this algorithm in this process; the last line says how far the step is from it.

``--save`` writes ``figures/throughput/profile/`` (``profile.csv``, ``floor.csv``: this
machine's times), then the stamp.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

PARTS = (  # (part, test on the frames of one sample: its stack, root first)
    ("LiDAR", lambda f: _has(f, "Lidar.scan")),
    ("plant", lambda f: _has(f, "QuadrotorPlant.step")),
    ("clearance", lambda f: _has(f, "_TrueClearance.along")),
    ("logging", lambda f: _has(f, "_Log.record")),
    ("QP (C)", lambda f: _last_ours(f).startswith("StageQP._solve") and _line(f) == _QP_LINE),
    ("QP (Python)", lambda f: _has(f, "QPChain.solve")),
    ("linearisation (C)", lambda f: _last_ours(f).startswith("NativeFunction.__call__")),
    ("linearisation (Python)", lambda f: _has(f, "LinearisationLadder.")),
    ("controller (Python)", lambda f: _has(f, "RealTimeNMPC.solve")),
    ("loop", lambda f: True),
)
_QP_LINE: int | None = None  # the line of StageQP._solve that calls the C solver
_TIMED: tuple[int, int] | None = None  # simulate's lines of the span its wall_time_s times


def _has(frames, name: str) -> bool:
    return any(f.startswith(name) for f in frames)


def _last_ours(frames) -> str:
    ours = [f for f in frames if "paper_repro" in f]
    return ours[-1] if ours else ""


def _line(frames) -> int | None:
    last = _last_ours(frames)
    return int(last.rsplit(":", 1)[1].rstrip(")")) if ":" in last else None


def _in_timed_flight(frames) -> bool:
    """The sample is in the measured flight's timed span: ``simulate`` called from
    :func:`_measured_flight` (not the warm-up, not the controller's build), at a line between
    its clock's start and its ``wall_time_s`` (not the set-up before the loop, whose
    KD-trees and checks the wall time per step does not include)."""
    if not _has(frames, "_measured_flight"):
        return False
    for f in frames:
        if f.startswith("simulate (") and "sim/loop.py" in f:
            line = int(f.rsplit(":", 1)[1].rstrip(")"))
            return _TIMED[0] <= line < _TIMED[1]
    return False


def _qp_call_line() -> int:
    """The source line of ``StageQP._solve`` that calls the compiled solver."""
    import inspect

    from paper_repro.solvers.riccati_qp import StageQP

    lines, first = inspect.getsourcelines(StageQP._solve)
    return next(first + i for i, line in enumerate(lines) if "stage_qp_solve(" in line)


def _timed_lines() -> tuple[int, int]:
    """The lines of ``simulate`` from its clock's start to the line that reads it."""
    import inspect

    from paper_repro.sim.loop import simulate

    lines, first = inspect.getsourcelines(simulate)
    start = next(first + i for i, line in enumerate(lines)
                 if "wall = time.perf_counter()" in line)
    end = next(first + i for i, line in enumerate(lines)
               if "wall_time_s" in line and first + i > start)
    return start, end


def child(steps: int, out: Path) -> None:
    """The profiled flight: the wall time per step goes to ``out``. The controller is built
    here, outside ``simulate``: built inside, its compilation and code generation (about
    0.6 s per build) were counted as steps of the loop, most of it as the linearisation's
    Python."""
    from paper_repro import Config
    from paper_repro.solvers.factory import make_controller

    ctl = make_controller(Config())
    ctl.ready()
    _warm_up(ctl)
    r = _measured_flight(ctl, steps)
    out.write_text(json.dumps({"steps": r.steps, "wall_s": r.meta["wall_time_s"]}))


def _warm_up(ctl) -> None:
    """A few steps first (caches warm); their samples are not counted."""
    from paper_repro import Config
    from paper_repro.sim.loop import simulate

    simulate(Config(), controller=ctl, max_steps=50, progress=False)


def _measured_flight(ctl, steps: int):
    """The flight whose samples are counted (see :func:`_in_timed_flight`)."""
    from paper_repro import Config
    from paper_repro.sim.loop import simulate

    return simulate(Config(), controller=ctl, max_steps=steps, progress=False)


def profile(steps: int) -> tuple[pd.DataFrame, dict]:
    global _QP_LINE, _TIMED
    _QP_LINE, _TIMED = _qp_call_line(), _timed_lines()
    with tempfile.TemporaryDirectory() as tmp:
        raw, info = Path(tmp) / "raw.txt", Path(tmp) / "info.json"
        subprocess.run(["py-spy", "record", "--format", "raw", "--rate", "500", "--output",
                        str(raw), "--", sys.executable, __file__, "--child", str(steps),
                        str(info)], check=True, capture_output=True)
        flight = json.loads(info.read_text())
        counts, loop = collections.Counter(), 0
        for line in raw.read_text().splitlines():
            stack, n = line.rsplit(" ", 1)
            frames = [f.strip() for f in stack.split(";")]
            if not _in_timed_flight(frames):
                continue  # imports, the controller's build, the warm-up, the set-up
            loop += int(n)
            part = next(name for name, test in PARTS if test(frames))
            counts[part] += int(n)
    ms_step = flight["wall_s"] / flight["steps"] * 1e3
    rows = [{"part": name, "share": counts[name] / loop, "ms_per_step": counts[name] / loop
             * ms_step} for name, _ in PARTS]
    return pd.DataFrame(rows), {**flight, "ms_per_step": ms_step, "samples": loop}


def floors(repeats: int = 2000) -> pd.DataFrame:
    """ms per call of each compiled part, repeated on the inputs of one step in view."""
    from paper_repro import Config, Lidar, make_scene
    from paper_repro.sim.plant import QuadrotorPlant
    from paper_repro.solvers.factory import make_controller

    cfg = Config()
    ctl = make_controller(cfg)
    ctl.ready()
    scene = make_scene(cfg.simulation.scenario, cfg.simulation.seed)
    lidar = Lidar(scene.clouds, cfg.sensor.range)
    captured = {}
    real_solve = ctl.qp.solve_bound

    def capture(bound):
        captured["qp"] = [np.array(a, copy=True) for a in bound.arrays]
        return real_solve(bound)

    ctl.qp.solve_bound = capture
    from paper_repro.sim.loop import simulate

    r = simulate(cfg, controller=ctl, max_steps=6000, progress=False)
    seen = np.flatnonzero(r.visible_points > 0)
    k = int(seen[len(seen) // 2]) if len(seen) else len(r.u) - 1
    x, visible = r.x[k], lidar.scan(r.x[k, :3])
    # The linearisation and the QP of this step, as the solver builds them.
    plan = ctl.solve(x, np.asarray(scene.targets[0], float), visible)
    ctl.solve(x, np.asarray(scene.targets[0], float), visible, previous=plan)
    rung = ctl.ladder.for_scan(visible)

    def per_call(fn) -> float:
        fn()
        t0 = time.perf_counter()
        for _ in range(repeats):
            fn()
        return (time.perf_counter() - t0) / repeats * 1e3

    qp_args = captured["qp"]
    n_ab = ctl.qp.layout.n_ab
    h, q, j, gap, eq, lb, ub = qp_args
    ab, c, d = np.ascontiguousarray(j[:n_ab]), np.ascontiguousarray(j[n_ab:]), -eq
    riccati = ctl.qp.riccati
    plant = QuadrotorPlant(cfg.quadrotor, cfg.nmpc.ts)
    rows = [
        ("linearisation (C)", per_call(rung.linearisation),
         f"capacity {rung.scan.capacity} points per region, {sum(len(v) for v in visible)} "
         "in view"),
        ("QP", per_call(lambda: riccati.solve(h, q, ab, gap, c, d, lb, ub)),
         "one warm-started Riccati solve (StageQP.solve: one factorisation)"),
        ("LiDAR", per_call(lambda: lidar.scan(x[:3])), "KD-tree ball query, regions split"),
        ("plant", per_call(lambda: plant.step(x, r.u[k])), "compiled DP45, one T_s"),
    ]
    return pd.DataFrame(rows, columns=["part", "ms_per_call", "what"])


def main() -> int:
    if len(sys.argv) >= 2 and sys.argv[1] == "--child":
        child(int(sys.argv[2]), Path(sys.argv[3]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    if args.steps < 100:
        parser.error("--steps must be >= 100")
    parts, flight = profile(args.steps)
    print(f"# paper mission, first {flight['steps']} steps, smoothed metric: "
          f"{flight['ms_per_step']:.3f} ms per step all-in ({1e3 / flight['ms_per_step']:,.0f}"
          f" steps/s), {flight['samples']} samples in the loop")
    print(f"{'part':<26}{'share':>8}{'ms/step':>10}")
    for r in parts.itertuples():
        print(f"{r.part:<26}{r.share:>8.1%}{r.ms_per_step:>10.4f}")
    floor = floors()
    print(f"\n{'floor of a part':<26}{'ms/call':>10}  what")
    for r in floor.itertuples():
        print(f"{r.part:<26}{r.ms_per_call:>10.4f}  {r.what}")
    c_parts = floor.set_index("part")["ms_per_call"]
    algorithm = c_parts["linearisation (C)"] + c_parts["QP"]
    loop_floor = algorithm + c_parts["LiDAR"] + c_parts["plant"]
    summary = {"all_in_ms_per_step": round(flight["ms_per_step"], 4),
               "algorithm_floor_ms": round(algorithm, 4),
               "loop_floor_ms": round(loop_floor, 4),
               "ratio_to_loop_floor": round(flight["ms_per_step"] / loop_floor, 2),
               "steps_per_s_at_loop_floor": round(1e3 / loop_floor)}
    print(f"\nfloor: one linearisation + one QP = {algorithm:.3f} ms; with the LiDAR and the "
          f"plant {loop_floor:.3f} ms ({1e3 / loop_floor:,.0f} steps/s); the step costs "
          f"{flight['ms_per_step'] / loop_floor:.1f}x that")
    if args.save:
        from paper_repro.evidence.golden import stamp
        from paper_repro.paths import figures_dir

        out = figures_dir() / "throughput" / "profile"
        out.mkdir(parents=True, exist_ok=True)
        parts.assign(steps=flight["steps"], all_in_ms=flight["ms_per_step"]).to_csv(
            out / "profile.csv", index=False, float_format="%.4g")
        floor.to_csv(out / "floor.csv", index=False, float_format="%.4g")
        stamp(out, " ".join(["python", "benchmarks/profile_step.py", *sys.argv[1:]]))
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())

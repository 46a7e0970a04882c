"""What a new machine waits for before the first step: building a controller from an empty cache.

    python benchmarks/build_time.py [--configs default euclidean moving-design paper-timeline]
                                    [--save] [--shared-barrier]

Each configuration is built in a fresh process whose compile cache (``PAPER_REPRO_CACHE``)
is an empty folder, so gcc compiles everything, as on a new machine. The process then flies
one step of the configuration's scenario, waits for every library, and exits. A second
process with the now warm cache builds it again. Columns:

* ``libraries``, ``source_MB``: the compiled libraries, and the C generated for the
  linearisation (every LiDAR capacity);
* ``controller_s``: ``make_controller`` returns (the libraries still compile in the
  background, one gcc per core);
* ``first_step_s``: the first closed-loop step is flown (the plant built, the rung the scan
  needs loaded): what a user waits for;
* ``all_built_s``: every library compiled and loaded;
* ``gcc_peak_MB``: the largest resident memory of one compiler process;
* ``warm_first_step_s``: the first step with a warm cache (a second run).

All are seconds (or MB) of wall time on this machine, measured from the process's
``make_controller`` call. ``--save`` writes ``figures/build_time/build_time.csv`` and its
stamp. The times move by 15-50 % on a shared machine; the ratio cold/warm is the message.
``--shared-barrier`` builds each configuration a second time with
``SolverParams(shared_barrier=True)`` and prints both (it saves nothing).
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd
from _table import print_table

from paper_repro import paths
from paper_repro.evidence.golden import stamp

CONFIGS = ("default", "euclidean", "moving-design", "paper-timeline")
"""The configurations measured: the printed one, its Euclidean baseline and two presets."""

_CHILD = r"""
import dataclasses, json, resource, sys, time
from pathlib import Path
from paper_repro import Config, simulate
from paper_repro.presets import preset
from paper_repro.solvers.factory import make_controller

name, shared = sys.argv[1], sys.argv[2] == "shared"
cfg = Config()
if name == "euclidean":
    cfg = dataclasses.replace(cfg, distance=dataclasses.replace(cfg.distance,
                                                                metric="euclidean"))
elif name == "moving-design":  # the design flies random crossings (a floor of 0.5 m)
    cfg = preset(name, dataclasses.replace(cfg, simulation=dataclasses.replace(
        cfg.simulation, kind="passage", scenario="random-crossing")))
elif name != "default":
    cfg = preset(name)
if shared:
    cfg = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, shared_barrier=True))
start = time.perf_counter()
ctl = make_controller(cfg)
controller = time.perf_counter() - start
simulate(cfg, controller=ctl, max_steps=1, progress=False)
first = time.perf_counter() - start
ctl.ready()
built = time.perf_counter() - start
source = sum(fn.source_bytes for rung in ctl.ladder.rungs for fn in rung[1:] if fn is not None)
print(json.dumps({"controller_s": controller, "first_step_s": first, "all_built_s": built,
                  "source_MB": source / 1e6,
                  "gcc_peak_MB": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1e3}))
"""


def measure(name: str, cache: Path, shared: bool = False) -> dict:
    """Build configuration ``name`` (``shared``: with the shared barrier) in a new process
    whose compile cache is ``cache``."""
    env = {**os.environ, "PAPER_REPRO_CACHE": str(cache)}
    out = subprocess.run([sys.executable, "-c", _CHILD, name, "shared" if shared else "inlined"],
                         env=env, capture_output=True,
                         text=True, check=False)
    if out.returncode:
        raise RuntimeError(f"building {name!r} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--configs", nargs="+", choices=CONFIGS, default=list(CONFIGS))
    parser.add_argument("--save", action="store_true")
    parser.add_argument("--shared-barrier", action="store_true")
    args = parser.parse_args()
    if args.save and args.shared_barrier:
        parser.error("--save writes the default build's table: it takes no --shared-barrier")
    rows = []
    variants = [(n, s) for n in args.configs for s in ((False, True) if args.shared_barrier
                                                        else (False,))]
    for name, shared in variants:
        with tempfile.TemporaryDirectory(prefix="build_time_") as tmp:
            cold = measure(name, Path(tmp), shared)
            warm = measure(name, Path(tmp), shared)
            libraries = len(list(Path(tmp).glob("*.so")))
        rows.append({"configuration": name + (" (shared barrier)" if shared else ""),
                     "libraries": libraries,
                     "source_MB": round(cold["source_MB"], 2),
                     "controller_s": round(cold["controller_s"], 1),
                     "first_step_s": round(cold["first_step_s"], 1),
                     "all_built_s": round(cold["all_built_s"], 1),
                     "gcc_peak_MB": round(cold["gcc_peak_MB"]),
                     "warm_first_step_s": round(warm["first_step_s"], 2)})
        print(f"# {name}: {json.dumps(rows[-1])}", flush=True)
    print_table(rows, [("configuration", "config", "s"), ("libraries", "libs", "d"),
                       ("source_MB", "source MB", ".2f"), ("controller_s", "ctl s", ".1f"),
                       ("first_step_s", "1st step s", ".1f"), ("all_built_s", "all s", ".1f"),
                       ("gcc_peak_MB", "gcc MB", "d"), ("warm_first_step_s", "warm s", ".2f")],
                width=14)
    if args.save:
        out = paths.figures_dir() / "build_time"
        out.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(rows).to_csv(out / "build_time.csv", index=False)
        stamp(out, "python benchmarks/build_time.py --save")


if __name__ == "__main__":
    main()

"""Fidelity of the fast solvers to the paper's controller (IPOPT at every instant).

    python benchmarks/fidelity.py                          # every window, every solver
    python benchmarks/fidelity.py --windows paper-euclidean-50 --solvers reference rti
    python benchmarks/fidelity.py --table-only             # re-print from the saved flights
    python benchmarks/fidelity.py --windows encounter-euclidean-15s --update

A *window* is a short closed loop flown by every solver from the same state: the state a
lead-in flight (the damped real-time iteration, fixed so that the windows never move)
reached at ``t0``: the paper mission with a region in view, the encounter (from 1 s after
the region comes into view, and its first 15 s with the whole avoidance), random passages
and the moving ``crossing``. IPOPT is the paper's solver, in two closed loops that differ
only where it stops at its iteration limit (the Euclidean metric): ``reference`` counts that
as a failed solve and applies the previous plan, shifted; ``reference-iterate`` applies the
iterate it stopped at. Per (window, solver) it prints the chattering measures after the
first :data:`SETTLE_STEPS` (total variation of u per second, share of thrust power above
5 Hz, sign changes of Δu, max |Δu|, steps with |Δu| > 1 N), the minimum clearance, the
largest position deviation from the IPOPT loop's trajectory, the instants at which IPOPT or the
iterated SQP stopped at its iteration limit (:func:`at_limit`) and
the median / p99 solve time, then the ratios to the IPOPT loop that applies what IPOPT
returns. Every flight is saved in ``results/fidelity/<window>/<solver>/``
and re-used; the flight columns go to ``figures/fidelity/fidelity.csv`` (byte-stable), the
solve times to ``figures/fidelity/fidelity_timings.csv`` (this machine's). Flights run in
parallel, one process per core (``--jobs``). ``--update`` writes the rows of the windows
flown into the committed tables and keeps the others (their flights are the same code's).
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import dataclasses
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
from _table import print_table  # benchmarks/_table.py (the script's folder)

from paper_repro import Config
from paper_repro.analysis.metrics import chattering_metrics
from paper_repro.evidence.golden import stamp
from paper_repro.paths import figures_dir, results_dir
from paper_repro.sim.loop import simulate
from paper_repro.sim.result import SimulationResult
from paper_repro.solvers.factory import make_controller
from paper_repro.studies.catalogue import passage_config

SOLVERS = {  # name -> (SolverParams.nlp_solver, controller options)
    "reference": ("reference", {}),  # IPOPT; a solve stopped at the iteration limit failed
    "reference-iterate": ("reference", {"apply_unconverged": True}),  # ... its iterate applied
    "rti": ("rti", {"max_iter": 1, "line_search": False}),  # the default
    "rti-damped": ("rti", {"max_iter": 1, "line_search": True}),
    "sqp": ("rti", {"max_iter": 20, "line_search": False}),
    # IPOPT at its own default limit (3000 iterations, the paper's CasADi default), its
    # iterate applied: does more iterating converge the Euclidean NLP? (paper-euclidean-50,
    # the first LIMIT_3000_STEPS steps only: up to 23 s per call)
    "reference-3000": ("reference", {"apply_unconverged": True, "max_iter": 3000}),
}
LIMIT_3000_STEPS = 60

# name -> (scenario, kind, seed, metric, t0 (s; "view": 1 s after a region first comes into
# view of the lead-in flight), steps); the crossing's region moves (oracle prediction)
WINDOWS = {
    "paper-euclidean-50": ("paper", "mission", 7, "euclidean", 50.0, 200),
    "paper-euclidean-120": ("paper", "mission", 7, "euclidean", 120.0, 200),
    "paper-euclidean-250": ("paper", "mission", 7, "euclidean", 250.0, 200),
    "paper-smooth-50": ("paper", "mission", 7, "smooth", 50.0, 200),
    "paper-smooth-120": ("paper", "mission", 7, "smooth", 120.0, 200),
    "paper-smooth-250": ("paper", "mission", 7, "smooth", 250.0, 200),
    "encounter-euclidean": ("encounter", "mission", 7, "euclidean", "view", 300),
    "encounter-smooth": ("encounter", "mission", 7, "smooth", "view", 300),
    "encounter-euclidean-15s": ("encounter", "mission", 7, "euclidean", 0.0, 1500),
    "encounter-smooth-15s": ("encounter", "mission", 7, "smooth", 0.0, 1500),
    "passage3-euclidean": ("random", "passage", 3, "euclidean", "view", 200),
    "passage3-smooth": ("random", "passage", 3, "smooth", "view", 200),
    "passage11-euclidean": ("random", "passage", 11, "euclidean", "view", 200),
    "passage11-smooth": ("random", "passage", 11, "smooth", "view", 200),
    "crossing-smooth": ("crossing", "mission", 7, "smooth", 0.0, 1000),
}

TEST_FLIGHTS = (("paper-euclidean-50", "reference-iterate"),
                ("paper-euclidean-120", "reference-iterate"), ("paper-smooth-50", "reference"))
"""IPOPT flights committed as (K, 16) rows (x_k, u_k) in ``figures/fidelity/``: the test flies
only the fast path from their first state and compares (IPOPT is too slow for CI there)."""

OUT = results_dir() / "fidelity"
TABLES = figures_dir() / "fidelity"


def window_config(window: str, solver: str) -> Config:
    scenario, kind, seed, metric, _, steps = WINDOWS[window]
    base = Config()
    base = dataclasses.replace(base, distance=dataclasses.replace(base.distance, metric=metric))
    if kind == "passage":
        cfg = passage_config(base, seed, steps, scenario, metric=metric)
    else:
        cfg = dataclasses.replace(base, simulation=dataclasses.replace(
            base.simulation, scenario=scenario, seed=seed, max_steps=steps),
            nmpc=dataclasses.replace(
                base.nmpc, prediction="oracle" if scenario == "crossing" else "static"))
    return dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver,
                                                               nlp_solver=SOLVERS[solver][0]))


def initial_state(window: str) -> np.ndarray | None:
    """The state the lead-in flight (the damped real-time iteration, named so that the
    windows do not move with the default) reached at t0 (cached); ``None``: the scene's
    start."""
    t0 = WINDOWS[window][4]
    if t0 == 0.0:
        return None
    folder = OUT / window / "lead-in"
    if not (folder / "result.npz").exists():
        cfg = window_config(window, "rti-damped")
        ctl = make_controller(cfg, **SOLVERS["rti-damped"][1])
        steps = 6000 if t0 == "view" else int(round(t0 / cfg.nmpc.ts))
        simulate(cfg, ctl, max_steps=steps, progress=False).save(folder)
    lead = SimulationResult.load(folder)
    if t0 == "view":
        seen = np.flatnonzero(lead.visible_points > 0)
        return lead.x[seen[0] + int(round(1.0 / lead.config.nmpc.ts))]
    return lead.x[-1]


def ipopt_loop(window: str) -> str:
    """The IPOPT loop a window is compared with: the one that applies what IPOPT returns."""
    return "reference-iterate" if WINDOWS[window][3] == "euclidean" else "reference"


def needed(window: str, solver: str) -> bool:
    """Which IPOPT loop a window needs: with the smoothed metric IPOPT converges and the two
    loops are one (``reference``); with the Euclidean one ``reference-iterate`` is what IPOPT
    does, and ``reference`` (the old plan flown open loop) is kept for the paper windows
    only, where it shows why the other one is the reference."""
    euclidean = WINDOWS[window][3] == "euclidean"
    if solver == "reference-3000":
        return window == "paper-euclidean-50"
    if solver == "reference-iterate":
        return euclidean
    if solver == "reference":
        return not euclidean or window in ("paper-euclidean-50", "paper-euclidean-120")
    return True


def fly(window: str, solver: str) -> Path:
    folder = OUT / window / solver
    if not (folder / "result.npz").exists():
        x0 = initial_state(window)
        cfg = window_config(window, solver)
        if solver == "reference-3000":
            cfg = dataclasses.replace(cfg, simulation=dataclasses.replace(
                cfg.simulation, max_steps=LIMIT_3000_STEPS))
        ctl = make_controller(cfg, **SOLVERS[solver][1])
        simulate(cfg, ctl, progress=False, initial_state=x0).save(folder)
        print(f"  flown {window} / {solver}", flush=True)
    return folder


SETTLE_STEPS = 20
"""Steps at the start of a window left out of the chattering measures (0.2 s): every solver
starts from the hover guess, and a real-time iteration needs a few instants to reach the
converged plan that IPOPT finds at once; that transient is the window's, not the solver's."""


def at_limit(solver: str, status: np.ndarray) -> float:
    """Instants at which the solver stopped at its iteration limit without meeting its own
    convergence test: IPOPT's ``Maximum_Iterations_Exceeded``, or an SQP of several
    iterations whose last step was still above ``step_tol`` (``"iterated"``). NaN for the
    one-step real-time iterations, which stop after one step by design."""
    if SOLVERS[solver][0] == "reference":
        return float(np.sum(status == "Maximum_Iterations_Exceeded"))
    if SOLVERS[solver][1].get("max_iter", 1) > 1:
        return float(np.sum(status == "iterated"))
    return np.nan


def row(window: str, solver: str, reference: SimulationResult | None) -> dict:
    r = SimulationResult.load(OUT / window / solver)
    u = r.u[SETTLE_STEPS:]
    ts, seconds = r.config.nmpc.ts, len(u) * r.config.nmpc.ts
    c = chattering_metrics(u, ts)
    du = np.abs(np.diff(u, axis=0)).max(axis=1)
    deviation = np.nan
    if reference is not None:
        n = min(reference.steps, r.steps) + 1
        deviation = float(np.linalg.norm(r.x[:n, :3] - reference.x[:n, :3], axis=1).max())
    st = r.solve_time * 1e3
    return {"window": window, "solver": solver, "steps": r.steps,
            "tv_per_s": c["total_variation"] / seconds, "hf_share": c["hf_energy_fraction"],
            "sign_changes": c["du_sign_changes"], "max_du": c["max_abs_du"],
            "jumps_1N": int(np.sum(du > 1.0)), "min_clearance_m": float(r.clearance.min()),
            "deviation_m": deviation, "failed": r.failures,
            "iteration_limit": at_limit(solver, r.status),
            "median_ms": float(np.median(st)), "p99_ms": float(np.percentile(st, 99)),
            "max_ms": float(st.max())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--windows", nargs="+", default=list(WINDOWS), choices=list(WINDOWS))
    parser.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=list(SOLVERS))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--table-only", action="store_true")
    parser.add_argument("--update", action="store_true",
                        help="write the rows of --windows into the committed tables")
    args = parser.parse_args()

    if not args.table_only:
        for window in args.windows:  # lead-ins first, once per window
            initial_state(window)
        jobs = [(w, s) for w in args.windows for s in args.solvers if needed(w, s)]
        with ProcessPoolExecutor(args.jobs) as pool:
            list(pool.map(fly, *zip(*jobs, strict=True)))
    rows = []
    for window in args.windows:
        ref_dir = OUT / window / ipopt_loop(window)
        reference = SimulationResult.load(ref_dir) if (ref_dir / "result.npz").exists() else None
        for solver in args.solvers:
            if (OUT / window / solver / "result.npz").exists():
                rows.append(row(window, solver, reference))
    table = pd.DataFrame(rows)
    # The ratios are to the IPOPT loop that applies what IPOPT returns (``reference`` where
    # IPOPT converges, the smoothed metric; ``reference-iterate`` for the Euclidean one).
    ref = table[table.solver == table.window.map(ipopt_loop)].set_index("window")
    for col in ("tv_per_s", "hf_share", "sign_changes", "max_du"):
        table[f"{col}_ratio"] = [getattr(r, col) / ref.loc[r.window, col] if r.window in ref.index
                                 else np.nan for r in table.itertuples()]
    print_table(table.to_dict("records"), [
        ("window", "window", "s"), ("solver", "solver", "s"), ("tv_per_s", "TV N/s", ".4g"),
        ("tv_per_s_ratio", "TV/ref", ".3g"), ("hf_share", ">5 Hz", ".3f"),
        ("hf_share_ratio", ">5Hz/ref", ".3g"),
        ("sign_changes", "sign ch.", "d"), ("max_du", "max|du| N", ".3g"),
        ("jumps_1N", "|du|>1N", "d"), ("min_clearance_m", "clear. m", ".4f"),
        ("deviation_m", "dev. m", ".3g"), ("iteration_limit", "at limit", ".0f"),
        ("median_ms", "med ms", ".3g"),
        ("p99_ms", "p99 ms", ".3g")], width=11)
    flight = [c for c in table.columns if not c.endswith("_ms")]
    timing = ["window", "solver", "median_ms", "p99_ms", "max_ms"]
    complete = set(args.windows) == set(WINDOWS) and set(args.solvers) == set(SOLVERS)
    if args.update and set(args.solvers) == set(SOLVERS):
        table = merged(table, flight, timing)
    elif not complete:
        return
    TABLES.mkdir(parents=True, exist_ok=True)
    table[flight].to_csv(TABLES / "fidelity.csv", index=False, float_format="%.6g")
    table[timing].to_csv(TABLES / "fidelity_timings.csv", index=False, float_format="%.4g")
    for window, solver in TEST_FLIGHTS:  # what tests/test_fidelity.py compares against
        if window in args.windows:
            r = SimulationResult.load(OUT / window / solver)
            np.save(TABLES / f"{window}-{solver}.npy", np.hstack([r.x[:-1], r.u]))
    stamp(TABLES, "python benchmarks/fidelity.py")


def merged(table: pd.DataFrame, flight: list[str], timing: list[str]) -> pd.DataFrame:
    """The committed tables with the rows of ``table``'s windows replaced by ``table``'s, in
    the order of :data:`WINDOWS` and :data:`SOLVERS`."""
    old = pd.read_csv(TABLES / "fidelity.csv").merge(
        pd.read_csv(TABLES / "fidelity_timings.csv"), on=["window", "solver"])
    out = pd.concat([old[~old.window.isin(table.window)], table[flight + timing[2:]]])
    order = {w: i for i, w in enumerate(WINDOWS)}
    rank = {s: i for i, s in enumerate(SOLVERS)}
    out = out.assign(_w=out.window.map(order), _s=out.solver.map(rank))
    return out.sort_values(["_w", "_s"]).drop(columns=["_w", "_s"]).reset_index(drop=True)

if __name__ == "__main__":
    sys.exit(main())

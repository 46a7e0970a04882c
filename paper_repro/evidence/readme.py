"""The numbers of the README and the book's pages, formatted from the committed tables (never
typed by hand).

Each block of a page (:func:`page_paths`: ``README.md`` and ``docs/**/*.md``) between
``<!-- begin NAME -->`` and ``<!-- end NAME -->`` is the markdown that :data:`BLOCKS`
``[NAME]`` renders from a committed table in ``figures/``. ``python -m paper_repro readme``
writes them; ``tests/test_report.py`` fails when a page holds anything else, so a
regenerated table and the prose that quotes it cannot part.
Only what the flights determine is quoted; solve times live in the benchmarks' own output.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from paper_repro import paths
from paper_repro.evidence import beyond, hardware
from paper_repro.evidence import formatting as fmt


def summary() -> str:
    """The paper mission, both presets: ``figures/summary.csv`` and the preset's."""
    rows = []
    for preset, folder in (("`paper` (N = 35)", paths.figures_dir()),
                           ("`paper-timeline` (N = 43)",
                            paths.figures_dir() / "presets" / "paper-timeline")):
        table = pd.read_csv(folder / "summary.csv")
        for r in table.itertuples():
            rows.append([preset, "smoothed D" if r.metric == "smooth" else "Euclidean ½d²",
                         f"{r.mission_time_s:,.1f} s", r.targets_reached,
                         f"{r.failed_solves:,}", f"{r.tv_u_N:,.0f} N",
                         fmt.share(r.hf_energy_fraction), f"{r.du_sign_changes:,}",
                         f"{r.max_abs_du_N:.2f} N", f"{r.min_clearance_m:.3f} m"])
    return fmt.markdown_table(["preset", "run", "mission time", "targets", "failed solves",
                      "total variation of u", "power > 5 Hz", "sign changes of Δu",
                      "max |Δu|", "min clearance"], rows)


def verdict() -> str:
    """The paper's claims against what the committed tables measure: the paper mission
    (``summary.csv``, both presets), the Monte Carlo (``mc_summary.csv``) and the fidelity
    windows (``fidelity.csv``)."""
    figs = paths.figures_dir()
    mission = pd.read_csv(figs / "summary.csv").set_index("metric")
    timeline = pd.read_csv(figs / "presets" / "paper-timeline" / "summary.csv").set_index("metric")
    mc = pd.read_csv(figs / "studies" / "monte_carlo" / "mc_summary.csv")
    rates = mc[mc["kind"] == "rate"].set_index(["event", "metric"])
    tv = mc[(mc["kind"] == "paired") & (mc["measure"] == "tv_u_rate_N_per_s")].iloc[0]
    fid = pd.read_csv(figs / "fidelity" / "fidelity.csv")
    paper_windows = fid[fid.window.str.startswith("paper-")]
    smooth_dev = paper_windows[paper_windows.window.str.contains("smooth")
                               & (paper_windows.solver == "rti")]["deviation_m"].max()
    euclid = paper_windows[paper_windows.window.str.contains("euclidean")]

    def at_limit(solver: str) -> str:
        rows = euclid[euclid.solver == solver]
        return f"{rows.iteration_limit.sum():.0f} of {rows.steps.sum()}"

    s, e = mission.loc["smooth"], mission.loc["euclidean"]
    rows = [
        ["the smoothed thrusts vary gently, the Euclidean ones chatter (Figs. 4 and 8)",
         f"power above 5 Hz {fmt.share(s.hf_energy_fraction)} against "
         f"{fmt.share(e.hf_energy_fraction)}; total variation {s.tv_u_N:,.0f} N against "
         f"{e.tv_u_N:,.0f} N", "`summary.csv`"],
        ["... and not only on the paper's scene",
         f"Euclidean/smoothed total variation per passage ×{fmt.num(tv.median_effect)} "
         f"[{fmt.num(tv.low)}, {fmt.num(tv.high)}] over {tv.scenes:.0f} random passages",
         "`mc_summary.csv`"],
        ["both keep clear of the clouds",
         f"min clearance {s.min_clearance_m:.2f} m and {e.min_clearance_m:.2f} m; collisions "
         f"{fmt.rate(rates.loc[('collision', 'smooth')])} and "
         f"{fmt.rate(rates.loc[('collision', 'euclidean')])} of the passages",
         "`summary.csv`, `mc_summary.csv`"],
        ["the mission ends within the figures' 500 s",
         f"{s.mission_time_s:,.0f} s with the printed parameters; "
         f"{timeline.loc['smooth'].mission_time_s:,.0f} s with N = 43 (`paper-timeline`)",
         "`summary.csv` of both presets"],
        ["(not claimed) the NMPC is local",
         f"passages stalled in front of a wall: {fmt.rate(rates.loc[('stalled', 'smooth')])} "
         f"smoothed, {fmt.rate(rates.loc[('stalled', 'euclidean')])} Euclidean",
         "`mc_summary.csv`"],
        ["the controller: IPOPT solves the NLP at every instant",
         f"smoothed: it converges, and the real-time iteration flies its path to "
         f"{fmt.metres(smooth_dev)}; Euclidean: on the paper's windows IPOPT stops at its "
         f"iteration limit at {at_limit('reference-iterate')} instants with a region in "
         f"view (at {at_limit('reference-3000')} with 3000 iterations), an SQP of 20 steps "
         f"at {at_limit('sqp')}: nothing converges there. {encounter_statuses(fid)}",
         "`fidelity.csv`"],
    ]
    return fmt.markdown_table(["the paper", "measured here", "table"], rows)


def encounter_statuses(fid: pd.DataFrame) -> str:
    """Where IPOPT converges with the Euclidean metric, and what the real-time iteration does
    there: the encounter's first 15 s (``encounter-euclidean-15s`` of ``fidelity.csv``)."""
    window = fid[fid.window == "encounter-euclidean-15s"].set_index("solver")
    ipopt, rti = window.loc["reference-iterate"], window.loc["rti"]
    return (f"On the encounter's first 15 s IPOPT stops at its limit at "
            f"{ipopt.iteration_limit:,.0f} of {ipopt.steps:,} instants and converges at the "
            f"others; the real-time iteration's total variation there is "
            f"×{fmt.num(rti.tv_per_s_ratio)} IPOPT's, on a path {fmt.metres(rti.deviation_m)} "
            f"from IPOPT's")


def fidelity() -> str:
    """``figures/fidelity/fidelity.csv``: every window, every solver."""
    table = pd.read_csv(paths.figures_dir() / "fidelity" / "fidelity.csv")
    rows = [[r.window, "rti (default)" if r.solver == "rti" else r.solver, fmt.num(r.tv_per_s),
             fmt.ratio(r.tv_per_s_ratio),
             f"{r.hf_share:.2f}", f"{r.sign_changes:,}", f"{r.max_du:.2f}",
             f"{r.jumps_1N}", f"{r.min_clearance_m:.3f}", fmt.metres(r.deviation_m),
             "—" if pd.isna(r.iteration_limit) else f"{r.iteration_limit:.0f} of {r.steps}"]
            for r in table.itertuples()]
    return fmt.markdown_table(["window", "solver", "TV of u, N/s", "TV / IPOPT", "power > 5 Hz",
                      "sign changes", "max |Δu|, N", "steps |Δu| > 1 N",
                      "min clearance, m", "from IPOPT's path", "at its iteration limit"], rows)


def ground_robot() -> str:
    """``figures/ground_robot/ground_robot.csv`` (flights) with its timings beside it."""
    folder = paths.figures_dir() / "ground_robot"
    table = pd.read_csv(folder / "ground_robot.csv").merge(
        pd.read_csv(folder / "ground_robot_timings.csv"), on=["metric", "solver"])
    names = {"reference": "IPOPT", "rti": "RTI (1 SQP step)", "sqp-2": "SQP, 2 steps"}
    rows = [["smooth" if r.metric == "smooth" else "Euclidean", names[r.solver],
             f"{fmt.ms(r.median_ms)} / {fmt.ms(r.p99_ms)}", r.failures,
             "—" if r.solver == "reference" else fmt.metres(r.max_dev_m),
             f"{r.min_clearance_m:.3f} m", "yes" if r.passed else "no: stops in front",
             r.outcome, f"{r.steps:,}", f"{r.tv_per_s:.3f}"] for r in table.itertuples()]
    return fmt.markdown_table(["metric", "solver", "median / p99 ms", "failed solves",
                           "max deviation from IPOPT", "min clearance", "past the wall",
                           "outcome", "steps", "TV of (v, ω) per s"], rows)


def solver_speed(scenario: str) -> str:
    """``figures/solver_speed/<scenario>/speed.csv`` with its timings beside it."""
    folder = paths.figures_dir() / "solver_speed" / scenario
    table = pd.read_csv(folder / "speed.csv").merge(
        pd.read_csv(folder / "speed_timings.csv"), on="solver")
    names = {"reference": "reference (IPOPT)",
             "rti": "rti (the default: 1 SQP step, Riccati QP, interior point in the tail)",
             "rti-damped": "rti-damped (line search and damping)",
             "rti-hpipm": "rti-hpipm (HPIPM for every QP)", "sqp-2": "sqp-2",
             "rti-riccati": "rti-riccati (the chain riccati: HPIPM in the tail)",
             "rti-damped-riccati": "rti-damped-riccati (damped, riccati)",
             "sqp-converged": "sqp-converged"}
    ipm = "ipm_qps" in table and bool(table["ipm_qps"].any())
    rows = [[names.get(r.solver, r.solver), f"{r.steps:,}", r.outcome,
             fmt.ms(r.median_ms), fmt.ms(r.p95_ms), fmt.ms(r.p99_ms),
             fmt.ms(r.max_ms), f"{r.iterations_median:.0f}", f"{r.failures:,}",
             *([f"{r.ipm_qps:,}"] if ipm else []),
             "–" if r.solver == "reference" else f"{r.hpipm_qps:,}",
             f"{r.shortened:,}", fmt.metres(r.max_dev_m) if r.solver != "reference" else "0",
             f"{r.min_clearance_m:.3f} m"] for r in table.itertuples()]
    return fmt.markdown_table(["solver", "calls", "outcome", "median ms", "p95 ms", "p99 ms",
                               "max ms", "iterations", "failures",
                               *(["QPs to the interior point"] if ipm else []),
                               "QPs sent to HPIPM", "shortened steps",
                               "max deviation from IPOPT", "min clearance"], rows)


def swept_pillar() -> str:
    """``figures/solver_speed/swept_pillar/``: the per-call tail with a pillar swept across the
    hovering UAV, per variant (the first pass's, and each call's least time over the passes),
    with the flight's clearance, the QPs per solver and the interior point's iterations."""
    folder = paths.figures_dir() / "solver_speed" / "swept_pillar"
    table = pd.read_csv(folder / "pillar.csv").merge(pd.read_csv(folder / "tails.csv"),
                                                     on="variant")
    def tail(x):  # to 0.01 ms below T_s: the goal, p99 <= 2 ms, is read against them
        return fmt.ms(x) if x >= 10 else f"{x:.2f}"
    def iterations(r):
        return (f"{r.ipm_iterations_median:g} / {r.ipm_iterations_p99:g} / "
                f"{r.ipm_iterations_max}" if r.ipm_qps else "—")
    passes = int(table["passes"].iloc[0])
    rows = [[r.variant, fmt.ms(r.median_ms), tail(r.p99_ms), tail(r.max_ms),
             f"{r.over_ts:,} of {r.steps:,}", tail(r.least_p99_ms), tail(r.least_max_ms),
             f"{r.least_over_ts:,}", f"{r.ipm_qps:,}", iterations(r), f"{r.hpipm_qps:,}",
             f"{r.min_clearance_m:.3f} m", r.outcome]
            for r in table.itertuples()]
    return fmt.markdown_table(["variant", "median ms", "p99 ms", "max ms", "calls over T_s",
                               f"least of {passes}: p99 ms", "max ms", "over T_s",
                               "QPs to the interior point",
                               "its iterations: median / p99 / max", "QPs sent to HPIPM",
                               "min clearance", "outcome"], rows)


def monte_carlo() -> str:
    """Rates and paired effects of ``figures/studies/monte_carlo/mc_summary.csv``."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "monte_carlo" / "mc_summary.csv")
    rates = table[table["kind"] == "rate"].set_index(["event", "metric"])
    events = [("completed", "passage completed"), ("collision", "collision (< 0.35 m)"),
              ("stalled", "stalled (deadlock)"), ("step_limit", "step limit (150 s)"),
              ("failed", "run failed")]
    rows = [[label, *(fmt.rate(rates.loc[(event, m)]) for m in ("smooth", "euclidean"))]
            for event, label in events]
    head = fmt.markdown_table(["", "smoothed D", "Euclidean ½d²"], rows)
    paired = table[table["kind"] == "paired"]
    return head + "\n\n" + fmt.paired_table(paired, "smoothed", "Euclidean")


def eta_sweep() -> str:
    """``figures/studies/eta_sweep/eta_sweep_settings.csv``, one row per setting."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "eta_sweep" / "eta_sweep_settings.csv")
    # The baseline, then η at the printed σ, then σ at the printed η.
    printed_sigma = table.loc[table["metric"] == "smooth", "sigma"].mode().iloc[0]
    order = (table["metric"] == "smooth").astype(int) + 2 * (table["sigma"] != printed_sigma) \
        * (table["metric"] == "smooth")
    table = table.assign(_order=order).sort_values(["_order", "eta", "sigma"])
    rows = []
    for r in table.itertuples():
        name = ("Euclidean (η → 0)" if r.metric == "euclidean"
                else f"η = {r.eta:g} m, σ = {r.sigma:g} m")
        rows.append([name, f"{r.runs}", fmt.share(r.hf_energy_fraction),
                     f"{r.tv_u_rate_N_per_s:,.3g} N/s",
                     fmt.rate_of(r.completed_rate, r.completed_low, r.completed_high),
                     fmt.share(r.stalled_rate), fmt.rate_of(r.collision_rate, r.collision_low,
                                                      r.collision_high),
                     f"{r.min_clearance_m:.2f} m"])
    return fmt.markdown_table(["setting", "passages", "power > 5 Hz (median)", "TV of u (median)",
                      "completed", "stalled", "collision", "min clearance (median)"], rows)


def sensor_noise() -> str:
    """``figures/studies/sensor_noise/sensor_noise_paired.csv``: Euclidean over smoothed, per
    sensor (the noisy one raw, and through the local map)."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "sensor_noise" /
                        "sensor_noise_paired.csv")
    labels = {"perfect": "perfect LiDAR", "noisy": "noisy LiDAR",
              "noisy-map": "noisy LiDAR, read through the local map"}
    parts = []
    for sensor in dict.fromkeys(table["sensor"]):
        parts.append(f"*{labels.get(sensor, sensor)}*\n\n" + fmt.paired_table(
            table[table["sensor"] == sensor], "smoothed", "Euclidean"))
    return "\n\n".join(parts)


def sensing_window() -> str:
    """``figures/studies/sensing_window/``: the paper mission with and without the window
    (``sensing_window_mission.csv``), then the passages, one row per width
    (``sensing_window_summary.csv``)."""
    folder = paths.figures_dir() / "studies" / "sensing_window"
    mission = pd.read_csv(folder / "sensing_window_mission.csv")
    rows = [["paper mission", f"{r.window_m:g} m", f"{r.scan_changes:g}",
             fmt.share(r.scan_change_jump_share),
             f"p90 {1e3 * r.du_scan_change_p90_N:.3g} / {1e3 * r.du_around_changes_p90_N:.3g} mN",
             f"{r.mannwhitney_p:.2g}", f"{r.min_clearance_m:.3f} m", "—"]
            for r in mission.itertuples()]
    table = pd.read_csv(folder / "sensing_window_summary.csv")
    rows += [[f"{r.runs} random passages (median)", f"{r.window_m:g} m", f"{r.scan_changes:g}",
              fmt.share(r.jump_share),
              f"{1e3 * r.du_at_changes_N:.3g} / {1e3 * r.du_around_changes_N:.3g} mN", "",
              f"{r.min_clearance_median_m:.3f} m", f"{r.tv_u_rate_N_per_s:.3g} N/s"]
             for r in table.itertuples()]
    return fmt.markdown_table(["run", "window w", "changes of the visible set",
                      "share with a step > 10 mN", "|Δu| at / around", "Mann–Whitney p",
                      "min clearance", "TV of u"], rows)


def regeneration() -> str:
    """Every evidence set: the command that made it (its ``evidence.json``) and how long it
    took on the machine that made it (its ``timings.json``); for a study resumed from the
    cache, how many runs that call flew and about how long an empty cache would take
    (:func:`~paper_repro.evidence.sets.resumed`)."""
    from paper_repro.evidence.sets import EVIDENCE_SETS, last_wall_time_s, resumed

    rows = []
    for name in EVIDENCE_SETS:
        folder = paths.figures_dir() / name
        if not folder.is_dir():
            continue
        seconds = last_wall_time_s(folder)
        wall = f"{seconds / 60:.1f} min" if seconds else "—"
        if seconds and (part := resumed(folder)):
            flown, runs, cached = part
            wall += (f" (resumed: {flown:,} of {runs:,} runs flown; about "
                     f"{(seconds + cached) / 60:.0f} min from an empty cache)")
        rows.append([f"`figures/{name}`" if name else "`figures/`", f"`{made_by(name)}`", wall])
    return fmt.markdown_table(["evidence set", "made by", "wall time (2 cores, last run)"], rows)


def commands(*names: str) -> str:
    """The command that made each of the evidence sets ``figures/<name>`` (their
    ``evidence.json``), one row each."""
    return fmt.markdown_table(["evidence set", "made by"],
                              [[f"`figures/{name}/`", f"`{made_by(name)}`"] for name in names])


def study_commands() -> str:
    """Every study of :data:`~paper_repro.evidence.sets.STUDY_NOTEBOOKS`: its runs (the rows
    of its ``table.csv``), its notebook and the command that made it."""
    from paper_repro.evidence.sets import STUDY_NOTEBOOKS

    rows = []
    for study, notebook in STUDY_NOTEBOOKS.items():
        table = paths.figures_dir() / "studies" / study / "table.csv"
        runs = f"{len(pd.read_csv(table, usecols=['name'])):,}" if table.is_file() else "—"
        rows.append([f"`{study}`", runs, f"`{notebook}`", f"`{made_by(f'studies/{study}')}`"])
    return fmt.markdown_table(["study", "runs", "notebook", "made by"], rows)


def made_by(name: str) -> str:
    """The command that made ``figures/<name>`` (its ``evidence.json``), or "—"."""
    import json

    stamp = paths.figures_dir() / name / "evidence.json"
    return json.loads(stamp.read_text())["made_by"] if stamp.is_file() else "—"


def throughput() -> str:
    """``figures/throughput/``: all-in steps per second per scene family and metric, the
    controller call's tail against T_s, the parallel run, the sampled profile and the floor."""
    folder = paths.figures_dir() / "throughput"
    fam = pd.read_csv(folder / "families.csv")
    par = pd.read_csv(folder / "parallel.csv").set_index("run")
    rows = [[r.family, "smoothed D" if r.metric == "smooth" else "Euclidean ½d²", f"{r.runs}",
             f"{r.steps:,}", f"{r.steps_per_s:,.0f}", f"{r.all_in_ms:.3f}",
             f"{r.median_ms:.2f} / {r.p99_ms:.2f} / {r.p999_ms:.2f} / {r.max_ms:.1f}",
             f"{r.over_ts:,} of {r.steps:,}", f"{r.least_p999_ms:.2f} / {r.least_max_ms:.1f}",
             f"{r.least_over_ts:,}"] for r in fam.itertuples()]
    passes = int(fam["passes"].iloc[0])
    out = fmt.markdown_table(["scene family", "metric", "runs", "steps", "all-in steps/s",
                              "ms per step", "controller call, median / p99 / p99.9 / max ms",
                              "calls over T_s",
                              f"least of {passes} passes: p99.9 / max ms", "calls over T_s"],
                             rows)
    out += (f"\n\nEach scene is flown {passes} times; the steps are one pass's, the speeds "
            "all passes'. The controller call's times are wall-clock (`solve_time`) in the "
            "first pass; the last two columns take each call's least time over the passes. "
            "The passes fly bit for bit alike and make the same calls, so a call slow in one "
            "pass only was slowed by the shared machine, not by the controller.")
    one = par.loc["1 worker"]
    both = par[par.index.str.endswith("together")].iloc[0]
    out += (f"\n\nThe paper mission, {one.steps:,} steps on one core: {one.steps_per_s:,.0f} "
            f"steps/s all-in ({one.ms:.3f} ms a step: controller {one.controller_ms:.3f}, plant "
            f"{one.plant_ms:.3f}, the rest {one.rest_ms:.3f}); two workers together "
            f"{both.steps_per_s:,.0f} steps/s, {both.steps_per_s / one.steps_per_s:.2f}× one.")
    if (folder / "cluster.csv").is_file():
        c = pd.read_csv(folder / "cluster.csv").iloc[0]
        out += (f"\n\nA {c.scenes_per_metric:,.0f}-scene Monte Carlo (both metrics, "
                f"{c.steps_per_passage:,.0f} steps a passage on average) at this speed: "
                f"{c.core_hours:,.0f} core-hours; {c.worker_rss_mb:,.0f} MB resident per "
                f"single-threaded worker; {c.result_mb_per_run:.2f} MB per saved run, "
                f"{c.results_gb:,.1f} GB of results.")
    prof = folder / "profile"
    if (prof / "profile.csv").is_file():
        parts = pd.read_csv(prof / "profile.csv")
        floors = pd.read_csv(prof / "floor.csv").set_index("part")
        floor, what = floors["ms_per_call"], floors["what"]
        out += "\n\n" + fmt.markdown_table(
            ["part of a step (sampled)", "share", "ms per step"],
            [[r.part, f"{100 * r.share:.1f} %", f"{r.ms_per_step:.4f}"]
             for r in parts.itertuples()])
        share = parts.set_index("part")["ms_per_step"]
        compiled = share[["QP (C)", "linearisation (C)", "LiDAR", "plant"]].sum()
        step = float(parts["all_in_ms"].iloc[0])
        out += ("\n\n" + fmt.markdown_table(["floor of a part, one call", "ms", "at"],
                                          [[k, f"{v:.4f}", what[k]] for k, v in floor.items()])
                + f"\n\nOn average over the profiled steps the compiled parts (the QP and the "
                f"linearisation in C, the LiDAR's KD-tree, the plant) take {compiled:.3f} ms a "
                f"step: the floor of this algorithm, {1e3 / compiled:,.0f} steps/s. The rest, "
                f"{step - compiled:.3f} ms of the profiled {step:.3f} ms, is Python. At a step "
                f"with a region close (the floor table) one linearisation and one QP alone take "
                f"{floor['linearisation (C)'] + floor['QP']:.3f} ms.")
    return out


def build_time() -> str:
    """``figures/build_time/``: building each configuration's controller from an empty
    compile cache, and again from a warm one."""
    t = pd.read_csv(paths.figures_dir() / "build_time" / "build_time.csv")
    rows = [[r.configuration, f"{r.libraries}", f"{r.source_MB:.2f}", f"{r.controller_s:.1f}",
             f"{r.first_step_s:.1f}", f"{r.all_built_s:.1f}", f"{r.gcc_peak_MB:,.0f}",
             f"{r.warm_first_step_s:.2f}"] for r in t.itertuples()]
    return fmt.markdown_table(
        ["configuration", "libraries", "C source, MB", "controller built, s", "first step, s",
         "all compiled, s", "largest gcc, MB", "first step, warm cache, s"], rows)


MACHINE_BLOCKS = frozenset({"build_time", "regeneration", "ground_robot", "solver_speed_encounter",
                            "solver_speed_crossing", "throughput", "swept_pillar",
                            "guidance_cost", "moving_obstacles_tails"})
"""Blocks quoting what the machine measured: rendered like the others, never asserted (they
change with every regeneration)."""

BLOCKS: dict[str, Callable[[], str]] = {
    "verdict": verdict, "regeneration": regeneration, "build_time": build_time,
    "summary": summary, "fidelity": fidelity, "ground_robot": ground_robot,
    "solver_speed_encounter": lambda: solver_speed("encounter"),
    "solver_speed_crossing": lambda: solver_speed("crossing"),
    "throughput": throughput, "swept_pillar": swept_pillar,
    "monte_carlo": monte_carlo,
    "eta_sweep": eta_sweep, "sensor_noise": sensor_noise, "sensing_window": sensing_window,
    "sensor_noise_cost": beyond.sensor_noise_cost, "guidance": beyond.guidance,
    "guidance_cost": beyond.guidance_cost, "guide_filter": beyond.guide_filter,
    "moving_obstacles": beyond.moving_obstacles,
    "moving_obstacles_tails": beyond.moving_obstacles_tails, "avoidability": beyond.avoidability,
    "moving_heldout": beyond.moving_heldout, "qp_failures": beyond.qp_failures,
    "moving_speeds": beyond.moving_speeds,
    "moving_levers": beyond.moving_levers, "timeline": beyond.timeline,
    "tuning": beyond.tuning, "beyond": beyond.overview,
    "passages": beyond.passage_pace, "moving_design": beyond.moving_design_settings,
    "moving_definition": beyond.moving_definition, "guidance_pace": beyond.lateral_pace,
    "studies": study_commands,
    "moving_commands": lambda: commands(
        "studies/moving_obstacles", "studies/moving_speeds", "studies/moving_heldout",
        "studies/avoidability"),
    "moving_speed_commands": lambda: commands("solver_speed/crossing",
                                              "solver_speed/swept_pillar"),
    "design_commands": lambda: commands("studies/moving_levers",
                                        "studies/moving_obstacles_definition"),
    "tuning_command": lambda: commands("tuning"),
    "hardware_agreement": hardware.agreement,
    "hardware_margins": lambda: hardware.margins(hardware.runs()),
    "hardware_cells": lambda: hardware.cells(hardware.runs()),
    "hardware_breaks": lambda: hardware.breaks(hardware.runs(), hardware.lidar_range()),
    "hardware_claim": lambda: hardware.claim(hardware.runs()),
    "hardware_combined": lambda: hardware.combined(hardware.runs((hardware.COMBINED,))),
    "hardware_combined_claim": lambda: hardware.claim(hardware.runs((hardware.COMBINED,)),
                                                      combined=True),
    "hardware_commands": lambda: commands("hardware", *(
        f"studies/{s}" for s in (*hardware.STUDIES, hardware.COMBINED)))}
"""Every generated block of the README, by name."""

_BLOCK = re.compile(r"(<!-- begin (?P<name>[a-z_]+) -->\n)(?P<body>.*?)(<!-- end (?P=name) -->)",
                    re.S)


def render(text: str) -> str:
    """``text`` with every block replaced by what :data:`BLOCKS` renders now."""
    def replace(match):
        name = match["name"]
        if name not in BLOCKS:
            raise ValueError(f"README block {name!r} is unknown; known: {sorted(BLOCKS)}")
        try:
            body = BLOCKS[name]()
        except FileNotFoundError as exc:
            raise ValueError(f"README block {name!r} needs {exc.filename}, which does not exist "
                             "(regenerate its evidence set first)") from exc
        return f"{match[1]}{body.rstrip()}\n{match[4]}"
    return _BLOCK.sub(replace, text)


def blocks(text: str) -> dict[str, str]:
    """The blocks of ``text``, by name (their current contents)."""
    return {m["name"]: m["body"] for m in _BLOCK.finditer(text)}


def readme_path() -> Path:
    return paths.repo_root() / "README.md"


def page_paths() -> list[Path]:
    """Every page that may hold blocks: the README, ``environment.md``, then the book's pages
    in ``docs/``."""
    docs = paths.repo_root() / "docs"
    return [readme_path(), paths.repo_root() / "environment.md",
            *sorted(p for p in docs.rglob("*.md") if "_build" not in p.parts)]


def page_blocks() -> dict[str, tuple[Path, str]]:
    """Every block of every page: name -> (page, current body). A name used twice is an
    error (one table, one place)."""
    out: dict[str, tuple[Path, str]] = {}
    for page in page_paths():
        for name, body in blocks(page.read_text()).items():
            if name in out:
                raise ValueError(f"block {name!r} is in both {out[name][0]} and {page}")
            out[name] = (page, body)
    return out

"""The blocks of the README and the book that quote the studies beyond the paper: the noisy
LiDAR through the map, the guide, moving regions and their avoidability, the levers of the
moving-obstacle barrier, the timeline study, the tuning, and the README's table of them all
(:func:`overview`). Each formats a committed table;
:data:`paper_repro.evidence.readme.BLOCKS` names them."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from paper_repro import paths
from paper_repro.evidence import formatting as fmt
from paper_repro.evidence import hardware


def sensor_noise_cost() -> str:
    """``figures/studies/sensor_noise/sensor_noise_cost.csv``: what the noisy LiDAR costs
    each metric against the perfect one on the same passage, raw and through the map."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "sensor_noise" /
                        "sensor_noise_cost.csv")
    labels = {"noisy": "noisy, raw scan", "noisy-map": "noisy, through the map"}
    rows = []
    for r in table[table["measure"].isin(["hf_energy_fraction", "tv_u_rate_N_per_s"])
                   ].itertuples():
        rows.append([r.metric, labels.get(r.sensor, r.sensor), r.label,
                     fmt.num(r.median_perfect), fmt.num(r.median_sensor),
                     f"×{fmt.num(r.median_effect)} [{fmt.num(r.low)}, {fmt.num(r.high)}]",
                     f"{int(r.scenes)}"])
    return fmt.markdown_table(["metric", "sensor", "measure (median over scenes)",
                               "perfect LiDAR", "this sensor", "ratio, per scene", "scenes"],
                              rows)


def guidance() -> str:
    """``figures/studies/guidance/``: outcomes per arm and metric (``guidance_rates.csv``)
    and the time to complete (``guidance_times.csv``)."""
    folder = paths.figures_dir() / "studies" / "guidance"
    rates = pd.read_csv(folder / "guidance_rates.csv").set_index(["arm", "metric", "event"])
    times = pd.read_csv(folder / "guidance_times.csv").set_index(["metric", "arm"])
    labels = {"paper": "the paper's controller (raw scan)", "map": "reading the local map",
              "map+guide": "local map + guide"}
    rows = []
    for metric, name in (("smooth", "smoothed D"), ("euclidean", "Euclidean ½d²")):
        for arm in dict.fromkeys(a for a, _, _ in rates.index):
            t = times.loc[(metric, arm)]
            rows.append([name, labels.get(arm, arm),
                         *(fmt.rate(rates.loc[(arm, metric, event)])
                           for event in ("completed", "stalled", "step_limit", "collision")),
                         "—" if pd.isna(t.median_s) else f"{t.median_s:.1f} s"])
    return fmt.markdown_table(["metric", "arm", "completed", "stalled (deadlock)",
                               "step limit (150 s)", "collision (< 0.35 m)",
                               "time to complete (median)"], rows)


def guidance_cost() -> str:
    """``figures/guidance_cost/cost.csv``: what the map and the guide cost per closed-loop
    step, on this machine (``benchmarks/guidance_cost.py``)."""
    table = pd.read_csv(paths.figures_dir() / "guidance_cost" / "cost.csv")
    rows = [[r.setup, f"{int(r.passages)}", f"{int(r.steps):,}", fmt.ms(r.all_in_ms),
             fmt.ms(r.controller_ms), fmt.ms(r.map_update_ms), fmt.ms(r.map_readout_ms),
             fmt.ms(r.guide_ms), fmt.ms(r.map_and_guide_ms)] for r in table.itertuples()]
    return fmt.markdown_table(["set-up", "passages", "steps", "all-in step, ms",
                               "controller, ms", "map update, ms", "map read-out, ms",
                               "guide, ms", "map and guide, ms"], rows)


def guide_filter() -> str:
    """``figures/guide_filter/summary.csv``: the guide's set-point filter, per time constant τ,
    on the first passages of the smoothed map-and-guide arm, against no filter
    (``benchmarks/guide_filter.py``)."""
    table = pd.read_csv(paths.figures_dir() / "guide_filter" / "summary.csv")
    rows = [["none" if r.tau_s == 0 else f"{r.tau_s:g} s", f"{r.completed}/{r.passages}",
             f"{r.collisions}/{r.passages}", fmt.num(r.hf_share_median),
             fmt.ratio(r.hf_share_ratio_median), fmt.ratio(r.tv_rate_ratio_median),
             fmt.ratio(r.time_ratio_median), fmt.metres(r.min_clearance_m)]
            for r in table.itertuples()]
    return fmt.markdown_table(["set-point filter τ", "completed", "collisions",
                               "share of thrust power above 5 Hz (median)",
                               "its ratio to no filter (median per passage)",
                               "total variation rate, ratio", "time to complete, ratio",
                               "min clearance"], rows)


def moving_obstacles() -> str:
    """``figures/studies/moving_obstacles/``: collisions per barrier, prediction and metric."""
    folder = paths.figures_dir() / "studies" / "moving_obstacles"
    rates = pd.read_csv(folder / "moving_obstacles_rates.csv").set_index(
        ["barrier", "prediction", "metric", "event"])
    summary = pd.read_csv(folder / "moving_obstacles_summary.csv").set_index(
        ["barrier", "prediction", "metric"])
    solves = pd.read_parquet(folder / "table.parquet", columns=[
        "barrier", "prediction", "metric", "failed_solves", "relaxed_solves"]).groupby(
        ["barrier", "prediction", "metric"]).sum()
    rows = []
    for barrier, prediction in dict.fromkeys((b, p) for b, p, _ in summary.index):
        row = [barrier, prediction]
        for metric in ("smooth", "euclidean"):
            c = rates.loc[(barrier, prediction, metric, "collision")]
            row.append(f"{int(c.k)}/{int(c.n)} [{100 * c.low:.0f}, {100 * c.high:.0f}] %")
        s = summary.loc[(barrier, prediction, "smooth")]
        e = summary.loc[(barrier, prediction, "euclidean")]
        left = [rates.loc[(barrier, prediction, m, "left_workspace")]
                for m in ("smooth", "euclidean")]
        n = [solves.loc[(barrier, prediction, m)] for m in ("smooth", "euclidean")]
        row += [f"{s.min_clearance_median_m:.3f} / {e.min_clearance_median_m:.3f} m",
                f"{s.min_clearance_min_m:.3f} / {e.min_clearance_min_m:.3f} m",
                f"{s.tv_u_rate_median_N_per_s:.3g} / {e.tv_u_rate_median_N_per_s:.3g} N/s",
                f"{fmt.share(s.completed)} / {fmt.share(e.completed)}",
                " / ".join(f"{int(r.k)}/{int(r.n)}" for r in left),
                " / ".join(f"{int(g.failed_solves):,}, {int(g.relaxed_solves):,}" for g in n),
                f"{fmt.share(s.cbf_condition_violated_share_median)} / "
                f"{fmt.share(e.cbf_condition_violated_share_median)}"]
        rows.append(row)
    return fmt.markdown_table(["barrier", "prediction", "collisions, smoothed",
                           "collisions, Euclidean",
                           "min clearance, median (smoothed / Euclidean)", "closest approach",
                           "TV of u, median", "completed", "left the workspace",
                           "failed, relaxed solves",
                           "steps breaking (15) with a region in view, median"], rows)


def moving_obstacles_tails() -> str:
    """``figures/studies/moving_obstacles/timings.csv`` (the machine's): the controller's
    solve-time tail per barrier and prediction, each run's p99 and max call against T_s."""
    from paper_repro.config import Config

    folder = paths.figures_dir() / "studies" / "moving_obstacles"
    runs = pd.read_parquet(folder / "table.parquet", columns=["name", "barrier", "prediction",
                                                              "metric"])
    times = runs.merge(pd.read_csv(folder / "timings.csv"), on="name")
    ts_ms = 1e3 * Config().nmpc.ts
    rows = []
    for (barrier, prediction), group in times.groupby(["barrier", "prediction"], sort=False):
        by = {m: group[group["metric"] == m] for m in ("smooth", "euclidean")}
        rows.append([barrier, prediction] + [
            " / ".join(fn(by[m]) for m in by) for fn in (
                lambda g: fmt.ms(g["solve_p99_ms"].median()),
                lambda g: fmt.ms(g["solve_p99_ms"].max()),
                lambda g: fmt.ms(g["solve_max_ms"].max()),
                lambda g: f"{int((g['solve_max_ms'] > ts_ms).sum())}/{len(g)}")])
    return fmt.markdown_table(
        ["barrier", "prediction", "p99 of a run's calls, median (smoothed / Euclidean), ms",
         "largest p99, ms", "largest call, ms", f"runs with a call over T_s = {ts_ms:g} ms"],
        rows)


def avoidability() -> str:
    """``figures/studies/avoidability/avoidability.csv``: the crossings a point mass with the
    quadrotor's bounds and full foresight flies clear, per pace of the crossings (the paper's
    rows fly them timed to the printed set-up, the design's to its own)."""
    from scipy import stats

    table = pd.read_csv(paths.figures_dir() / "studies" / "avoidability" / "avoidability.csv")
    rows = []
    for pace, g in table.groupby("approach_time_s", sort=False):
        k, n = int(g["avoidable"].sum()), len(g)
        ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
        found, paced = g[g["avoidable"]], g.dropna(subset=["study_time_s"])
        k_p = int((paced["at_pace_outcome"] == "avoidable").sum())
        rows.append([f"{pace:g} s", f"{n}", f"{k}/{n} [{100 * ci.low:.0f}, {100 * ci.high:.0f}] %",
                     ", ".join(str(s) for s in g.loc[~g["avoidable"], "scene_seed"]) or "none",
                     f"{found['clearance_m'].min():.2f} to {found['clearance_m'].max():.2f} m",
                     ", ".join(f"{q} ({c})" for q, c in found["guess"].value_counts().items()),
                     f"{k_p}/{len(paced)} (closest approach "
                     f"{paced['at_pace_clearance_m'].min():.2f} m)"])
    missing = table[~table["avoidable"]]
    verdict = ("\n\nEvery crossing has a passage: every collision of the studies counts against "
               "the controller." if missing.empty else
               "\n\nA crossing without a passage found does not count its collisions against "
               "the controller.")
    return fmt.markdown_table(
        ["crossings timed to", "crossings", "avoidable", "no passage found",
         "clearance of the passages found", "first guess that found them",
         "avoidable within the controller's time"], rows) + verdict


_OUTCOME_WORDS = {"left_workspace": "left the workspace", "step_limit": "at the step limit"}


def moving_heldout() -> str:
    """``figures/studies/moving_heldout/heldout.csv``: the design on crossings 50-99, seen while
    it was chosen, and on crossings no design was chosen on."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "moving_heldout" / "heldout.csv")
    rows = [[r.set, r.prediction, r.metric,
             fmt.rate_of(r.collisions / r.runs, r.collision_low, r.collision_high,
                         int(r.collisions), int(r.runs)),
             f"{r.min_clearance_m:.3f} m", f"{int(r.completed)}/{int(r.runs)}",
             f"{int(r.failed_solves):,}, {int(r.relaxed_solves):,}",
             f"{int(r.encounters)}/{int(r.runs)}"]
            for r in table.itertuples()]
    runs = pd.read_csv(paths.figures_dir() / "studies" / "moving_heldout" / "table.csv",
                       usecols=["scene_seed", "set", "prediction", "metric", "collision",
                                "outcome"])

    def crossings(which, outcome=False):
        by = ["scene_seed", "outcome"] if outcome else ["scene_seed"]
        return "; ".join(
            f"crossing {g['scene_seed'].iloc[0]} ({g['set'].iloc[0]}: "
            + ", ".join(f"{p} {m}" for p, m in zip(g["prediction"], g["metric"]))
            + (f"; {_OUTCOME_WORDS.get(g['outcome'].iloc[0], g['outcome'].iloc[0])}"
               if outcome else "") + ")"
            for _, g in runs[which].groupby(by))

    hits = crossings(runs["collision"].astype(bool))
    ended = crossings(runs["outcome"] != "completed", outcome=True)
    return fmt.markdown_table(["crossings", "prediction", "metric", "collisions",
                               "closest approach", "completed", "failed, relaxed solves",
                               "a region within 3 m"], rows) + (
        f"\n\nThe runs that collide: {hits}." if hits else "\n\nNo run collides.") + (
        f" The runs that did not complete: {ended}." if ended else " Every run completes.")


def qp_failures() -> str:
    """``figures/studies/qp_failures/``: the moving studies' runs whose hard QP fails most,
    each flown as designed and with the hard QP on the paper's 𝒳, with the cause of every
    hard QP that failed (``runs.csv``, ``causes.csv``)."""
    folder = paths.figures_dir() / "studies" / "qp_failures"
    runs = pd.read_csv(folder / "runs.csv")
    causes = pd.read_csv(folder / "causes.csv")
    rows = [[r.study, r.name.replace("passage-", "").replace("-eta0.3-sigma0.8", ""),
             r.variant, f"{r.steps:,}", f"{r.failed_solves:,}", f"{r.relaxed_solves:,}",
             f"{r.longest_streak:,}", f"{r.hard_qp_failed_in_view:,}", r.outcome,
             "no" if r.left_workspace_step < 0 else f"step {r.left_workspace_step:,}",
             f"{r.min_altitude_m:,.4f}"] for r in runs.itertuples()]
    out = fmt.markdown_table(["study", "run", "controller", "steps", "failed solves",
                              "relaxed solves", "longest streak", "hard QP failed, points in view",
                              "outcome", "left the workspace", "lowest altitude, m"], rows)
    by = ["variant", "path", "active_set", "interior_point", "hpipm", "outside_state_box"]
    total = causes.groupby(by, dropna=False)["count"].sum().sort_values(ascending=False)
    out += "\n\n" + fmt.markdown_table(
        ["controller", "then", "active set", "interior point", "HPIPM", "state outside 𝒳",
         "solves"],
        [[*("skipped" if pd.isna(v) else str(v) for v in key), f"{n:,}"]
         for key, n in total.sort_index(level=0, sort_remaining=False).items()])
    sentences = []
    for variant, g in runs.groupby("variant", sort=False):
        done = int((g["outcome"] == "completed").sum())
        left = int((g["left_workspace_step"] >= 0).sum())
        sentences.append(
            f"{variant[0].upper() + variant[1:]}: {int(g['failed_solves'].sum()):,} failed and "
            f"{int(g['relaxed_solves'].sum()):,} relaxed solves over {len(g)} runs; "
            f"{done} completed, {left} left the workspace.")
    finite = bool(causes["finite_data"].all()) if len(causes) else True
    sentences.append(f"Of {int(causes['count'].sum()):,} hard QPs that failed, "
                     f"{'every one' if finite else 'not every one'} had finite data.")
    return out + "\n\n" + " ".join(sentences)


def moving_speeds() -> str:
    """``figures/studies/moving_speeds/``: how fast the UAV moved sideways on the crossings
    (``speeds.csv``) and how the collisions came about (``collisions.csv``)."""
    folder = paths.figures_dir() / "studies" / "moving_speeds"
    speeds = pd.read_csv(folder / "speeds.csv")
    hits = pd.read_csv(folder / "collisions.csv")
    rows = []
    for r in speeds.itertuples():
        g = hits[(hits["set"] == r.set) & (hits["barrier"] == r.barrier)
                 & (hits["prediction"] == r.prediction) & (hits["metric"] == r.metric)]
        rows.append([r.set, r.barrier, r.prediction, r.metric,
                     f"{r.max_horizontal_speed_median_m_s:.2f} / "
                     f"{r.max_horizontal_speed_p90_m_s:.2f} m/s",
                     f"{int(r.runs_with_a_region_faster)}/{int(r.runs)}",
                     f"{int(r.collisions)}/{int(r.runs)}",
                     "—" if g.empty else f"{g['region_speed_m_s'].median():.2f} m/s",
                     "—" if g.empty else f"{g['uav_speed_before_m_s'].median():.2f} m/s",
                     "—" if g.empty else f"{int((g['cos_uav_region'] > 0.5).sum())}/{len(g)}"])
    return fmt.markdown_table(
        ["set", "barrier", "prediction", "metric",
         "largest horizontal speed of a run, median / 90th percentile",
         "runs with a region faster than that", "collisions",
         "colliding region's speed, median", "UAV's speed over the 3 s before, median",
         "collisions fleeing along the region's path (cos > 0.5)"], rows)


def moving_levers() -> str:
    """``figures/studies/moving_levers/levers.csv``: each lever on a set of crossings, one row
    per lever and set; the runs of each prediction and metric side by side."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "moving_levers" / "levers.csv")

    def collisions(g: pd.DataFrame, metric: str) -> str:
        g = g[g["metric"] == metric]
        return (" / ".join(f"{c}" for c in g["collisions"]) + f" of {g['runs'].iloc[0]}"
                + ("" if set(g["prediction"]) != {"static"} else " (static)"))

    def spread(x: pd.Series, form: str, unit: str) -> str:
        x = x.dropna()
        if x.empty:
            return "—"
        low, high = form.format(x.min()), form.format(x.max())
        return (low if low == high else f"{low}–{high}") + unit

    rows = []
    for (scenes, lever), g in table.groupby(["scenes", "lever"], sort=False):
        rows.append([scenes, f"`{lever}`", f"{g['encounters'].sum()}/{g['runs'].sum()}",
                     collisions(g, "smooth"), collisions(g, "euclidean"),
                     f"{g['min_clearance_m'].min():.2f} m",
                     f"{g['completed'].sum()}/{g['runs'].sum()}", f"{g['stalled'].sum()}",
                     " / ".join(spread(g.loc[g["metric"] == m, "tv_u_rate_median_N_per_s"],
                                       "{:.3g}", "") for m in ("smooth", "euclidean")) + " N/s",
                     f"{g['failed_solves'].sum():,}, {g['relaxed_solves'].sum():,}",
                     spread(100 * g["cbf_condition_violated_share_median"], "{:.0f}", " %")])
    return fmt.markdown_table(["crossings", "lever", "runs with a region in range",
                               "collisions, smoothed (oracle / Kalman)",
                               "collisions, Euclidean (oracle / Kalman)", "closest approach",
                               "completed", "stalled", "TV of u, median (smoothed / Euclidean)",
                               "failed, relaxed solves", "steps breaking (15), median"],
                              rows)


def moving_definition() -> str:
    """``figures/studies/moving_obstacles_definition/table.csv``: the study's smoothed crossings
    with the barrier in Definition 1's form (c = δ), per barrier and prediction."""
    from paper_repro.analysis import statistics

    runs = pd.read_csv(paths.figures_dir() / "studies" / "moving_obstacles_definition" /
                       "table.csv")
    rates = statistics.rates(runs, by=["barrier", "prediction"]).set_index(
        ["barrier", "prediction", "event"])
    clearance = runs.groupby(["barrier", "prediction"], sort=False)["min_clearance_m"].median()
    rows = [[barrier, prediction, fmt.rate(rates.loc[(barrier, prediction, "collision")]),
             fmt.rate(rates.loc[(barrier, prediction, "completed")]), f"{value:.3f} m"]
            for (barrier, prediction), value in clearance.items()]
    return fmt.markdown_table(["barrier", "prediction", "collisions", "completed",
                               "min clearance, median"], rows)


def moving_design_settings() -> str:
    """The settings the moving study's ``design`` rows flew, per metric, beside the paper's
    barrier (``figures/studies/moving_obstacles/study.json``: each run's configuration
    changes; a setting a run did not change keeps :class:`~paper_repro.config.Config`'s
    default)."""
    import json

    from paper_repro.config import Config

    specs = json.loads((paths.figures_dir() / "studies" / "moving_obstacles" /
                        "study.json").read_text())["specs"]
    default = Config()

    def changes(barrier: str, metric: str) -> dict:
        return next(s["config_changes"] for s in specs if s["labels"]["barrier"] == barrier
                    and s["labels"]["metric"] == metric)

    def value(changed: dict, key: str):
        section, field = key.split(".")
        return changed.get(key, getattr(getattr(default, section), field))

    def step(changed: dict) -> float:
        return value(changed, "nmpc.prediction_ts") or default.nmpc.ts

    def off(x: float, unit: str) -> str:
        return "off" if x == 0 else f"{x:g} {unit}"

    runs = [changes("paper", "smooth"), changes("design", "smooth"),
            changes("design", "euclidean")]
    rows = [["margin of a region predicted to move (`barrier.moving_d_min`)",
             *(off(value(c, "barrier.moving_d_min"), "m²") for c in runs)],
            ["swept path (`barrier.sweep_time`)",
             *(off(value(c, "barrier.sweep_time"), "s") for c in runs)],
            ["look-ahead at the artificial equilibrium (`barrier.equilibrium_lookahead`)",
             *(off(value(c, "barrier.equilibrium_lookahead"), "s") for c in runs)],
            ["prediction step h (`nmpc.prediction_ts`)", *(f"{step(c):g} s" for c in runs)],
            ["prediction span N·h", *(f"{default.nmpc.horizon * step(c):g} s" for c in runs)],
            ["crossings timed to (`simulation.approach_time`)",
             *(f"{value(c, 'simulation.approach_time'):g} s" for c in runs)]]
    return fmt.markdown_table(["setting", "the paper's barrier", "design, smoothed",
                               "design, Euclidean"], rows)


def lateral_pace() -> str:
    """One sentence: the printed set-up's lateral time constant, from the lever sweep of
    ``figures/studies/timeline/timeline_levers.csv`` (the row of the printed offset weight)."""
    levers = pd.read_csv(paths.figures_dir() / "studies" / "timeline" / "timeline_levers.csv")
    tau = levers[(levers["lever"] == "T") & (levers["value"] == 1)]["tau_lateral_s"].iloc[0]
    return (f"Under the printed weights, the lateral time constant of the closed loop is "
            f"τ ≈ {tau:.0f} s (`figures/studies/timeline/timeline_levers.csv`). The UAV's speed "
            f"is then about (distance to its set-point)/{tau:.0f} s.")


def passage_pace() -> str:
    """:func:`lateral_pace`, then how long the completed passages of the Monte Carlo study
    took (``figures/studies/monte_carlo/table.csv``)."""
    runs = pd.read_csv(paths.figures_dir() / "studies" / "monte_carlo" / "table.csv",
                       usecols=["completed", "time_to_complete_s"])
    times = runs.loc[runs["completed"].astype(bool), "time_to_complete_s"]
    return (lateral_pace() + f" A completed passage of the Monte Carlo study takes "
            f"{times.min():.0f} to {times.max():.0f} s of flight, {times.median():.0f} s at the "
            "median.")


def timeline() -> str:
    """``figures/studies/timeline/timeline_flights.csv``: the candidates flown."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "timeline" / "timeline_flights.csv")
    rows = [[r.candidate, f"{r.predicted_s:,.0f} s", f"{r.mission_time_s:,.1f} s",
             f"{r.first_target_s:,.0f} s", r.avoidance, f"{r.min_clearance_m:.2f} m",
             f"{r.tv_u_N:,.0f} N"] for r in table.itertuples()]
    return fmt.markdown_table(["candidate", "linear loop", "mission", "first target",
                      "cloud in view", "min clearance", "total variation of u"], rows)


def tuning() -> str:
    """``figures/tuning/``: the front (``tuning_pareto.csv``), the held-out passages per
    set-up (``tuning_heldout_summary.csv``), each tuned set-up against the printed one, scene
    by scene, and which set-ups are offered as presets (``presets.json``)."""
    import json

    folder = paths.figures_dir() / "tuning"
    front = pd.read_csv(folder / "tuning_pareto.csv")
    rows = [[f"{r.number}", f"{r.eta:g} m", f"{r.sigma:g} m", f"{r.d_min:g} m²",
             f"{r.kappa:g}", f"{r.mu:g}", f"{r.delta:g}", fmt.share(r.hf_energy_fraction),
             f"{r.time_to_complete_s:.1f} s", f"{r.min_clearance_m:.2f} m"]
            for r in front.itertuples()]
    parts = ["*The front (training passages)*\n\n" + fmt.markdown_table(
        ["trial", "η", "σ", "d_min", "κ", "μ", "δ", "power > 5 Hz", "time to complete",
         "min clearance"], rows)]
    table = pd.read_csv(folder / "tuning_heldout_summary.csv")
    parts.append("*Held-out passages*\n\n" + _heldout_rates(table))
    presets = json.loads((folder / "presets.json").read_text())
    for setup in dict.fromkeys(table.loc[table["kind"] == "paired", "setup"]):
        trial = presets.get(setup, {}).get("trial")
        paired = table[(table["kind"] == "paired") & (table["setup"] == setup)]
        paired = paired.rename(columns={"median_printed": "median_smooth",
                                        f"median_{setup}": "median_euclidean"})
        parts.append(f"*{setup} (trial {trial}) against printed, per held-out scene*\n\n"
                     + fmt.paired_table(paired, "printed", setup))
    parts.append(_offered(presets))
    return "\n\n".join(parts)


def _heldout_rates(table: pd.DataFrame) -> str:
    """Completed, collision, stalled and step-limit rates per held-out set-up."""
    rates = table[table["kind"] == "rate"].set_index(["setup", "event"])
    setups = list(dict.fromkeys(rates.index.get_level_values(0)))
    rows = [[label, *(fmt.rate(rates.loc[(s, event)]) for s in setups)]
            for event, label in (("completed", "completed"), ("collision", "collision"),
                                 ("stalled", "stalled"), ("step_limit", "step limit"))]
    return fmt.markdown_table(["", *setups], rows)


def _offered(presets: dict) -> str:
    """One sentence: the tuned set-ups offered as presets, or none and why."""
    tuned = {k: v for k, v in presets.items() if k != "printed"}
    offered = [k for k, v in tuned.items() if v.get("offered")]
    if offered:
        return ("Offered as a preset (`studies.tuning_results.preset_config`): "
                + "; ".join(f"`{k}` ({tuned[k]['why']})" for k in offered) + ".")
    return ("No tuned set-up is offered as a preset: "
            + "; ".join(f"`{k}`: {v.get('why', 'not evaluated')}" for k, v in tuned.items())
            + ".")


def _heldout_collisions() -> str:
    """The design's collisions on the crossings no design was chosen on, then on those it was
    chosen looking at besides the study's, per prediction and metric."""
    table = pd.read_csv(paths.figures_dir() / "studies" / "moving_heldout" / "heldout.csv")
    parts = []
    for label, text in (("held out", "crossings no design was chosen on"),
                        ("seen", "crossings seen while choosing it")):
        by = table[table["set"] == label].set_index(["prediction", "metric"])
        parts.append(f"On {int(by['runs'].max())} {text}: " + "; ".join(
            f"{'Kalman' if prediction == 'kalman' else prediction} " + ", ".join(
                f"{name} " + fmt.rate_of(r.collisions / r.runs, r.collision_low,
                                         r.collision_high, int(r.collisions), int(r.runs))
                for metric, name in (("smooth", "smoothed"), ("euclidean", "Euclidean"))
                for r in [by.loc[(prediction, metric)]])
            for prediction in dict.fromkeys(by.index.get_level_values(0))))
    return ". ".join(parts)


def _design_span(study_json) -> float:
    """s, the prediction span N·h the moving study's design rows flew, from its ``study.json``."""
    import json

    from paper_repro.config import Config

    specs = json.loads(Path(study_json).read_text())["specs"]
    steps = {s["config_changes"].get("nmpc.prediction_ts") for s in specs
             if s["labels"]["barrier"] == "design"}
    if len(steps) != 1 or None in steps:
        raise ValueError(f"{study_json}: the design rows fly prediction steps {steps}, "
                         "expected one step set by the design")
    return Config().nmpc.horizon * steps.pop()


def overview() -> str:
    """Beyond the paper, for the README: the moving crossings with the paper's barrier and the
    design (``moving_obstacles_rates.csv``), whether they were avoidable (``avoidability.csv``),
    the tuning's held-out passages, the guide past the deadlocks (``guidance_rates.csv``),
    the noisy LiDAR through the map (``sensor_noise_cost.csv``) and the flights against
    RotorPy (:func:`paper_repro.evidence.hardware.overview`)."""
    import json

    figs = paths.figures_dir()
    moving = pd.read_csv(figs / "studies" / "moving_obstacles" /
                         "moving_obstacles_rates.csv").set_index(["barrier", "prediction",
                                                                  "metric", "event"])
    avoid = pd.read_csv(figs / "studies" / "avoidability" / "avoidability.csv")
    tuned = pd.read_csv(figs / "tuning" / "tuning_heldout_summary.csv")
    presets = json.loads((figs / "tuning" / "presets.json").read_text())

    def collided(barrier: str, prediction: str) -> str:
        return ", ".join(
            f"{label} {fmt.rate(moving.loc[(barrier, prediction, metric, 'collision')])}"
            for metric, label in (("smooth", "smoothed"), ("euclidean", "Euclidean")))

    n = int(moving.loc[("paper", "oracle", "smooth", "collision")].n)
    span = _design_span(figs / "studies" / "moving_obstacles" / "study.json")
    grounded = moving.xs("left_workspace", level="event").loc["paper"]
    rows = [["moving regions, the paper's barrier",
             f"collisions over {n} crossings: static prediction {collided('paper', 'static')}; "
             f"oracle {collided('paper', 'oracle')}; Kalman {collided('paper', 'kalman')}. "
             f"Runs that left the workspace: {int(grounded['k'].min())} "
             f"to {int(grounded['k'].max())} of {n} per prediction and metric",
             "`moving_obstacles_rates.csv`"],
            ["... could a vehicle as agile have passed?",
             f"a clear passage exists for {int(avoid['avoidable'].sum())} of {len(avoid)} "
             "crossings, timed to either controller's pace (point mass with the quadrotor's "
             "bounds and full foresight)",
             "`avoidability.csv`"],
            ["... with the design for moving regions (`studies.catalogue.moving_design`: a "
             f"wider, swept margin and a {span:g} s prediction)",
             f"collisions over {n} crossings: oracle {collided('design', 'oracle')}; Kalman "
             f"{collided('design', 'kalman')}. {_heldout_collisions()}",
             "`moving_obstacles_rates.csv`, `heldout.csv`"]]
    rates = tuned[tuned["kind"] == "rate"].set_index(["setup", "event"])
    rows.append(["tuned parameters, held-out passages", "; ".join(
        f"{s}: completed {fmt.rate(rates.loc[(s, 'completed')])}, collisions "
        f"{fmt.rate(rates.loc[(s, 'collision')])}"
        for s in dict.fromkeys(rates.index.get_level_values(0))) + ". " + _offered(presets),
        "`tuning_heldout_summary.csv`, `presets.json`"])
    guided = pd.read_csv(figs / "studies" / "guidance" / "guidance_rates.csv").set_index(
        ["arm", "metric", "event"])
    n = int(guided.loc[("paper", "smooth", "completed")].n)

    def outcomes(arm: str) -> str:
        return ", ".join(f"{label} {fmt.rate(guided.loc[(arm, 'smooth', event)])}"
                         for event, label in (("completed", "completed"), ("stalled", "stalled"),
                                              ("collision", "collisions")))

    rows.append([f"deadlocks: a local map and a guide (`guide.planner`), {n} random passages",
                 f"the paper's controller: {outcomes('paper')}; map + guide: "
                 f"{outcomes('map+guide')} (smoothed D)", "`guidance_rates.csv`"])
    cost = pd.read_csv(figs / "studies" / "sensor_noise" / "sensor_noise_cost.csv").set_index(
        ["metric", "sensor", "measure"])
    hf = {s: cost.loc[("smooth", s, "hf_energy_fraction")] for s in ("noisy", "noisy-map")}
    tv = cost.loc[("smooth", "noisy-map", "tv_u_rate_N_per_s")]
    rows.append([f"a noisy LiDAR through the local map ({int(tv.scenes)} passages)",
                 f"smoothed D, share of thrust power above 5 Hz: perfect LiDAR "
                 f"{fmt.num(hf['noisy'].median_perfect)}, noisy raw scan "
                 f"{fmt.num(hf['noisy'].median_sensor)}, noisy through the map "
                 f"{fmt.num(hf['noisy-map'].median_sensor)}; total variation through the map "
                 f"×{fmt.num(tv.median_effect)} [{fmt.num(tv.low)}, {fmt.num(tv.high)}] the "
                 "perfect sensor's, per passage", "`sensor_noise_cost.csv`"])
    rows.append(hardware.overview(hardware.runs(), hardware.runs((hardware.COMBINED,))))
    return fmt.markdown_table(["beyond the paper", "measured here", "table"], rows)

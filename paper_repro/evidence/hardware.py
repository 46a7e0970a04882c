"""The book's tables of the flights against RotorPy, formatted from the committed tables.

* :func:`agreement`: RotorPy with every effect off against our plant
  (``figures/hardware/agreement.csv``, ``benchmarks/rotorpy_agreement.py``);
* :func:`margins`: per effect and metric, the largest level flown with no unsafe run;
* :func:`cells`: each effect alone at each level, with and without its remedy;
* :func:`claim`: per cell, the Euclidean thrusts' power above 5 Hz over the smoothed ones';
* :func:`breaks`: what breaks first, and what its remedy buys, in sentences;
* :func:`combined`: every effect at once.

They read the studies' run tables (``figures/studies/<study>/table.parquet``, :func:`runs`).
A run is *unsafe* when it collides, leaves the workspace (into the ground, say) or ends on a
fault
(:func:`paper_repro.analysis.statistics.margins`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from paper_repro import paths
from paper_repro.analysis import statistics
from paper_repro.evidence import formatting as fmt

METRICS = ("smooth", "euclidean")
"""The arms, in the order of every "smoothed / Euclidean" column."""
LABELS = {"smooth": "smoothed D", "euclidean": "Euclidean ½d²"}
"""Each arm's name in a sentence."""

STUDIES = ("hardware_vehicle", "hardware_air_latency")
"""The studies of one effect at a time (``studies.catalogue.HARDWARE_GROUPS``)."""
COMBINED = "hardware_combined"
"""The study of every effect at once (``studies.catalogue.hardware_combined``)."""

EFFECTS = {"none": "every effect off", "motor_lag": "motor lag", "rotor_drag": "rotor drag",
           "thrust": "thrust", "mass": "mass", "com_offset": "centre of mass", "wind": "wind",
           "gust": "gust", "estimation": "state estimate", "delay": "computation delay",
           "combined": "every effect at once"}
"""Each effect's name in the book (the ``effect`` column holds the catalogue's)."""
COMBINED_REMEDIES = {"none": "", "all": ", every remedy",
                     "all + filtered": ", every remedy and the estimate filter"}
"""The remedies of every effect at once in the book (``studies.catalogue.COMBINED_REMEDIES``):
``all`` is each remedy that inverts a known model."""


def agreement(folder: Path | None = None) -> str:
    """``agreement.csv``: per scene, the steps, the largest distance between the two paths and
    the largest thrust difference."""
    folder = paths.figures_dir() / "hardware" if folder is None else Path(folder)
    t = pd.read_csv(folder / "agreement.csv")
    rows = [[r.scene, f"{r.steps_ours:,} / {r.steps_rotorpy:,}",
             f"{r.max_position_difference_m:.1e} m", f"{r.max_thrust_difference_N:.1e} N",
             f"{r.outcome_ours} / {r.outcome_rotorpy}"] for r in t.itertuples()]
    return fmt.markdown_table(["scene", "steps (ours / RotorPy)",
                               "largest distance between the paths",
                               "largest thrust difference", "outcome (ours / RotorPy)"], rows)


def lidar_range(study: str = STUDIES[0], root: Path | None = None) -> float:
    """m, the LiDAR's range r_s of the study's flights (its ``study.json``)."""
    import json

    root = paths.figures_dir() / "studies" if root is None else Path(root)
    return float(json.loads((root / study / "study.json").read_text())
                 ["base_config"]["sensor"]["range"])


def runs(studies=STUDIES, root: Path | None = None) -> pd.DataFrame:
    """The run tables of ``studies`` (those committed), one row per run, with the boolean
    columns ``collision`` (False for a failed run) and ``unsafe``."""
    root = paths.figures_dir() / "studies" if root is None else Path(root)
    tables = [pd.read_parquet(root / s / "table.parquet") for s in studies
              if (root / s / "table.parquet").is_file()]
    t = pd.concat(tables, ignore_index=True).drop_duplicates("name")  # a shared baseline once
    ok = t["status"] == "ok"
    t["collision"] = ok & t["collision"].fillna(False).astype(bool)
    t["unsafe"] = t["collision"] | (ok & t["outcome"].isin(["left_workspace", "fault"]))
    return t


def _alone(table: pd.DataFrame) -> pd.DataFrame:
    """The flown runs (status ``ok``) of one effect at a time, the baseline included."""
    return table[(table["effect"] != "combined") & (table["status"] == "ok")]


def _listed(names: list[str]) -> str:
    """``"a, b or c"``."""
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def margins(table: pd.DataFrame) -> str:
    """Per effect: its levels, and per metric the margin and the first unsafe level."""
    m = statistics.margins(table).set_index(["effect", "metric"])
    rows = []
    for effect in dict.fromkeys(m.index.get_level_values("effect")):
        cells = table[table["effect"] == effect].sort_values("level")
        names = dict(zip(cells["level"], cells["level_name"]))
        row = [EFFECTS[effect], ", ".join(names.values())]
        for column in ("margin", "first_failure"):
            row.append(" / ".join("—" if np.isnan(v := m.loc[(effect, metric), column])
                                  else names[v] for metric in METRICS))
        row.append(" / ".join(f"{int(m.loc[(effect, metric), 'worst_k'])}/"
                              f"{int(m.loc[(effect, metric), 'worst_n'])}" for metric in METRICS))
        rows.append(row)
    return fmt.markdown_table(["effect", "levels flown", "margin (smoothed / Euclidean)",
                               "first unsafe level", "unsafe runs, worst cell"], rows)


def _unsafe(g: pd.DataFrame) -> str:
    """``k/n [low, high] %``: the unsafe runs of ``g`` with a Clopper–Pearson interval."""
    return _share_of(g["unsafe"])


def _share_of(events: pd.Series) -> str:
    """``k/n [low, high] %``: the runs with a boolean event, with a Clopper–Pearson
    interval."""
    k, n = int(events.sum()), len(events)
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    return f"{k}/{n} [{100 * ci.low:.0f}, {100 * ci.high:.0f}] %"


def _cell_rows(table: pd.DataFrame, name) -> list[list[str]]:
    """One row per cell of ``table`` (grouped by effect, level and remedy, in table order),
    named by ``name(first row)``; both metrics side by side."""
    rows = []
    for _, g in table.groupby(["effect", "level", "remedy"], sort=False):
        by = {m: g[g["metric"] == m] for m in METRICS}
        rows.append([name(g.iloc[0]), " / ".join(_unsafe(by[m]) for m in METRICS),
                     " / ".join(f"{int(by[m]['completed'].fillna(False).sum())}/{len(by[m])}"
                                for m in METRICS),
                     " / ".join(f"{by[m]['min_clearance_m'].min():.2f}" for m in METRICS) + " m",
                     " / ".join(fmt.share(by[m]["hf_energy_fraction"].median())
                                for m in METRICS)])
    return rows


HEADER = ["unsafe runs (smoothed / Euclidean)", "completed", "closest approach",
          "thrust power above 5 Hz, median"]


def cells(table: pd.DataFrame) -> str:
    """Each effect alone at each level (the baseline first), with its remedy where flown."""
    t = table[table["effect"] != "combined"]
    return fmt.markdown_table(["cell", *HEADER], _cell_rows(t, cell_name))


def cell_name(r) -> str:
    """A cell's name in the book: its effect, level and remedy (a row of the run table)."""
    if r["effect"] == "none":
        return EFFECTS["none"]
    if r["effect"] == "combined":
        return f"{EFFECTS['combined']}, {r['level_name']}" + COMBINED_REMEDIES[r["remedy"]]
    return (f"{EFFECTS[r['effect']]} {r['level_name']}"
            + ("" if r["remedy"] == "none" else f", {r['remedy']}"))


def combined(table: pd.DataFrame) -> str:
    """Every effect at once, at each level, without and with every remedy; with the
    collisions apart, each with its Clopper–Pearson interval."""
    t = table[table["effect"] == "combined"]
    rows = _cell_rows(t, cell_name)
    for row, (_, g) in zip(rows, t.groupby(["effect", "level", "remedy"], sort=False),
                           strict=True):
        row.insert(1, " / ".join(_share_of(g[g["metric"] == m]["collision"]) for m in METRICS))
    return fmt.markdown_table(["cell", "collisions (smoothed / Euclidean)", *HEADER], rows)


CHATTER = 0.5
"""A run's thrusts *chatter* when most of their power (this share) lies above 5 Hz."""


def claim(table: pd.DataFrame, n_resamples: int = 2000, combined: bool = False) -> str:
    """Per cell of one effect alone (of every effect at once with ``combined``), passage by
    passage: the Euclidean thrusts' share of power above 5 Hz over the smoothed ones', its
    median over the passages with a percentile bootstrap interval
    (:func:`paper_repro.analysis.statistics.paired`), and whether the Euclidean thrusts
    chatter more (the whole interval above 1). Then the cells where the smoothed thrusts
    chatter too (median share above :data:`CHATTER`): there the claim fails, whatever the
    ratio."""
    t = table[(table["effect"] == "combined") == combined]
    rows, chattering = [], []
    for _, g in t.groupby(["effect", "level", "remedy"], sort=False):
        p = statistics.paired(g, columns=("hf_energy_fraction",), n_resamples=n_resamples)
        r = p.iloc[0]
        more = ("yes" if r["low"] > 1 else "no, less" if r["high"] < 1
                else "not shown") if r["effect"] == "ratio b/a" else "not measured"
        rows.append([cell_name(g.iloc[0]), f"{int(r['scenes'])}",
                     f"{fmt.share(r['median_smooth'])} / {fmt.share(r['median_euclidean'])}",
                     f"{fmt.ratio(r['median_effect'])} [{r['low']:.3g}, {r['high']:.3g}]",
                     more])
        if r["median_smooth"] > CHATTER:
            chattering.append(f"{cell_name(g.iloc[0])} ({fmt.share(r['median_smooth'])})")
    table_text = fmt.markdown_table(
        ["cell", "passages", "power above 5 Hz, median (smoothed / Euclidean)",
         "Euclidean over smoothed, per passage (median, 95 %)", "Euclidean chatters more"],
        rows)
    verdict = (f"The smoothed thrusts chatter too (more than {fmt.share(CHATTER)} of their "
               f"power above 5 Hz, median) in: {'; '.join(chattering)}. There the claim "
               "fails, whatever the ratio." if chattering else
               f"The smoothed thrusts keep less than {fmt.share(CHATTER)} of their power "
               "above 5 Hz (median) in every cell.")
    return f"{table_text}\n\n{verdict}"


def breaks(table: pd.DataFrame, lidar_range: float) -> str:
    """What breaks first, as a list: the collisions over every passage of one effect alone,
    then per metric each effect with an unsafe run (its unsafe levels, and the same levels
    with its remedy), and the effects with none."""
    t = _alone(table)
    counts = []
    for metric, label in LABELS.items():
        c = t.loc[t["metric"] == metric, "collision"]
        high = stats.binomtest(int(c.sum()), len(c)).proportion_ci(0.95, method="exact").high
        counts.append(f"{label} {int(c.sum())} in {len(c):,} (the rate is below "
                      f"{100 * high:.2g} % at 95 % confidence)")
    lines = [f"- Collisions, each effect alone: {'; '.join(counts)}."]
    m = statistics.margins(table)
    for metric, label in LABELS.items():
        mine = m[m["metric"] == metric]
        lines.append(f"- With the {label}:")
        for effect in mine.loc[mine["first_failure"].notna(), "effect"]:
            lines.append("  - " + _effect_breaks(
                t[(t["effect"] == effect) & (t["metric"] == metric)], lidar_range))
        safe = [EFFECTS[e] for e in mine.loc[mine["first_failure"].isna(), "effect"]]
        lines.append(f"  - no unsafe run with {_listed(safe)}, at any level flown." if safe
                     else "  - every effect has an unsafe run at some level.")
    return "\n".join(lines)


def _collided(g: pd.DataFrame) -> str:
    """``", k collided"`` when runs of ``g`` collided, else ``""``."""
    k = int(g["collision"].sum())
    return f", {k} collided" if k else ""


def _effect_breaks(t: pd.DataFrame, lidar_range: float) -> str:
    """One effect's unsafe levels for one metric (``t``: its runs), with its remedy's."""
    plain = t[t["remedy"] == "none"]
    unsafe = [(level, g) for level, g in plain.groupby("level") if g["unsafe"].any()]
    first = unsafe[0][1].iloc[0]
    text = (f"{EFFECTS[first['effect']]}: unsafe from {first['level_name']} ("
            + ", ".join(f"{int(g['unsafe'].sum())}/{len(g)} at {g.iloc[0]['level_name']}"
                        + _collided(g) for _, g in unsafe) + ").")
    blind = [g.iloc[0]["level_name"] for _, g in unsafe
             if g["min_clearance_m"].min() > lidar_range]
    if blind:
        text += (f" At {', '.join(blind)} every run left the workspace before a region came "
                 f"within the LiDAR's {lidar_range:g} m.")
    remedied = t[(t["remedy"] != "none") & t["level"].isin([level for level, _ in unsafe])]
    for remedy, g in remedied.groupby("remedy", sort=False):
        text += f" With its remedy ({remedy}): " + ", ".join(
            f"{int(c['unsafe'].sum())}/{len(c)} at {c.iloc[0]['level_name']}"
            for _, c in g.groupby("level")) + "."
    return text


def overview(table: pd.DataFrame, together: pd.DataFrame | None = None) -> list[str]:
    """The README's row of the hardware studies: what was flown, what it measured, the
    tables. ``table``: the runs of one effect at a time; ``together``: those of every effect
    at once (their headline cell's collisions, when given)."""
    t = _alone(table)
    names = {"smooth": "smoothed", "euclidean": "Euclidean"}
    collisions = ", ".join(f"{names[metric]} {int(t.loc[t['metric'] == metric, 'collision'].sum())}"
                           f"/{int((t['metric'] == metric).sum()):,}" for metric in METRICS)
    m = statistics.margins(table)
    per_metric = []
    for metric, label in names.items():
        mine = m[(m["metric"] == metric) & m["first_failure"].notna()]
        unsafe = [f"{EFFECTS[r.effect]} (worst cell {int(r.worst_k)}/{int(r.worst_n)}"
                  + _remedied_worst(t[(t["effect"] == r.effect) & (t["metric"] == metric)])
                  + ")" for r in mine.itertuples()]
        per_metric.append(f"{label}: {', '.join(unsafe) if unsafe else 'none'}")
    hf = t[(t["effect"] == "none")].groupby("metric")["hf_energy_fraction"].median()
    smooth = t[t["metric"] == "smooth"].groupby(["effect", "level", "remedy"], sort=False)
    chatter = list(dict.fromkeys(EFFECTS[effect] for (effect, _, _), g in smooth
                                 if g["hf_energy_fraction"].median() > CHATTER))
    at_once = ""
    if together is not None:
        head = headline(together)
        at_once = (f". Every effect at once ({cell_name(head.iloc[0]).split(', ', 1)[1]}): "
                   + ", ".join(f"{names[m]} {int(g['collision'].sum())} collided and "
                               f"{int(g['unsafe'].sum())} unsafe in {len(g):,}"
                               for m in METRICS for g in [head[head["metric"] == m]]))
    return [f"towards hardware: RotorPy as the plant, with motor lag, drag, parameter "
            f"mismatch, wind, a late noisy estimate or a computation delay, one at a time "
            f"({len(t):,} passages), then all at once",
            f"collisions: {collisions}. Effects with an unsafe run (collided, left the workspace "
            f"or faulted): {'; '.join(per_metric)}. Share of thrust power above 5 Hz with "
            f"every effect off: smoothed {fmt.share(hf['smooth'])}, Euclidean "
            f"{fmt.share(hf['euclidean'])}; the smoothed thrusts chatter too (most of their "
            f"power above 5 Hz) with: {', '.join(chatter) if chatter else 'no effect'}"
            f"{at_once}",
            "`hardware_*/table.parquet`"]


def headline(together: pd.DataFrame) -> pd.DataFrame:
    """The runs of the cell of every effect at once flown on the most passages (the
    catalogue's ``HEADLINE``)."""
    t = together[together["effect"] == "combined"]
    level, remedy = t.groupby(["level", "remedy"], sort=False).size().idxmax()
    return t[(t["level"] == level) & (t["remedy"] == remedy)]


def _remedied_worst(t: pd.DataFrame) -> str:
    """``"; with <remedy> k/n"``: the worst cell of one effect and metric (``t``: its runs)
    with its remedy, or ``""`` when none was flown."""
    remedied = t[t["remedy"] != "none"]
    if remedied.empty:
        return ""
    worst = max((g for _, g in remedied.groupby(["level", "remedy"], sort=False)),
                key=lambda g: g["unsafe"].mean())
    return (f"; with {worst.iloc[0]['remedy']} {int(worst['unsafe'].sum())}/{len(worst)}")

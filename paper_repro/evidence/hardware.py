"""The book's tables of the flights against RotorPy, formatted from the committed tables.

* :func:`agreement`: RotorPy with every effect off against our plant
  (``figures/hardware/agreement.csv``, ``benchmarks/rotorpy_agreement.py``);
* :func:`margins`: per effect and metric, the largest level flown with no unsafe run;
* :func:`cells`: each effect alone at each level, with and without its remedy;
* :func:`combined`: every effect at once.

The last three read the studies' run tables (``figures/studies/<study>/table.parquet``). A run
is *unsafe* when it collides, leaves the workspace (into the ground, say) or ends on a fault
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

STUDIES = ("hardware_vehicle", "hardware_air_latency")
"""The studies of one effect at a time (``studies.catalogue.HARDWARE_GROUPS``)."""


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


def runs(studies=STUDIES, root: Path | None = None) -> pd.DataFrame:
    """The run tables of ``studies`` (those committed), one row per run, with the boolean
    column ``unsafe``."""
    root = paths.figures_dir() / "studies" if root is None else Path(root)
    tables = [pd.read_parquet(root / s / "table.parquet") for s in studies
              if (root / s / "table.parquet").is_file()]
    t = pd.concat(tables, ignore_index=True).drop_duplicates("name")  # a shared baseline once
    ok = t["status"] == "ok"
    t["unsafe"] = ok & (t["collision"].fillna(False).astype(bool)
                        | t["outcome"].isin(["left_workspace", "fault"]))
    return t


def margins(table: pd.DataFrame) -> str:
    """Per effect: its levels, and per metric the margin and the first unsafe level."""
    m = statistics.margins(table).set_index(["effect", "metric"])
    rows = []
    for effect in dict.fromkeys(m.index.get_level_values("effect")):
        cells = table[table["effect"] == effect].sort_values("level")
        names = dict(zip(cells["level"], cells["level_name"]))
        row = [effect, ", ".join(names.values())]
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
    k, n = int(g["unsafe"].sum()), len(g)
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
    return fmt.markdown_table(["cell", *HEADER], _cell_rows(t, lambda r: (
        "every effect off" if r["effect"] == "none" else f"{r['effect']} {r['level_name']}"
        + ("" if r["remedy"] == "none" else f", {r['remedy']}"))))


def combined(table: pd.DataFrame) -> str:
    """Every effect at once, at each level, without and with every remedy."""
    t = table[table["effect"] == "combined"]
    return fmt.markdown_table(["level", *HEADER], _cell_rows(t, lambda r: (
        r["level_name"] + ("" if r["remedy"] == "none" else ", every remedy"))))

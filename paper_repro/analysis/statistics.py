"""Statistics over study tables: rates with binomial intervals, paired per-scene comparisons
with bootstrap intervals and Wilcoxon tests, and per-setting aggregates for sweeps.

A study table (:func:`paper_repro.studies.engine.run_study`) has one row per run. Runs that raised
(``status == "failed"``) are counted, never silently dropped: :func:`rates` reports them, and
the paired comparisons use only the scenes where both runs flew.

All intervals are 95 % (``confidence``) and every resampling is seeded.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

EVENTS = ("completed", "collision", "stalled", "step_limit", "left_workspace", "fault",
          "failed")
"""Per-run outcomes whose rates :func:`rates` reports: ``completed`` (finish line crossed or
every target reached), ``collision`` (clearance < 0.35 m), ``stalled`` (deadlock),
``step_limit`` (neither, in the time allowed), ``left_workspace`` (below the ground or
through a wall), ``fault`` (persistent faults), ``failed`` (the run raised). Every run is
in exactly one of them but ``collision``, which a run of any outcome can have."""

PAIRED_COLUMNS = {
    "tv_u_rate_N_per_s": "total variation of u per second, N/s",
    "hf_energy_fraction": "share of thrust power above 5 Hz",
    "max_abs_du_N": "max |Δu|, N",
    "min_clearance_m": "min clearance, m",
}
"""The per-run measures compared scene by scene, with their labels."""


def rates(table: pd.DataFrame, by: str | list[str] = "metric",
          confidence: float = 0.95) -> pd.DataFrame:
    """Rate of each of :data:`EVENTS` per group, with Clopper–Pearson intervals.

    Returns one row per (group, event): ``n`` runs, ``k`` events, ``rate``, ``low``, ``high``.
    ``failed`` counts runs that raised; the other events are over all runs of the group (a
    failed run has none of them).
    """
    t = _events(table)
    rows = []
    for key, group in t.groupby(by, sort=False, dropna=False):
        n = len(group)
        for event in EVENTS:
            k = int(group[event].sum())
            ci = stats.binomtest(k, n).proportion_ci(confidence, method="exact")
            rows.append({**_group_dict(by, key), "event": event, "n": n, "k": k,
                         "rate": k / n, "low": ci.low, "high": ci.high})
    return pd.DataFrame(rows)


def paired(table: pd.DataFrame, a: str = "smooth", b: str = "euclidean",
           columns=tuple(PAIRED_COLUMNS), pair_on: str = "scene_seed", group: str = "metric",
           n_resamples: int = 5000, confidence: float = 0.95, seed: int = 0) -> pd.DataFrame:
    """Scene-by-scene comparison of runs ``a`` and ``b`` (values of ``group``).

    For each column: the medians of ``a`` and ``b``, the median of the per-scene ratio b/a
    (or of the difference b − a for clearance, which can be compared on its own scale) with a
    percentile-bootstrap interval (``scipy.stats.bootstrap``, scenes resampled), and the two-sided
    Wilcoxon signed-rank p-value of the differences. Only scenes where both runs succeeded.
    """
    ok = table[table["status"] == "ok"]
    wide = ok.pivot_table(index=pair_on, columns=group, values=list(columns), aggfunc="first")
    rows = []
    for col in columns:
        if (col, a) not in wide or (col, b) not in wide:
            continue
        pair = wide[[(col, a), (col, b)]].dropna()
        va, vb = pair[(col, a)].to_numpy(float), pair[(col, b)].to_numpy(float)
        ratio_scale = col != "min_clearance_m" and np.all(va > 0)
        effect = vb / va if ratio_scale else vb - va
        row = {"measure": col, "label": PAIRED_COLUMNS.get(col, col), "scenes": len(pair),
               f"median_{a}": float(np.median(va)) if len(va) else np.nan,
               f"median_{b}": float(np.median(vb)) if len(vb) else np.nan,
               "effect": "ratio b/a" if ratio_scale else "difference b − a",
               "median_effect": float(np.median(effect)) if len(effect) else np.nan,
               "low": np.nan, "high": np.nan, "wilcoxon_p": np.nan,
               f"share_{b}_greater": float(np.mean(vb > va)) if len(va) else np.nan}
        if len(pair) >= 3:
            ci = _bootstrap_median(effect, n_resamples, confidence, seed)
            row["low"], row["high"] = ci
            d = vb - va
            if np.any(d != 0):
                row["wilcoxon_p"] = float(stats.wilcoxon(va, vb).pvalue)
        rows.append(row)
    return pd.DataFrame(rows)


def by_setting(table: pd.DataFrame, settings=("metric", "eta", "sigma"),
               columns=("tv_u_rate_N_per_s", "hf_energy_fraction", "max_abs_du_N",
                        "min_clearance_m", "time_to_complete_s"),
               n_resamples: int = 2000, confidence: float = 0.95, seed: int = 0,
               events=("completed", "collision", "stalled", "failed")) -> pd.DataFrame:
    """Per setting (e.g. each (η, σ) of a sweep): the median of each column over scenes with a
    bootstrap interval, and the rate of each of ``events`` (completion, collision, stall and
    failure; any event column of the run table, such as ``"unsafe"``) with binomial intervals.
    """
    t = _events(table)
    rows = []
    for key, group in t.groupby(list(settings), sort=True, dropna=False):
        row = {**_group_dict(list(settings), key), "runs": len(group)}
        for event in events:
            k = int(group[event].sum())
            ci = stats.binomtest(k, len(group)).proportion_ci(confidence, method="exact")
            row.update({f"{event}_rate": k / len(group), f"{event}_low": ci.low,
                        f"{event}_high": ci.high})
        ok = group[group["status"] == "ok"]
        for col in columns:
            v = ok[col].dropna().to_numpy(float)
            row[col] = float(np.median(v)) if len(v) else np.nan
            lo, hi = (_bootstrap_median(v, n_resamples, confidence, seed) if len(v) >= 3
                      else (np.nan, np.nan))
            row[f"{col}_low"], row[f"{col}_high"] = lo, hi
        rows.append(row)
    return pd.DataFrame(rows)


def margins(table: pd.DataFrame, event: str = "unsafe", confidence: float = 0.95
            ) -> pd.DataFrame:
    """The robustness margin of each effect swept over levels, per metric.

    ``table`` has the columns ``effect``, ``level`` (rising with severity), ``metric`` and
    ``remedy``, and one row per run. Only the cells without a remedy and of one effect alone
    count (not ``"none"`` or ``"combined"``). Per (effect, metric): the levels flown, the
    ``margin`` (the largest level below the first level with any ``event``; NaN when the
    first level already has one), ``first_failure`` (that level; NaN when none has one), and
    the worst cell's rate with its Clopper–Pearson interval. ``event`` is a column of the
    table's events: ``"unsafe"`` (default) is a collision, a flight that left the workspace
    (into the ground, say) or one ended by a fault.
    """
    t = _events(table)
    t = t[(t["remedy"] == "none") & ~t["effect"].isin(["none", "combined"])]
    rows = []
    for (effect, metric), cells in t.groupby(["effect", "metric"], sort=False):
        levels = sorted(cells["level"].unique())
        counts = [(level, int(cells.loc[cells["level"] == level, event].sum()),
                   int((cells["level"] == level).sum())) for level in levels]
        failing = [level for level, k, _ in counts if k > 0]
        first = failing[0] if failing else np.nan
        below = [level for level in levels if not failing or level < first]
        _, k, n = max(counts, key=lambda c: (c[1] / c[2], c[0]))
        ci = stats.binomtest(k, n).proportion_ci(confidence, method="exact")
        rows.append({"effect": effect, "metric": metric, "levels": len(levels),
                     "margin": below[-1] if below else np.nan, "first_failure": first,
                     "worst_k": k, "worst_n": n, "worst_rate": k / n, "worst_low": ci.low,
                     "worst_high": ci.high})
    return pd.DataFrame(rows)


def ecdf(values) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF: sorted values and the share of values ≤ each."""
    v = np.sort(np.asarray(values, float)[~np.isnan(np.asarray(values, float))])
    return v, np.arange(1, len(v) + 1) / max(len(v), 1)


# --- helpers --------------------------------------------------------------------------------

def _events(table: pd.DataFrame) -> pd.DataFrame:
    """Boolean event columns for every row, failed rows included (with no other event)."""
    t = table.copy()
    failed = t["status"] == "failed"
    for col in ("completed", "collision", "stalled"):
        t[col] = t[col].fillna(False).astype(bool) & ~failed if col in t else False
    for outcome in ("step_limit", "left_workspace", "fault"):
        t[outcome] = (t["outcome"] == outcome) & ~failed if "outcome" in t else False
    t["failed"] = failed
    t["unsafe"] = t["collision"] | t["left_workspace"] | t["fault"]
    return t


def _group_dict(by, key) -> dict:
    names = [by] if isinstance(by, str) else list(by)
    values = key if isinstance(key, tuple) else (key,)
    return dict(zip(names, values, strict=True))


def _bootstrap_median(values, n_resamples: int, confidence: float, seed: int):
    v = np.asarray(values, float)
    if np.all(v == v[0]):
        return float(v[0]), float(v[0])
    res = stats.bootstrap((v,), np.median, n_resamples=n_resamples, confidence_level=confidence,
                          method="percentile", random_state=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)

"""Figures of a study table: rates, paired differences, clearance ECDF, sweeps."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from paper_repro.analysis import metrics
from paper_repro.plots.common import axes_or_new

# --- studies (tables of many runs, paper_repro.studies.engine) -------------------------------

METRIC_COLOURS = {"smooth": "tab:blue", "euclidean": "tab:red"}


def plot_rates(rates, ax=None):
    """Outcome rates per metric with their 95 % intervals
    (:func:`paper_repro.analysis.statistics.rates`).
    """
    fig, ax = axes_or_new(ax, (7.0, 3.2))
    events = list(dict.fromkeys(rates["event"]))
    metrics_ = list(dict.fromkeys(rates["metric"]))
    rate_bars(ax, rates, "metric", metrics_, {m: METRIC_COLOURS.get(m) for m in metrics_},
              events, alpha=0.8)
    ax.legend(frameon=False)
    return fig


def rate_bars(ax, rates, by: str, groups, colours, events, alpha: float,
              name=str) -> None:
    """Bars of the rate of each of ``events`` for each of ``groups`` (values of the column
    ``by`` of :func:`paper_repro.analysis.statistics.rates`), side by side, with their 95 %
    Clopper–Pearson intervals; each group labelled ``name(group)`` and its number of runs."""
    width = 0.8 / max(len(groups), 1)
    for i, g in enumerate(groups):
        r = rates[rates[by] == g].set_index("event").loc[list(events)]
        x = np.arange(len(events)) + (i - (len(groups) - 1) / 2) * width
        ax.bar(x, r["rate"], width, color=colours[g], alpha=alpha,
               label=f"{name(g)} (n = {int(r['n'].iloc[0])})")
        ax.errorbar(x, r["rate"], yerr=[r["rate"] - r["low"], r["high"] - r["rate"]],
                    fmt="none", ecolor="k", capsize=3, lw=1)
    ax.set_xticks(np.arange(len(events)), events)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share of runs")


def plot_paired(table, a: str = "smooth", b: str = "euclidean", pair_on: str = "scene_seed",
                columns=("tv_u_rate_N_per_s", "hf_energy_fraction", "max_abs_du_N",
                         "min_clearance_m")):
    """One panel per measure: each scene's run ``b`` against its run ``a`` (log axes for the
    chattering measures), with the diagonal y = x."""
    from paper_repro.analysis.statistics import PAIRED_COLUMNS

    ok = table[table["status"] == "ok"]
    wide = ok.pivot_table(index=pair_on, columns="metric", values=list(columns),
                          aggfunc="first")
    fig, axes = plt.subplots(1, len(columns), figsize=(3.3 * len(columns), 3.3),
                             constrained_layout=True)
    for ax, col in zip(np.atleast_1d(axes), columns, strict=True):
        pair = wide[[(col, a), (col, b)]].dropna()
        va, vb = pair[(col, a)].to_numpy(float), pair[(col, b)].to_numpy(float)
        ax.scatter(va, vb, s=12, alpha=0.7, color="k")
        both = np.r_[va, vb]
        positive = both[both > 0]
        if col != "min_clearance_m" and len(positive):
            ax.set_xscale("log")
            ax.set_yscale("log")
            lo, hi = positive.min() / 1.5, positive.max() * 1.5
        else:
            lo, hi = (both.min() - 0.05, both.max() + 0.05) if len(both) else (0, 1)
        ax.plot([lo, hi], [lo, hi], color="0.6", lw=1, ls="--")
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_xlabel(f"{a}")
        ax.set_ylabel(f"{b}")
        ax.set_title(PAIRED_COLUMNS.get(col, col), fontsize=9)
    return fig


def plot_paired_by(paired, by: str, a: str = "smoothed", b: str = "Euclidean"):
    """The paired effects of :func:`paper_repro.analysis.statistics.paired` (median and 95 %
    interval) for each value of ``by`` side by side, one panel per measure; ratios on a log
    axis with the line of no difference. ``a`` and ``b`` name the two sides of the pairs for
    the caption that defines the effect ("ratio b/a": b's measure over a's on the same
    scene, its median over the scenes)."""
    measures = list(dict.fromkeys(paired["measure"]))
    groups = list(dict.fromkeys(paired[by]))
    fig, axes = plt.subplots(1, len(measures), figsize=(3.0 * len(measures), 3.0),
                             constrained_layout=True)
    for ax, m in zip(np.atleast_1d(axes), measures, strict=True):
        rows = paired[paired["measure"] == m].set_index(by).loc[groups]
        x = np.arange(len(groups))
        y = rows["median_effect"].to_numpy(float)
        err = np.vstack([y - rows["low"].to_numpy(float), rows["high"].to_numpy(float) - y])
        ax.errorbar(x, y, yerr=np.abs(err), fmt="o", color="k", capsize=4)
        ratio = rows["effect"].iloc[0].startswith("ratio")
        ax.axhline(1.0 if ratio else 0.0, color="0.6", ls="--", lw=1)
        if ratio and np.all(np.r_[y, rows["low"]] > 0):
            ax.set_yscale("log")
        ax.set_xticks(x, groups)
        ax.set_xlim(-0.6, len(groups) - 0.4)
        ax.set_title(f"{rows['label'].iloc[0]}\n({rows['effect'].iloc[0]})", fontsize=8)
    fig.supxlabel(f"b = {b}, a = {a}, on the same scene: ratio b/a (or difference b − a) per "
                  "scene, its median over the scenes and 95 % bootstrap interval", fontsize=8)
    return fig


def plot_clearance_ecdf(table, ax=None, collision: float = metrics.COLLISION_CLEARANCE):
    """ECDF of each run's minimum clearance, per metric, with the collision threshold."""
    from paper_repro.analysis.statistics import ecdf

    fig, ax = axes_or_new(ax, (5.5, 3.4))
    ok = table[table["status"] == "ok"]
    for m, group in ok.groupby("metric", sort=False):
        x, f = ecdf(group["min_clearance_m"])
        ax.step(x, f, where="post", color=METRIC_COLOURS.get(m), label=f"{m} ({len(x)} runs)")
    ax.axvline(collision, color="k", ls=":", lw=1, label=f"collision < {collision} m")
    ax.set_xlabel("minimum clearance over the run, m")
    ax.set_ylabel("share of runs ≤ x")
    ax.legend(frameon=False)
    return fig


def plot_study_solve_times(table, ts_ms: float = 10.0):
    """ECDFs of each run's median and 99th-percentile solve time, per metric, against T_s."""
    from paper_repro.analysis.statistics import ecdf

    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2), constrained_layout=True, sharey=True)
    ok = table[table["status"] == "ok"]
    for ax, col, title in zip(axes, ("solve_median_ms", "solve_p99_ms"),
                              ("median per run", "99th percentile per run"), strict=True):
        for m, group in ok.groupby("metric", sort=False):
            x, f = ecdf(group[col])
            ax.step(x, f, where="post", color=METRIC_COLOURS.get(m), label=m)
        ax.axvline(ts_ms, color="k", ls=":", lw=1, label=f"T_s = {ts_ms:g} ms")
        ax.set_xscale("log")
        ax.set_xlabel("solve time, ms")
        ax.set_title(title, fontsize=9)
    axes[0].set_ylabel("share of runs ≤ x")
    axes[0].legend(frameon=False)
    return fig


def plot_sweep(settings, x: str, fixed: dict, columns=(
        ("tv_u_rate_N_per_s", "TV of u per second, N/s", True),
        ("hf_energy_fraction", "thrust power above 5 Hz", False),
        ("min_clearance_m", "min clearance, m", False),
        ("time_to_complete_s", "passage time, s", False),
        ("max_abs_du_N", "max |Δu|, N", False),
        ("completed_rate", "completion rate", False),
        ("stalled_rate", "stall rate", False),
        ("collision_rate", "collision rate (clearance < 0.35 m)", False))):
    """Medians over scenes (bands: their 95 % intervals) of the smooth runs against ``x``
    (``"eta"`` or ``"sigma"``) with the other parameter held at ``fixed``; the Euclidean
    baseline as a dashed line (:func:`paper_repro.analysis.statistics.by_setting`)."""
    smooth = settings[settings["metric"] == "smooth"]
    for name, value in fixed.items():
        smooth = smooth[np.isclose(smooth[name], value)]
    smooth = smooth.sort_values(x)
    base = settings[settings["metric"] == "euclidean"]
    rows = -(-len(columns) // 4)
    fig, axes = plt.subplots(rows, 4, figsize=(14.0, 2.8 * rows), constrained_layout=True,
                             squeeze=False)
    for ax in axes.ravel()[len(columns):]:
        ax.set_visible(False)  # no empty panel
    for ax, (col, label, log) in zip(axes.ravel(), columns):
        stem = col.removesuffix("_rate")  # rates' intervals are <event>_low, _high
        lo_col, hi_col = f"{stem}_low", f"{stem}_high"
        xs = smooth[x].to_numpy(float)
        ax.plot(xs, smooth[col], "o-", color=METRIC_COLOURS["smooth"], label="smoothed D")
        if lo_col in smooth and hi_col in smooth:
            ax.fill_between(xs, smooth[lo_col], smooth[hi_col], color=METRIC_COLOURS["smooth"],
                            alpha=0.2, lw=0)
        if len(base):
            ax.axhline(float(base[col].iloc[0]), color=METRIC_COLOURS["euclidean"], ls="--",
                       label="Euclidean (η → 0)")
        values = np.r_[smooth[col].to_numpy(float), base[col].to_numpy(float)]
        if not np.isfinite(values).any():  # e.g. no run completed: nothing to draw
            ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", color="0.5")
        else:
            ax.set_xscale("log")
            ax.set_xticks(xs, [f"{v:g}" for v in xs])  # the swept values, not log decades
            ax.minorticks_off()
            if log and np.nanmin(values) > 0:
                ax.set_yscale("log")
        ax.set_xlabel(f"{'η' if x == 'eta' else 'σ'}, m  ("
                      + ", ".join(f"{'σ' if k == 'sigma' else 'η'} = {v:g} m"
                                  for k, v in fixed.items()) + ")")
        ax.set_title(label, fontsize=9)
        if col.endswith("_rate"):
            ax.set_ylim(-0.05, 1.05)  # a share: the whole range, so 25 % looks like 25 %
    axes[0, 0].legend(frameon=False, fontsize=8)
    return fig


def plot_cells(cells, columns=("collision_rate", "hf_energy_fraction")):
    """Per cell of a sweep (one row of :func:`paper_repro.analysis.statistics.by_setting` per
    cell and metric, with a ``cell`` column naming it): each column's value with its 95 %
    interval (``<column>_low`` and ``<column>_high``; ``<event>_low`` and ``<event>_high``
    for a rate ``<event>_rate``), both metrics side by side, one panel per column."""
    names = list(dict.fromkeys(cells["cell"]))
    fig, axes = plt.subplots(len(columns), 1, figsize=(max(6.0, 0.45 * len(names)),
                                                        2.4 * len(columns)),
                             sharex=True, constrained_layout=True)
    labels = {"collision_rate": "collision rate", "completed_rate": "completion rate",
              "unsafe_rate": "unsafe rate",
              "hf_energy_fraction": "share of thrust power > 5 Hz (median)",
              "min_clearance_m": "min clearance, m (median)"}
    for ax, col in zip(np.atleast_1d(axes), columns, strict=True):
        for i, (metric, rows) in enumerate(cells.groupby("metric", sort=False)):
            rows = rows.set_index("cell").reindex(names)
            x = np.arange(len(names)) + (i - 0.5) * 0.25
            y = rows[col].to_numpy(float)
            stem = col.removesuffix("_rate")
            err = np.abs(np.vstack([y - rows[f"{stem}_low"].to_numpy(float),
                                    rows[f"{stem}_high"].to_numpy(float) - y]))
            ax.errorbar(x, y, yerr=err, fmt="o", ms=4, capsize=3,
                        color=METRIC_COLOURS.get(metric), label=metric)
        ax.set_ylabel(labels.get(col, col), fontsize=8)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(fontsize=8)
    np.atleast_1d(axes)[-1].set_xticks(np.arange(len(names)), names, rotation=60,
                                       ha="right", fontsize=7)
    return fig

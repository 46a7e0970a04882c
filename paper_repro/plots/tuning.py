"""Figures of a tuning study, drawn from the saved study and its held-out table."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from paper_repro.studies.tuning_results import HELDOUT_COLUMNS
from paper_repro.studies.tuning_space import DEFAULT_OBJECTIVES, OBJECTIVES

# --- figures (drawn from the saved study and table) -----------------------------------------

def plot_front(frame, objectives: Sequence[str] = DEFAULT_OBJECTIVES, setups=None):
    """The trials in objective space: feasible (dots), infeasible (crosses), the feasible
    Pareto front (line), the printed set-up (star) and the held-out picks (circled)."""
    import matplotlib.pyplot as plt

    x, y = objectives[0], objectives[-1]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    feas, infeas = frame[frame["feasible"]], frame[~frame["feasible"]]
    fin = infeas[np.isfinite(infeas[x]) & np.isfinite(infeas[y])]
    ax.scatter(fin[x], fin[y], marker="x", color="0.6", label=f"infeasible ({len(infeas)})")
    ax.scatter(feas[x], feas[y], s=18, color="C0", label=f"feasible ({len(feas)})")
    front = frame[frame["pareto"]].sort_values(x)
    ax.step(front[x], front[y], where="post", color="C1", lw=1.5,
            label=f"Pareto front ({len(front)})")
    ax.scatter(front[x], front[y], s=30, color="C1", zorder=3)
    pr = frame[frame["printed"]]
    ax.scatter(pr[x], pr[y], marker="*", s=220, color="C3", zorder=4, edgecolor="k",
               label="printed (trial 0)")
    for k, (name, params) in enumerate((setups or {}).items()):
        if "trial" in params:
            row = frame[frame["number"] == params["trial"]]
            ax.scatter(row[x], row[y], s=160, facecolor="none", edgecolor=f"C{k + 4}",
                       lw=2, zorder=5, label=name.replace("_", " "))
    ax.set_xlabel(OBJECTIVES.get(x, x))
    ax.set_ylabel(OBJECTIVES.get(y, y))
    ax.set_title("Training scenes: mean over scenes per trial")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_importances(imp):
    """Parameter importances, one group of bars per target."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    imp.plot.barh(ax=ax)
    ax.set_xlabel("importance (Optuna get_param_importances, normalised per target)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_heldout(summary):
    """Held-out comparison, per set-up: the completion and collision rates, and the median of
    each measure, with 95 % intervals. Set-ups that are one trial (the front's best on each
    objective may be the same) share one column, labelled with every name."""
    import matplotlib.pyplot as plt

    setups = list(dict.fromkeys(summary.loc[summary["kind"] == "rate", "setup"]))
    columns = ["setup", "event", "measure", "rate", "median", "low", "high"]
    same: dict[str, list[str]] = {}
    for s in setups:  # group set-ups whose rows are identical (one trial under two names)
        rows = summary.loc[summary["setup"] == s, columns[1:]].reset_index(drop=True)
        twin = next((t for t in same if summary.loc[summary["setup"] == t, columns[1:]]
                     .reset_index(drop=True).equals(rows)), None)
        if twin is None:
            same[s] = [s]
        else:
            same[twin].append(s)
    shown = list(same)
    names = [" =\n".join(n.replace("_", " ") for n in same[s]) for s in shown]
    panels = ([("completed", "completion rate"), ("collision", "collision rate")]
              + [(c, OBJECTIVES.get(c, c)) for c in HELDOUT_COLUMNS])
    fig, axes = plt.subplots(1, len(panels), figsize=(2.8 * len(panels), 3.4))
    for ax, (col, label) in zip(axes, panels):
        if col in ("completed", "collision"):
            d = summary[(summary["kind"] == "rate") & (summary["event"] == col)]
            mid = d.set_index("setup")["rate"]
            ax.set_ylim(-0.05, 1.05)
        else:
            d = summary[(summary["kind"] == "median") & (summary["measure"] == col)]
            mid = d.set_index("setup")["median"]
        d = d.set_index("setup").reindex(shown)
        mid = mid.reindex(shown)
        err = np.vstack([mid - d["low"], d["high"] - mid]).clip(min=0)
        colour = "tab:red" if col == "collision" else "tab:blue"
        ax.errorbar(range(len(shown)), mid, yerr=np.nan_to_num(err), fmt="o", capsize=4,
                    color=colour)
        ax.set_xticks(range(len(shown)), names, fontsize=7)
        ax.set_xlim(-0.5, len(shown) - 0.5)
        ax.set_title(label if col != "min_clearance_m" else "min clearance, m", fontsize=9)
    n = int(summary.loc[summary["kind"] == "rate", "n"].max())
    fig.suptitle(f"held-out scenes ({n} per set-up), 95 % intervals", fontsize=10)
    fig.tight_layout()
    return fig

"""Figures of the mission's clock (paper_repro.analysis.clock)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from paper_repro.analysis import metrics
from paper_repro.plots.common import LINESTYLES, MAX_POINTS, stride_indices

# --- the mission's clock (paper_repro.analysis.clock) ---------------------------------------------

def plot_clock_levers(sweeps, paper_time: float = 500.0, tolerance: float = 0.10,
                      printed: dict | None = None):
    """Mission time of the linear loop against each lever, beside the paper's clock.

    Parameters
    ----------
    sweeps : DataFrame of :func:`paper_repro.analysis.clock.lever_sweep` rows (several levers).
    paper_time : s, the paper's mission (a band of ± ``tolerance`` around it is shaded).
    printed : lever → printed value, marked with a dotted line.
    """
    from paper_repro.analysis.clock import LEVERS

    levers = list(dict.fromkeys(sweeps["lever"]))
    fig, axes = plt.subplots(1, len(levers), figsize=(2.6 * len(levers), 3.0), sharey=True,
                             squeeze=False)
    for ax, lever in zip(axes[0], levers):
        rows = sweeps[sweeps["lever"] == lever].sort_values("value")
        ax.plot(rows["value"], rows["mission_time_s"], "o-", ms=3, lw=1.0, color="black")
        ax.axhspan(paper_time * (1 - tolerance), paper_time * (1 + tolerance),
                   color="tab:green", alpha=0.2, lw=0)
        ax.axhline(paper_time, color="tab:green", lw=0.8)
        if printed and lever in printed:
            ax.axvline(printed[lever], color="0.4", ls=":", lw=1.0)
        if lever in ("T", "R", "rate weights"):
            ax.set_xscale("log")
        ax.set_xlabel(LEVERS[lever][0] if lever in LEVERS else lever, fontsize=8)
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("mission time, linear loop [s]")
    fig.suptitle(f"the clock under one changed parameter (band: {paper_time:g} s "
                 f"± {tolerance:.0%})", fontsize=10)
    fig.tight_layout()
    return fig


def plot_flight_clocks(results, labels, paper_time: float = 500.0,
                       paper_avoidance=(50.0, 120.0), merge_gap_s: float = 5.0):
    """Distance to the active target against time for each flight, with its avoidance
    windows (a cloud within the LiDAR's range) as bars, beside the paper's clock.

    Parameters
    ----------
    results : SimulationResults.   labels : one legend entry each.
    paper_time : s, end of the paper's time axes (dashed line).
    paper_avoidance : (t0, t1) s, the paper's avoidance phases (shaded).
    """
    from paper_repro.analysis.clock import avoidance_windows

    fig, (ax, bars) = plt.subplots(2, 1, figsize=(7.5, 5.0), sharex=True,
                                   gridspec_kw={"height_ratios": (3, 1.3)})
    for i, (r, label) in enumerate(zip(results, labels, strict=True)):
        dist = np.linalg.norm(metrics.tracking_error(r), axis=1)
        idx = stride_indices(len(dist), MAX_POINTS)
        line, = ax.plot(r.t[idx], dist[idx], LINESTYLES[i], lw=1.0, label=label)
        for a, b in avoidance_windows(r, merge_gap_s):
            bars.plot([a, b], [i, i], color=line.get_color(), lw=5, solid_capstyle="butt")
    for a in (ax, bars):
        a.axvspan(*paper_avoidance, color="tab:orange", alpha=0.15, lw=0)
        a.axvline(paper_time, color="tab:green", ls="--", lw=1.0)
        a.grid(alpha=0.3)
    ax.set_ylabel("‖y − y_t‖ [m]")
    ax.set_title(f"the paper mission's clock (dashed: the paper's {paper_time:g} s; shaded: "
                 f"its avoidance, {paper_avoidance[0]:g}–{paper_avoidance[1]:g} s)",
                 fontsize=9)
    ax.legend(fontsize="small", loc="upper right")
    bars.set_yticks(range(len(labels)), labels, fontsize=7)
    bars.set_ylim(-0.7, len(labels) - 0.3)
    bars.invert_yaxis()
    bars.set_xlabel("t [s]")
    bars.set_ylabel("cloud in view", fontsize=8)
    fig.tight_layout()
    return fig

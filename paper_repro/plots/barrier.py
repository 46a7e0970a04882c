"""Tutorial figure of the CBF penalty: F(g) of eq. (19) and the decay that g ≤ 0 allows
(eq. 16, 18). Every value is the :class:`~paper_repro.problem.ocp.OCP`'s own."""

from __future__ import annotations

import dataclasses

import matplotlib.pyplot as plt
import numpy as np

from paper_repro.config import Config
from paper_repro.problem.ocp import OCP

# --- tutorial: the penalty F(g) and the discrete CBF condition (eq. 16-19) --------------------

def plot_barrier_penalty(config: Config | None = None, kappas=(2.5, 10.0, 40.0),
                         epsilons=(1.0, 2.0, 3.0), g_range=(-0.5, 0.5), n: int = 401,
                         floor: float = 1e-6):
    """F(g) (eq. 19) for several κ and ε, and the slowest decay of β that g ≤ 0 allows.

    Left: F for each κ in ``kappas`` at the configuration's ε, with its limit
    κ^(ε−1)·max(0, g)^ε as κ → ∞ (dashed). Middle: F for each ε in ``epsilons`` at the
    configuration's κ. Both on a log scale: F > 0 everywhere, F(0) = (ln 2)^ε / κ, and
    F ≈ e^(εκg) / κ for g ≪ 0. Right: β_j = c^j·β_0 over the horizon N, the smallest
    sequence with every g_j = c·β_j − β_{j+1} ≤ 0 (eq. 18), for c = 1 − δ (eq. 18 as
    printed) and c = δ (Definition 1, eq. 15).

    Parameters
    ----------
    config : the ``barrier`` (δ, κ, ε) and ``nmpc.horizon`` (N) to draw; default
        :class:`~paper_repro.config.Config`.
    kappas : κ > 0 of the left panel, 1/m².  epsilons : ε ≥ 1 of the middle panel.
    g_range : (g_min, g_max), m², the abscissa of both penalty panels.
    n : points per curve.  floor : lower limit of the log axes of F, m².

    Returns
    -------
    matplotlib Figure.
    """
    config = config or Config()
    b = config.barrier
    g = np.linspace(*g_range, n)
    fig, (ax_k, ax_e, ax_d) = plt.subplots(1, 3, figsize=(14, 4.0), constrained_layout=True)
    for kappa, color in zip(kappas, plt.rcParams["axes.prop_cycle"].by_key()["color"]):
        ax_k.semilogy(g, penalty_values(config, g, kappa=kappa), color=color,
                      label=f"κ = {kappa:g} 1/m²")
        ax_k.semilogy(g, kappa ** (b.epsilon - 1) * np.maximum(g, 0) ** b.epsilon, "--",
                      color=color, lw=0.9)
    ax_k.set_title(f"F(g), ε = {b.epsilon:g}; dashed: "
                   "$\\kappa^{\\epsilon-1}\\max(0,g)^\\epsilon$", fontsize="medium")
    for eps in epsilons:
        ax_e.semilogy(g, penalty_values(config, g, epsilon=eps), label=f"ε = {eps:g}")
    ax_e.set_title(f"F(g), κ = {b.kappa:g} 1/m²", fontsize="medium")
    for ax in (ax_k, ax_e):
        ax.axvline(0.0, color="0.6", lw=0.8)
        ax.set_ylim(bottom=floor)
        ax.set_xlabel("g [m²]  (g ≤ 0: the CBF condition holds)")
        ax.set_ylabel("F(g) [m²]")
        ax.legend(fontsize="small", loc="upper left")
        ax.grid(alpha=0.3, which="major")

    j = np.arange(config.nmpc.horizon + 1)
    for form, style in (("printed", "o-"), ("definition", "s-")):
        decay = _ocp(config, form=form).decay
        label = "c = 1 − δ (printed)" if form == "printed" else "c = δ (Definition 1)"
        ax_d.semilogy(j, decay ** j, style, ms=3, label=f"{label} = {decay:.2f}")
    ax_d.set_ylim(floor, 2.0)
    ax_d.set_xlabel("prediction step j")
    ax_d.set_ylabel("$\\beta_j / \\beta_0$, smallest allowed")
    ax_d.set_title(f"$\\beta_{{j+1}} \\geq c\\,\\beta_j$ ⇒ $\\beta_j \\geq c^j \\beta_0$ "
                   f"(δ = {b.delta:g}, N = {config.nmpc.horizon})", fontsize="medium")
    ax_d.legend(fontsize="small", loc="center right")
    ax_d.grid(alpha=0.3, which="major")
    return fig


def penalty_values(config: Config | None, g, **barrier) -> np.ndarray:
    """F(g) (eq. 19) as the :class:`~paper_repro.problem.ocp.OCP` computes it, for numbers.

    Parameters
    ----------
    config : the configuration (default :class:`~paper_repro.config.Config`).
    g : array of violations, m².
    barrier : fields of :class:`~paper_repro.config.BarrierParams` to replace (``kappa``,
        ``epsilon``, ...).

    Returns
    -------
    array of the shape of ``g``, m² (1/κ times a number).
    """
    g = np.asarray(g, float)
    values = _ocp(config or Config(), **barrier).penalty(g.ravel())
    return np.asarray(values, float).reshape(g.shape)


# --- helpers --------------------------------------------------------------------------------

def _ocp(config: Config, **barrier) -> OCP:
    """The problem's description with some barrier fields replaced (no solver is built)."""
    return OCP(dataclasses.replace(config, barrier=dataclasses.replace(config.barrier,
                                                                      **barrier)))

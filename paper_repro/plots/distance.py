"""Tutorial figures of the smoothed distance on a 2-D slice (eq. 8-13)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial import cKDTree

from paper_repro.plots.common import AXIS_LABELS, CLOUD_COLOR, axes_or_new, axes_row
from paper_repro.problem.distance import (
    CloudWeights,
    euclidean_distance,
    smooth_distance,
    smooth_projection,
)

# --- tutorial: the smoothed distance on a 2-D slice (eq. 8-13) ------------------------------

def slice_grid(extent, z: float, n: int):
    """Query points on the plane z = const: X, Y (n, n) and the points (n·n, 3), m.

    ``extent`` : (x_min, x_max, y_min, y_max), m.
    """
    x0, x1, y0, y1 = extent
    X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    return X, Y, np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, float(z))])


def plot_distance_slice(cloud, z: float, extent, eta: float, sigma: float, n: int = 200,
                        axes=None, levels=None):
    """D_{η,σ} (eq. 8) beside ½·d² on the plane z = const, same contour levels (m²).

    The Euclidean level sets have kinks where two parts of the cloud are equally near (the
    inside of a concave corner); those of D are smooth.
    """
    fig, axes = axes_row(axes, 2, figsize=(10, 4.2))
    X, Y, q = slice_grid(extent, z, n)
    values = (smooth_distance(q, cloud, eta, sigma).reshape(X.shape),
              euclidean_distance(q, cloud).reshape(X.shape))
    levels = levels if levels is not None else [0.125, 0.5, 1.0, 2.0, 4.0, 8.0]
    titles = (f"smoothed $D_{{\\eta,\\sigma}}$ (η = {eta:g} m, σ = {sigma:g} m)",
              "Euclidean $\\frac{1}{2}d^2$")
    for ax, v, title in zip(axes, values, titles):
        filled = ax.contourf(X, Y, v, levels=[0, *levels, v.max() + 1], cmap="Blues_r",
                             extend="neither")
        lines = ax.contour(X, Y, v, levels=levels, colors="black", linewidths=0.8)
        ax.clabel(lines, fmt="%g", fontsize="x-small")
        _slice_points(ax, cloud, z)
        ax.set_title(title, fontsize="medium")
        _slice_axes(ax, extent)
    fig.colorbar(filled, ax=list(axes), label="m²", shrink=0.9)
    return fig


def plot_eta_sigma(cloud, z: float, extent, etas=(0.1, 0.3, 0.6), sigmas=(0.8, 2.0, 100.0),
                   eta: float = 0.3, sigma: float = 0.8, n: int = 120, level: float = 1.0):
    """The level set D = ``level`` (m²) for several η (top row, σ fixed) and σ (bottom row,
    η fixed), each against the Euclidean ½d² = ``level`` (dashed).

    η (eq. 8) smooths the corners and, for a fixed level, pulls the set slightly outwards;
    σ (eq. 9) weights the points near the centroid: a small σ lowers the weight of the
    cloud's extremities, raising D there by up to η²·ln(V/W_j).
    """
    cols = max(len(etas), len(sigmas))
    fig, axes = plt.subplots(2, cols, figsize=(3.3 * cols, 6.2), squeeze=False,
                             constrained_layout=True)
    X, Y, q = slice_grid(extent, z, n)
    half_sq = euclidean_distance(q, cloud).reshape(X.shape)
    rows = ([(e, sigma) for e in etas], [(eta, s) for s in sigmas])
    for r, pairs in enumerate(rows):
        for c in range(cols):
            ax = axes[r, c]
            if c >= len(pairs):
                ax.set_visible(False)
                continue
            e, s = pairs[c]
            d = smooth_distance(q, cloud, e, s).reshape(X.shape)
            ax.contour(X, Y, half_sq, levels=[level], colors="gray", linestyles="--",
                       linewidths=1.0)
            ax.contourf(X, Y, d, levels=[0, level], colors=["tab:blue"], alpha=0.25)
            ax.contour(X, Y, d, levels=[level], colors="tab:blue", linewidths=1.4)
            _slice_points(ax, cloud, z)
            ax.set_title(f"η = {e:g} m, σ = {s:g} m", fontsize="medium")
            _slice_axes(ax, extent)
    fig.suptitle(f"level set D = {level:g} m² (blue) against ½d² = {level:g} m² (dashed)")
    return fig


def plot_gradient_field(cloud, z: float, extent, eta: float, sigma: float, n: int = 25,
                        axes=None):
    """Directions of ∇D = y − Π (eq. 13, smooth) and of ∇(½d²) = y − a* (nearest point a*).

    Arrows are unit vectors (in-plane part), coloured by the angle between the smooth and the
    Euclidean directions; the Euclidean field flips across the line where two parts of the
    cloud are equally near, the smooth one turns continuously.
    """
    fig, axes = axes_row(axes, 2, figsize=(10, 4.2))
    X, Y, q = slice_grid(extent, z, n)
    smooth = q - smooth_projection(q, cloud, eta, sigma)
    nearest = np.asarray(cloud)[cKDTree(cloud).query(q)[1]]
    euclid = q - nearest
    for ax, g, title in zip(axes, (smooth, euclid),
                            (f"$y - \\Pi_{{\\eta,\\sigma}}(y)$ (η = {eta:g} m, σ = {sigma:g} m)",
                             "$y - a^*(y)$, nearest point")):
        u = g[:, :2] / np.maximum(np.linalg.norm(g[:, :2], axis=1, keepdims=True), 1e-12)
        ax.quiver(X, Y, u[:, 0].reshape(X.shape), u[:, 1].reshape(X.shape), angles="xy",
                  scale_units="xy", scale=n / (extent[1] - extent[0]) * 1.3, width=0.004,
                  color="tab:blue")
        _slice_points(ax, cloud, z)
        ax.set_title(title, fontsize="medium")
        _slice_axes(ax, extent)
    return fig


def plot_half_squared_limit(cloud, z: float, extent, etas=None, sigma: float = 0.8,
                            n: int = 60, ax=None):
    """Why D → ½d² as η → 0: the gap D − ½d² on the slice against η, with its bound.

    D is a weighted soft-min of ½‖y − a_j‖², so  ½d² ≤ D ≤ ½d² + η²·ln(V/W_*)  (W_* the weight
    of the nearest point): the gap vanishes like η². The plot shows the largest and the
    median gap on the slice, and the bound η²·max_j ln(V/W_j).
    """
    fig, ax = axes_or_new(ax, figsize=(6, 3.8))
    etas = np.asarray(etas if etas is not None else np.geomspace(0.03, 1.0, 12), float)
    X, Y, q = slice_grid(extent, z, n)
    half_sq = euclidean_distance(q, cloud)
    weights = CloudWeights.from_cloud(cloud, sigma)
    worst_log_ratio = float(weights.log_volume - weights.log_weights.min())
    gaps = np.array([smooth_distance(q, weights, e, sigma) - half_sq for e in etas])
    ax.loglog(etas, gaps.max(axis=1), "o-", label="max over the slice")
    ax.loglog(etas, np.median(gaps, axis=1), "s-", label="median over the slice")
    ax.loglog(etas, etas**2 * worst_log_ratio, "k--",
              label="bound $\\eta^2 \\max_j \\ln(V/W_j)$")
    ax.set_xlabel("η [m]")
    ax.set_ylabel("$D_{\\eta,\\sigma} - \\frac{1}{2}d^2$ [m²]")
    ax.set_title(f"D tends to ½d² like η² (σ = {sigma:g} m)")
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3, which="both")
    return fig


# --- helpers --------------------------------------------------------------------------------

def slice_through(cloud, pad: float = 3.0):
    """A horizontal slice through the middle of a cloud: (z, extent), m.

    z is the mid-height of the cloud's bounding box; extent = (x_min, x_max, y_min, y_max) is
    its horizontal bounding box widened by ``pad``.
    """
    cloud = np.asarray(cloud, float)
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    extent = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
    return float((lo[2] + hi[2]) / 2), tuple(float(v) for v in extent)


def _slice_points(ax, cloud, z: float, slab: float = 0.5):
    """Cloud points within ``slab`` (m) of the plane, drawn as red dots."""
    cloud = np.asarray(cloud)
    near = np.abs(cloud[:, 2] - z) <= slab
    ax.scatter(cloud[near, 0], cloud[near, 1], s=6, color=CLOUD_COLOR, zorder=3, lw=0)


def _slice_axes(ax, extent):
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel(AXIS_LABELS[0])
    ax.set_ylabel(AXIS_LABELS[1])

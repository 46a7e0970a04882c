"""What every figure shares: colours, decimation of long runs, axes helpers,
:func:`save_figure` and :func:`show_figure`.

Each function takes a :class:`~paper_repro.sim.result.SimulationResult` (and the
:class:`~paper_repro.world.scene.Scene` it flew in, ``result.scene``) and returns the matplotlib
Figure; pass ``ax``/``axes`` to draw into an existing one. Long runs are decimated for drawing
(at most ``max_points`` per line) with a min/max envelope, so chattering keeps its visible
amplitude. :func:`save_figure` writes PDF (without a creation date, so byte-stable) and PNG;
:func:`show_figure` displays a saved PNG in a notebook.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

MAX_POINTS = 5000
"""Default cap on the points drawn per line (a full mission has ≈135,000 steps)."""

CLOUD_COLOR = "tab:red"
SPHERE_COLOR = "tab:blue"
AXIS_LABELS = ("x [m]", "y [m]", "z [m]")
LINESTYLES = ("-", "--", "-.", ":") * 4  # runs that coincide stay distinguishable


# --- saving ---------------------------------------------------------------------------------

def save_figure(fig, stem: str, directory, formats=("pdf", "png"), dpi: int = 150,
                close: bool = False, show: bool = False) -> list[Path]:
    """Write ``directory/stem.pdf`` and ``directory/stem.png``; returns the paths.

    The PDF carries no creation date (``CreationDate: None``), so saving the same figure twice
    gives the same bytes and regenerated figures only show up in git when they change.
    ``show``: display the saved PNG in the notebook that runs this (:func:`show_figure`) and
    close the figure, so the page shows the file itself, whatever matplotlib's backend.
    """
    if show and "png" not in formats:
        raise ValueError(f"show displays the PNG: formats must include 'png', got {formats!r}")
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = out / f"{stem}.{fmt}"
        if fmt == "pdf":
            fig.savefig(path, format="pdf", metadata={"CreationDate": None}, bbox_inches="tight")
        elif fmt == "png":
            fig.savefig(path, format="png", dpi=dpi, bbox_inches="tight")
        else:
            raise ValueError(f"format must be 'pdf' or 'png', got {fmt!r}")
        paths.append(path)
    if show:
        show_figure(stem, out)
    if close or show:
        plt.close(fig)
    return paths


def show_figure(stem: str, directory, fmt: str = "png") -> Path:
    """Display ``directory/stem.<fmt>`` (``"png"`` or ``"gif"``) in the notebook that runs
    this, as an image output; returns its path. Outside IPython nothing is displayed.

    A notebook shows a saved figure this way, e.g. one a study command drew from flights the
    notebook does not fly again.
    """
    if fmt not in ("png", "gif"):
        raise ValueError(f"fmt must be 'png' or 'gif', got {fmt!r}")
    path = Path(directory) / f"{stem}.{fmt}"
    if not path.is_file():
        raise ValueError(f"no figure {path}: the command that draws {stem!r} writes it")
    try:
        from IPython import get_ipython
        from IPython.display import Image, display
    except ImportError:  # no IPython: nothing to display into
        return path
    if get_ipython() is not None:
        display(Image(filename=str(path)))
    return path


def stride_indices(n: int, max_points: int = MAX_POINTS) -> np.ndarray:
    """Evenly spaced indices into a length-n sequence, at most ``max_points``, first and last
    included (for smooth curves such as the trajectory)."""
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max(2, max_points)).round().astype(int))


def envelope_indices(y, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices keeping the min and the max of y in each of ``max_points``/2 buckets.

    Unlike a stride, this keeps the envelope of a chattering signal: a 40 Hz oscillation
    stays visible at full amplitude after decimation.
    """
    y = np.asarray(y, float).ravel()
    n = len(y)
    if n <= max_points:
        return np.arange(n)
    buckets = max(1, max_points // 2)
    edges = np.linspace(0, n, buckets + 1).round().astype(int)
    keep = [0, n - 1]
    for a, b in zip(edges[:-1], edges[1:]):
        if b > a:
            seg = y[a:b]
            keep += [a + int(np.argmin(seg)), a + int(np.argmax(seg))]
    return np.unique(keep)


def axes_or_new(ax, figsize):
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, constrained_layout=True)
        return fig, ax
    return ax.figure, ax


def axes3d_or_new(ax):
    if ax is None:
        fig = plt.figure(figsize=(7.5, 6), constrained_layout=True)
        ax = fig.add_subplot(projection="3d")
        return fig, ax
    return ax.figure, ax


def axes_column(axes, n, figsize):
    if axes is None:
        fig, axes = plt.subplots(n, 1, figsize=figsize, sharex=True, constrained_layout=True)
        return fig, list(np.atleast_1d(axes))
    axes = list(np.atleast_1d(axes))
    if len(axes) != n:
        raise ValueError(f"axes must hold {n} Axes, got {len(axes)}")
    return axes[0].figure, axes


def axes_row(axes, n, figsize):
    if axes is None:
        fig, axes = plt.subplots(1, n, figsize=figsize, constrained_layout=True)
        return fig, list(np.atleast_1d(axes))
    axes = list(np.atleast_1d(axes))
    if len(axes) != n:
        raise ValueError(f"axes must hold {n} Axes, got {len(axes)}")
    return axes[0].figure, axes


def draw_sphere(ax, center, radius, alpha: float = 0.12, label=None):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, np.pi, 13))
    xs = center[0] + radius * np.cos(u) * np.sin(v)
    ys = center[1] + radius * np.sin(u) * np.sin(v)
    zs = center[2] + radius * np.cos(v)
    return ax.plot_surface(xs, ys, zs, color=SPHERE_COLOR, alpha=alpha, linewidth=0,
                           shade=False, label=label)

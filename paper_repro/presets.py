"""Named configurations: the printed set-up, and the one that reproduces the paper's clock.

``paper`` (the default everywhere) is :class:`~paper_repro.config.Config` as printed in
Section V. Under it the paper mission lasts ≈1,390 s of flight, where the paper's time axes
(Figs. 4–8) span 0–500 s. :mod:`paper_repro.analysis.clock` shows why (the terminal equality
x_N = x_a over N·h = 0.35 s makes the lateral approach an exponential with τ ≈ 155 s) and
which single reading of the printed numbers gives the paper's clock; the timeline study
(``python -m paper_repro study timeline``, notebook ``11_timeline``) flies the candidates.
``paper-timeline`` is the smallest departure from the printed parameters that brings the
obstacle mission within 10 % of 500 s and stays safe: the horizon N = 43 instead of 35 (see
:data:`PRESETS` and the README).

Why N = 43. The clock is set by the prediction span N·h (τ_lat ∝ (N·h)^−5 near the printed
point), so three single changes reach it; flown on the ``paper`` scene with its clouds:

* N = 43: 492.5 s (−1.5 %), min clearance 1.351 m. N = 42 gives 552.1 s (+10.4 %), outside
  the band and beyond the paper's 500 s axis: 43 is the smallest N that fits.
* h = 0.0118 s at N = 35: 517.8 s (+3.6 %), 1.343 m. It changes the model's step, which the
  paper never distinguishes from T_s, and adds a number the paper does not print.
* T × 2.66: 533.9 s (+6.8 %), 1.295 m. An unprinted factor on a printed weight, with no
  reading of "T = 1000" behind it, and the smallest clearance of the three.

N = 43 changes one printed integer, keeps the prediction model's step equal to the sampling
period as printed, and lands closest to 500 s.

Select one with ``--preset NAME`` (``run``, ``reproduce``, ``study``) or :func:`preset`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

from paper_repro.config import Config


@dataclass(frozen=True)
class Preset:
    """A named set-up.

    Attributes
    ----------
    name : what ``--preset`` accepts.
    description : one sentence: what differs from the printed set-up, and why.
    apply : ``Config -> Config``, the overrides (``dataclasses.replace``), applied to a base
        configuration so that other options (metric, solver, scene) are kept.
    """

    name: str
    description: str
    apply: Callable[[Config], Config]


def _printed(config: Config) -> Config:
    return config


def _paper_timeline(config: Config) -> Config:
    return dataclasses.replace(config, nmpc=dataclasses.replace(config.nmpc, horizon=43))


PRESETS: dict[str, Preset] = {
    "paper": Preset(
        "paper", "the parameters as printed in Section V (N = 35, T_s = 0.01 s, "
        "T = 1000·I); the mission lasts ≈1,390 s", _printed),
    "paper-timeline": Preset(
        "paper-timeline", "the printed parameters with the horizon N = 43 instead of 35 "
        "(N·T_s = 0.43 s): the smallest change of one printed number that brings the paper "
        "mission within 10 % of the paper's 500 s (notebook 11_timeline)", _paper_timeline),
}
"""Every preset by name; ``paper`` is the default."""

DEFAULT = "paper"
"""The preset used when none is named: the printed parameters."""


def preset(name: str = DEFAULT, base: Config | None = None) -> Config:
    """The configuration of preset ``name``.

    Parameters
    ----------
    name : a key of :data:`PRESETS`.
    base : configuration the preset's overrides are applied to (default :class:`Config`).

    Raises
    ------
    ValueError : ``name`` is not a preset (the message names the accepted ones).
    """
    check_name(name)
    return PRESETS[name].apply(base if base is not None else Config())


def check_name(name: str) -> str:
    """``name`` if it is a preset; otherwise ``ValueError`` naming the accepted names."""
    if not (isinstance(name, str) and name in PRESETS):
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {name!r}")
    return name

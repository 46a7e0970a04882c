"""The catalogue of studies: each is plain data, a list of run specs over random passages
(Monte Carlo, the eta sweep, sensor noise, the sensing window, moving obstacles, the clock,
the flights against RotorPy towards hardware)."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from paper_repro.config import PREDICTIONS, Config, GuideParams
from paper_repro.evidence.sets import STUDY_NOTEBOOKS  # noqa: F401 (each study's notebook)
from paper_repro.presets import (  # noqa: F401 (the moving study's design, a preset too)
    MOVING_APPROACH_TIME,
    MOVING_DESIGN,
    MOVING_PREDICTION_TS,
    moving_design,
    moving_design_controller,
)
from paper_repro.studies.runs import RunSpec
from paper_repro.validation import require_int
from paper_repro.world.lidar import NOISY_LIDAR
from paper_repro.world.local_map import MAP_VOXEL

PASSAGE_STEPS = 15_000
"""Step limit of a passage (150 s of flight): about three times the 40-60 s a passage takes, so
only a stall or a very long detour reaches it."""

QUICK_STEPS = 400
"""Step limit of a ``--quick`` study's runs (4 s of flight): exercises every part, proves
nothing."""


@dataclass(frozen=True)
class Study:
    """A named list of runs.

    Attributes
    ----------
    name : folder name of the study's output (``monte_carlo``).
    specs : the runs; names must be unique.
    description : one paragraph, stored in ``study.json``.
    """

    name: str
    specs: tuple
    description: str = ""

    def __post_init__(self):
        if not self.name or "/" in self.name:
            raise ValueError(f"name must be a non-empty folder name, got {self.name!r}")
        if not self.specs or not all(isinstance(s, RunSpec) for s in self.specs):
            raise ValueError("specs must be a non-empty sequence of RunSpec")
        names = [s.name for s in self.specs]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"specs must have unique names, repeated: {dup[:5]}")
        object.__setattr__(self, "specs", tuple(self.specs))


# --- the studies ----------------------------------------------------------------------------

def passage_config(base: Config | None = None, seed: int = 0, max_steps: int = PASSAGE_STEPS,
                   scenario: str = "random", **distance) -> Config:
    """``base`` flying a passage through the random scene of ``seed`` (``scenario``:
    ``"random"``, or ``"random-crossing"`` whose regions move across the line); ``distance``
    overrides fields of :class:`~paper_repro.config.DistanceParams` (``metric``, ``eta``,
    ``sigma``)."""
    base = base or Config()
    return dataclasses.replace(
        base, distance=dataclasses.replace(base.distance, **distance),
        simulation=dataclasses.replace(base.simulation, scenario=scenario, kind="passage",
                                       seed=int(seed), max_steps=int(max_steps)))


def passage_spec(seed: int, metric: str = "smooth", eta: float | None = None,
                 sigma: float | None = None, max_steps: int = PASSAGE_STEPS,
                 base: Config | None = None, tag: str = "", scenario: str = "random"
                 ) -> RunSpec:
    """A passage through random scene ``seed``; the name says what differs from ``base`` (and
    ``tag`` anything else a study varies), so the same flight has the same name (and cache
    folder) in every study that asks for it."""
    base = base or Config()
    over = {"metric": metric}
    if metric == "smooth":
        over.update(eta=base.distance.eta if eta is None else eta,
                    sigma=base.distance.sigma if sigma is None else sigma)
    cfg = passage_config(base, seed, max_steps, scenario, **over)
    name = (f"passage-smooth-eta{cfg.distance.eta:g}-sigma{cfg.distance.sigma:g}"
            if metric == "smooth" else f"passage-{metric}") + (f"-{tag}" if tag else "") + \
        f"-s{seed:03d}"
    labels = (("metric", metric),
              ("eta", cfg.distance.eta if metric == "smooth" else 0.0),
              ("sigma", cfg.distance.sigma if metric == "smooth" else float("nan")),
              ("scene_seed", seed))
    return RunSpec(name, cfg, max_steps, labels)


def monte_carlo(quick: bool = False, scenes: int | None = None,
                base: Config | None = None) -> Study:
    """The paper's claim over random scenes: ``scenes`` passages (100; 3 with ``quick``) ×
    {smoothed, Euclidean}, everything else as printed."""
    n = scenes if scenes is not None else (3 if quick else 100)
    require_int("scenes", n, 1)
    steps = QUICK_STEPS if quick else PASSAGE_STEPS
    specs = [passage_spec(seed, metric, max_steps=steps, base=base)
             for metric in ("smooth", "euclidean") for seed in range(n)]
    return Study("monte_carlo" + ("-quick" if quick else ""), tuple(specs),
                 f"{n} random passages x {{smooth, euclidean}}, printed parameters")


ETAS = (0.05, 0.1, 0.2, 0.3, 0.5, 0.8)
"""η values of :func:`eta_sweep`, m (the paper's 0.3 in the middle)."""

SIGMAS = (0.4, 0.8, 1.6)
"""σ values of :func:`eta_sweep`, m (the paper's 0.8 in the middle)."""


def eta_sweep(quick: bool = False, scenes: int | None = None, etas: Sequence[float] = ETAS,
              sigmas: Sequence[float] = SIGMAS, grid: bool = False,
              base: Config | None = None) -> Study:
    """η and σ over ``scenes`` random passages (20; 2 with ``quick``), plus the Euclidean
    baseline (the η → 0 limit) on the same scenes.

    By default one factor at a time about the printed point (η = 0.3 m, σ = 0.8 m): every η
    of ``etas`` at the printed σ, every σ of ``sigmas`` at the printed η (9 configurations with
    the baseline). ``grid=True`` flies the full η × σ grid (19).
    """
    n = scenes if scenes is not None else (2 if quick else 20)
    require_int("scenes", n, 1)
    base = base or Config()
    if quick:
        etas, sigmas = (0.1, 0.3), (0.8,)
    for name, values in (("etas", etas), ("sigmas", sigmas)):
        if not values or not all(math.isfinite(v) and v > 0 for v in values):
            raise ValueError(f"{name} must be a non-empty sequence of finite values > 0 (m), "
                             f"got {values!r}")
    eta0, sigma0 = base.distance.eta, base.distance.sigma
    pairs = ([(e, s) for s in sigmas for e in etas] if grid else
             [(e, sigma0) for e in etas] + [(eta0, s) for s in sigmas if s != sigma0])
    pairs = list(dict.fromkeys(pairs))  # unique, in order
    steps = QUICK_STEPS if quick else PASSAGE_STEPS
    specs = [passage_spec(seed, "smooth", eta, sigma, steps, base)
             for eta, sigma in pairs for seed in range(n)]
    specs += [passage_spec(seed, "euclidean", max_steps=steps, base=base) for seed in range(n)]
    return Study("eta_sweep" + ("-quick" if quick else ""), tuple(specs),
                 f"(eta, sigma) in {pairs} and the Euclidean baseline over {n} random "
                 "passages")




def with_map(config: Config) -> Config:
    """``config`` with the controller reading the local map (:data:`MAP_VOXEL`)."""
    return dataclasses.replace(config, sensor=dataclasses.replace(config.sensor,
                                                                  map_voxel=MAP_VOXEL))


def with_guide(config: Config) -> Config:
    """``config`` with the local map and the guide (``guide.planner = "grid"``, the defaults of
    :class:`~paper_repro.config.GuideParams`) handing the NMPC its set-points."""
    return dataclasses.replace(with_map(config), guide=GuideParams(planner="grid"))


def sensor_noise(quick: bool = False, scenes: int | None = None,
                 base: Config | None = None) -> Study:
    """Smooth against Euclidean with a perfect and a noisy LiDAR (:data:`NOISY_LIDAR`), and the
    noisy one read through the local map (``sensor`` label ``"noisy-map"``, :func:`with_map`),
    on ``scenes`` random passages (8; 2 with ``quick``; the perfect runs are those of
    :func:`monte_carlo`). The smoothed distance averages many points where the Euclidean one
    follows the nearest, so noise should widen the gap; the map should take the noise out."""
    n, base, steps = _passages(quick, scenes, 8, base)
    specs = []
    for level, tag in (("perfect", ""), ("noisy", "noisy"), ("noisy-map", "noisy-map")):
        for metric in ("smooth", "euclidean"):
            for seed in range(n):
                cfg = base if level == "perfect" else dataclasses.replace(
                    base, sensor=dataclasses.replace(NOISY_LIDAR, seed=seed))
                cfg = with_map(cfg) if level == "noisy-map" else cfg
                spec = passage_spec(seed, metric, max_steps=steps, base=cfg, tag=tag)
                specs.append(dataclasses.replace(spec, labels=spec.labels
                                                 + (("sensor", level),)))
    return Study("sensor_noise" + ("-quick" if quick else ""), tuple(specs),
                 f"smooth vs euclidean, perfect vs noisy LiDAR ({NOISY_LIDAR}) vs the noisy "
                 f"one through the local map ({MAP_VOXEL} m voxels), {n} passages")


GUIDANCE_ARMS = ("paper", "map", "map+guide")
"""The arms of :func:`guidance`: the paper's controller on the raw scan, the same controller
reading the local map, and the map with the guide handing it its set-points."""

def guidance(quick: bool = False, scenes: int | None = None,
             base: Config | None = None) -> Study:
    """The random passages of :func:`monte_carlo` (100; 2 with ``quick``) × the arms of
    :data:`GUIDANCE_ARMS` × both metrics (the paper arm is the Monte Carlo study's runs). Do a
    map and a guide take the paper's controller past the deadlocks of a local NMPC, and at
    what cost in flight time?"""
    n, base, steps = _passages(quick, scenes, 100, base)
    specs = []
    for arm, make, tag in (("paper", lambda c: c, ""), ("map", with_map, "map"),
                           ("map+guide", with_guide, "guide")):
        for metric in ("smooth", "euclidean"):
            for seed in range(n):
                spec = passage_spec(seed, metric, max_steps=steps, base=make(base), tag=tag)
                specs.append(dataclasses.replace(spec, labels=spec.labels + (("arm", arm),)))
    return Study("guidance" + ("-quick" if quick else ""), tuple(specs),
                 f"{n} random passages x {GUIDANCE_ARMS} x both metrics, printed parameters")


SENSING_WINDOWS = (0.0, 0.5, 1.0)
"""Widths w (m) of the smooth sensing window flown by :func:`sensing_window` (0: the paper's
hard cut-off at r_s = 3 m)."""


def sensing_window(quick: bool = False, scenes: int | None = None,
                   base: Config | None = None) -> Study:
    """The smooth metric with the sensing window of each width in :data:`SENSING_WINDOWS`, on
    ``scenes`` random passages (12; 2 with ``quick``; w = 0 are the runs of
    :func:`monte_carlo`). Do thrust steps at changes of the visible set disappear, and at what
    cost in clearance and completion?"""
    n, base, steps = _passages(quick, scenes, 12, base)
    specs = []
    for width in SENSING_WINDOWS:
        cfg = dataclasses.replace(base, distance=dataclasses.replace(base.distance,
                                                                     window=width))
        for seed in range(n):
            spec = passage_spec(seed, "smooth", max_steps=steps, base=cfg,
                                tag="" if width == 0 else f"w{width:g}")
            specs.append(dataclasses.replace(spec, labels=spec.labels + (("window_m", width),)))
    return Study("sensing_window" + ("-quick" if quick else ""), tuple(specs),
                 f"smooth metric, sensing window w in {SENSING_WINDOWS} m, {n} passages")


"""How the NMPC predicts a moving region (``NMPCParams.prediction``): not at all (the
paper), with its true velocity, or with a Kalman filter on its visible centroid."""


def moving_obstacles(quick: bool = False, scenes: int | None = None,
                     base: Config | None = None) -> Study:
    """Random crossings (``"random-crossing"``: every region moves across the line at
    0.5–1.5 m/s) × the predictions of :data:`PREDICTIONS` × {smoothed, Euclidean}, on
    ``scenes`` passages (50; 2 with ``quick``), with the paper's barrier (label ``barrier``
    ``"paper"``); then, with the predictions that hand the problem velocities (oracle,
    Kalman), the barrier of :data:`MOVING_DESIGN` for each metric (``"design"``). Does the
    static assumption collide where prediction does not, and does the design keep every
    crossing clear?

    Flown with the damped real-time iteration (``solver.line_search = True``): where a region
    moves at the vehicle the full Gauss-Newton steps fall into a period-2 oscillation of the
    thrusts between their bounds that the converged controller (IPOPT) does not show, and the
    damped iteration stays within millimetres of IPOPT there (``benchmarks/fidelity.py``).
    Its QPs go to the default ``"riccati-ipm"`` chain (``solver.qp_solver``): where a moving
    region sweeps the active set faster than the active-set method follows, the interior point
    on the same Riccati kernels solves them exactly within the sampling time, where the
    ``"riccati"`` chain's fallback (HPIPM) returns approximate solutions after up to 10 ms
    (``benchmarks/swept_pillar.py``)."""
    n, base, steps = _passages(quick, scenes, 50, base)
    base = dataclasses.replace(base, solver=dataclasses.replace(base.solver, line_search=True))
    specs = []
    for barrier, predictions in (("paper", PREDICTIONS), ("design", PREDICTIONS[1:])):
        for prediction in predictions:
            predicted = dataclasses.replace(base, nmpc=dataclasses.replace(
                base.nmpc, prediction=prediction))
            for metric in ("smooth", "euclidean"):
                tag = f"crossing-{prediction}" + ("-design" if barrier == "design" else "")
                for seed in range(n):
                    spec = passage_spec(seed, metric, max_steps=steps, base=predicted, tag=tag,
                                        scenario="random-crossing")
                    if barrier == "design":
                        spec = dataclasses.replace(spec, config=moving_design(spec.config,
                                                                              metric))
                    specs.append(dataclasses.replace(spec, labels=spec.labels + (
                        ("prediction", prediction), ("barrier", barrier))))
    return Study("moving_obstacles" + ("-quick" if quick else ""), tuple(specs),
                 f"random crossings, prediction in {PREDICTIONS} x both metrics, {n} passages; "
                 f"the design barriers {MOVING_DESIGN} with oracle and kalman")


def timeline_flights(quick: bool = False, scenes: int | None = None,
                     base: Config | None = None) -> Study:
    """The paper mission under each reading of the printed set-up that could set its clock
    (:func:`timeline_study`); ``scenes`` does not apply."""
    if scenes is not None:
        raise ValueError("scenes does not apply to the timeline study (it flies the paper "
                         "mission)")
    return timeline_study(quick=quick, base=base)


# --- towards hardware: the controller against RotorPy, with what its model leaves out ------

HARDWARE_STEPS = 8_000
"""Step limit of a passage against RotorPy (80 s of flight). A passage takes about 50 s; a
RotorPy step costs about five times a solve, so a passage not through in 80 s is ended and
counted as not completed (``step_limit``) rather than flown to 150 s."""

AIR = {"rotor_drag": 1e-4, "parasitic_drag": (0.01, 0.01, 0.01)}
"""The drag the wind acts through in the wind cells: a rotor drag between the x500's
values and a body drag of about 1e-2 (``PlantParams``)."""

GUST_CLEARANCE = 2.0
"""m, the gust cells' gust starts when the vehicle first comes this close to a cloud point
(``PlantParams.gust_clearance``), so that the gust (0.75 s, ``gust_duration``) meets the
closest approach."""

EFFECTS: dict[str, tuple[tuple[float, str, dict], ...]] = {
    "motor_lag": tuple((tau, f"{tau * 1e3:g} ms", {"motor_lag": tau})
                       for tau in (0.0125, 0.025, 0.05, 0.07)),
    "rotor_drag": tuple((k, f"{k:g}", {"rotor_drag": k}) for k in (8e-5, 2.6e-4)),
    "thrust": ((0.9, "-10 %", {"thrust_scale": 0.9}), (1.1, "+10 %", {"thrust_scale": 1.1})),
    "mass": ((1.1, "+10 %", {"mass_scale": 1.1}),),
    "com_offset": tuple((d, f"{d * 100:g} cm", {"com_offset": (d, 0.0, 0.0)})
                        for d in (0.01, 0.02)),
    "wind": tuple((w, f"{w:g} m/s", {"wind": (0.0, w, 0.0), "turbulence": "light", **AIR})
                  for w in (3.0, 6.0)),
    "gust": tuple((g, f"{g:g} m/s", {"gust": (0.0, g, 0.0), "gust_clearance": GUST_CLEARANCE,
                                      **AIR})
                  for g in (2.0, 4.0)),
    "estimation": ((1.0, "mocap", {"estimation": "mocap"}), (2.0, "vio", {"estimation": "vio"})),
    "delay": tuple((d, f"{d} step" + "s" * (d > 1), {"delay_steps": d}) for d in (1, 2)),
}
"""Each effect of ``PlantParams`` at each level, alone: (level, its name, the settings).
Magnitudes for a 2.2 kg quadrotor: motor lags of PX4's simulators (12.5-50 ms) and fitted
x500 thrust lags (up to 70 ms); the x500's rotor drag; ±10 % thrust, +10 % mass and a centre
of mass 1-2 cm off; a mean wind across the +y axis with light Dryden turbulence; a 1-cosine
gust of 2-4 m/s timed by :data:`GUST_CLEARANCE`; the
estimates of :data:`~paper_repro.config.ESTIMATES` (level 1 motion capture, 2 visual-inertial)
and a computation delay of 1-2 steps. The levels of an effect rise with its severity."""

COMBINED: dict[str, dict] = {
    "light": {"motor_lag": 0.025, "rotor_drag": 8e-5, "parasitic_drag": (0.01, 0.01, 0.01),
              "thrust_scale": 0.95, "mass_scale": 1.05, "wind": (0.0, 3.0, 0.0),
              "turbulence": "light", "estimation": "mocap", "delay_steps": 1},
    "moderate": {"motor_lag": 0.05, "rotor_drag": 2.6e-4, "parasitic_drag": (0.01, 0.01, 0.01),
                 "thrust_scale": 0.9, "mass_scale": 1.1, "com_offset": (0.01, 0.0, 0.0),
                 "wind": (0.0, 6.0, 0.0), "turbulence": "moderate", "estimation": "vio",
                 "delay_steps": 2},
}
"""Every effect at once, at a light and at a moderate level (``PlantParams`` settings)."""

HOVER_THRUST_TIME = 2.0
"""s, the time constant of the hover-thrust remedy (``PlantParams.hover_thrust_time``)."""

ESTIMATE_FILTER_TIME = 0.1
"""s, the time constant of the estimate-filter remedy (``PlantParams.estimate_filter_time``).
On three passages of each estimate, 50 / 100 / 200 ms took the smoothed thrusts' median share
of power above 5 Hz from 0.92 to 0.47 / 0.24 / 0.09 with the motion-capture estimate, the
closest approach unchanged; with the visual-inertial estimate no time constant helped."""

REMEDIES: dict[str, Callable[[dict], dict]] = {
    "compensated": lambda effect: {"compensate_latency": True},
    "hover thrust": lambda effect: {"hover_thrust_time": HOVER_THRUST_TIME},
    "lag compensated": lambda effect: {"motor_lag_compensation": effect["motor_lag"]},
    "filtered": lambda effect: {"estimate_filter_time": ESTIMATE_FILTER_TIME},
}
"""Each remedy by name (the ``remedy`` column): the ``PlantParams`` settings that apply it,
given the cell's own settings. ``compensated`` predicts the measured state over the latencies
with the nominal model; ``hover thrust`` scales the thrusts by the thrust the vehicle is
learnt to lack; ``lag compensated`` sends each thrust with the lead that inverts the rotors'
lag, for its time constant as identified (the cell's ``motor_lag``); ``filtered`` smooths the
noisy estimate with the nominal model (:data:`ESTIMATE_FILTER_TIME`)."""

EVERY_REMEDY = ("compensated", "hover thrust", "lag compensated")
"""The remedies of ``"all"``: those that invert a known model (the latencies, the thrust the
vehicle lacks, the rotors' lag). The estimate filter trades a lag for less noise, so it is
flown apart, added to them (``"all + filtered"``)."""

REMEDIED = {"estimation": ("compensated", "filtered"), "delay": ("compensated",),
            "thrust": ("hover thrust",), "mass": ("hover thrust",),
            "motor_lag": ("lag compensated",)}
"""The effects flown again with each of their remedies (:data:`REMEDIES`): the latencies,
which the nominal model can predict over; the estimate's noise, which it can filter; a vehicle
weaker or heavier than the nominal one; and rotors that lag."""


def with_remedy(effect: dict, remedy: str) -> dict:
    """The ``PlantParams`` settings of the cell ``effect`` with ``remedy``: ``"none"``, a name
    of :data:`REMEDIES`, ``"all"`` (each of :data:`EVERY_REMEDY` that applies to ``effect``),
    or names joined by ``" + "``."""
    if remedy == "none":
        return dict(effect)
    names = [n for part in remedy.split(" + ")
             for n in (EVERY_REMEDY if part == "all" else (part,))]
    unknown = [n for n in names if n not in REMEDIES]
    if unknown:
        raise ValueError(f"remedy: {unknown[0]!r} is not one of {sorted(REMEDIES)}, 'all' "
                         "or 'none'")
    names = [n for n in names if n != "lag compensated" or "motor_lag" in effect]
    return {**effect, **{k: v for n in names for k, v in REMEDIES[n](effect).items()}}


def hardware_spec(seed: int, metric: str, changes: dict, tag: str, steps: int,
                  base: Config, labels: tuple) -> RunSpec:
    """A random passage flown against RotorPy with the ``PlantParams`` settings ``changes``;
    the turbulence and the estimate's noise are drawn from the scene's seed, the same for both
    metrics."""
    plant = dataclasses.replace(base.plant, simulator="rotorpy", seed=seed, **changes)
    spec = passage_spec(seed, metric, max_steps=steps, base=dataclasses.replace(
        base, plant=plant), tag=f"rotorpy-{tag}" if tag else "rotorpy")
    return dataclasses.replace(spec, labels=spec.labels + labels)


HARDWARE_GROUPS = {"hardware_vehicle": ("motor_lag", "rotor_drag", "thrust", "mass",
                                         "com_offset"),
                   "hardware_air_latency": ("wind", "gust", "estimation", "delay")}
"""The effects of :data:`EFFECTS` by study: what the vehicle is (its motors, drag and
parameters), and what it flies in and through (the air, the estimate, the delay). Each study
also flies the baseline it is paired with, and lands on its own (about 1,200 passages each)."""


def hardware(group: str, quick: bool = False, scenes: int | None = None,
             base: Config | None = None) -> Study:
    """Towards hardware, one effect at a time: ``scenes`` random passages (50; 1 with
    ``quick``) × both metrics against RotorPy, with every effect off (``effect`` ``"none"``,
    the baseline the cells are paired with) and with each effect of the study ``group`` of
    :data:`HARDWARE_GROUPS` alone at each level of :data:`EFFECTS`; the latencies
    and the vehicle's thrust and mass (:data:`REMEDIED`) once more with their remedy (the
    ``remedy`` column). What breaks first, and does the smoothed metric keep its smooth
    thrusts?"""
    n, base, steps = _passages(quick, scenes, 50, base)
    steps = QUICK_STEPS if quick else HARDWARE_STEPS
    cells = [("none", 0.0, "off", {}, "none")]
    for effect in HARDWARE_GROUPS[group]:
        for level, name, changes in EFFECTS[effect]:
            cells.append((effect, level, name, changes, "none"))
            cells += [(effect, level, name, with_remedy(changes, remedy), remedy)
                      for remedy in REMEDIED.get(effect, ())]
    specs = [hardware_spec(seed, metric, changes,
                           "" if effect == "none" else
                           f"{effect}-{level:g}" + _remedy_tag(remedy),
                           steps, base, (("effect", effect), ("level", level),
                                         ("level_name", name), ("remedy", remedy)))
             for effect, level, name, changes, remedy in cells
             for metric in ("smooth", "euclidean") for seed in range(n)]
    return Study(group + ("-quick" if quick else ""), tuple(specs),
                 f"{n} random passages x both metrics against RotorPy: every effect off, "
                 f"each of {HARDWARE_GROUPS[group]} alone per level"
                 + "".join(f", {effect} with the remedy {remedy!r}"
                           for effect in HARDWARE_GROUPS[group]
                           for remedy in REMEDIED.get(effect, ())))


def _remedy_tag(remedy: str) -> str:
    """The run name's suffix of a remedy: ``""`` for none, else its name hyphenated."""
    return "" if remedy == "none" else "-" + remedy.replace(" + ", "+").replace(" ", "-")


COMBINED_REMEDIES = ("none", "all", "all + filtered")
"""The remedies of every combined level: none; those that invert a known model
(:data:`EVERY_REMEDY`); and those with the estimate filter."""

HEADLINE = ("light", "all")
"""The combined cell flown on the most passages: every effect at its light level, with every
remedy that inverts a known model, as a vehicle would be flown. Without its remedies the light
level leaves the workspace within seconds (the latencies and the motor lag compound), so that
cell is not the headline."""


def hardware_combined(quick: bool = False, scenes: int | None = None,
                      base: Config | None = None, others: int = 50) -> Study:
    """Towards hardware, every effect at once: at each level of :data:`COMBINED`, with each
    remedy of :data:`COMBINED_REMEDIES` (the ``remedy`` column), both metrics against
    RotorPy. The :data:`HEADLINE` cell flies ``scenes`` random passages (300; 2 with
    ``quick``), every other cell the first ``others`` of them.
    Zero collisions in 300 passages bound the rate below 1 % with one-sided 95 % confidence
    (the rule of three; the two-sided Clopper–Pearson interval of the tables ends at 1.2 %)."""
    n, base, _ = _passages(quick, scenes, 300, base)
    require_int("others", others, 1)
    steps = QUICK_STEPS if quick else HARDWARE_STEPS
    specs = [hardware_spec(seed, metric, with_remedy(changes, remedy),
                           f"{level}" + _remedy_tag(remedy), steps, base,
                           (("effect", "combined"), ("level", float(i + 1)),
                            ("level_name", level), ("remedy", remedy)))
             for i, (level, changes) in enumerate(COMBINED.items())
             for remedy in COMBINED_REMEDIES
             for metric in ("smooth", "euclidean")
             for seed in range(n if (level, remedy) == HEADLINE else min(n, others))]
    return Study("hardware_combined" + ("-quick" if quick else ""), tuple(specs),
                 f"{n} random passages x both metrics against RotorPy, every effect at once at "
                 f"the level {HEADLINE[0]!r} with every remedy; {min(n, others)} of them at "
                 f"each level of {tuple(COMBINED)} with the remedies {COMBINED_REMEDIES}")


STUDIES: dict[str, Callable[..., Study]] = {"monte_carlo": monte_carlo, "eta_sweep": eta_sweep,
                                            "sensor_noise": sensor_noise,
                                            "sensing_window": sensing_window,
                                            "moving_obstacles": moving_obstacles,
                                            "timeline": timeline_flights,
                                            "guidance": guidance,
                                            **{g: functools.partial(hardware, g)
                                               for g in HARDWARE_GROUPS},
                                            "hardware_combined": hardware_combined}
"""The studies ``python -m paper_repro study NAME`` knows."""


# --- the timeline study: the paper mission per reading of the clock ------------------------

CANDIDATES: dict[str, dict] = {
    "printed": {},
    "N = 42": {"horizon": 42},
    "N = 43": {"horizon": 43},
    "T × 2.66": {"t": (2660.0, 2660.0, 2660.0)},
    "h = 0.0118 s": {"prediction_ts": 0.0118},
}
"""Readings of the printed set-up flown by :func:`timeline_study`: label → overrides of
:class:`~paper_repro.config.NMPCParams`. Each is the single change that the linear loop
(:func:`predicted_mission_time`) puts closest to 500 s in its own parameter."""

TIMELINE_QUICK_STEPS = 300
"""Step limit of a quick timeline study (3 s of flight: what CI flies; it proves nothing about
the clock, only that every part runs)."""


def candidate_config(label: str, base: Config | None = None) -> Config:
    """``base`` (default :class:`Config`) with the overrides of ``CANDIDATES[label]``."""
    if label not in CANDIDATES:
        raise ValueError(f"label must be one of {sorted(CANDIDATES)}, got {label!r}")
    base = base or Config()
    return dataclasses.replace(base, nmpc=dataclasses.replace(base.nmpc, **CANDIDATES[label]))


def timeline_study(quick: bool = False, max_steps: int | None = None,
                   labels=None, base: Config | None = None):
    """The paper mission (``paper`` scene, obstacles, smoothed distance) under each candidate.

    Parameters
    ----------
    quick : fly :data:`TIMELINE_QUICK_STEPS` steps per run (the start of the mission only).
    max_steps : explicit step limit (default: the config's, 200,000 = 2,000 s, i.e. the whole
        mission under every candidate).
    labels : which of :data:`CANDIDATES` (default: all).
    base : configuration the candidates change (default :class:`Config`, the printed one).

    Returns
    -------
    :class:`~paper_repro.studies.catalogue.Study` named ``timeline`` (``timeline-quick``). The
    printed
    candidate's run is named ``paper-smooth``, as in ``reproduce``, so the two share its cache
    folder when they share a cache root.
    """

    from paper_repro.studies.runs import RunSpec

    base = base or Config()
    steps = max_steps if max_steps is not None else (
        TIMELINE_QUICK_STEPS if quick else base.simulation.max_steps)
    specs = []
    for label in labels if labels is not None else CANDIDATES:
        cfg = candidate_config(label, base)
        cfg = dataclasses.replace(cfg, simulation=dataclasses.replace(
            cfg.simulation, scenario="paper", kind="mission", max_steps=steps))
        p = cfg.nmpc
        slug = "".join(c for c in label.replace(".", "p") if c.isalnum())
        name = "paper-smooth" if label == "printed" else f"timeline-{slug}"
        specs.append(RunSpec(name, cfg, steps, (
            ("candidate", label), ("horizon", p.horizon), ("t_weight", p.t[0]),
            ("prediction_ts", p.prediction_step))))
    return Study("timeline" + ("-quick" if quick else ""), tuple(specs),
                 "the paper mission under readings of the printed set-up (issue 12)")


def make_study(name: str, quick: bool = False, base: Config | None = None,
               scenes: int | None = None) -> Study:
    """The study of :data:`STUDIES` called ``name``, its runs built on ``base`` (default
    :class:`Config`, e.g. a :func:`paper_repro.presets.preset`), over ``scenes`` random
    passages (default: the study's own)."""
    if name not in STUDIES:
        raise ValueError(f"study must be one of {sorted(STUDIES)}, got {name!r}")
    return STUDIES[name](quick=quick, base=base, scenes=scenes)


STUDY_NOTEBOOK_QUICK = {"sensing_window": {"mission": "encounter", "mission_steps": 3000},
                        "moving_obstacles": {"crossing_steps": 1500}, "timeline": {"quick": True},
                        "guidance": {"scene_steps": 400},
                        "hardware_combined": {"passage_steps": 400}}
"""Notebook parameters of a ``--quick`` study beyond its table (notebook 15 also flies one
mission with and without the window: the encounter's first 30 s instead of the paper's;
notebook 16 flies the crossing scene with each prediction: its first 15 s, past the meeting,
instead of the whole passage; notebook 11 sweeps fewer values per lever; notebook 17 flies its
deadlock scene's first 4 s; notebook 18 flies the first 4 s of the passages it draws)."""


def _passages(quick: bool, scenes: int | None, default: int, base: Config | None):
    """(number of scenes, base config, steps per passage) of a passage study: ``default``
    scenes, 2 with ``quick`` (and the short quick passages), unless ``scenes`` says."""
    n = scenes if scenes is not None else (2 if quick else default)
    require_int("scenes", n, 1)
    return n, base or Config(), QUICK_STEPS if quick else PASSAGE_STEPS



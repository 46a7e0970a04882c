"""The named scenes: the paper's mission, the encounter, and the moving crossing and oncoming
scenes; :func:`make_scene` builds any of them (and random scenes) by name."""

from __future__ import annotations

import dataclasses

from paper_repro.world.motion import Motion
from paper_repro.world.scene import Region, Scene
from paper_repro.world.shapes import Box, Cylinder, Difference, Union

SCENARIOS = ("paper", "encounter", "random", "crossing", "oncoming", "random-crossing")
"""The names :func:`make_scene` knows (``SimulationParams.scenario``)."""


def make_scene(name: str, seed: int = 7, approach_time: float = 150.0) -> Scene:
    """The named scene: ``"paper"`` (Section V mission), ``"encounter"`` (one region, short),
    ``"random"`` (:func:`paper_repro.world.random_scenes.random_scene` of ``seed``: a seeded field
    of regions across a straight flight, with a finish line for passages), or a scene whose
    regions move: ``"crossing"`` (:func:`crossing_scene`), ``"oncoming"``
    (:func:`oncoming_scene`) and ``"random-crossing"`` (the ``"random"`` field of ``seed``,
    each region crossing the flight line, ``random_scene(seed, moving=True)``, its crossings
    timed to a UAV approaching as e^{−t/``approach_time``}, s; a pace other than the default
    150 s is named ``f"random-crossing-{seed}@{approach_time:g}s"``)."""
    from paper_repro.world.random_scenes import RandomSceneParams, random_scene

    if name not in SCENARIOS:
        raise ValueError(f"scenario must be one of {SCENARIOS}, got {name!r}")
    if approach_time != 150.0:
        if name != "random-crossing":
            raise ValueError(f"approach_time times the crossings of 'random-crossing' only; "
                             f"{name!r} takes the default 150 s, got {approach_time!r}")
        scene = random_scene(seed, RandomSceneParams(approach_time=approach_time), moving=True)
        return dataclasses.replace(scene, name=f"{scene.name}@{approach_time:g}s")
    builders = {"paper": paper_scene, "encounter": encounter_scene, "random": random_scene,
                "crossing": crossing_scene, "oncoming": oncoming_scene,
                "random-crossing": lambda s: random_scene(s, moving=True)}
    return builders[name](seed)


def mission_scene(sim) -> Scene:
    """The scene a mission flies: ``sim`` (a :class:`~paper_repro.config.SimulationParams`)
    names it by its scenario, seed and, for crossings, their pace (``approach_time``)."""
    return make_scene(sim.scenario, sim.seed, sim.approach_time)


def paper_scene(seed: int = 7) -> Scene:
    """Section V: start [22, −22, 0], targets [−12, 18, 11] then [−21, 18, 0].

    The paper does not give its regions, only that they lie across the flight (Figs. 1-3).
    Under the printed weights the UAV first climbs to the target height and then flies the
    straight line in the horizontal plane, so the regions straddle that path at flight level,
    each offset so that the straight path cuts its edge by about half a metre:

    * ``tower``: a 16 m tall box a quarter of the way along the first leg;
    * ``L-wall``: a nonconvex L of two 1 m thick walls, half-way along the first leg;
    * ``U-channel``: a floating box with a channel cut into its far side (nonconvex);
    * ``column``: a cylinder on the descent of the second leg.
    """
    regions = (
        Region("tower", Box((14.0, -11.55, 8.0), (2.0, 2.0, 16.0))),
        Region("L-wall", Union((Box((5.5, -1.0, 11.0), (5.0, 1.0, 5.0)),
                                Box((3.5, 1.0, 11.0), (1.0, 5.0, 5.0))))),
        Region("U-channel", Difference(Box((-3.83, 9.78, 11.0), (3.0, 3.0, 4.0)),
                                        Box((-3.83, 10.55, 11.0), (1.6, 1.5, 2.4)))),
        Region("column", Cylinder((-16.5, 19.5, 0.0), 1.2, 12.0)),
    )
    return Scene("paper", regions, (22.0, -22.0, 0.0), ((-12.0, 18.0, 11.0), (-21.0, 18.0, 0.0)),
                 seed)


def encounter_scene(seed: int = 7) -> Scene:
    """A short flight past one nonconvex region (an L-shaped corner) for tests and benchmarks.

    The UAV starts at [−20, 0, 2], about 3 m before the corner, with its target 40 m away so
    that it cruises at the speed of the paper's mission (≈0.27 m/s: under the printed weights
    the speed is about the distance to the target over 155 s). The straight line to the target
    passes 0.9 m from the corner, inside the safety margin, so the barrier must bend the path
    around the near arm and then along the second arm; the near arm is passed in about 1,500
    steps and the whole region in about 2,500.
    """
    x0 = -20.0
    regions = (
        Region("corner", Union((Box((x0 + 3.5, 2.15, 2.0), (1.0, 2.5, 3.0)),
                                Box((x0 + 5.0, 1.4, 2.0), (2.0, 1.0, 3.0))))),
    )
    return Scene("encounter", regions, (x0, 0.0, 2.0), ((x0 + 40.0, 0.0, 2.0),), seed)


CROSSING_SPEED = 1.0
"""m/s, speed of the region of the ``crossing`` scene across the flight line."""

ONCOMING_SPEED = 0.5
"""m/s, speed of the region of the ``oncoming`` scene along the flight line, towards the UAV."""

MEETING_TIME = 8.0
"""s, when the UAV, flying straight, meets the moving region of ``crossing`` and ``oncoming``."""


def crossing_scene(seed: int = 7) -> Scene:
    """A 2 × 2 × 3 m box that crosses the UAV's straight path at 1.0 m/s, for moving obstacles.

    The UAV starts at rest at [−20, 0, 2] with its target 40 m ahead, [20, 0, 2], as in the
    encounter: it cruises at ≈0.25 m/s (about the distance to the target over 155 s; flying
    straight it is at x ≈ −18.0 m at t = 8 s, after dipping to z ≈ 1.3 m). The box (its
    points at t = 0 are the stored cloud) is centred at [−18, −8, 2] at t = 0 and moves along
    +y at ``CROSSING_SPEED``, so that its centre is on the path at x = −18 at t =
    ``MEETING_TIME`` = 8 s, just when the UAV gets there: flown straight (no avoidance, or an
    avoidance that takes the box as static) the two meet. The box covers the path between
    t = 7 and 9 s; it comes within the 3 m LiDAR range of the UAV at t ≈ 4 s. The finish line
    of a passage is 2 m past the box's far face, at x = −15.
    """
    x0, xc = -20.0, -18.0
    t_meet = MEETING_TIME
    region = Region("crossing-box", Box((xc, -CROSSING_SPEED * t_meet, 2.0), (2.0, 2.0, 3.0)))
    return Scene("crossing", (region,), (x0, 0.0, 2.0), ((x0 + 40.0, 0.0, 2.0),), seed,
                 ((xc + 3.0, 0.0, 2.0), (1.0, 0.0, 0.0)),
                 motions=(Motion.constant((0.0, CROSSING_SPEED, 0.0)),))


def oncoming_scene(seed: int = 7) -> Scene:
    """A 2 × 2 × 3 m box on the UAV's path that comes towards it at 0.5 m/s.

    Start [−20, 0, 2] and target [20, 0, 2], as :func:`crossing_scene`. The box (its points
    at t = 0 are the stored cloud) is centred at [−13, 0, 2] at t = 0, its near face 6 m ahead
    of the UAV, and moves along −x at ``ONCOMING_SPEED`` for ever; with the UAV at ≈0.25 m/s
    they close at ≈0.75 m/s: the box comes within the 3 m LiDAR range at t ≈ 4 s and, flown
    straight, meets the UAV at t ≈ ``MEETING_TIME`` = 8 s, at x ≈ −18 m. The finish line of a
    passage is 2 m past the box's far face at that time, at x = −14: the UAV has to get round
    or over the box.
    """
    x0 = -20.0
    region = Region("oncoming-box", Box((-13.0, 0.0, 2.0), (2.0, 2.0, 3.0)))
    return Scene("oncoming", (region,), (x0, 0.0, 2.0), ((x0 + 40.0, 0.0, 2.0),), seed,
                 ((-14.0, 0.0, 2.0), (1.0, 0.0, 0.0)),
                 motions=(Motion.constant((-ONCOMING_SPEED, 0.0, 0.0)),))

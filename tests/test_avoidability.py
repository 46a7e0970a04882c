"""The avoidability check: a point mass with the quadrotor's bounds and full foresight.

It must find a passage where one plainly exists (a slow box, a static box on the line that
needs a detour), verify it against the true clouds every 10 ms, and find none where none
exists (a wall wider than the workspace sweeping over the start faster than the UAV flies)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from paper_repro import Config
from paper_repro.analysis.avoidability import (
    FINE_STEP,
    PointMassBounds,
    find_passage,
    passage_row,
)
from paper_repro.analysis.metrics import COLLISION_CLEARANCE
from paper_repro.world.motion import Motion
from paper_repro.world.scene import Region, Scene
from paper_repro.world.shapes import Box

START, FINISH = (-10.0, 0.0, 3.0), ((0.0, 0.0, 3.0), (1.0, 0.0, 0.0))


def _scene(boxes, motions=None):
    return Scene("avoidability-test", tuple(Region(f"box-{i}", b) for i, b in enumerate(boxes)),
                 START, ((10.0, 0.0, 3.0),), finish=FINISH, motions=motions)


def _true_clearance(scene, t, p):
    """Minimum distance from p(t) to every cloud where it is at t, by brute force."""
    return min(float(np.linalg.norm(np.concatenate(scene.clouds_at(float(s))) - q, axis=1).min())
               for s, q in zip(t, p, strict=True))


def test_the_bounds_are_the_quadrotors():
    b = PointMassBounds.of_quadrotor(Config())
    assert b.velocity_upper == (5.0, 5.0, 3.0) and b.velocity_lower == (-5.0, -5.0, -3.0)
    assert b.acceleration_upper[0] == pytest.approx(9.81 * math.tan(math.pi / 6))
    assert b.acceleration_upper[2] == pytest.approx(4 * 12 / 2.24 - 9.81)
    assert b.acceleration_lower[2] == pytest.approx(-9.81)


def test_a_slow_box_crossing_the_line_is_avoidable():
    """A 2 m box crossing the line at 0.5 m/s halfway: a passage exists, and the check's
    answer holds against the true clouds (brute force, every 10 ms up to the finish)."""
    scene = _scene([Box((-5.0, -4.0, 3.0), (2.0, 2.0, 2.0))],
                   (Motion.constant((0.0, 0.5, 0.0)),))
    passage = find_passage(scene, horizon=40.0)
    assert passage.avoidable and passage.clearance >= COLLISION_CLEARANCE
    upto = int(np.searchsorted(passage.t, passage.time)) + 1
    t, p = passage.t[:upto], passage.p[:upto]
    assert np.allclose(np.diff(t), FINE_STEP)
    assert (p[-1] - FINISH[0]) @ np.asarray(FINISH[1]) >= 0  # past the finish line
    assert np.allclose(p[0], START)
    assert _true_clearance(scene, t[::5], p[::5]) >= COLLISION_CLEARANCE - 1e-9
    assert np.all(np.abs(np.diff(p, axis=0)) <= np.array([5.0, 5.0, 3.0]) * FINE_STEP + 1e-6)
    row = passage_row(4, passage)
    assert row["avoidable"] and row["scene_seed"] == 4 and row["outcome"] == "avoidable"


def test_a_box_on_the_line_is_passed_round_after_constraints_are_added():
    """A static box straddling the straight line: the first solve goes through it; the added
    clearance constraints move the passage round it, verified against the cloud."""
    scene = _scene([Box((-5.0, 0.0, 3.0), (1.5, 3.0, 3.0))])
    passage = find_passage(scene, horizon=30.0, guesses=("straight-3",))
    rounds, constraints, worst, _ = passage.tries["straight-3"]
    assert passage.avoidable and rounds > 1 and constraints > 0
    assert worst >= COLLISION_CLEARANCE
    upto = int(np.searchsorted(passage.t, passage.time)) + 1
    assert _true_clearance(scene, passage.t[:upto:5], passage.p[:upto:5]) >= \
        COLLISION_CLEARANCE - 1e-9


def test_a_wall_sweeping_over_the_start_faster_than_the_uav_is_unavoidable():
    """A wall across the whole workspace (60 × 60 m, 1 m thick) behind the start, coming at
    8 m/s where the UAV flies at most 5 m/s: it catches the UAV wherever it goes."""
    wall = Box((-14.0, 0.0, 12.5), (1.0, 60.0, 30.0))
    scene = _scene([wall], (Motion.constant((8.0, 0.0, 0.0)),))
    passage = find_passage(scene, horizon=15.0, rounds=8)
    assert passage.outcome == "no_passage_found" and not passage.avoidable
    assert math.isnan(passage.clearance) and len(passage.tries) > 1


@pytest.mark.parametrize("kwargs, name", [
    (dict(horizon=0.0), "horizon"), (dict(horizon=10.0, dt=-1.0), "dt"),
    (dict(horizon=10.0, margin=-0.1), "margin"), (dict(horizon=10.0, rounds=0), "rounds"),
    (dict(horizon=10.0, guesses=("sideways",)), "guesses"),
    (dict(horizon=10.0, margin=True), "margin"), (dict(horizon=10.0, solid="yes"), "solid"),
])
def test_bad_arguments_are_refused_before_any_solve(kwargs, name):
    with pytest.raises(ValueError, match=name):
        find_passage(_scene([Box((-5.0, 0.0, 3.0), (1.0, 1.0, 1.0))]), **kwargs)


def test_a_scene_without_a_finish_line_is_refused():
    from paper_repro import make_scene

    with pytest.raises(ValueError, match="finish line"):
        find_passage(make_scene("paper"), horizon=10.0)

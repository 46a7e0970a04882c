"""Faults injected into closed loops: every run completes or ends with its named outcome, the
fault is recorded, the result saves and loads, and the UAV keeps clear of the clouds.

The flights are short stretches of the ``encounter`` scene (the UAV starts 3 m before an
L-shaped corner whose near arm it passes within the first 1,500 steps), long enough for the
barrier to act.
"""

import dataclasses
import warnings

import numpy as np
import pytest

from paper_repro import Config, NMPCParams, SimulationParams, make_scene
from paper_repro.analysis.metrics import COLLISION_CLEARANCE, summary_row
from paper_repro.sim.checks import SetupHazardWarning
from paper_repro.sim.loop import Faults, simulate
from paper_repro.sim.result import SimulationResult
from paper_repro.solvers.factory import make_controller
from paper_repro.world.scene import Region, Scene
from paper_repro.world.shapes import Box

ENCOUNTER = Config(simulation=SimulationParams(scenario="encounter"))
STEPS = 1600


@pytest.fixture(scope="module")
def controller():
    return make_controller(ENCOUNTER)


@pytest.fixture(scope="module")
def clean(controller):
    return simulate(ENCOUNTER, controller, max_steps=STEPS, progress=False)


def _fly(controller, faults=None, config=ENCOUNTER, steps=STEPS, scene=None):
    return simulate(config, controller, max_steps=steps, progress=False, faults=faults,
                    scene=scene)


def _saves_and_loads(result, tmp_path):
    loaded = SimulationResult.load(result.save(tmp_path / "run"))
    np.testing.assert_array_equal(loaded.x, result.x)
    assert loaded.outcome == result.outcome and list(loaded.status) == list(result.status)
    return loaded


# --- a clean slate for each flight ----------------------------------------------------------

def test_a_reused_controller_flies_bit_identically(controller, clean):
    """Between two flights of the same mission, the controller flies another one; the Riccati
    solver's warm-start state is reset, so the repeat is the same to the last bit."""
    other = dataclasses.replace(ENCOUNTER, simulation=dataclasses.replace(
        ENCOUNTER.simulation, seed=8))
    _fly(controller, config=other, steps=300)
    again = _fly(controller)
    np.testing.assert_array_equal(again.x, clean.x)
    np.testing.assert_array_equal(again.u, clean.u)
    fresh = _fly(make_controller(ENCOUNTER))
    np.testing.assert_array_equal(fresh.x, clean.x)


# --- sensor faults --------------------------------------------------------------------------

def test_nan_and_inf_points_are_dropped_counted_and_flown_around(controller, clean, tmp_path):
    def corrupt(k, visible):
        out = [v.copy() for v in visible]
        for v in out:
            if len(v) >= 2 and k % 3 == 0:
                v[0, 1], v[1, 2] = np.nan, np.inf
        return out

    result = _fly(controller, Faults(scan=corrupt))
    assert result.steps == STEPS and result.outcome == "step_limit"
    dropped = result.dropped_points
    assert dropped.sum() > 50 and set(np.unique(dropped)) <= {0, 2}
    assert np.all(dropped[np.arange(STEPS) % 3 != 0] == 0)
    assert result.failures == 0
    assert result.clearance.min() > 1.0  # the barrier still holds (clean run: see below)
    assert abs(result.clearance.min() - clean.clearance.min()) < 0.05
    assert summary_row(_saves_and_loads(result, tmp_path))["dropped_points"] == dropped.sum()


def test_a_dropped_scan_keeps_the_plan_and_the_clearance(controller, clean):
    """The LiDAR returns nothing for 20 steps near the corner: the controller flies on what
    it plans with no obstacle in view, then sees the corner again; no collision."""
    near = int(np.argmin(clean.clearance))
    window = range(max(near - 10, 0), near + 10)

    def blind(k, visible):
        return [v[:0] for v in visible] if k in window else visible

    result = _fly(controller, Faults(scan=blind))
    assert np.all(result.visible_points[list(window)] == 0)
    assert result.outcome == "step_limit" and result.failures == 0
    assert result.clearance.min() > COLLISION_CLEARANCE


def test_a_transient_nan_state_is_a_recorded_fault_and_the_flight_goes_on(controller, clean):
    def glitch(k, x):
        return np.full_like(x, np.nan) if 200 <= k < 210 else x

    result = _fly(controller, Faults(state=glitch))
    assert list(result.status[200:210]) == ["state_fault"] * 10
    assert not result.success[200:210].any() and result.success[210:].all()
    assert result.outcome == "step_limit" and np.all(np.isfinite(result.x))
    # The previous plan is applied meanwhile (it ends at rest): the UAV keeps clear.
    assert result.clearance.min() > 1.0
    assert np.all(np.isfinite(result.u))


def test_a_persistent_nan_state_ends_the_run_with_its_outcome_saved(controller, tmp_path):
    limit = 30
    cfg = dataclasses.replace(ENCOUNTER, simulation=dataclasses.replace(
        ENCOUNTER.simulation, fault_steps=limit))

    def dead(k, x):
        return np.full_like(x, np.nan) if k >= 100 else x

    result = _fly(controller, Faults(state=dead), config=cfg)
    assert result.outcome == "fault" and result.steps == 100 + limit + 1
    assert "state_fault" in result.meta["fault"]
    loaded = _saves_and_loads(result, tmp_path)
    assert summary_row(loaded)["outcome"] == "fault" and not summary_row(loaded)["completed"]


def test_a_solve_that_raises_is_recorded_not_fatal(controller):
    def bad_scan(k, visible):  # a region given as a (3, k) array: the solver refuses it
        return [v.T for v in visible] if k == 300 and len(visible[0]) else visible

    result = _fly(controller, Faults(scan=bad_scan), steps=400)
    faults = np.flatnonzero(result.status == "solve_error")
    assert len(faults) <= 1 and result.outcome == "step_limit"
    if len(faults):
        assert faults[0] == 300 and "visible" in result.meta["errors"][0]


# --- unsafe set-ups and overloaded sensors ----------------------------------------------------

def test_a_target_inside_a_cloud_is_warned_and_recorded_and_the_uav_stops_outside():
    encounter = make_scene("encounter")
    corner = encounter.clouds[0]
    target = tuple(corner[len(corner) // 2])
    scene = dataclasses.replace(encounter, targets=(target,), clouds=None)
    with pytest.warns(SetupHazardWarning, match="target"):
        result = simulate(ENCOUNTER, max_steps=400, progress=False, scene=scene)
    assert result.meta["hazards"]["targets_unsafe"] == [True]
    assert result.clearance.min() > COLLISION_CLEARANCE
    assert not result.completed


def test_more_regions_in_view_than_slots_keeps_the_nearest_and_stays_clear():
    """Three boxes around the flight line, all within the 3 m range at once, two slots."""
    regions = tuple(Region(f"post-{i}", Box((x, y, 2.0), (1.0, 1.0, 3.0)))
                    for i, (x, y) in enumerate([(-16.0, 2.2), (-16.0, -2.2), (-14.6, 2.2)]))
    scene = Scene("posts", regions, (-20.0, 0.0, 2.0), ((20.0, 0.0, 2.0),))
    cfg = dataclasses.replace(ENCOUNTER, nmpc=NMPCParams(region_slots=2))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SetupHazardWarning)  # a safe set-up warns of nothing
        result = simulate(cfg, max_steps=1500, progress=False, scene=scene)
    pos = result.x[:-1, :3]
    regions_in_view = sum(
        (np.linalg.norm(pos[:, None] - c[None], axis=2) <= 3.0).any(axis=1)
        for c in result.scene.clouds)
    assert regions_in_view.max() == 3  # more regions than slots, at some steps
    assert result.failures == 0
    assert result.clearance.min() > COLLISION_CLEARANCE


def test_a_saturated_region_keeps_the_nearest_points_and_stays_clear():
    """A dense wall shows far more points than a slot holds (32): the nearest are kept."""
    wall = Region("dense wall", Box((-16.5, 1.8, 2.0), (1.0, 2.5, 3.0)), density=30.0)
    scene = Scene("dense", (wall,), (-20.0, 0.0, 2.0), ((20.0, 0.0, 2.0),))
    cfg = dataclasses.replace(ENCOUNTER, nmpc=NMPCParams(points_per_region=32))
    result = simulate(cfg, max_steps=1200, progress=False, scene=scene)
    assert result.visible_points.max() > 32  # saturated
    assert result.failures == 0 and result.clearance.min() > COLLISION_CLEARANCE

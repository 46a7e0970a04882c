"""The closed loop's named parts: termination's rules one by one, the tracker's tuning in the
configuration (and the run key), the truth kept apart from the sensor."""

import dataclasses

import numpy as np
import pytest

from paper_repro import Config
from paper_repro.config import SimulationParams, TrackerParams
from paper_repro.presets import MOVING_FLOOR, moving_design_controller
from paper_repro.sim.perception import Perception
from paper_repro.sim.termination import Termination
from paper_repro.vehicles.quadrotor import quadrotor_model
from paper_repro.world.scene import Scene
from paper_repro.world.truth import TrueClearance

TWO_TARGETS = Scene("two", (), start=(0.0, 0.0, 1.0), targets=((5.0, 0.0, 1.0), (5.0, 5.0, 1.0)))


def _stop(scene=TWO_TARGETS, **simulation) -> Termination:
    cfg = Config(simulation=dataclasses.replace(SimulationParams(), **simulation))
    return Termination(cfg, scene, quadrotor_model())


def _state(y, v=(0.0, 0.0, 0.0)):
    x = np.zeros(12)
    x[:3], x[6:9] = y, v
    return x


def test_targets_are_reached_in_turn_and_the_last_completes_a_mission():
    stop = _stop()
    moving = (1.0, 0.0, 0.0)
    assert not stop.after_step(0, _state((4.9, 0.0, 1.0), moving), np.array([4.9, 0.0, 1.0]),
                               np.zeros(3))
    assert stop.target_index == 1 and list(stop.reached) == [1, -1]
    assert stop.after_step(7, _state((5.0, 4.8, 1.0), moving), np.array([5.0, 4.8, 1.0]),
                           np.zeros(3))
    assert stop.outcome == "completed" and list(stop.reached) == [1, 8]


def test_a_vehicle_slow_far_from_its_target_for_stall_time_is_stalled():
    """stall_time 0.05 s at T_s = 0.01 s: more than 5 slow steps in a row end the flight;
    a step at speed resets the count."""
    stop = _stop(stall_time=0.05)
    y, still = np.array([0.0, 0.0, 1.0]), _state((0.0, 0.0, 1.0))
    ended = [stop.after_step(k, still, y, y) for k in range(5)]
    assert not any(ended)
    assert not stop.after_step(5, _state((0, 0, 1.0), (1.0, 0, 0)), y, y)  # moving: reset
    ended = [stop.after_step(k, still, y, y) for k in range(6, 12)]
    assert ended == [False] * 5 + [True] and stop.outcome == "stalled"


def test_persistent_faults_end_the_flight_and_a_usable_step_resets_them():
    stop = _stop(fault_steps=2)
    y, x = np.array([0.0, 0.0, 1.0]), _state((0.0, 0.0, 1.0), (1.0, 0.0, 0.0))
    for status in ("state_fault", "solve_error", "Solve_Succeeded", "state_fault"):
        stop.count_fault(status)
        assert not stop.after_step(0, x, y, y)
    stop.count_fault("state_fault")
    stop.count_fault("state_fault")
    assert stop.after_step(1, x, y, y) and stop.outcome == "fault"


@pytest.mark.parametrize("position, leaves", [
    ((0.0, 0.0, -0.05), False), ((0.0, 0.0, -0.11), True), ((25.05, 0.0, 1.0), False),
    ((0.0, -25.2, 1.0), True), ((0.0, 0.0, 25.2), True)])
def test_a_vehicle_beyond_the_workspace_by_more_than_workspace_exit_has_left_it(position,
                                                                                 leaves):
    """The quadrotor's position box is x, y in [−25, 25] m and z in [0, 25] m."""
    y = np.array(position)
    stop = _stop(workspace_exit=0.1)
    assert stop.after_step(0, _state(position, (1.0, 0.0, 0.0)), y, y) is leaves
    assert stop.outcome == ("left_workspace" if leaves else "step_limit")
    off = _stop(workspace_exit=None)  # no such rule: the flight goes on
    assert not off.after_step(0, _state(position, (1.0, 0.0, 0.0)), y, y)


@pytest.mark.parametrize("value", [-0.1, float("inf"), float("nan"), "1", True])
def test_a_bad_workspace_exit_is_refused_by_name(value):
    with pytest.raises(ValueError, match="workspace_exit"):
        SimulationParams(workspace_exit=value)


def test_the_workspace_is_the_world_box_not_the_floor_the_controller_keeps():
    """The moving design keeps its plans 0.5 m above the ground; a vehicle below that floor
    but above the ground is still inside the workspace."""
    kalman = Config(nmpc=dataclasses.replace(Config().nmpc, prediction="kalman"))
    cfg = moving_design_controller(kalman, "smooth")
    assert cfg.quadrotor.state_lower[2] == MOVING_FLOOR > 0
    stop = Termination(cfg, TWO_TARGETS, quadrotor_model(cfg))
    for z, leaves in ((0.2, False), (-0.01, True)):
        y = np.array([0.0, 0.0, z])
        assert stop.after_step(0, _state(tuple(y), (1.0, 0.0, 0.0)), y, y) is leaves


def test_workspace_exit_enters_the_key_off_the_value_that_flew_before_it():
    off = Config(simulation=SimulationParams(workspace_exit=None))
    assert "workspace_exit" not in off.key_dict()["simulation"]
    assert Config().key_dict()["simulation"]["workspace_exit"] == 0.0


def test_the_tracker_is_tuned_from_the_configuration_and_keyed_only_off_its_defaults():
    base = Config(nmpc=dataclasses.replace(Config().nmpc, prediction="kalman"))
    tuned = dataclasses.replace(base, tracker=TrackerParams(accel_noise=1.5))
    assert "tracker" not in base.key_dict() and tuned.key_dict()["tracker"]["accel_noise"] == 1.5
    assert Config.from_dict(tuned.to_dict()) == tuned
    scene = Scene("empty", (), start=(0.0, 0.0, 1.0), targets=((1.0, 0.0, 1.0),))
    tracker = Perception(tuned, scene).predict.__self__
    assert tracker.accel_noise == 1.5 and tracker.dim == 3


@pytest.mark.parametrize("name, value", [("accel_noise", 0.0), ("gate_probability", 1.0),
                                         ("subset_jump", -1.0), ("forget_after", np.inf)])
def test_bad_tracker_settings_are_refused_by_name(name, value):
    with pytest.raises(ValueError, match=f"^{name} must"):
        TrackerParams(**{name: value})


def test_an_empty_scene_is_infinitely_clear():
    assert np.isinf(TrueClearance(TWO_TARGETS).along(np.zeros((3, 3)), np.zeros(3))).all()

"""Termination: when a closed-loop flight ends, and how (:data:`~paper_repro.sim.result.OUTCOMES`).

After each step, in this order:

1. a target is reached when the output comes within ``simulation.tolerance`` of it; the next
   one becomes active, and reaching the last completes a mission;
2. a passage (``simulation.kind = "passage"``) completes when the output crosses the
   scene's finish line;
3. a flight is stalled when it has moved slower than ``stall_speed`` for ``stall_time``
   while still farther than ``stall_distance`` from its target (a deadlock);
4. a flight ends as a fault after more than ``fault_steps`` steps in a row without a usable
   measured state or solve (:data:`~paper_repro.sim.result.FAULT_STATUSES`);
5. with ``simulation.workspace_exit`` set, a flight has left the workspace when a position
   state is farther than that outside it (:func:`workspace`; the quadrotor below the
   ground: a crash).

A flight that none of these ends stops at its step limit.
"""

from __future__ import annotations

import math

import numpy as np

from paper_repro.config import Config
from paper_repro.sim.result import FAULT_STATUSES
from paper_repro.vehicles.base import VehicleModel
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER, Scene


class Termination:
    """The targets, the finish line and the stopping rules of one flight (module docstring).

    Attributes
    ----------
    targets : (k, p) m, the scene's targets.   target_index : the active one.
    reached : (k,) the step after which each target was reached (−1: not yet).
    outcome : ``"step_limit"`` until a rule ends the flight.
    faults_in_a_row : steps in a row whose status is a fault.
    error : m, the distance from the output to the active target after the last step.
    """

    def __init__(self, config: Config, scene: Scene, model: VehicleModel):
        sim, ts = config.simulation, config.nmpc.ts
        self.sim = sim
        self.targets = np.atleast_2d(np.asarray(scene.targets, float))
        self.passage = sim.kind == "passage"
        self.finish_point, self.finish_dir = (
            (np.asarray(v, float) for v in scene.finish) if self.passage else (None, None))
        self.stall_steps = int(np.ceil(sim.stall_time / ts))
        self.ts = ts
        self.velocity = np.array(model.velocity, dtype=np.intp)
        self.position = np.array(model.position, dtype=np.intp)
        exit_ = sim.workspace_exit
        lower, upper = workspace(scene, model)
        self.inside = None if exit_ is None else (lower - exit_, upper + exit_)
        self.reached = np.full(len(self.targets), -1)
        self.target_index, self.outcome = 0, "step_limit"
        self.faults_in_a_row, self.error, self._slow = 0, math.inf, 0

    @property
    def target(self) -> np.ndarray:
        """(p,) m, the active target."""
        return self.targets[self.target_index]

    def count_fault(self, status: str) -> None:
        """Count the step's solver status towards a fault (a usable one resets the count)."""
        self.faults_in_a_row = self.faults_in_a_row + 1 if status in FAULT_STATUSES else 0

    def after_step(self, k: int, x: np.ndarray, y: np.ndarray, y_before: np.ndarray) -> bool:
        """Apply the rules after step ``k``, the vehicle now in state ``x`` with output ``y``
        (``y_before`` before the step); True when the flight ends (:attr:`outcome` says
        how)."""
        sim, target = self.sim, self.target
        self.error = error = _norm(y - target)
        if error < sim.tolerance and self.reached[self.target_index] < 0:
            self.reached[self.target_index] = k + 1
            if self.target_index + 1 < len(self.targets):
                self.target_index += 1
            elif not self.passage:
                return self._end("completed")
        if self.passage and float(np.dot(y - self.finish_point, self.finish_dir)) >= 0.0:
            return self._end("completed")
        speed = (_norm(x[self.velocity]) if len(self.velocity)
                 else _norm(y - y_before) / self.ts)
        self._slow = self._slow + 1 if (speed < sim.stall_speed
                                        and error > sim.stall_distance) else 0
        if self._slow > self.stall_steps:
            return self._end("stalled")
        if self.faults_in_a_row > sim.fault_steps:
            return self._end("fault")
        if self.inside is not None:
            p = x[self.position]
            if (p < self.inside[0]).any() or (p > self.inside[1]).any():
                return self._end("left_workspace")
        return False

    def _end(self, outcome: str) -> bool:
        self.outcome = outcome
        return True


def workspace(scene: Scene, model: VehicleModel) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper), m, the box a flight stays in: the paper's 50 × 50 × 25 m workspace for
    a scene in space (its floor is the ground, whatever floor the controller's 𝒳 keeps), the
    vehicle's own position bounds for a planar one (the floor plan of its model)."""
    if scene.dim == 3:
        return WORKSPACE_LOWER.copy(), WORKSPACE_UPPER.copy()
    position = list(model.position)
    return (np.asarray(model.state_lower, float)[position],
            np.asarray(model.state_upper, float)[position])


def _norm(v: np.ndarray) -> float:
    """‖v‖₂ of a vector, computed as ``np.linalg.norm`` does it (√(v·v), the same number) at
    a fraction of its cost: a few of them run at every step."""
    return math.sqrt(v.dot(v))

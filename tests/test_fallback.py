"""What the closed loop applies when a solve fails: one rule, each branch tested.

The rule (``sim.loop``): after a failed solve the previous plan is shifted by one step and
its first input applied. The shifted plan ends at rest at its artificial equilibrium (x_a,
u_a), so after as many failures in a row as the horizon has stages the loop holds u_a. With
no plan yet (a failure at the first step) it applies the rest input at the measured state.
A vehicle written in a test (the point mass of ``test_any_vehicle``) keeps it fast."""

import dataclasses

import numpy as np
import pytest
from test_any_vehicle import CONFIG, SCENE, point_mass

from paper_repro.sim.loop import simulate
from paper_repro.solvers.factory import make_controller


class Failing:
    """A controller that reports its solve at the chosen steps as failed (``qp_failed``), and
    keeps every solution it returned."""

    def __init__(self, controller, failing):
        self.controller, self.failing, self.solutions, self.previous = controller, failing, [], []

    def __getattr__(self, name):
        return getattr(self.controller, name)

    def solve(self, *args, previous=None, **kwargs):
        sol = self.controller.solve(*args, previous=previous, **kwargs)
        if len(self.solutions) in self.failing:
            sol = dataclasses.replace(sol, success=False, status="qp_failed")
        self.solutions.append(sol)
        self.previous.append(previous)
        return sol


@pytest.fixture(scope="module")
def controller():
    return make_controller(CONFIG, point_mass())


def _fly(controller, failing, steps=60):
    ctl = Failing(controller, set(failing))
    run = simulate(CONFIG, ctl, max_steps=steps, progress=False, scene=SCENE)
    return ctl, run


def test_after_one_failure_the_previous_plan_shifted_by_one_step_is_applied(controller):
    ctl, run = _fly(controller, [10])
    plan = ctl.solutions[9]
    assert not run.success[10] and run.status[10] == "qp_failed"
    np.testing.assert_array_equal(run.u[10], plan.u[1])
    # the next solve starts from that shifted plan
    np.testing.assert_array_equal(ctl.previous[11].u, plan.shifted().u)


def test_failures_in_a_row_walk_down_the_plan_then_hold_its_rest_input(controller):
    n = CONFIG.nmpc.horizon
    ctl, run = _fly(controller, range(10, 10 + n + 5), steps=10 + n + 8)
    plan = ctl.solutions[9]
    for i in range(n - 1):
        np.testing.assert_array_equal(run.u[10 + i], plan.u[1 + i])
    for i in range(n - 1, n + 5):
        np.testing.assert_array_equal(run.u[10 + i], plan.u_a)
    assert run.success[10 + n + 5]  # and the controller takes over again
    assert np.isfinite(run.x).all()


def test_a_failure_before_any_plan_applies_the_rest_input_where_the_vehicle_is(controller):
    ctl, run = _fly(controller, [0], steps=5)
    rest = controller.hover_guess(run.x[0])
    np.testing.assert_array_equal(run.u[0], rest.u[0])
    assert run.outcome == "step_limit" and run.success[1:].all()

"""The relaxed QP (soft state bounds and terminal rows, exact ℓ1): the hard QP's step where the
hard QP has one, a step that keeps the dynamics and the input bounds where it has none."""

import dataclasses

import numpy as np
import pytest

from paper_repro import Config, NMPCParams, SimulationParams, SolverParams
from paper_repro.solvers.factory import make_controller
from paper_repro.solvers.relaxed_qp import RelaxedQP
from paper_repro.solvers.rti import RealTimeNMPC

SMALL = NMPCParams(region_slots=1, points_per_region=48)
CONFIG = Config(simulation=SimulationParams(scenario="encounter"), nmpc=SMALL)


@pytest.fixture(scope="module")
def relaxed():
    return RealTimeNMPC(CONFIG, capacities=(), relaxed_qp=True, cold_start="rti")


@pytest.fixture(scope="module")
def hard():
    return RealTimeNMPC(CONFIG, capacities=(), relaxed_qp=False, cold_start="rti")


def _state(position, velocity=(0.0, 0.0, 0.0), roll=0.0, roll_rate=0.0):
    x = np.zeros(12)
    x[0:3], x[6:9], x[3], x[9] = position, velocity, roll, roll_rate
    return x


FALLING = _state([0.0, 0.0, 0.22], velocity=(0.0, 0.0, -3.0))
"""0.22 m above the ground, falling at 3 m/s: no thrust stops it before the ground."""
TUMBLING = _state([0.0, 0.0, 5.0], roll=2.0, roll_rate=3.0)
"""Rolled 2 rad (the bound is π/6) and rolling on at 3 rad/s."""
CRUISING = _state([-20.0, 0.0, 5.0])
"""At rest 40 m from the target: the hard QP has a solution, with large terminal multipliers."""


def _qp(ctl, x0, target):
    """The QP the controller built at its last solve, as (h, q, j, gap, eq, lb, ub) copies."""
    ctl.reset()
    sol = ctl.solve(x0, target)
    (bound,) = ctl._bound_qps.values()
    return sol, [np.array(a) for a in bound.arrays]


def test_where_the_hard_qp_has_a_solution_the_relaxed_qp_gives_it(hard):
    """Exactness of the ℓ1 penalty: no slack, the hard QP's step (to HPIPM's tolerance)."""
    for x0, target in [(_state([0.0, 0.0, 5.0]), [5.0, 0.0, 5.0]), (CRUISING, [20.0, 0.0, 5.0])]:
        sol, data = _qp(hard, x0, np.array(target))
        assert sol.status == "iterated"
        step = hard.qp.solve(*data)
        assert step is not None
        bounded = np.isfinite(hard.ocp.state_bounds[0])
        soft = RelaxedQP(hard.layout, bounded)
        relaxed = soft.solve(*data)
        assert soft.last_violation < 1e-6
        assert np.abs(relaxed - step).max() < 1e-6 * max(1.0, np.abs(step).max())


@pytest.mark.parametrize("x0", [FALLING, TUMBLING], ids=["falling", "tumbling"])
def test_an_infeasible_qp_is_solved_with_slacks_and_reported_as_relaxed(hard, relaxed, x0):
    target = np.array([0.0, 0.0, 5.0])
    sol, data = _qp(hard, x0, target)
    assert sol.status == "qp_failed" and not sol.success
    assert hard.last_failure["finite_data"]

    relaxed.reset()
    before = dict(relaxed.qp_counts)
    sol = relaxed.solve(x0, target)
    assert sol.success and sol.status == "relaxed"
    assert relaxed.qp_counts["relaxed"] == before["relaxed"] + 1
    assert relaxed.qp_counts["failed"] == before["failed"]
    # why the hard QP failed is kept: the same statuses the hard controller reports
    assert relaxed.last_relaxation == hard.last_failure
    assert np.isfinite(sol.x).all() and np.isfinite(sol.u).all()
    lower, upper = relaxed.ocp.input_bounds
    assert (sol.u >= lower - 1e-6).all() and (sol.u <= upper + 1e-6).all()

    # The step keeps the linearised dynamics, the input bounds and the equilibrium box hard;
    # only the state bounds and the terminal rows give, and they give a positive amount.
    h, q, j, gap, eq, lb, ub = data
    soft = RelaxedQP(hard.layout, np.isfinite(hard.ocp.state_bounds[0]))
    dw = soft.solve(*data)
    lay = hard.layout
    _, A = lay.dense(h, j)
    assert np.abs(A[:lay.n_gap_rows] @ dw + gap).max() < 1e-6
    hard_entries = np.concatenate([lay.iu.ravel(), lay.ia[0]])
    assert (dw[hard_entries] >= lb[hard_entries] - 1e-6).all()
    assert (dw[hard_entries] <= ub[hard_entries] + 1e-6).all()
    assert soft.last_violation > 1e-3


def test_the_falling_vehicle_is_braked_towards_the_ground_bound(relaxed):
    """The relaxed step's first input is the strongest upwards push the rotors give: every
    rotor at (or near) its upper bound."""
    relaxed.reset()
    sol = relaxed.solve(FALLING, np.array([0.0, 0.0, 5.0]))
    upper = relaxed.ocp.input_bounds[1]
    assert (sol.u[0] > 0.9 * upper).all(), (sol.u[0], upper)


def test_the_option_reaches_the_controller_from_the_config():
    ctl = make_controller(CONFIG, capacities=())  # on by default
    assert ctl.qp.relaxed is not None and "relaxed" in ctl.qp_counts
    cfg = dataclasses.replace(CONFIG, solver=SolverParams(relaxed_qp=False))
    assert make_controller(cfg, capacities=()).qp.relaxed is None
    with pytest.raises(ValueError, match="relaxed_qp"):
        SolverParams(relaxed_qp=1)


def test_the_option_enters_the_run_key_off_the_value_that_flew_before_it():
    """Off is how the flights before the option were flown: it stays out of the run's key,
    so such a run keeps its key; on (the default) enters it."""
    off = dataclasses.replace(CONFIG, solver=SolverParams(relaxed_qp=False))
    assert CONFIG.key_dict() != off.key_dict()
    assert "relaxed_qp" not in off.key_dict().get("solver", {})
    assert CONFIG.key_dict()["solver"]["relaxed_qp"] is True


def test_a_run_counts_the_causes_of_its_relaxed_and_its_failed_solves_apart():
    """A flight that starts falling towards the ground: its first QPs have no solution. With the
    relaxed QP, ``meta["qp_relaxations"]`` counts them by the hard QP's cause, one per relaxed
    solve, and no solve fails; without, ``meta["qp_failures"]`` counts the failed ones."""
    from paper_repro.sim.loop import simulate

    runs = {}
    for relaxed_qp in (True, False):
        cfg = dataclasses.replace(CONFIG, solver=SolverParams(relaxed_qp=relaxed_qp,
                                                              cold_start="rti"))
        runs[relaxed_qp] = simulate(cfg, max_steps=5, initial_state=FALLING, progress=False)
    relaxed, hard = runs[True], runs[False]
    assert (relaxed.status == "relaxed").any() and relaxed.success.all()
    assert sum(relaxed.meta["qp_relaxations"].values()) == int(np.sum(relaxed.status == "relaxed"))
    assert "qp_failures" not in relaxed.meta
    assert all("outside_state_box" in cause for cause in relaxed.meta["qp_relaxations"])
    assert sum(hard.meta["qp_failures"].values()) == int(np.sum(hard.status == "qp_failed")) > 0
    assert "qp_relaxations" not in hard.meta

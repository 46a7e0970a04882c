"""The compiled plant (DP45 in C) against solve_ivp, its fallback and its input checks."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from paper_repro._native import compiler
from paper_repro.config import QuadrotorParams
from paper_repro.sim import plant as plant_module
from paper_repro.sim.plant import QuadrotorPlant
from paper_repro.vehicles.quadrotor import continuous_dynamics, equilibrium, plant_step

needs_compiler = pytest.mark.skipif(compiler() is None, reason="no C compiler")
TS = 0.01


def aggressive_inputs(steps: int = 100) -> np.ndarray:
    """(steps, 4) N: hover plus differential thrusts that roll, pitch and yaw the UAV hard
    (roll near 1.5 rad, pitch near 1 rad, rates of several rad/s) and a collective climb then
    drop."""
    hover = QuadrotorParams().hover_thrust
    t = np.arange(steps) * TS
    roll = 0.5 * np.sin(2 * np.pi * 1.5 * t)           # f2 − f4
    pitch = 2.0 * np.cos(2 * np.pi * 1.1 * t + 0.3)     # f3 − f1
    yaw = 1.5 * np.sign(np.sin(2 * np.pi * 0.8 * t))    # (f1 + f3) − (f2 + f4)
    collective = 1.5 * np.sin(2 * np.pi * 0.7 * t)
    u = np.column_stack([hover + collective - pitch + yaw, hover + collective + roll - yaw,
                         hover + collective + pitch + yaw, hover + collective - roll - yaw])
    return u


@pytest.fixture(scope="module")
def compiled() -> QuadrotorPlant:
    if compiler() is None:
        pytest.skip("no C compiler")
    return QuadrotorPlant(ts=TS)


@needs_compiler
def test_compiled_plant_follows_solve_ivp_over_one_second_of_aggressive_flight(compiled):
    assert compiled.native
    x_ref, _ = equilibrium([1.0, -2.0, 3.0], 0.4)
    x = x_ref.copy()
    worst = 0.0
    angles = []
    for u in aggressive_inputs(100):  # 100 ZOH intervals = 1 s
        x_ref = plant_step(x_ref, u, TS)
        x = compiled.step(x, u)
        worst = max(worst, float(np.max(np.abs(x - x_ref))))
        angles.append(x_ref[3:6])
    angles = np.array(angles)
    # The flight really is aggressive: roll beyond 1.2 rad, pitch beyond 0.8 rad, yaw spun up.
    assert np.max(np.abs(angles[:, 0])) > 1.2 and np.max(np.abs(angles[:, 1])) > 0.8
    assert np.max(np.abs(angles[:, 2] - 0.4)) > 0.3
    assert worst < 1e-9


@needs_compiler
def test_each_interval_takes_solve_ivps_steps(compiled, rng):
    """Same step control: the number of accepted RK45 steps and of right-hand-side
    evaluations matches solve_ivp's on random states, far from hover included."""
    params = QuadrotorParams()
    for _ in range(20):
        x = np.concatenate([rng.normal(0, 2, 3), rng.uniform(-1.2, 1.2, 3),
                            rng.normal(0, 3, 3), rng.normal(0, 6, 3)])
        u = params.hover_thrust + rng.normal(0, 2, 4)
        sol = solve_ivp(lambda _t, s, u=u: continuous_dynamics(s, u), (0.0, TS), x, method="RK45",
                        rtol=1e-8, atol=1e-10)
        x_next = compiled.step(x, u)
        assert compiled.stats[0] == len(sol.t) - 1
        assert compiled.stats[2] == sol.nfev
        np.testing.assert_allclose(x_next, sol.y[:, -1], rtol=0, atol=1e-11)


@needs_compiler
def test_step_returns_a_new_array_and_leaves_its_arguments_alone(compiled):
    x, u = equilibrium([0.0, 0.0, 1.0])
    x0, u0 = x.copy(), u.copy()
    a = compiled.step(x, u + 0.5)
    b = compiled.step(x, u)
    assert a is not b and not np.shares_memory(a, b)
    assert a[2] > b[2]  # more thrust climbs; a was not overwritten by the second call
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(u, u0)
    np.testing.assert_allclose(b, x, atol=1e-12)  # hover is an equilibrium


@needs_compiler
def test_other_parameters_give_another_plant():
    heavy = QuadrotorParams(mass=3.0)
    x, u = equilibrium([0.0, 0.0, 1.0])  # hover thrust of the default mass
    x_heavy = QuadrotorPlant(heavy, ts=TS).step(x, u)
    np.testing.assert_allclose(x_heavy, plant_step(x, u, TS, heavy), atol=1e-12)
    assert x_heavy[8] < -1e-3  # too little thrust for 3 kg: it sinks


@pytest.mark.parametrize("how", ["compile=False", "no compiler"])
def test_without_the_compiled_integrator_it_falls_back_on_solve_ivp(how, monkeypatch):
    if how == "no compiler":
        monkeypatch.setattr(plant_module, "compiler", lambda: None)
        fallback = QuadrotorPlant(ts=TS)
    else:
        fallback = QuadrotorPlant(ts=TS, compile=False)
    assert not fallback.native
    x, _ = equilibrium([0.5, 0.0, 2.0], 0.1)
    for u in aggressive_inputs(5):
        expected = plant_step(x, u, TS)
        x = fallback.step(x, u)
        np.testing.assert_array_equal(x, expected)


@pytest.mark.parametrize("compile", [True, False])
@pytest.mark.parametrize("name, x, u", [
    ("x", np.zeros(11), np.ones(4)),
    ("x", np.zeros((12, 1)), np.ones(4)),
    ("x", np.r_[np.zeros(11), np.nan], np.ones(4)),
    ("u", np.zeros(12), np.ones(3)),
    ("u", np.zeros(12), np.array([1.0, np.inf, 1.0, 1.0])),
])
def test_bad_states_and_inputs_are_rejected_by_name(compile, name, x, u):
    with pytest.raises(ValueError, match=rf"^{name} must"):
        QuadrotorPlant(ts=TS, compile=compile).step(x, u)


@pytest.mark.parametrize("kwargs, name", [
    ({"ts": 0.0}, "ts"), ({"ts": -0.01}, "ts"), ({"ts": float("nan")}, "ts"),
    ({"ts": "0.01"}, "ts"), ({"rtol": 0.0}, "rtol"), ({"rtol": float("inf")}, "rtol"),
    ({"atol": -1e-10}, "atol"), ({"atol": float("nan")}, "atol"),
    ({"params": {"mass": 2.0}}, "params"),
])
def test_bad_settings_are_rejected_by_name(kwargs, name):
    with pytest.raises(ValueError, match=rf"^{name} must"):
        QuadrotorPlant(**kwargs)

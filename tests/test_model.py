"""Properties of the quadrotor model (Table I): equilibria, rotor layout, rigid-body physics,
and agreement of the numeric, symbolic, RK4 and plant implementations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from paper_repro.config import QuadrotorParams
from paper_repro.vehicles.quadrotor import (
    continuous_dynamics,
    equilibrium,
    hover_input,
    plant_step,
    rk4_discretisation,
    symbolic_dynamics,
)

P = QuadrotorParams()
IXX, IYY, IZZ = P.inertia
ASYMMETRIC = QuadrotorParams(inertia=(0.03, 0.05, 0.07))  # exercises every ω × Iω term


def _state(position=(0.0, 0.0, 0.0), angles=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0),
           rates=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.concatenate([position, angles, velocity, rates]).astype(float)


def _random_state(gen: np.random.Generator) -> np.ndarray:
    """A state away from the Euler singularity θ = ±π/2."""
    return _state(gen.uniform(-20, 20, 3), gen.uniform(-0.6, 0.6, 3) * [1, 1, 5],
                  gen.uniform(-3, 3, 3), gen.uniform(-1.5, 1.5, 3))


def _body_rates(s: np.ndarray) -> np.ndarray:
    """ω = E(φ, θ)·[φ̇, θ̇, ψ̇] for Z-Y-X Euler angles."""
    phi, theta = s[3], s[4]
    e = np.array([[1.0, 0.0, -np.sin(theta)],
                  [0.0, np.cos(phi), np.sin(phi) * np.cos(theta)],
                  [0.0, -np.sin(phi), np.cos(phi) * np.cos(theta)]])
    return e @ s[9:12]


def _rotation(s: np.ndarray) -> np.ndarray:
    """R = Rz(ψ)·Ry(θ)·Rx(φ), built independently with SciPy (intrinsic Z-Y-X)."""
    return Rotation.from_euler("ZYX", [s[5], s[4], s[3]]).as_matrix()


# --- equilibria -----------------------------------------------------------------------------

@pytest.mark.parametrize("position", [(0.0, 0.0, 0.0), (22.0, -22.0, 0.0), (-12.0, 18.0, 11.0)])
@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5, np.pi])
def test_hover_is_equilibrium(position, yaw):
    """Any position and yaw with zero tilt, velocity and rates, at f_i = m·g/4, has ẋ = 0."""
    x_s, u_s = equilibrium(position, yaw)
    np.testing.assert_array_equal(x_s[:3], position)
    assert x_s[5] == yaw
    np.testing.assert_allclose(u_s, hover_input())
    np.testing.assert_allclose(continuous_dynamics(x_s, u_s), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.array(symbolic_dynamics()(x_s, u_s)).ravel(), 0.0, atol=1e-12)


def test_hover_input_is_weight_over_four():
    """Σ f_i = m·g at hover, with equal rotor thrusts."""
    u = hover_input()
    assert u.shape == (4,)
    assert np.all(u == u[0])
    assert u.sum() == pytest.approx(P.mass * P.gravity, rel=1e-14)


def test_plant_stays_at_equilibrium():
    """Integrating the plant from an equilibrium leaves the state unchanged."""
    x_s, u_s = equilibrium((3.0, -4.0, 5.0), 0.3)
    x = x_s
    for _ in range(10):
        x = plant_step(x, u_s, 0.01)
    np.testing.assert_allclose(x, x_s, atol=1e-12)


# --- forces and torques ---------------------------------------------------------------------

@pytest.mark.parametrize("extra", [-3.0, -0.5, 0.7, 4.0])
@pytest.mark.parametrize("yaw", [0.0, 1.2])
def test_equal_extra_thrust_gives_pure_vertical_acceleration(extra, yaw):
    """Equal rotor thrusts at level attitude: z̈ = Σf/m − g, and no other state derivative."""
    x = _state(angles=(0.0, 0.0, yaw))
    u = hover_input() + extra
    xdot = continuous_dynamics(x, u)
    expected = np.zeros(12)
    expected[8] = u.sum() / P.mass - P.gravity
    np.testing.assert_allclose(xdot, expected, atol=1e-12)
    assert np.sign(xdot[8]) == np.sign(extra)


@pytest.mark.parametrize(
    ("delta_u", "axis", "torque"),
    [
        # rotor 2 (+y_b) stronger than rotor 4 (−y_b): τx = h(f2 − f4) > 0, roll up
        ((0.0, 0.5, 0.0, -0.5), 0, P.arm * 1.0),
        # rotor 3 (−x_b) stronger than rotor 1 (+x_b): τy = h(f3 − f1) > 0, pitch up
        ((-0.5, 0.0, 0.5, 0.0), 1, P.arm * 1.0),
        # f1 + f3 > f2 + f4 at the same total: τz = (k_τ/b)(f1 − f2 + f3 − f4) > 0
        ((0.5, -0.5, 0.5, -0.5), 2, P.yaw_torque_ratio * 2.0),
    ],
)
def test_rotor_layout_signs_and_magnitudes(delta_u, axis, torque):
    """"+" layout (rotor 1 at +x, 2 at +y, 3 at −x, 4 at −y): a thrust difference at the same
    total produces only the angular acceleration τ/I about the expected axis, with the
    expected sign, and no translational acceleration (level attitude, at rest)."""
    x = _state()
    xdot = continuous_dynamics(x, hover_input() + np.array(delta_u))
    expected = np.zeros(3)
    expected[axis] = torque / P.inertia[axis]
    assert xdot[9 + axis] > 0
    np.testing.assert_allclose(xdot[9:12], expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(xdot[:9], 0.0, atol=1e-12)


def test_rotor_torques_from_lever_arms():
    """τ = Σ r_i × (0, 0, f_i) with r_1 = (h,0,0), r_2 = (0,h,0), r_3 = (−h,0,0), r_4 = (0,−h,0),
    plus the yaw reaction; checked for an arbitrary input at level attitude, at rest."""
    h = P.arm
    arms = np.array([[h, 0, 0], [0, h, 0], [-h, 0, 0], [0, -h, 0]])
    u = np.array([4.1, 6.3, 5.2, 7.7])
    tau = sum(np.cross(r, [0.0, 0.0, f]) for r, f in zip(arms, u, strict=True))
    tau[2] = P.yaw_torque_ratio * (u[0] - u[1] + u[2] - u[3])
    xdot = continuous_dynamics(_state(), u)
    np.testing.assert_allclose(xdot[9:12], tau / np.array(P.inertia), rtol=1e-12)


@pytest.mark.parametrize("angle", [0.1, 0.4])
def test_tilt_direction(angle):
    """R = Rz(ψ)Ry(θ)Rx(φ): at hover thrust, φ > 0 accelerates toward −y (ÿ = −g sin φ) and
    θ > 0 toward +x (ẍ = g sin θ); yawing by π/2 turns the pitch acceleration to +y."""
    u = hover_input()
    g = P.gravity
    roll = continuous_dynamics(_state(angles=(angle, 0.0, 0.0)), u)
    assert roll[7] < 0
    np.testing.assert_allclose(roll[6:9], [0.0, -g * np.sin(angle), g * (np.cos(angle) - 1)],
                               atol=1e-12)
    pitch = continuous_dynamics(_state(angles=(0.0, angle, 0.0)), u)
    assert pitch[6] > 0
    np.testing.assert_allclose(pitch[6:9], [g * np.sin(angle), 0.0, g * (np.cos(angle) - 1)],
                               atol=1e-12)
    yawed = continuous_dynamics(_state(angles=(0.0, angle, np.pi / 2)), u)
    np.testing.assert_allclose(yawed[6:9], [0.0, g * np.sin(angle), g * (np.cos(angle) - 1)],
                               atol=1e-12)


def test_translational_acceleration_is_rotated_thrust(rng):
    """m·p̈ = R·[0, 0, Σf] − m·g·e3 with R from SciPy's intrinsic Z-Y-X Euler angles."""
    for _ in range(20):
        x = _random_state(rng)
        u = rng.uniform(0, 12, 4)
        acc = _rotation(x) @ [0.0, 0.0, u.sum()] / P.mass - [0.0, 0.0, P.gravity]
        np.testing.assert_allclose(continuous_dynamics(x, u)[6:9], acc, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(continuous_dynamics(x, u)[:6], np.r_[x[6:9], x[9:12]])


# --- torque-free rigid body -----------------------------------------------------------------

@pytest.mark.parametrize("params", [P, ASYMMETRIC], ids=["table-I", "asymmetric"])
@pytest.mark.parametrize("seed", [1, 2])
def test_torque_free_motion_conserves_energy_and_momentum(params, seed):
    """With equal rotor thrusts (τ = 0), ½ωᵀIω, |Iω| and the inertial angular momentum
    R·I·ω are constant along the flow — this pins the gyroscopic ω × Iω and the Ė·η̇ terms of
    the Euler-angle accelerations, and their consistency with R = Rz Ry Rx."""
    gen = np.random.default_rng(seed)
    x0 = _state(angles=gen.uniform(-0.3, 0.3, 3), velocity=gen.uniform(-1, 1, 3),
                rates=gen.uniform(-0.8, 0.8, 3))
    u = np.full(4, 5.0)  # equal thrusts, not hover: the body also accelerates
    inertia = np.array(params.inertia)
    sol = solve_ivp(lambda _t, s: continuous_dynamics(s, u, params), (0.0, 1.5), x0,
                    method="DOP853", rtol=1e-11, atol=1e-12, t_eval=np.linspace(0, 1.5, 31))
    assert sol.success
    assert np.max(np.abs(sol.y[4])) < 1.2  # stays well away from gimbal lock θ = ±π/2
    omegas = np.array([_body_rates(s) for s in sol.y.T])
    energy = 0.5 * np.sum(omegas**2 * inertia, axis=1)
    momentum = omegas * inertia
    inertial_momentum = np.array([_rotation(s) @ l for s, l in zip(sol.y.T, momentum, strict=True)])
    np.testing.assert_allclose(energy, energy[0], rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(momentum, axis=1), np.linalg.norm(momentum[0]),
                               rtol=1e-6)
    np.testing.assert_allclose(inertial_momentum,
                               np.broadcast_to(inertial_momentum[0], inertial_momentum.shape),
                               rtol=1e-6, atol=1e-9)
    # the test is not vacuous: the Euler-angle rates do change along the motion
    assert np.max(np.abs(sol.y[9:12] - x0[9:12, None])) > 1e-2


# --- implementations agree ------------------------------------------------------------------

def test_numeric_and_symbolic_dynamics_agree(rng):
    """The NumPy and CasADi dynamics are built from the same expressions: equal to 1e-12."""
    f = symbolic_dynamics(ASYMMETRIC)
    for _ in range(25):
        x, u = _random_state(rng), rng.uniform(0, 12, 4)
        np.testing.assert_allclose(np.array(f(x, u)).ravel(),
                                   continuous_dynamics(x, u, ASYMMETRIC), rtol=1e-12, atol=1e-12)


def test_rk4_step_is_classical_runge_kutta(rng):
    """rk4_discretisation(ts) performs exactly one classical RK4 step of the numeric dynamics
    (and steps=k performs k of length ts/k)."""
    ts = 0.01

    def rk4(x, u, h):
        k1 = continuous_dynamics(x, u)
        k2 = continuous_dynamics(x + h / 2 * k1, u)
        k3 = continuous_dynamics(x + h / 2 * k2, u)
        k4 = continuous_dynamics(x + h * k3, u)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    f1, f3 = rk4_discretisation(ts), rk4_discretisation(ts, steps=3)
    for _ in range(5):
        x, u = _random_state(rng), rng.uniform(0, 12, 4)
        np.testing.assert_allclose(np.array(f1(x, u)).ravel(), rk4(x, u, ts),
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.array(f3(x, u)).ravel(),
                                   rk4(rk4(rk4(x, u, ts / 3), u, ts / 3), u, ts / 3),
                                   rtol=1e-12, atol=1e-12)


def test_rk4_prediction_matches_plant_over_one_second():
    """100 RK4 steps of 10 ms (the NMPC's prediction model) and 100 solve_ivp plant steps from
    a tilted, moving, rotating state under a constant non-hover input agree within 1e-6.

    RK4's global error is O(h⁴) ≈ 1e-8 × (derivative scale) here and the plant is solved to
    rtol 1e-8, so 1e-6 leaves margin while still catching any modelling mismatch (a sign or a
    missing term changes the 1 s state by centimetres or more)."""
    x0 = np.array([0.3, -0.2, 1.0, 0.2, -0.15, 0.4, 0.5, -0.3, 0.2, 0.3, -0.2, 0.25])
    u = hover_input() + np.array([0.1, -0.05, 0.08, -0.02])
    f = rk4_discretisation(0.01)
    x_rk, x_pl = x0.copy(), x0.copy()
    for _ in range(100):
        x_rk = np.array(f(x_rk, u)).ravel()
        x_pl = plant_step(x_pl, u, 0.01)
    np.testing.assert_allclose(x_rk[:3], x_pl[:3], rtol=0, atol=1e-6)
    np.testing.assert_allclose(x_rk, x_pl, rtol=0, atol=1e-6)
    assert np.linalg.norm(x_rk[:3] - x0[:3]) > 1.0  # the state really moved


# --- input validation -----------------------------------------------------------------------

@pytest.mark.parametrize(
    ("x", "u", "match"),
    [
        (np.zeros(11), hover_input(), "x"),
        (np.zeros((12, 1)), hover_input(), "x"),
        (np.r_[np.zeros(11), np.nan], hover_input(), "x"),
        (np.r_[np.zeros(11), np.inf], hover_input(), "x"),
        (np.zeros(12), np.zeros(3), "u"),
        (np.zeros(12), np.zeros((2, 2)), "u"),
        (np.zeros(12), np.array([1.0, np.nan, 1.0, 1.0]), "u"),
    ],
)
@pytest.mark.parametrize("func", ["continuous_dynamics", "plant_step"])
def test_bad_state_or_input_raises(x, u, match, func):
    """Wrong shapes or non-finite values of x or u raise a ValueError naming the argument."""
    with pytest.raises(ValueError, match=rf"^{match} "):
        if func == "continuous_dynamics":
            continuous_dynamics(x, u)
        else:
            plant_step(x, u, 0.01)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"mass": -1.0}, "mass"), ({"mass": 0.0}, "mass"), ({"mass": float("nan")}, "mass"),
     ({"arm": -0.3}, "arm"), ({"gravity": 0.0}, "gravity"),
     ({"inertia": (0.1, -0.1, 0.1)}, "inertia"), ({"inertia": (0.1, 0.1)}, "inertia")],
)
def test_bad_quadrotor_params(kwargs, match):
    """Non-physical parameters are rejected with a ValueError naming the field."""
    with pytest.raises(ValueError, match=match):
        QuadrotorParams(**kwargs)


@pytest.mark.parametrize("ts", [0.0, -0.01, float("nan"), float("inf")])
def test_rk4_bad_sampling_time(ts):
    """The prediction model needs a finite T_s > 0."""
    with pytest.raises(ValueError, match="ts"):
        rk4_discretisation(ts)


@pytest.mark.parametrize("ts", [0.0, -0.01, float("nan"), float("inf")])
def test_plant_step_bad_sampling_time(ts):
    """The plant needs a finite T_s > 0 (NaN used to hang solve_ivp, ts < 0 ran backwards)."""
    x_s, u_s = equilibrium((0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="ts"):
        plant_step(x_s, u_s, ts)


@pytest.mark.parametrize("steps", [0, -1, 1.5])
def test_rk4_bad_substeps(steps):
    """steps must be a positive integer (steps = −1 used to return the identity map)."""
    with pytest.raises(ValueError, match="steps"):
        rk4_discretisation(0.01, steps=steps)


@pytest.mark.parametrize(("position", "yaw", "match"),
                         [((0.0, 0.0), 0.0, "position"), ((0.0, np.nan, 0.0), 0.0, "position"),
                          ((0.0, 0.0, 0.0), float("nan"), "yaw")])
def test_equilibrium_bad_input(position, yaw, match):
    """equilibrium() validates its position and yaw."""
    with pytest.raises(ValueError, match=match):
        equilibrium(position, yaw)

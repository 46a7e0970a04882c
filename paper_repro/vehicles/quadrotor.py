"""Quadrotor model of Table I: continuous dynamics, RK4 prediction, plant integration.

State  x = [x, y, z, φ, θ, ψ, ẋ, ẏ, ż, φ̇, θ̇, ψ̇]  (m, rad, m/s, rad/s), inertial position,
Z-Y-X Euler angles (R = Rz(ψ)·Ry(θ)·Rx(φ)) and their time derivatives.
Input  u = [f1, f2, f3, f4]  (N), rotor thrusts in a "+" layout: rotor 1 on +x_b, 2 on +y_b,
3 on −x_b, 4 on −y_b, each at distance h (``arm``) from the centre of mass.

Forces and torques (body frame)::

    thrust  Σf along z_b          τx = h(f2 − f4)
    τy = h(f3 − f1)               τz = (k_τ/b)(f1 − f2 + f3 − f4)

Translational dynamics m·p̈ = R·[0, 0, Σf] − m·g·e3. Rotational dynamics are the full
rigid-body equations I·ω̇ + ω × I·ω = τ for the body rate ω = E(φ, θ)·[φ̇, θ̇, ψ̇], rewritten for
the Euler-angle accelerations: [φ̈, θ̈, ψ̈] = E⁻¹(I⁻¹(τ − ω × Iω) − Ė·[φ̇, θ̇, ψ̇]).

The same expression code builds the CasADi (symbolic) and the NumPy (numeric) dynamics, so the
prediction model of the NMPC and the simulated plant cannot drift apart.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

from paper_repro.config import Config, QuadrotorParams
from paper_repro.validation import as_vector
from paper_repro.vehicles.base import Equilibria, VehicleModel, rk4

N_STATES = 12
N_INPUTS = 4
STATE_NAMES = ("x", "y", "z", "phi", "theta", "psi", "vx", "vy", "vz", "p_phi", "p_theta",
               "p_psi")
"""The state x = (position, Euler angles φ θ ψ, velocity, the angles' rates), eq. (1)."""


def continuous_dynamics(x, u, params: QuadrotorParams | None = None) -> np.ndarray:
    """ẋ = f_c(x, u) for numeric arguments.

    Parameters
    ----------
    x : (12,) array, state (see module docstring).
    u : (4,) array, rotor thrusts f1..f4 in N.
    params : quadrotor parameters, Table I by default.

    Returns
    -------
    (12,) array, state derivative.
    """
    x = as_vector("x", x, N_STATES)
    u = as_vector("u", u, N_INPUTS)
    return np.array(_dynamics_terms(x, u, params or QuadrotorParams(), math.sin, math.cos))


def symbolic_dynamics(params: QuadrotorParams | None = None) -> ca.Function:
    """CasADi function ``f_c(x[12], u[4]) -> xdot[12]`` built from the same expressions."""
    x = ca.SX.sym("x", N_STATES)
    u = ca.SX.sym("u", N_INPUTS)
    xs = [x[i] for i in range(N_STATES)]
    us = [u[i] for i in range(N_INPUTS)]
    xdot = ca.vertcat(*_dynamics_terms(xs, us, params or QuadrotorParams(), ca.sin, ca.cos))
    return ca.Function("f_c", [x, u], [xdot], ["x", "u"], ["xdot"])


def rk4_discretisation(ts: float, params: QuadrotorParams | None = None,
                       steps: int = 1) -> ca.Function:
    """One RK4 step of length ``ts`` (split into ``steps`` sub-steps), zero-order-hold input.

    Returns the CasADi function ``f(x[12], u[4]) -> x_next[12]`` used as prediction model (eq. 1).
    """
    return rk4(symbolic_dynamics(params), ts, steps)


def quadrotor_model(config: Config | None = None) -> VehicleModel:
    """The quadrotor as the NMPC sees it (:class:`~paper_repro.vehicles.base.VehicleModel`).

    Output y = position (3,). 𝒳 and 𝒰 are the boxes of ``config.quadrotor``. Its equilibria are
    parametrised exactly by a = (position, yaw) with hover thrust (see :func:`equilibrium`).
    """
    cfg = config or Config()
    p = cfg.quadrotor
    x = ca.SX.sym("x", N_STATES)
    a = ca.SX.sym("a", 4)
    hover = p.hover_thrust
    position_and_yaw = np.array([0, 1, 2, 5])  # an index array: of_state runs every step
    equilibria = Equilibria(
        state=ca.Function("x_a", [a], [ca.vertcat(a[:3], 0, 0, a[3], ca.SX.zeros(6))]),
        input=ca.Function("u_a", [a], [ca.DM.ones(N_INPUTS) * hover]),
        of_state=lambda xs: np.asarray(xs, float)[position_and_yaw])
    return VehicleModel(
        "quadrotor", symbolic_dynamics(p), ca.Function("h", [x], [x[:3]]),
        p.state_lower, p.state_upper, p.input_lower, p.input_upper, equilibria,
        position=(0, 1, 2), velocity=(6, 7, 8), state_names=STATE_NAMES,
        input_names=tuple(f"f{i + 1}" for i in range(N_INPUTS)))


def plant_step(x, u, ts: float, params: QuadrotorParams | None = None,
               rtol: float = 1e-8, atol: float = 1e-10) -> np.ndarray:
    """Integrate the plant over one sampling interval with ``solve_ivp`` (RK45, ODE45's
    counterpart) under zero-order hold of ``u``. Returns the (12,) state at t + ts."""
    x = as_vector("x", x, N_STATES)
    u = as_vector("u", u, N_INPUTS)
    if not (ts > 0 and math.isfinite(ts)):  # NaN would hang solve_ivp, ts < 0 runs backwards
        raise ValueError(f"ts must be a finite number > 0 (s), got {ts!r}")
    params = params or QuadrotorParams()
    sol = solve_ivp(
        lambda _t, s: _dynamics_terms(s, u, params, math.sin, math.cos),
        (0.0, ts), x, method="RK45", rtol=rtol, atol=atol,
    )
    if not sol.success:  # pragma: no cover - RK45 on this smooth ODE does not fail
        raise RuntimeError(f"plant integration failed: {sol.message}")
    return sol.y[:, -1]


def hover_input(params: QuadrotorParams | None = None) -> np.ndarray:
    """(4,) rotor thrusts at hover, f_i = m·g/4 (N)."""
    return np.full(N_INPUTS, (params or QuadrotorParams()).hover_thrust)


def equilibrium(position, yaw: float = 0.0, params: QuadrotorParams | None = None):
    """An element (x_s, u_s) of the equilibrium set.

    The equilibria of the quadrotor are exactly: any position and yaw, zero roll and pitch,
    zero velocities and rates, and f_i = m·g/4.

    Returns
    -------
    x_s : (12,) array;  u_s : (4,) array in N.
    """
    p = as_vector("position", position, 3)
    if not math.isfinite(yaw):
        raise ValueError(f"yaw must be finite (rad), got {yaw!r}")
    x = np.zeros(N_STATES)
    x[:3] = p
    x[5] = yaw
    return x, hover_input(params)


def _dynamics_terms(x, u, p: QuadrotorParams, sin, cos) -> list:
    """State derivative as a list of 12 expressions; ``sin``/``cos`` select the backend."""
    phi, theta, psi = x[3], x[4], x[5]
    vx, vy, vz = x[6], x[7], x[8]
    dphi, dtheta, dpsi = x[9], x[10], x[11]
    f1, f2, f3, f4 = u[0], u[1], u[2], u[3]
    ixx, iyy, izz = p.inertia

    thrust = f1 + f2 + f3 + f4
    tau = (p.arm * (f2 - f4), p.arm * (f3 - f1), p.yaw_torque_ratio * (f1 - f2 + f3 - f4))

    sphi, cphi = sin(phi), cos(phi)
    sth, cth = sin(theta), cos(theta)
    spsi, cpsi = sin(psi), cos(psi)

    # Third column of R = Rz(ψ)Ry(θ)Rx(φ): direction of the thrust in the inertial frame.
    ax = thrust / p.mass * (cpsi * sth * cphi + spsi * sphi)
    ay = thrust / p.mass * (spsi * sth * cphi - cpsi * sphi)
    az = thrust / p.mass * (cth * cphi) - p.gravity

    # Body rates ω = E·η̇ and their Euler-angle-rate-only part Ė·η̇.
    wx = dphi - sth * dpsi
    wy = cphi * dtheta + sphi * cth * dpsi
    wz = -sphi * dtheta + cphi * cth * dpsi
    edot_x = -cth * dtheta * dpsi
    edot_y = -sphi * dphi * dtheta + (cphi * cth * dphi - sphi * sth * dtheta) * dpsi
    edot_z = -cphi * dphi * dtheta - (sphi * cth * dphi + cphi * sth * dtheta) * dpsi

    # Euler's equations: ω̇ = I⁻¹(τ − ω × Iω).
    wdot_x = (tau[0] - (izz - iyy) * wy * wz) / ixx
    wdot_y = (tau[1] - (ixx - izz) * wz * wx) / iyy
    wdot_z = (tau[2] - (iyy - ixx) * wx * wy) / izz

    # η̈ = E⁻¹(ω̇ − Ė·η̇) with E⁻¹ for Z-Y-X angles (singular only at θ = ±π/2).
    rx, ry, rz = wdot_x - edot_x, wdot_y - edot_y, wdot_z - edot_z
    ddpsi = (sphi * ry + cphi * rz) / cth
    ddtheta = cphi * ry - sphi * rz
    ddphi = rx + sth * ddpsi
    return [vx, vy, vz, dphi, dtheta, dpsi, ax, ay, az, ddphi, ddtheta, ddpsi]



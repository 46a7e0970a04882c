"""A plant from another simulator: RotorPy's multirotor, with effects our model leaves out.

:class:`RotorpyPlant` is a :class:`~paper_repro.sim.plant.Plant`. It steps rotorpy 3.0.0's
``Multirotor`` (Folk et al., MIT licence) with ``control_abstraction='cmd_motor_thrusts'``.
It takes our 12-state vector and the four rotor thrusts (N) of
:mod:`paper_repro.vehicles.quadrotor`, in our rotor order and "+" layout. It converts them to
RotorPy's state dict and back. The vehicle is built from our
:class:`~paper_repro.config.QuadrotorParams`.

The effects RotorPy models and ours does not are settings of
:class:`~paper_repro.config.PlantParams`. All are off by default. With all of them off the
plant is our quadrotor, integrated by RotorPy.

How RotorPy 3.0.0 is used, as read from its source:

* The rotor speeds ω_i (rad/s) are states, with the first-order lag
  ω̇_i = (ω_cmd,i − ω_i)/τ_m. ``tau_m = 0`` divides by zero there. So without a lag this plant
  sets the rotor speeds to the commanded ones before each step and gives RotorPy
  τ_m = ∞: the speeds are then constant over the step, and each thrust is held exactly.
* The lag acts on rotor speed; thrust is k_η·ω². The thrust follows a first-order lag of
  time constant τ_m only for small changes of thrust (to 1 % for a 10 % step).
* It integrates with ``solve_ivp``; its default is RK45 at rtol 1e-3. This plant passes
  RK45 at rtol 1e-6 and atol 1e-8. With every effect off it then flies our closed loop over
  the encounter's first 5 s to 4e-13 m, as at our plant's own tolerances (rtol 1e-8, atol
  1e-10), in three quarters of the time: RotorPy's right-hand side, evaluated about 20 times
  a step, costs most of a step (about 1.3 ms).
* Gravity is fixed at 9.81 m/s² in its constructor. This plant overwrites the instance's
  weight for another ``QuadrotorParams.gravity``. Nothing of the installed package is patched.
* Wind acts only through the aerodynamic effects (drag, inflow, lift, flapping). With all
  of them off, wind changes nothing.
* It draws rotor-speed noise from NumPy's global generator at every step, even with zero
  noise. This plant restores that generator's state after each step.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from paper_repro.config import PlantParams, QuadrotorParams
from paper_repro.validation import as_vector, require_positive
from paper_repro.vehicles.quadrotor import N_INPUTS, N_STATES

INSTALL = 'pip install -e ".[hardware]"'
"""The command that installs rotorpy (the ``hardware`` extra of this package)."""

_ROTORS = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_DIRECTIONS = np.array([1, -1, 1, -1])  # yaw torque (k_τ/b)(f1 − f2 + f3 − f4)


class RotorpyPlant:
    """Our quadrotor flown by RotorPy's ``Multirotor``, optionally with the effects of
    :class:`PlantParams` and a wind. Needs rotorpy 3.0.0 (``pip install -e ".[hardware]"``).

    State kept between steps: the rotor speeds (rad/s) and the time t = k·T_s (s). The 12-state
    vector itself comes in with every :meth:`step`.

    Parameters
    ----------
    params : quadrotor parameters, Table I by default (the nominal vehicle).
    ts : T_s, s, the sampling interval (the thrusts are held over it).
    effects : the effects, all off by default.
    wind : a callable ``wind(t) -> (3,)`` m/s in the world frame, e.g.
        :class:`paper_repro.world.wind.Wind`; None for still air. It is read at the start of
        each step and held over it (RotorPy's ``state['wind']``).
    rtol, atol : tolerances of RotorPy's RK45 (``solve_ivp``).

    Raises
    ------
    ValueError : a bad parameter, named with its accepted range.
    ImportError : rotorpy is not installed.
    """

    def __init__(self, params: QuadrotorParams | None = None, ts: float = 0.01,
                 effects: PlantParams | None = None, wind=None,
                 rtol: float = 1e-6, atol: float = 1e-8):
        if not isinstance(params, (QuadrotorParams, type(None))):
            raise ValueError(f"params must be a QuadrotorParams or None, got {params!r}")
        if not isinstance(effects, (PlantParams, type(None))):
            raise ValueError(f"effects must be a PlantParams or None, got {effects!r}")
        if wind is not None and not callable(wind):
            raise ValueError(f"wind must be a callable wind(t) -> (3,) m/s or None, got {wind!r}")
        require_positive("ts (s)", ts)
        for name, value in (("rtol", rtol), ("atol", atol)):
            require_positive(name, value)
        self.params = params or QuadrotorParams()
        self.effects = effects or PlantParams()
        self.ts, self.wind, self.rtol, self.atol = float(ts), wind, float(rtol), float(atol)
        if wind is not None and not self.effects.aerodynamic:
            warnings.warn("wind acts only through an aerodynamic effect (rotor_drag, "
                          "induced_inflow, translational_lift, blade_flapping, parasitic_drag);"
                          " all are 0, so this wind changes nothing", stacklevel=2)
        try:
            from rotorpy.vehicles.multirotor import Multirotor
        except ImportError as err:
            raise ImportError(f"RotorpyPlant needs rotorpy 3.0.0, which is not installed: "
                              f"{INSTALL}") from err
        self.vehicle = Multirotor(
            rotorpy_params(self.params, self.effects), control_abstraction="cmd_motor_thrusts",
            aero=self.effects.aerodynamic, enable_ground=False,
            integrator_kwargs={"method": "RK45", "rtol": self.rtol, "atol": self.atol})
        # RotorPy fixes g = 9.81 in its constructor; the weight is the one term that uses it.
        self.vehicle.g = self.params.gravity
        self.vehicle.weight = np.array([0.0, 0.0, -self.vehicle.mass * self.params.gravity])
        self._k = 0
        self._rotor_speeds: np.ndarray | None = None

    @property
    def time(self) -> float:
        """t, s: the time of the state the next :meth:`step` starts from."""
        return self._k * self.ts

    @property
    def rotor_speeds(self) -> np.ndarray:
        """(4,) rad/s, the rotor speeds now (hover before the first step)."""
        if self._rotor_speeds is None:
            return self.commanded_speeds(np.full(N_INPUTS, self.params.hover_thrust))
        return self._rotor_speeds.copy()

    @property
    def rotor_thrusts(self) -> np.ndarray:
        """(4,) N, the thrusts the rotors produce now: k_η·ω² with the true k_η."""
        return self.vehicle.k_eta * self.rotor_speeds**2

    def commanded_speeds(self, u) -> np.ndarray:
        """(4,) rad/s: the rotor speeds the thrusts ``u`` (4,) N command, √(max(f, 0)/b)."""
        return np.sqrt(np.clip(u, 0.0, None) / self.params.thrust_coefficient)

    def reset(self, x0) -> None:
        """Start a flight at x0 (12,): t = 0, rotor speeds at hover (√(m·g/4 / b))."""
        as_vector("x0", x0, N_STATES)
        self._k = 0
        self._rotor_speeds = self.commanded_speeds(np.full(N_INPUTS, self.params.hover_thrust))

    def step(self, x, u) -> np.ndarray:
        """The state one sampling interval later.

        Parameters
        ----------
        x : (12,) array, state now (m, rad, m/s, rad/s; see :mod:`paper_repro.vehicles.quadrotor`).
        u : (4,) array, commanded rotor thrusts f1..f4 held over the interval, N.

        Returns
        -------
        (12,) array, the state at t + T_s (a new array). The Euler angles are unwrapped to
        stay within π of those of ``x``.
        """
        x = as_vector("x", x, N_STATES)
        u = as_vector("u", u, N_INPUTS)
        if self._rotor_speeds is None:
            self.reset(x)
        state = to_rotorpy_state(x, self._rotor_speeds)
        if self.effects.motor_lag == 0:
            state["rotor_speeds"] = self.commanded_speeds(u)
        if self.wind is not None:
            state["wind"] = as_vector("wind(t)", self.wind(self.time), 3)
        # RotorPy's cmd_motor_thrusts asks for √(f/k_η) with its (true) k_η; scaling f by
        # k_η/b makes that the nominal √(f/b) (see PlantParams.thrust_scale).
        control = {"cmd_motor_thrusts": u * self.effects.thrust_scale}
        # RotorPy draws (zero) motor noise from the legacy global generator: leave it as found.
        rng_state = np.random.get_state()  # noqa: NPY002
        try:
            new = self.vehicle.step(state, control, self.ts)
        finally:
            np.random.set_state(rng_state)  # noqa: NPY002
        self._rotor_speeds = np.array(new["rotor_speeds"], float)
        self._k += 1
        return from_rotorpy_state(new, x[3:6])


def rotorpy_params(params: QuadrotorParams, effects: PlantParams) -> dict:
    """RotorPy's parameter dict of our quadrotor with ``effects``.

    Rotor i sits at h·e_i in the "+" layout (rotor 1 on +x_b, 2 on +y_b, 3 on −x_b, 4 on −y_b),
    minus the centre-of-mass offset. k_η = thrust_scale·b, k_m = k_τ, rotor directions
    (1, −1, 1, −1), so that the yaw torque is (k_τ/b)(f1 − f2 + f3 − f4). Rotor speeds are
    within [0, ∞): RotorPy clips negative commands to 0, and the NMPC's bounds, not the
    plant, limit the thrusts.
    """
    offset = np.asarray(effects.com_offset, float)
    ixx, iyy, izz = params.inertia
    c_d = effects.parasitic_drag
    return {
        "mass": params.mass * effects.mass_scale,
        "Ixx": ixx, "Iyy": iyy, "Izz": izz, "Ixy": 0.0, "Ixz": 0.0, "Iyz": 0.0,
        "num_rotors": N_INPUTS,
        "rotor_pos": {f"r{i + 1}": params.arm * _ROTORS[i] - offset for i in range(N_INPUTS)},
        "rotor_directions": _DIRECTIONS.copy(),
        "c_Dx": float(c_d[0]), "c_Dy": float(c_d[1]), "c_Dz": float(c_d[2]),
        "k_eta": params.thrust_coefficient * effects.thrust_scale,
        "k_m": params.drag_coefficient,
        "k_d": float(effects.rotor_drag), "k_z": float(effects.induced_inflow),
        "k_h": float(effects.translational_lift), "k_flap": float(effects.blade_flapping),
        "tau_m": float(effects.motor_lag) if effects.motor_lag > 0 else math.inf,
        "rotor_speed_min": 0.0, "rotor_speed_max": math.inf, "motor_noise_std": 0.0,
    }


def to_rotorpy_state(x, rotor_speeds, wind=(0.0, 0.0, 0.0)) -> dict:
    """RotorPy's state dict of our state ``x`` (12,).

    Returns ``{'x', 'v'}`` (3,) m and m/s, ``'q'`` (4,) the quaternion [i, j, k, w] of
    R = Rz(ψ)·Ry(θ)·Rx(φ), ``'w'`` (3,) the body rates ω = E(φ, θ)·(φ̇, θ̇, ψ̇) in rad/s,
    ``'wind'`` (3,) m/s and ``'rotor_speeds'`` (4,) rad/s.
    """
    phi, theta, psi = x[3], x[4], x[5]
    dphi, dtheta, dpsi = x[9], x[10], x[11]
    sphi, cphi, sth, cth = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta)
    omega = np.array([dphi - sth * dpsi, cphi * dtheta + sphi * cth * dpsi,
                      -sphi * dtheta + cphi * cth * dpsi])
    return {"x": np.array(x[0:3], float), "v": np.array(x[6:9], float),
            "q": Rotation.from_euler("ZYX", [psi, theta, phi]).as_quat(), "w": omega,
            "wind": np.array(wind, float), "rotor_speeds": np.array(rotor_speeds, float)}


def from_rotorpy_state(state: dict, angles_near=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Our state (12,) of RotorPy's state dict; the inverse of :func:`to_rotorpy_state`.

    The Euler angles (φ, θ, ψ) are unwrapped to within π of ``angles_near`` (3,) rad.
    """
    psi, theta, phi = Rotation.from_quat(state["q"]).as_euler("ZYX")
    near = np.asarray(angles_near, float)
    angles = np.array([phi, theta, psi])
    angles = near + (angles - near + np.pi) % (2 * np.pi) - np.pi
    phi, theta = angles[0], angles[1]
    wx, wy, wz = state["w"]
    sphi, cphi, sth, cth = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta)
    dpsi = (sphi * wy + cphi * wz) / cth
    dtheta = cphi * wy - sphi * wz
    dphi = wx + sth * dpsi
    return np.concatenate([state["x"], angles, state["v"], [dphi, dtheta, dpsi]])

"""The model interface: what the NMPC needs to know about a vehicle, for any vehicle.

A :class:`VehicleModel` is plain data, as acados' ``AcadosModel``: continuous dynamics
ẋ = f_c(x, u) and an output map y = h(x) ∈ R^p (p = 3 for a flying vehicle, 2 for a ground
robot) as CasADi functions, box bounds on x and u (the sets 𝒳 and 𝒰 of eq. 7), and optionally
an exact parametrisation of the equilibrium set (:class:`Equilibria`). Problem (21) is built
from it by :class:`paper_repro.problem.ocp.OCP`, and both solvers read that.

The equilibrium parametrisation is what makes the artificial equilibrium cheap. With it,
(x_a, u_a) = (state(a), input(a)) for a free a ∈ R^{n_a} (for the quadrotor a = (position,
yaw), with hover thrust), and the condition x_a = f(x_a, u_a) holds by construction. Without
it, the real-time solver carries (x_a, u_a) themselves and imposes x_a = f(x_a, u_a) as
equality rows at the last stage: any model works, at the price of n_x + n_u carried states
instead of n_a.

A ground robot, for example (:mod:`paper_repro.vehicles.unicycle` has the full version)::

    x, u = ca.SX.sym("x", 3), ca.SX.sym("u", 2)          # (p_x, p_y, θ), (v, ω)
    unicycle = VehicleModel(
        "unicycle",
        dynamics=ca.Function("f_c", [x, u], [ca.vertcat(u[0] * ca.cos(x[2]),
                                                         u[0] * ca.sin(x[2]), u[1])]),
        output=ca.Function("h", [x], [x[:2]]),
        state_lower=(-10, -10, -2 * np.pi), state_upper=(10, 10, 2 * np.pi),
        input_lower=(-1, -2), input_upper=(1, 2))
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass(frozen=True)
class Equilibria:
    """An exact parametrisation of a model's equilibrium set: f_c(state(a), input(a)) = 0.

    Attributes
    ----------
    state : CasADi function a (n_a,) -> x_a (n_x,).
    input : CasADi function a (n_a,) -> u_a (n_u,).
    of_state : x (n_x,) -> a (n_a,), the equilibrium "at" a state (where a guess rests).
    lower, upper : (n_a,) box on a, standing for (x_a, u_a) ∈ λ(𝒳 × 𝒰). ``None`` (the usual
        case) when every a_k is an entry of x_a, as the quadrotor's position and yaw: the
        :class:`~paper_repro.problem.ocp.OCP` then bounds a_k by λ(𝒳) at that entry.
    """

    state: ca.Function
    input: ca.Function
    of_state: Callable[[np.ndarray], np.ndarray]
    lower: tuple[float, ...] | None = None
    upper: tuple[float, ...] | None = None

    @property
    def size(self) -> int:
        """n_a, the number of parameters."""
        return int(self.state.size1_in(0))


@dataclass(frozen=True)
class VehicleModel:
    """A vehicle as the NMPC sees it.

    Attributes
    ----------
    name : a short name (used in generated code and messages).
    dynamics : CasADi function f_c(x (n_x,), u (n_u,)) -> ẋ (n_x,), continuous time.
    output : CasADi function h(x (n_x,)) -> y (p,), p = 2 or 3: the point that must keep clear
        of the clouds (and the one tracked to the target y_t), m.
    state_lower, state_upper : (n_x,) the box 𝒳.
    input_lower, input_upper : (n_u,) the box 𝒰.
    equilibria : an exact parametrisation of the equilibrium set, or ``None``: then the solvers
        carry (x_a, u_a) and impose x_a = f(x_a, u_a). Those rows must be linearly independent
        at the equilibria (as the quadrotor's are); where they are not, give a parametrisation
        (the unicycle's v cos θ = v sin θ = 0 are not, and IPOPT fails on them).
    rest_input : (n_u,) the input of a guess that rests where the vehicle is, when there is no
        parametrisation (``None``: zero, clipped into 𝒰).
    position : indices of the states that are the vehicle's position, along which its dynamics
        are invariant. The real-time solver moves the previous plan along them to where the
        vehicle is (:meth:`~paper_repro.problem.ocp.NMPCSolution.reanchored`); ``()`` shifts it in
        time instead. :func:`~paper_repro.sim.loop.simulate` starts the vehicle at rest with
        these states at the scene's start.
    velocity : indices of the states that are the vehicle's velocity (m/s), which the closed
        loop reads to tell a stall; ``()``: the output's change over a step tells it instead.
    state_names, input_names : a name for each state and each input (identifiers): the
        columns of :meth:`~paper_repro.sim.result.SimulationResult.to_frame`. ``()``:
        ``x0, x1, …`` and ``u0, u1, …``.
    """

    name: str
    dynamics: ca.Function
    output: ca.Function
    state_lower: tuple[float, ...]
    state_upper: tuple[float, ...]
    input_lower: tuple[float, ...]
    input_upper: tuple[float, ...]
    equilibria: Equilibria | None = None
    rest_input: tuple[float, ...] | None = None
    position: tuple[int, ...] = ()
    velocity: tuple[int, ...] = ()
    state_names: tuple[str, ...] = ()
    input_names: tuple[str, ...] = ()

    def __post_init__(self):
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ValueError(f"name must be an identifier (it names generated C), got "
                             f"{self.name!r}")
        f, h = self.dynamics, self.output
        if not (isinstance(f, ca.Function) and f.n_in() == 2 and f.n_out() == 1):
            raise ValueError("dynamics must be a CasADi Function f_c(x, u) -> xdot")
        nx, nu = f.size1_in(0), f.size1_in(1)
        if f.size_out(0) != (nx, 1) or f.size2_in(0) != 1 or f.size2_in(1) != 1:
            raise ValueError(f"dynamics must map x ({nx},) and u ({nu},) to xdot ({nx},), got "
                             f"an output of shape {f.size_out(0)}")
        if not (isinstance(h, ca.Function) and h.n_in() == 1 and h.size_in(0) == (nx, 1)
                and h.size2_out(0) == 1 and h.size1_out(0) in (2, 3)):
            raise ValueError(f"output must be a CasADi Function h(x ({nx},)) -> y of shape "
                             f"(2,) or (3,)")
        for name, n in (("state_lower", nx), ("state_upper", nx), ("input_lower", nu),
                        ("input_upper", nu)):
            v = getattr(self, name)
            if not (len(v) == n and all(math.isfinite(float(b)) for b in v)):
                raise ValueError(f"{name} must be {n} finite numbers, got {v!r}")
        for lo, hi in (("state_lower", "state_upper"), ("input_lower", "input_upper")):
            for i, (a, b) in enumerate(zip(getattr(self, lo), getattr(self, hi))):
                if not a < b:
                    raise ValueError(f"{lo}[{i}] must be < {hi}[{i}], got {a!r} >= {b!r}")
        e = self.equilibria
        if e is not None:
            na = e.size
            if e.state.size_out(0) != (nx, 1) or e.input.size_out(0) != (nu, 1) \
                    or e.input.size1_in(0) != na:
                raise ValueError(f"equilibria must map a ({na},) to x_a ({nx},) and u_a ({nu},)")
            if (e.lower is None) != (e.upper is None) or e.lower is not None and not (
                    len(e.lower) == na == len(e.upper)
                    and all(a < b for a, b in zip(e.lower, e.upper))):
                raise ValueError(f"equilibria.lower < equilibria.upper must hold for all {na} "
                                 "parameters (or both be None)")
        for name, n in (("state_names", nx), ("input_names", nu)):
            v = getattr(self, name)
            if v and not (len(v) == n and len(set(v)) == n
                          and all(isinstance(c, str) and c.isidentifier() for c in v)):
                raise ValueError(f"{name} must be {n} distinct identifiers (or empty), got "
                                 f"{v!r}")
        for name in ("position", "velocity"):
            if not all(isinstance(i, int) and 0 <= i < nx for i in getattr(self, name)):
                raise ValueError(f"{name} must hold state indices in [0, {nx}), got "
                                 f"{getattr(self, name)!r}")
        if self.rest_input is not None and len(self.rest_input) != nu:
            raise ValueError(f"rest_input must have {nu} entries, got {self.rest_input!r}")

    @property
    def nx(self) -> int:
        """n_x, the number of states."""
        return int(self.dynamics.size1_in(0))

    @property
    def nu(self) -> int:
        """n_u, the number of inputs."""
        return int(self.dynamics.size1_in(1))

    @property
    def ny(self) -> int:
        """p, the dimension of the output y (2 or 3)."""
        return int(self.output.size1_out(0))

    def description(self) -> dict:
        """What a saved run needs to read its arrays without the model: the vehicle's name,
        the names of its states and inputs, and which states are its position."""
        return {"name": self.name,
                "states": list(self.state_names or (f"x{i}" for i in range(self.nx))),
                "inputs": list(self.input_names or (f"u{i}" for i in range(self.nu))),
                "position": list(self.position)}

    def rest(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(x_a, u_a): the equilibrium a guess rests at, for the vehicle in state ``x``.

        With a parametrisation, state(a) and input(a) for a = of_state(x); without, x itself and
        ``rest_input`` (not necessarily an equilibrium: the solver makes it one).
        """
        x = np.asarray(x, float)
        e = self.equilibria
        if e is not None:
            a = np.asarray(e.of_state(x), float)
            return (np.asarray(e.state(a), float).ravel(), np.asarray(e.input(a), float).ravel())
        lo, hi = np.asarray(self.input_lower, float), np.asarray(self.input_upper, float)
        u = np.zeros(self.nu) if self.rest_input is None else np.asarray(self.rest_input, float)
        return x.copy(), np.clip(u, lo, hi)


def rk4(dynamics: ca.Function, ts: float, steps: int = 1) -> ca.Function:
    """One RK4 step of length ``ts`` (s, split into ``steps`` sub-steps) of ẋ = f_c(x, u) under
    zero-order hold of u: the CasADi function ``f(x, u) -> x_next``, the prediction model of
    eq. (1)."""
    if not (isinstance(ts, (int, float)) and math.isfinite(ts) and ts > 0):
        raise ValueError(f"ts must be a finite number > 0 (s), got {ts!r}")
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
    x = ca.SX.sym("x", dynamics.size1_in(0))
    u = ca.SX.sym("u", dynamics.size1_in(1))
    h = ts / steps
    xk = x
    for _ in range(steps):
        k1 = dynamics(xk, u)
        k2 = dynamics(xk + h / 2 * k1, u)
        k3 = dynamics(xk + h / 2 * k2, u)
        k4 = dynamics(xk + h * k3, u)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("f_d", [x, u], [xk], ["x", "u"], ["x_next"])

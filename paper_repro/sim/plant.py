"""The plant: what the closed loop flies, and the plants this package brings.

:class:`Plant` is the interface. Anything with ``step(x, u) -> x_next`` is a plant:
:func:`~paper_repro.sim.loop.simulate` holds u over T_s and asks the plant where the vehicle
is one sampling interval later. A plant may also have ``reset(x0)``, called once before the
first step (a plant with states of its own, such as rotor speeds or a wind field, starts
them there), and ``measure(x) -> x_measured``, the state the controller is given at an
instant (an estimate with noise or latency); without it the controller is given the true
state. A plant from another simulator is an object of a few lines around its step function.

Two plants come with the package:

* :class:`QuadrotorPlant`, the quadrotor of Table I. The paper simulates it with MATLAB's
  ODE45; :func:`paper_repro.vehicles.quadrotor.plant_step` does it with ``solve_ivp`` (RK45,
  the same Dormand–Prince 5(4) pair). That costs about 0.2–0.3 ms per sampling interval,
  nearly all of it Python: eight calls of the right-hand side and the solver's bookkeeping.
  :class:`QuadrotorPlant` runs the same method in C: the right-hand side is
  :func:`paper_repro.vehicles.quadrotor.symbolic_dynamics` generated as C by CasADi, and the
  integration loop (``_plant_dp45.c``) replicates scipy's RK45 step control — initial step
  selection, RMS error norm, safety factor 0.9, step factors within [0.2, 10], the last step
  cut to end at t = T_s — so both take the same steps and agree to rounding (about 1e-12
  over a second of flight). Without a C compiler (or with ``compile=False``) it falls back on
  :func:`~paper_repro.vehicles.quadrotor.plant_step`: same results, slower.
* :class:`ModelPlant`, any :class:`~paper_repro.vehicles.base.VehicleModel`'s own dynamics
  integrated by RK4.
"""

from __future__ import annotations

import ctypes
import math
import os
import tempfile
from importlib import resources
from pathlib import Path
from typing import Protocol, runtime_checkable

import casadi as ca
import numpy as np

from paper_repro._native import compiler, load_library
from paper_repro.config import ESTIMATES, Config, QuadrotorParams
from paper_repro.validation import as_vector
from paper_repro.vehicles.base import VehicleModel, rk4
from paper_repro.vehicles.quadrotor import (
    N_INPUTS,
    N_STATES,
    plant_step,
    symbolic_dynamics,
)

_EPS = np.finfo(float).eps
_STATUS = {1: "the step size fell below 10 ulp of t", 2: "the right-hand side failed"}


@runtime_checkable
class Plant(Protocol):
    """What :func:`~paper_repro.sim.loop.simulate` flies: an object with a ``step``.

    Optional methods, used when present:

    * ``reset(x0)``: called once before the first step, with the initial state (n_x,).
    * ``measure(x) -> x_measured``: the state (n_x,) the controller is given when the vehicle
      is in the true state ``x``; without it the controller is given ``x``.
    """

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The state one sampling interval later: ``x`` (n_x,) the state now, ``u`` (n_u,)
        the input held over the interval; a new (n_x,) array."""
        ...


class QuadrotorPlant:
    """The quadrotor of Table I integrated over one sampling interval under zero-order hold.

    Built once (compiling the C on first use per machine, then loading it from the cache of
    :mod:`paper_repro._native`); :meth:`step` is the hot path.

    Parameters
    ----------
    params : quadrotor parameters, Table I by default.
    ts : T_s, s, sampling interval (the input is held over it). *paper* 0.01.
    rtol, atol : relative and absolute tolerances of the RK45 step control, as
        :func:`~paper_repro.vehicles.quadrotor.plant_step` uses them (ODE45-like accuracy).
    compile : use the compiled integrator when a C compiler is available; ``False`` (or no
        compiler) integrates with :func:`~paper_repro.vehicles.quadrotor.plant_step`
        (``solve_ivp``).

    Attributes
    ----------
    native : bool, whether :meth:`step` runs the compiled integrator.
    stats : (3,) int array of the last compiled step: accepted steps, rejected steps,
        right-hand-side evaluations (zeros on the fallback path).
    """

    def __init__(self, params: QuadrotorParams | None = None, ts: float = 0.01,
                 rtol: float = 1e-8, atol: float = 1e-10, compile: bool = True):
        if not isinstance(params, (QuadrotorParams, type(None))):
            raise ValueError(f"params must be a QuadrotorParams or None, got {params!r}")
        for name, value, low in (("ts", ts, 0.0), ("rtol", rtol, 100 * _EPS)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > low):
                raise ValueError(f"{name} must be a finite number > {low:g}, got {value!r}")
        if not (isinstance(atol, (int, float)) and math.isfinite(atol) and atol >= 0):
            raise ValueError(f"atol must be a finite number >= 0, got {atol!r}")
        self.params = params or QuadrotorParams()
        self.ts, self.rtol, self.atol = float(ts), float(rtol), float(atol)
        self.native = bool(compile) and compiler() is not None
        self.stats = np.zeros(3, dtype=np.intc)
        if self.native:
            self._fn = _library(self.params).plant_dp45
            # Fixed buffers: a step copies its arguments in and the result out, and the
            # pointers are made once (ctypes conversions cost more than the integration).
            self._x, self._u, self._out = (np.zeros(n) for n in (N_STATES, N_INPUTS, N_STATES))
            self._args = [ctypes.c_void_p(a.ctypes.data) for a in (self._x, self._u)]
            self._args += [ctypes.c_double(self.ts), ctypes.c_double(self.rtol),
                           ctypes.c_double(self.atol), ctypes.c_void_p(self._out.ctypes.data),
                           ctypes.c_void_p(self.stats.ctypes.data)]

    def step(self, x, u) -> np.ndarray:
        """The state one sampling interval later.

        Parameters
        ----------
        x : (12,) array, state now (m, rad, m/s, rad/s; see :mod:`paper_repro.vehicles.quadrotor`).
        u : (4,) array, rotor thrusts f1..f4 held over the interval, N.

        Returns
        -------
        (12,) array, the state at t + T_s (a new array).
        """
        x = as_vector("x", x, N_STATES)
        u = as_vector("u", u, N_INPUTS)
        if not self.native:
            return plant_step(x, u, self.ts, self.params, rtol=self.rtol, atol=self.atol)
        self._x[:] = x
        self._u[:] = u
        info = self._fn(*self._args)
        if info:  # pragma: no cover - RK45 on this smooth ODE does not fail
            raise RuntimeError(f"plant integration failed: {_STATUS.get(info, info)}")
        return self._out.copy()


def _library(params: QuadrotorParams) -> ctypes.CDLL:
    """CasADi's C of the right-hand side with the DP45 loop appended, built once (cached)."""
    f_c = symbolic_dynamics(params)
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator("plant_rhs.c", {"with_header": False})
        gen.add(f_c)
        rhs = Path(gen.generate(str(Path(tmp)) + os.sep)).read_bytes()
    sizes = (f"#define PLANT_SZ_ARG {f_c.sz_arg()}\n#define PLANT_SZ_RES {f_c.sz_res()}\n"
             f"#define PLANT_SZ_IW {f_c.sz_iw()}\n#define PLANT_SZ_W {f_c.sz_w()}\n")
    loop = resources.files("paper_repro.sim").joinpath("_plant_dp45.c").read_bytes()
    lib = load_library("plant_dp45", rhs + sizes.encode() + loop,
                       key_extra=ca.__version__.encode())
    lib.plant_dp45.restype = ctypes.c_int
    lib.plant_dp45.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_double,
                               ctypes.c_double, ctypes.c_double, ctypes.c_void_p,
                               ctypes.c_void_p]
    return lib


class ModelPlant:
    """The plant of any :class:`~paper_repro.vehicles.base.VehicleModel`: its own dynamics
    f_c, integrated by RK4 over T_s in ``substeps`` steps under zero-order hold of u.

    ``step(x (n_x,), u (n_u,)) -> x_next (n_x,)``, as every :class:`Plant`. A vehicle of
    your own flies with this unless you give :func:`~paper_repro.sim.loop.simulate` a plant.
    """

    def __init__(self, model: VehicleModel, ts: float, substeps: int = 10):
        self.model, self.ts, self.substeps = model, ts, substeps
        self._step = rk4(model.dynamics, ts, substeps)

    def step(self, x, u) -> np.ndarray:
        x = as_vector("x", x, self.model.nx)
        u = as_vector("u", u, self.model.nu)
        return np.asarray(self._step(x, u), float).ravel()


def plant_for(model: VehicleModel, config: Config, altitude: float = 2.0, scene=None):
    """The plant a closed loop flies ``model`` with, as ``config.plant`` says.

    * The simulator: :class:`QuadrotorPlant` (RK45 in C, as the paper's ODE45) for the
      quadrotor of ``config``, :class:`ModelPlant` for any other vehicle; or, with
      ``plant.simulator = "rotorpy"``, :class:`~paper_repro.sim.rotorpy_plant.RotorpyPlant`
      with the plant's effects and wind (:func:`wind_of`, its turbulence at ``altitude``, m).
    * ``plant.estimation``: the controller is given an estimate
      (:class:`~paper_repro.sim.imperfect.EstimatedState`).
    * ``plant.delay_steps``: the inputs arrive late
      (:class:`~paper_repro.sim.imperfect.DelayedInput`).
    * ``plant.estimate_filter_time``: the estimate is filtered with the nominal model
      (:class:`~paper_repro.sim.imperfect.EstimateFilter`).
    * ``plant.compensate_latency``: the controller is given the state predicted over both
      latencies with the nominal model
      (:class:`~paper_repro.sim.imperfect.LatencyCompensation`).
    * ``plant.motor_lag_compensation``: each thrust is sent with a lead that inverts the
      rotors' lag (:class:`~paper_repro.sim.imperfect.MotorLagCompensation`).
    * ``plant.hover_thrust_time``: the thrusts sent are scaled by a learnt correction
      (:class:`~paper_repro.sim.imperfect.HoverThrustEstimate`).
    * ``plant.gust_clearance``: the gust starts when the vehicle comes that close to a cloud
      point of ``scene`` (:class:`GustTrigger`).
    """
    from paper_repro.sim.imperfect import (
        DelayedInput,
        EstimatedState,
        EstimateFilter,
        HoverThrustEstimate,
        LatencyCompensation,
        MotorLagCompensation,
    )

    p, ts = config.plant, config.nmpc.ts
    quadrotor = model.name == "quadrotor"
    if not quadrotor and (p.simulator != "ours" or p.estimation != "perfect"):
        raise ValueError(f"plant.simulator {p.simulator!r} and plant.estimation "
                         f"{p.estimation!r} are for the quadrotor; {model.name!r} flies "
                         "simulator 'ours' with estimation 'perfect'")
    if p.simulator == "rotorpy":
        from paper_repro.sim.rotorpy_plant import RotorpyPlant

        wind = wind_of(config, altitude) if p.moving_air() else None
        plant = RotorpyPlant(config.quadrotor, ts, p, wind=wind)
        if p.gust_clearance is not None:
            if scene is None:
                raise ValueError("plant.gust_clearance times the gust by the scene's clouds: "
                                 "plant_for needs the scene")
            plant = GustTrigger(plant, wind.gusts[0], scene, p.gust_clearance, ts)
    elif quadrotor:
        plant = QuadrotorPlant(config.quadrotor, ts)
    else:
        plant = ModelPlant(model, ts)
    if p.motor_lag_compensation is not None:
        if not quadrotor:
            raise ValueError(f"plant.motor_lag_compensation is for the quadrotor, not "
                             f"{model.name!r}")
        plant = MotorLagCompensation(plant, ts, p.motor_lag_compensation,
                                     (model.input_lower, model.input_upper))
    if p.estimation != "perfect":
        s_p, s_a, s_v, s_r, latency = ESTIMATES[p.estimation]
        plant = EstimatedState(plant, np.repeat([s_p, s_a, s_v, s_r], 3), latency, p.seed)
    rest_input = model.rest(np.zeros(model.nx))[1]
    if p.delay_steps:
        plant = DelayedInput(plant, p.delay_steps, rest_input)

    def nominal():  # the NMPC's own model, for the remedies that predict with it
        return QuadrotorPlant(config.quadrotor, ts) if quadrotor else ModelPlant(model, ts)

    if p.estimate_filter_time is not None:
        plant = EstimateFilter(plant, nominal(), ts, p.estimate_filter_time, p.latency_steps(),
                               rest_input)
    if p.hover_thrust_time is not None:
        if not quadrotor:
            raise ValueError(f"plant.hover_thrust_time is for the quadrotor, not "
                             f"{model.name!r}")
        q = config.quadrotor
        plant = HoverThrustEstimate(plant, ts, q.mass, q.gravity, p.hover_thrust_time,
                                    (model.input_lower, model.input_upper), p.latency_steps(),
                                    rest_input)
    if p.compensate_latency:
        plant = LatencyCompensation(plant, nominal(), p.latency_steps(), rest_input)
    return plant


def wind_of(config: Config, altitude: float):
    """The :class:`~paper_repro.world.wind.Wind` of ``config.plant``: its mean wind, its
    Dryden turbulence at ``altitude`` (m, at least 0.5), seen at the mean wind's speed (at
    least 1 m/s) from the mean wind's heading, and its 1-cosine gust."""
    from paper_repro.world.wind import OneCosineGust, Wind, dryden_turbulence

    p = config.plant
    mean = np.asarray(p.wind, float)
    turbulence = None
    if p.turbulence != "none":
        turbulence = dryden_turbulence(p.turbulence, max(float(altitude), 0.5),
                                       max(float(np.linalg.norm(mean)), 1.0),
                                       config.nmpc.ts, p.seed,
                                       heading=float(np.arctan2(mean[1], mean[0])))
    gusts = ((OneCosineGust(p.gust, p.gust_duration, p.gust_start),) if any(p.gust) else ())
    return Wind(mean, turbulence, gusts)


class GustTrigger:
    """``plant``, whose ``gust`` (a :class:`~paper_repro.world.wind.OneCosineGust` of its wind)
    starts at the first step at which the vehicle's position is within ``distance`` (m) of a
    cloud point of ``scene`` (where the cloud is at that time). Until then the gust is off.

    The position is the quadrotor's, states 0-2; the time is the step's, k·``ts``."""

    def __init__(self, plant, gust, scene, distance: float, ts: float):
        from paper_repro.world.truth import TrueClearance

        self.plant, self.gust, self.distance, self.ts = plant, gust, float(distance), ts
        self.clearance = TrueClearance(scene)
        self.gust.start, self.k = math.inf, 0  # off until the vehicle comes close

    def reset(self, x0) -> None:
        self.gust.start, self.k = math.inf, 0
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        """Start the gust now if the vehicle is close enough, then step the plant."""
        t = self.k * self.ts
        if math.isinf(self.gust.start):
            near = self.clearance.along(np.asarray(x, float)[None, :3], np.array([t]))[0]
            if near < self.distance:
                self.gust.start = t
        self.k += 1
        return self.plant.step(x, u)

    def measure(self, x) -> np.ndarray:
        measure = getattr(self.plant, "measure", None)
        return measure(x) if callable(measure) else x

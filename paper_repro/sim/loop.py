"""The closed loop for any vehicle: perception → controller → plant (zero-order hold).

The step loop of :func:`simulate` is short on purpose; read it to see exactly what happens at
each sampling instant. Its parts have modules of their own: what the controller is given
(:mod:`~paper_repro.sim.perception`), what the vehicle flies in (:mod:`~paper_repro.sim.plant`)
and when the flight ends (:mod:`~paper_repro.sim.termination`). :class:`SimulationResult`
saves itself as ``result.npz`` with the full ``config.json`` beside it, and becomes a pandas
DataFrame with :meth:`SimulationResult.to_frame`.

Before anything is built, :func:`~paper_repro.sim.checks.check_setup` rejects an inconsistent
mission (``ValueError``) and :func:`~paper_repro.sim.checks.setup_hazards` warns of an unsafe
one (a start or target inside the unsafe set or within the rotor radius of a cloud, a
target the artificial equilibrium cannot reach); the hazards are kept in
``meta["hazards"]``.

At step k (time t = k·T_s) the LiDAR sees each region where it is at t
(:meth:`~paper_repro.world.lidar.Lidar.scan`), and the clearance is measured to the regions'
true positions at t. With ``nmpc.prediction`` ``"static"`` (the paper) the
controller is called as ``ctl.solve(x, target, visible, previous=plan)``; with
``"oracle"`` or ``"kalman"`` it is also given ``velocities=``, one (3,) m/s per region of
the scan: the regions' true velocities at t (:func:`~paper_repro.world.truth.scene_velocities`),
or the estimates of a :class:`paper_repro.world.tracking.RegionTracker` updated with each scan.

The run ends when it is complete (every target reached; for ``kind="passage"`` the finish
line crossed), when it stalls, after ``max_steps``, or after persistent faults: see
:data:`OUTCOMES`. A failed solve never stops the run: it is recorded in
``success``/``status`` and the previous plan, shifted by one step, is applied instead (its
first input). Non-finite points in a scan are dropped and counted in ``dropped_points``; a
non-finite measured state or a solve that raises is a fault (:data:`FAULT_STATUSES`),
handled the same way.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from paper_repro.config import Config, relaxed_box
from paper_repro.problem.ocp import Controller, NMPCSolution, selected_states
from paper_repro.progress import step_progress
from paper_repro.sim.checks import SetupHazardWarning, check_setup, setup_hazards
from paper_repro.sim.perception import Perception
from paper_repro.sim.plant import plant_for
from paper_repro.sim.result import (
    FAULT_STATUSES,
    RESULT_ARRAYS,
    SimulationResult,
    run_metadata,
)
from paper_repro.sim.termination import Termination
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.base import VehicleModel
from paper_repro.vehicles.quadrotor import quadrotor_model
from paper_repro.world.guide import Guide
from paper_repro.world.local_map import VoxelMap
from paper_repro.world.scenarios import mission_scene
from paper_repro.world.scene import Scene
from paper_repro.world.truth import TrueClearance


@dataclass(frozen=True)
class Faults:
    """Faults injected into a closed loop, for robustness tests and studies.

    Attributes
    ----------
    scan : ``(k, visible) -> visible``, applied to the LiDAR scan of step k (e.g. NaN points,
        an empty scan, a region's points removed).
    state : ``(k, x) -> x_measured``, the state the controller is given at step k (e.g. a NaN
        estimate); the plant keeps its true state.
    """

    scan: Callable | None = None
    state: Callable | None = None


def simulate(config: Config | None = None, controller: Controller | None = None,
             max_steps: int | None = None, progress: bool | None = None,
             scene: Scene | None = None, faults: Faults | None = None,
             initial_state=None, model: VehicleModel | None = None,
             plant=None) -> SimulationResult:
    """Fly the configured scenario in closed loop, with any vehicle.

    Parameters
    ----------
    config : run configuration (defaults: the paper's settings, ``paper`` scenario).
    controller : a built controller for the same config (built here if omitted; building is
        the slow part, so pass one in when flying several missions). It is reset first
        (:meth:`reset`), so a flight is the same whether the controller is new or reused.
    max_steps : overrides ``config.simulation.max_steps``.
    progress : a progress bar (``True``; default: only when writing to a terminal), or a
        callable that receives a plain progress line every 15 s (for logs).
    scene : fly this scene instead of ``config.simulation.scenario`` (e.g. your own regions, or
        a variant made with ``dataclasses.replace``); it is saved with the result.
    faults : sensor faults to inject (:class:`Faults`); none by default.
    initial_state : (n_x,) state to start from instead of rest at ``scene.start`` (to fly a
        window of a mission from a state another flight reached, every solver from the same
        state; the clock still starts at t = 0, so use it on static scenes).
    model : the :class:`~paper_repro.vehicles.base.VehicleModel` flown (default: the
        controller's, ``controller.ocp.model``, else the quadrotor of ``config``). Its output
        y = h(x) is what the LiDAR sees from, what keeps clear and what tracks the targets; its
        ``position`` states start at ``scene.start`` (at rest, the other states zero); its
        ``velocity`` states tell a stall. A planar vehicle (p = 2) flies a planar scene.
    plant : what the vehicle flies in, any :class:`~paper_repro.sim.plant.Plant`: an object
        with ``step(x, u) -> x_next`` over T_s, and optionally ``reset(x0)`` (called before
        the first step) and ``measure(x) -> x_measured`` (the state the controller is given;
        :class:`Faults` ``state`` then acts on it). Default
        :func:`~paper_repro.sim.plant.plant_for`: the quadrotor's RK45 in C, RK4 of the
        model's own dynamics for any other vehicle.
    """
    cfg = config or Config()
    if max_steps is not None:
        cfg = dataclasses.replace(cfg, simulation=dataclasses.replace(cfg.simulation,
                                                                      max_steps=max_steps))
    f = _assemble(cfg, controller, scene, faults, initial_state, model, plant)
    ctl, stop, log, perception, guide = f.controller, f.stop, f.log, f.perception, f.guide
    x, ts = f.x0, cfg.nmpc.ts
    plan: NMPCSolution | None = None
    errors, last_good = [], x.copy()
    bar = step_progress(cfg.simulation.max_steps, progress)
    wall = time.perf_counter()
    y = f.output(x)
    for k in range(cfg.simulation.max_steps):
        t, target = k * ts, stop.target
        measured = f.measure(k, x)
        seen = perception.sense(k, t, y)
        if seen.velocities is not None:
            log.region_velocities[k] = seen.velocities  # what the controller is handed
        set_point = target
        if guide is not None:  # the path's look-ahead, from the map just updated
            set_point = log.set_points[k] = guide.set_point(perception.local_map, y, t, target)
        sol = _solve(ctl, measured, set_point, seen.visible, plan, errors, seen.velocities,
                     f.model)
        f.counters.count(sol)
        if sol.success:
            plan, last_good = sol, measured
        else:
            plan, sol = _fall_back(ctl, sol, plan, last_good)
        stop.count_fault(sol.status)
        u = plan.u[0]
        log.record(k, t, x, y, u, sol, stop.target_index,
                   sum(len(v) for v in seen.visible), seen.dropped)
        x, y_before = f.plant.step(x, u), y
        y = f.output(x)
        ended = stop.after_step(k, x, y, y_before)
        _show_progress(bar, k, stop, sol)
        if ended:
            break
    if bar is not None:
        bar.close()
    if stop.outcome == "fault":
        f.meta["fault"] = (f"{stop.faults_in_a_row} steps in a row without a usable state or "
                           f"solve (last: {sol.status}{': ' + errors[-1] if errors else ''})")
    f.meta.update(wall_time_s=time.perf_counter() - wall, errors=errors)
    return _result(f, cfg, x, y)


class _Flight(NamedTuple):
    """The parts :func:`simulate` wires together, built before the first step."""

    scene: Scene
    model: VehicleModel
    x0: np.ndarray
    plant: object
    measure: Callable[[int, np.ndarray], np.ndarray]
    output: Callable[[np.ndarray], np.ndarray]
    perception: Perception
    stop: Termination
    guide: Guide | None
    controller: Controller
    counters: _SolverCounters
    log: _Log
    meta: dict


def _assemble(cfg: Config, controller, scene, faults, initial_state, model, plant) -> _Flight:
    """Check the mission, then build every part of the flight (the controller last: building
    it is the slow part). ``meta`` holds the hazards, the vehicle, the commit and versions."""
    scene = scene if scene is not None else mission_scene(cfg.simulation)
    model = _vehicle(cfg, controller, model)
    check_setup(cfg, scene, model)  # an inconsistent mission fails here, before any build
    x = _start_state(model, scene, initial_state)
    hazards = setup_hazards(cfg, scene, model)
    for line in hazards["warnings"]:
        warnings.warn(f"{scene.name}: {line}", SetupHazardWarning, stacklevel=3)
    plant = _plant(plant, model, cfg, x, scene)
    perception = Perception(cfg, scene, None if faults is None else faults.scan)
    output = _output_map(model)
    guide = _guide(cfg, model, perception.local_map)
    ctl = controller or make_controller(cfg, model)
    ctl.reset()
    log = _Log(cfg.simulation.max_steps, model.nx, model.nu, len(output(x)),
               None if cfg.nmpc.prediction == "static" else (len(scene.clouds), scene.dim),
               None if guide is None else scene.dim)
    meta = run_metadata()  # before flying: the commit and versions that produce this run
    meta["hazards"], meta["vehicle"] = hazards, model.description()
    if callable(getattr(plant, "reset", None)):
        plant.reset(x.copy())
    return _Flight(scene, model, x, plant, _measurement(plant, faults), output, perception,
                   Termination(cfg, scene, model), guide, ctl, _SolverCounters(ctl), log, meta)


def _measurement(plant, faults: Faults | None) -> Callable[[int, np.ndarray], np.ndarray]:
    """The state the controller is given at step k: the plant's ``measure(x)`` if it has one,
    else x; then the state fault of ``faults``, if any."""
    measure = getattr(plant, "measure", None)
    state_fault = None if faults is None else faults.state

    def measured(k: int, x: np.ndarray) -> np.ndarray:
        m = x if measure is None else np.asarray(measure(x.copy()), float)
        return m if state_fault is None else state_fault(k, m.copy())
    return measured


def _result(f: _Flight, cfg: Config, x, y) -> SimulationResult:
    """The flight's result: the log, the true clearance of every step, the solver counts."""
    arrays = {**f.log.arrays(x, y), **f.perception.scans.arrays()}
    # The true clearance of every step at once, after the flight: it is only logged, and one
    # batched KD-tree query costs a fraction of one query per step.
    arrays["clearance"] = TrueClearance(f.scene).along(f.log.y[:f.log.n], arrays["t"])
    f.meta.update(scene=f.scene.name, **f.counters.since(),
                  **({} if f.guide is None else {"guide": dict(f.guide.stats)}))
    return SimulationResult(targets=f.stop.targets, reached=f.stop.reached,
                            outcome=f.stop.outcome, scene=f.scene, config=cfg, meta=f.meta,
                            **arrays)


def _fall_back(ctl, sol: NMPCSolution, plan: NMPCSolution | None, last_good):
    """After a failed solve: the previous plan shifted by one step (its first input is
    applied), or hover where the vehicle last had a usable state when there is no plan yet;
    and the failed solution, given that plan's artificial equilibrium when the solve never
    started (a fault) so that the log has one."""
    plan = plan.shifted() if plan is not None else ctl.hover_guess(last_good)
    if sol.status in FAULT_STATUSES:
        sol = dataclasses.replace(sol, x_a=plan.x_a, u_a=plan.u_a)
    return plan, sol


def _plant(plant, model: VehicleModel, cfg: Config, x0: np.ndarray, scene):
    """``plant`` checked (an object with ``step``), or the one ``cfg.plant`` describes for
    ``model`` starting at ``x0`` in ``scene`` (:func:`~paper_repro.sim.plant.plant_for`)."""
    if plant is None:
        position = x0[list(model.position)]
        plant = plant_for(model, cfg, float(position[2]) if len(position) == 3 else 2.0, scene)
    if not callable(getattr(plant, "step", None)):
        raise ValueError(f"plant must have a step(x, u) -> x_next method, got "
                         f"{type(plant).__name__}")
    return plant


def _show_progress(bar, k: int, stop: Termination, sol: NMPCSolution) -> None:
    """One step on the progress bar, with the target, the error and the solve time every 50
    steps."""
    if bar is None:
        return
    bar.update(1)
    if k % 50 == 0:
        bar.set_postfix(target=stop.target_index, error=f"{stop.error:.2f} m",
                        solve=f"{sol.solve_time * 1e3:.2g} ms")


def _guide(cfg: Config, model: VehicleModel, local_map: VoxelMap | None) -> Guide | None:
    """The :class:`~paper_repro.world.guide.Guide` of ``cfg.guide`` on the map, in the
    λ-relaxed box of the vehicle's position states (where the artificial equilibrium may
    rest); None when the set-point is the target (the paper)."""
    g = cfg.guide
    if g.planner == "none":
        return None
    lower, upper = relaxed_box(model.state_lower, model.state_upper, cfg.nmpc.lam)
    index = list(model.position)
    return Guide(lower[index], upper[index], cell=g.cell, inflation=g.inflation,
                 lookahead=g.lookahead, check_period=g.check_period,
                 replan_period=g.replan_period, max_turn=g.max_turn, climb=g.climb,
                 stuck_time=g.stuck_time, set_point_filter=g.set_point_filter)


class _SolverCounters:
    """The QPs and steps of one run by solver path (the ``rti`` solver counts them over its
    life), and why its hard QPs failed: ``since()`` gives this run's, as ``meta`` entries
    (``qp_failures``: how many failed solves had each cause; ``qp_relaxations``: the same for
    the solves the relaxed QP rescued; a cause is every QP backend's status, as
    :attr:`~paper_repro.solvers.rti.RealTimeNMPC.last_failure`)."""

    def __init__(self, ctl):
        self.ctl = ctl
        self.before = {name: dict(getattr(ctl, name)) for name in ("qp_counts", "step_counts")
                       if hasattr(ctl, name)}
        self.causes: dict[str, dict[str, int]] = {"qp_failures": {}, "qp_relaxations": {}}

    def count(self, sol: NMPCSolution) -> None:
        """Count the cause of ``sol`` when its QP failed or was relaxed."""
        entry, cause = {"qp_failed": ("qp_failures", "last_failure"),
                        "relaxed": ("qp_relaxations", "last_relaxation")}.get(
                            sol.status, (None, None))
        cause = getattr(self.ctl, cause, None) if cause else None
        if cause is not None:
            key = ", ".join(f"{k} {v}" for k, v in cause.items())
            self.causes[entry][key] = self.causes[entry].get(key, 0) + 1

    def since(self) -> dict:
        counts = {name: {k: v - before.get(k, 0) for k, v in getattr(self.ctl, name).items()}
                  for name, before in self.before.items()}
        return {**counts, **{name: c for name, c in self.causes.items() if c}}


def _vehicle(config: Config, controller, model: VehicleModel | None) -> VehicleModel:
    """The vehicle flown: ``model``, else the controller's, else the quadrotor of ``config``;
    a ``model`` that is not the controller's vehicle is refused."""
    ocp = getattr(controller, "ocp", None)
    if model is None:
        model = ocp.model if ocp is not None else quadrotor_model(config)
    if not isinstance(model, VehicleModel):
        raise ValueError(f"model must be a VehicleModel, got {type(model).__name__}")
    if ocp is not None and (ocp.model.name, ocp.nx, ocp.nu, ocp.ny) != (
            model.name, model.nx, model.nu, model.ny):
        raise ValueError(f"model {model.name!r} (n_x = {model.nx}, n_u = {model.nu}) is not "
                         f"the controller's vehicle {ocp.model.name!r} (n_x = {ocp.nx}, "
                         f"n_u = {ocp.nu})")
    return model


def _start_state(model: VehicleModel, scene: Scene, initial_state) -> np.ndarray:
    """``initial_state`` checked, or the vehicle at rest with its position states at
    ``scene.start`` (for the quadrotor, hover there with zero yaw)."""
    if initial_state is not None:
        x = np.array(initial_state, dtype=float)
        if x.shape != (model.nx,) or not np.isfinite(x).all():
            raise ValueError(f"initial_state must be a finite ({model.nx},) state, got "
                             f"{np.shape(initial_state)}")
        return x
    if len(model.position) != scene.dim:
        raise ValueError(f"model {model.name!r} has {len(model.position)} position states and "
                         f"scene {scene.name!r} is {scene.dim}-D: give the model's position "
                         "(VehicleModel.position) or an initial_state")
    x = np.zeros(model.nx)
    x[list(model.position)] = scene.start
    return x


def _output_map(model: VehicleModel):
    """y = h(x) as a function of a state array: an index when h selects states (as every
    vehicle here does), else h evaluated."""
    index = selected_states(model.output)
    if index is not None:
        return lambda x: x[index]
    return lambda x: np.asarray(model.output(x), float).ravel()


class _Log:
    """Preallocated per-step arrays of :func:`simulate` (no list growth in the loop)."""

    def __init__(self, capacity: int, nx: int, nu: int, ny: int, regions: tuple | None = None,
                 set_points: int | None = None):
        self.n = 0
        self.region_velocities = None if regions is None else np.empty((capacity, *regions))
        self.set_points = None if set_points is None else np.empty((capacity, set_points))
        self.t = np.empty(capacity)
        self.x = np.empty((capacity + 1, nx))
        self.u = np.empty((capacity, nu))
        self.x_a = np.empty((capacity, nx))
        self.u_a = np.empty((capacity, nu))
        self.solve_time = np.empty(capacity)
        self.iterations = np.empty(capacity, dtype=int)
        self.success = np.empty(capacity, dtype=bool)
        self.status = np.empty(capacity, dtype=object)
        self.y = np.empty((capacity + 1, ny))  # the position the clearance is measured at
        self.target_index = np.empty(capacity, dtype=int)
        self.visible_points = np.empty(capacity, dtype=int)
        self.dropped_points = np.empty(capacity, dtype=int)

    def record(self, k, t, x, y, u, sol, target_index, visible, dropped) -> None:
        self.t[k], self.x[k], self.y[k], self.u[k] = t, x, y, u
        self.x_a[k], self.u_a[k] = sol.x_a, sol.u_a
        self.solve_time[k], self.iterations[k] = sol.solve_time, sol.iterations
        self.success[k], self.status[k] = sol.success, sol.status
        self.target_index[k] = target_index
        self.visible_points[k], self.dropped_points[k] = visible, dropped
        self.n = k + 1

    def arrays(self, x_last, y_last) -> dict:
        """The recorded rows (and ``x``, ``y`` with the state after the last step and its
        output appended); the clearance is not among them (:meth:`TrueClearance.along`)."""
        n = self.n
        self.x[n], self.y[n] = x_last, y_last
        out = {k: getattr(self, k)[:n].copy() for k in RESULT_ARRAYS
               if k not in ("x", "clearance")}
        out["x"], out["y"] = self.x[:n + 1].copy(), self.y[:n + 1].copy()
        out["status"] = self.status[:n].astype(str)
        for name in ("region_velocities", "set_points"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)[:n].copy()
        return out


def _solve(ctl, measured, target, visible, plan, errors: list, velocities,
           model: VehicleModel) -> NMPCSolution:
    """The controller's solution, or a failed one with the fault's status: a non-finite
    measured state is never handed to the solver, and a solve that raises is recorded (its
    first messages in ``errors``) instead of ending the flight. ``velocities`` (one (3,) m/s
    per region) is passed on only when given, so a static prediction calls the solver as
    before moving regions existed."""
    status = "state_fault"
    if np.isfinite(measured).all():
        try:
            if velocities is None:
                return ctl.solve(measured, target, visible, previous=plan)
            return ctl.solve(measured, target, visible, previous=plan, velocities=velocities)
        except Exception as exc:  # noqa: BLE001 - recorded; persistent faults end the run
            status = "solve_error"
            if len(errors) < 20:
                errors.append(f"{type(exc).__name__}: {exc}")
    nx, nu = model.nx, model.nu
    return NMPCSolution(np.zeros((0, nu)), np.zeros((0, nx)), np.full(nx, np.nan),
                        np.full(nu, np.nan), False, status, 0, 0.0, np.nan)


"""Closed-loop mission: LiDAR scan → NMPC → plant (RK45, zero-order hold), and its result.

The step loop of :func:`simulate` is short on purpose; read it to see exactly what happens at
each sampling instant. :class:`SimulationResult` saves itself as ``result.npz`` with the full
``config.json`` beside it, and becomes a pandas DataFrame with :meth:`SimulationResult.to_frame`.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from paper_repro.config import Config
from paper_repro.problem.ocp import Controller, NMPCSolution
from paper_repro.progress import step_progress
from paper_repro.sim.checks import SetupHazardWarning, check_setup, setup_hazards
from paper_repro.sim.plant import Plant
from paper_repro.sim.result import FAULT_STATUSES, RESULT_ARRAYS, SimulationResult, run_metadata
from paper_repro.solvers.factory import make_controller
from paper_repro.vehicles.quadrotor import N_INPUTS, N_STATES, equilibrium
from paper_repro.world.lidar import Lidar
from paper_repro.world.scenarios import make_scene
from paper_repro.world.scene import Scene


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
             initial_state=None) -> SimulationResult:
    """Fly the configured scenario in closed loop.

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
    initial_state : (12,) state to start from instead of hover at ``scene.start`` (to fly a
        window of a mission from a state another flight reached, every solver from the same
        state; the clock still starts at t = 0, so use it on static scenes).

    Before anything is built, :func:`~paper_repro.sim.checks.check_setup` rejects an inconsistent
    mission (``ValueError``) and :func:`~paper_repro.sim.checks.setup_hazards` warns of an unsafe
    one (a start or target inside the unsafe set or within the rotor radius of a cloud, a
    target the artificial equilibrium cannot reach); the hazards are kept in
    ``meta["hazards"]``.

    At step k (time t = k·T_s) the LiDAR sees each region where it is at t
    (:meth:`~paper_repro.world.lidar.Lidar.scan`), and the clearance is measured to the regions'
    true positions at t. With ``simulation.prediction`` ``"static"`` (the paper) the
    controller is called as ``ctl.solve(x, target, visible, previous=plan)``; with
    ``"oracle"`` or ``"kalman"`` it is also given ``velocities=``, one (3,) m/s per region of
    the scan: the regions' true velocities at t (:meth:`~paper_repro.world.lidar.Lidar.velocities`),
    or the estimates of a :class:`paper_repro.world.tracking.RegionTracker` updated with each scan.

    The run ends when it is complete (every target reached; for ``kind="passage"`` the finish
    line crossed), when it stalls, after ``max_steps``, or after persistent faults: see
    :data:`OUTCOMES`. A failed solve never stops the run: it is recorded in
    ``success``/``status`` and the previous plan, shifted by one step, is applied instead (its
    first input). Non-finite points in a scan are dropped and counted in ``dropped_points``; a
    non-finite measured state or a solve that raises is a fault (:data:`FAULT_STATUSES`),
    handled the same way.
    """
    cfg = config or Config()
    if max_steps is not None:
        cfg = dataclasses.replace(cfg, simulation=dataclasses.replace(cfg.simulation,
                                                                      max_steps=max_steps))
    sim, ts = cfg.simulation, cfg.nmpc.ts
    scene = scene if scene is not None else make_scene(sim.scenario, sim.seed)
    passage = sim.kind == "passage"
    check_setup(cfg, scene)  # an inconsistent mission fails here, before anything is built
    if initial_state is not None:
        start = np.array(initial_state, dtype=float)
        if start.shape != (N_STATES,) or not np.isfinite(start).all():
            raise ValueError(f"initial_state must be a finite ({N_STATES},) state, got "
                             f"{np.shape(initial_state)}")
    hazards = setup_hazards(cfg, scene)
    for line in hazards["warnings"]:
        warnings.warn(f"{scene.name}: {line}", SetupHazardWarning, stacklevel=2)
    lidar = Lidar(scene.clouds, sim.lidar_range, noise=cfg.sensor, motions=scene.motions)
    plant = Plant(cfg.quadrotor, ts)  # RK45 in C, as solve_ivp (ODE45 in the paper)
    truth = _TrueClearance(scene)
    tracker = None
    if sim.prediction == "kalman":
        from paper_repro.world.tracking import RegionTracker

        tracker = RegionTracker(ts)
    ctl = controller or make_controller(cfg)
    ctl.reset()
    counts_before = dict(ctl.qp_counts) if hasattr(ctl, "qp_counts") else None
    steps_before = dict(ctl.step_counts) if hasattr(ctl, "step_counts") else None
    targets = np.atleast_2d(np.asarray(scene.targets, float))
    finish_point, finish_dir = ((np.asarray(v, float) for v in scene.finish) if passage
                                else (None, None))
    stall_steps = int(np.ceil(sim.stall_time / ts))

    if initial_state is None:
        x, _ = equilibrium(scene.start, 0.0, cfg.quadrotor)
    else:
        x = start.copy()
    log = _Log(sim.max_steps)
    reached = np.full(len(targets), -1)
    target_index, slow, outcome = 0, 0, "step_limit"
    plan: NMPCSolution | None = None
    in_a_row, errors, last_good = 0, [], x.copy()
    meta = run_metadata()  # before flying: the commit and versions that produce this run
    meta["hazards"] = hazards
    bar = step_progress(sim.max_steps, progress)
    wall = time.perf_counter()
    for k in range(sim.max_steps):
        target = targets[target_index]
        t = k * ts
        measured = x if faults is None or faults.state is None else faults.state(k, x.copy())
        visible = lidar.scan(x[:3], t)
        if faults is not None and faults.scan is not None:
            visible = faults.scan(k, visible)
        visible, dropped = _finite_points(visible)
        if sim.prediction == "static":
            velocities = None
        elif sim.prediction == "oracle":
            velocities = lidar.velocities(t)
        else:
            velocities = tracker.update(visible, t)
        sol = _solve(ctl, measured, target, visible, plan, errors, velocities)
        if sol.success:
            plan, last_good = sol, measured
        else:
            plan = plan.shifted() if plan is not None else ctl.hover_guess(last_good)
            if sol.status == "solve_error" or sol.status == "state_fault":
                sol = dataclasses.replace(sol, x_a=plan.x_a, u_a=plan.u_a)
        in_a_row = in_a_row + 1 if sol.status in FAULT_STATUSES else 0
        u = plan.u[0]
        log.record(k, t, x, u, sol, truth(x[:3], t), target_index,
                   sum(len(v) for v in visible), dropped)

        x = plant.step(x, u)
        error = float(np.linalg.norm(x[:3] - target))
        if bar is not None:
            bar.update(1)
            if k % 50 == 0:
                bar.set_postfix(target=target_index, error=f"{error:.2f} m",
                                solve=f"{sol.solve_time * 1e3:.2g} ms")
        if error < sim.tolerance and reached[target_index] < 0:
            reached[target_index] = k + 1
            if target_index + 1 < len(targets):
                target_index += 1
            elif not passage:
                outcome = "completed"
                break
        if passage and float(np.dot(x[:3] - finish_point, finish_dir)) >= 0.0:
            outcome = "completed"
            break
        # Stalled: slow for stall_time while still far from the target (a deadlock).
        slow = slow + 1 if (np.linalg.norm(x[6:9]) < sim.stall_speed
                            and error > sim.stall_distance) else 0
        if slow > stall_steps:
            outcome = "stalled"
            break
        if in_a_row > sim.fault_steps:
            outcome = "fault"
            meta["fault"] = (f"{in_a_row} steps in a row without a usable state or solve "
                             f"(last: {sol.status}{': ' + errors[-1] if errors else ''})")
            break
    if bar is not None:
        bar.close()

    arrays = log.arrays(x)
    meta["wall_time_s"] = time.perf_counter() - wall
    meta["errors"] = errors
    meta["scene"] = scene.name
    if counts_before is not None:  # QPs of this run by solver path (rti solver only)
        meta["qp_counts"] = {k: v - counts_before.get(k, 0) for k, v in ctl.qp_counts.items()}
    if steps_before is not None:
        meta["step_counts"] = {k: v - steps_before.get(k, 0) for k, v in ctl.step_counts.items()}
    return SimulationResult(targets=targets, reached=reached, outcome=outcome, scene=scene,
                            config=cfg, meta=meta, **arrays)


class _Log:
    """Preallocated per-step arrays of :func:`simulate` (no list growth in the loop)."""

    def __init__(self, capacity: int):
        self.n = 0
        self.t = np.empty(capacity)
        self.x = np.empty((capacity + 1, N_STATES))
        self.u = np.empty((capacity, N_INPUTS))
        self.x_a = np.empty((capacity, N_STATES))
        self.u_a = np.empty((capacity, N_INPUTS))
        self.solve_time = np.empty(capacity)
        self.iterations = np.empty(capacity, dtype=int)
        self.success = np.empty(capacity, dtype=bool)
        self.status = np.empty(capacity, dtype=object)
        self.clearance = np.empty(capacity)
        self.target_index = np.empty(capacity, dtype=int)
        self.visible_points = np.empty(capacity, dtype=int)
        self.dropped_points = np.empty(capacity, dtype=int)

    def record(self, k, t, x, u, sol, clearance, target_index, visible, dropped) -> None:
        self.t[k], self.x[k], self.u[k] = t, x, u
        self.x_a[k], self.u_a[k] = sol.x_a, sol.u_a
        self.solve_time[k], self.iterations[k] = sol.solve_time, sol.iterations
        self.success[k], self.status[k] = sol.success, sol.status
        self.clearance[k], self.target_index[k] = clearance, target_index
        self.visible_points[k], self.dropped_points[k] = visible, dropped
        self.n = k + 1

    def arrays(self, x_last) -> dict:
        """The recorded rows (and ``x`` with the state after the last step appended)."""
        n = self.n
        self.x[n] = x_last
        out = {k: getattr(self, k)[:n].copy() for k in RESULT_ARRAYS if k != "x"}
        out["x"] = self.x[:n + 1].copy()
        out["status"] = self.status[:n].astype(str)
        return out


class _TrueClearance:
    """Distance (m) from a position to the nearest cloud point where it is at time t: one
    KD-tree over every point for a static scene (as always), one per region queried at
    y − c_i(t) for a moving one; ``inf`` for a scene without points."""

    def __init__(self, scene: Scene):
        self.motions = scene.motions
        if self.motions is None:
            points = scene.all_points
            self.trees = [cKDTree(points)] if len(points) else []
        else:
            self.trees = [cKDTree(c) if len(c) else None for c in scene.clouds]

    def __call__(self, y: np.ndarray, t: float) -> float:
        if self.motions is None:
            return self.trees[0].query(y)[0] if self.trees else np.inf
        return min((tree.query(y if m is None else y - m.offset(t))[0]
                    for tree, m in zip(self.trees, self.motions, strict=True)
                    if tree is not None), default=np.inf)


def _solve(ctl, measured, target, visible, plan, errors: list,
           velocities=None) -> NMPCSolution:
    """The controller's solution, or a failed one with the fault's status: a non-finite
    measured state is never handed to the solver, and a solve that raises is recorded (its
    first messages in ``errors``) instead of ending the flight. ``velocities`` (one (3,) m/s
    per region) is passed on only when given, so a static prediction calls the solver as
    before moving regions existed."""
    status = "state_fault"
    if np.all(np.isfinite(measured)):
        try:
            if velocities is None:
                return ctl.solve(measured, target, visible, previous=plan)
            return ctl.solve(measured, target, visible, previous=plan, velocities=velocities)
        except Exception as exc:  # noqa: BLE001 - recorded; persistent faults end the run
            status = "solve_error"
            if len(errors) < 20:
                errors.append(f"{type(exc).__name__}: {exc}")
    nan = np.full(N_STATES, np.nan)
    return NMPCSolution(np.zeros((0, N_INPUTS)), np.zeros((0, N_STATES)), nan,
                        np.full(N_INPUTS, np.nan), False, status, 0, 0.0, np.nan)


def _finite_points(visible) -> tuple[list[np.ndarray], int]:
    """The scan without its non-finite points (a bad return is dropped, not flown on), and
    how many were dropped."""
    clean, dropped = [], 0
    for v in visible:
        ok = np.isfinite(v).all(axis=1)
        if ok.all():
            clean.append(v)
        else:
            clean.append(v[ok])
            dropped += int(len(v) - ok.sum())
    return clean, dropped



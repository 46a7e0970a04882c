"""Closed-loop mission: LiDAR scan → NMPC → plant (solve_ivp, zero-order hold), and its result.

The step loop of :func:`simulate` is short on purpose; read it to see exactly what happens at
each sampling instant. :class:`SimulationResult` saves itself as ``result.npz`` with the full
``config.json`` beside it, and becomes a pandas DataFrame with :meth:`SimulationResult.to_frame`.
"""

from __future__ import annotations

import dataclasses
import json
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .config import Config
from .model import equilibrium, plant_step
from .nmpc import NMPCSolution, TrackingNMPC, make_controller
from .scene import Lidar, Scene, make_scene

_ARRAYS = ("t", "x", "u", "x_a", "u_a", "solve_time", "iterations", "success", "clearance",
           "target_index", "visible_points")


@dataclass
class SimulationResult:
    """A closed-loop run. Arrays have one row per step k = 0..K−1, except ``x`` (K+1 rows).

    Attributes
    ----------
    t : (K,) s, time of each step.          x : (K+1, 12) states (last one after the last step).
    u : (K, 4) N, applied thrusts.          x_a : (K, 12), u_a : (K, 4) artificial equilibrium.
    solve_time : (K,) s.   iterations : (K,).   success : (K,) bool, solver converged.
    status : (K,) solver return status.     clearance : (K,) m, true minimum Euclidean distance
        from the UAV to any cloud point.    target_index : (K,) index of the active set-point.
    visible_points : (K,) number of points the LiDAR saw.
    targets : (k, 3) m.   reached : (k,) step at which each target was reached (−1 if not).
    config : the :class:`~paper_repro.config.Config` of the run.   meta : versions, machine.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    x_a: np.ndarray
    u_a: np.ndarray
    solve_time: np.ndarray
    iterations: np.ndarray
    success: np.ndarray
    status: np.ndarray
    clearance: np.ndarray
    target_index: np.ndarray
    visible_points: np.ndarray
    targets: np.ndarray
    reached: np.ndarray
    config: Config
    meta: dict = field(default_factory=dict)

    @property
    def steps(self) -> int:
        return len(self.t)

    @property
    def failures(self) -> int:
        return int(np.sum(~self.success))

    @property
    def completed(self) -> bool:
        """All targets reached."""
        return bool(np.all(self.reached >= 0))

    def summary(self) -> str:
        """One line: metric, steps, targets reached, clearance, solve times, failures."""
        st = self.solve_time * 1e3
        metric = self.config.distance.metric
        reached = int(np.sum(self.reached >= 0))
        return (f"{self.config.simulation.scenario}/{metric}: {self.steps} steps "
                f"({self.steps * self.config.nmpc.ts:.2f} s simulated), targets reached "
                f"{reached}/{len(self.targets)}, min clearance {self.clearance.min():.3f} m, "
                f"solve median {np.median(st):.1f} ms p95 {np.percentile(st, 95):.1f} ms, "
                f"failed solves {self.failures}")

    def to_frame(self):
        """One row per step: t, position, Euler angles, velocities, thrusts, y_a, solver data."""
        import pandas as pd

        names = ["x", "y", "z", "phi", "theta", "psi", "vx", "vy", "vz", "p_phi", "p_theta",
                 "p_psi"]
        data = {"t": self.t}
        data.update({n: self.x[:-1, i] for i, n in enumerate(names)})
        data.update({f"f{i + 1}": self.u[:, i] for i in range(4)})
        data.update({f"{c}_a": self.x_a[:, i] for i, c in enumerate("xyz")})
        data.update({f"f{i + 1}_a": self.u_a[:, i] for i in range(4)})
        data.update({"solve_time": self.solve_time, "iterations": self.iterations,
                     "success": self.success, "status": self.status,
                     "clearance": self.clearance, "target_index": self.target_index,
                     "visible_points": self.visible_points})
        return pd.DataFrame(data)

    def save(self, directory) -> Path:
        """Write ``result.npz`` and ``config.json`` (config + versions + commit + machine)."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        arrays = {k: getattr(self, k) for k in _ARRAYS}
        np.savez_compressed(out / "result.npz", status=self.status.astype(str),
                            targets=self.targets, reached=self.reached, **arrays)
        payload = {"config": self.config.to_dict(), "meta": self.meta}
        (out / "config.json").write_text(json.dumps(payload, indent=2, default=str) + "\n")
        return out

    @classmethod
    def load(cls, directory) -> SimulationResult:
        d = Path(directory)
        payload = json.loads((d / "config.json").read_text())
        with np.load(d / "result.npz") as z:
            arrays = {k: z[k] for k in z.files}
        return cls(config=Config.from_dict(payload["config"]), meta=payload.get("meta", {}),
                   **arrays)


def simulate(config: Config | None = None, controller: TrackingNMPC | None = None,
             max_steps: int | None = None, progress: bool | None = None,
             scene: Scene | None = None) -> SimulationResult:
    """Fly the configured scenario in closed loop.

    Parameters
    ----------
    config : run configuration (defaults: the paper's settings, ``paper`` scenario).
    controller : a built controller for the same config (built here if omitted; building is
        the slow part, so pass one in when flying several missions).
    max_steps : overrides ``config.simulation.max_steps``.
    progress : show a progress bar (default: only when writing to a terminal).
    scene : fly this scene instead of ``config.simulation.scenario`` (e.g. your own regions, or
        a variant made with ``dataclasses.replace``); its name is stored in ``meta["scene"]``.

    A failed solve never stops the run: it is recorded in ``success``/``status`` and the
    previous plan, shifted by one step, is applied instead (its first input).
    """
    cfg = config or Config()
    if max_steps is not None:
        cfg = dataclasses.replace(cfg, simulation=dataclasses.replace(cfg.simulation,
                                                                      max_steps=max_steps))
    sim, ts = cfg.simulation, cfg.nmpc.ts
    scene = scene if scene is not None else make_scene(sim.scenario, sim.seed)
    lidar = Lidar(scene.clouds, sim.lidar_range)
    truth = cKDTree(scene.all_points)
    ctl = controller or make_controller(cfg)
    counts_before = dict(ctl.qp_counts) if hasattr(ctl, "qp_counts") else None
    targets = np.asarray(scene.targets, float)

    x, _ = equilibrium(scene.start, 0.0, cfg.quadrotor)
    log = {k: [] for k in ("t", "x", "u", "x_a", "u_a", "solve_time", "iterations", "success",
                           "status", "clearance", "target_index", "visible_points")}
    reached = np.full(len(targets), -1)
    target_index = 0
    plan: NMPCSolution | None = None
    meta = run_metadata()  # before flying: the commit and versions that produce this run
    bar = _progress_bar(sim.max_steps, progress)
    wall = time.perf_counter()
    for k in range(sim.max_steps):
        target = targets[target_index]
        visible = lidar.scan(x[:3])
        sol = ctl.solve(x, target, visible, previous=plan)
        if sol.success:
            plan = sol
        else:
            plan = plan.shifted() if plan is not None else ctl.hover_guess(x)
        u = plan.u[0]

        for key, value in (("t", k * ts), ("x", x), ("u", u), ("x_a", sol.x_a),
                           ("u_a", sol.u_a), ("solve_time", sol.solve_time),
                           ("iterations", sol.iterations), ("success", sol.success),
                           ("status", sol.status), ("clearance", truth.query(x[:3])[0]),
                           ("target_index", target_index),
                           ("visible_points", sum(len(v) for v in visible))):
            log[key].append(value)

        x = plant_step(x, u, ts, cfg.quadrotor)
        error = float(np.linalg.norm(x[:3] - target))
        if bar is not None:
            bar.update(1)
            if k % 50 == 0:
                bar.set_postfix(target=target_index, error=f"{error:.2f} m",
                                solve=f"{sol.solve_time * 1e3:.2g} ms")
        if error < sim.tolerance:
            reached[target_index] = k + 1
            target_index += 1
            if target_index == len(targets):
                break
    if bar is not None:
        bar.close()

    log["x"].append(x)
    arrays = {k: np.asarray(v) for k, v in log.items()}
    arrays["status"] = arrays["status"].astype(str)
    meta["wall_time_s"] = time.perf_counter() - wall
    meta["scene"] = scene.name
    if counts_before is not None:  # QPs of this run by solver path (rti solver only)
        meta["qp_counts"] = {k: v - counts_before.get(k, 0) for k, v in ctl.qp_counts.items()}
    return SimulationResult(targets=targets, reached=reached, config=cfg, meta=meta, **arrays)


def run_metadata() -> dict:
    """Package versions, git commit and machine, stored beside every result."""
    import casadi
    import scipy

    from . import __version__

    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, timeout=5).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"paper_repro": __version__, "python": sys.version.split()[0],
            "numpy": np.__version__, "scipy": scipy.__version__, "casadi": casadi.__version__,
            "git_commit": commit, "machine": platform.platform(), "processor": platform.machine(),
            "cpu_count": __import__("os").cpu_count()}


def _progress_bar(total: int, progress: bool | None):
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="step", desc="closed loop", smoothing=0.05)

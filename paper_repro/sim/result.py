"""What a closed-loop run leaves: :class:`SimulationResult`, which saves itself beside its
config and scene and becomes a DataFrame, and the metadata stored with every result."""

from __future__ import annotations

import json
import platform
import subprocess
import sys
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from paper_repro.config import Config
from paper_repro.paths import atomic_text, sha256_of
from paper_repro.world.scene import Scene

RESULT_ARRAYS = ("t", "x", "u", "x_a", "u_a", "solve_time", "iterations", "success", "clearance",
           "target_index", "visible_points", "dropped_points")

OPTIONAL_ARRAYS = ("region_velocities", "set_points", "y", "scan_points", "scan_sizes",
                   "scan_index")
"""Arrays a result holds only where the run has them (see :class:`SimulationResult`)."""


OUTCOMES = ("completed", "stalled", "step_limit", "fault", "left_workspace")
"""How a run ends: ``completed`` (every target reached, or for a passage the finish line
crossed), ``stalled`` (the NMPC deadlocked, see
:class:`~paper_repro.config.SimulationParams`), ``step_limit`` (``max_steps`` flown first),
``fault`` (more than ``fault_steps`` steps in a row without a usable state or solve; the
reason is in ``meta["fault"]``)."""

FAULT_STATUSES = ("state_fault", "solve_error")
"""Step statuses of a fault: the measured state was not finite, or the solve raised before it
could start (its message is in ``meta["errors"]``)."""


@dataclass
class SimulationResult:
    """A closed-loop run. Arrays have one row per step k = 0..K−1, except ``x`` (K+1 rows).

    Attributes
    ----------
    t : (K,) s, time of each step.          x : (K+1, 12) states (last one after the last step).
    u : (K, 4) N, applied thrusts.          x_a : (K, 12), u_a : (K, 4) artificial equilibrium.
    solve_time : (K,) s.   iterations : (K,).   success : (K,) bool, solver converged.
    status : (K,) solver return status.     clearance : (K,) m, true minimum Euclidean distance
        from the UAV to any cloud point (where it is at t, for moving regions).
    target_index : (K,) index of the active set-point.
    visible_points : (K,) number of points the LiDAR saw (after dropping non-finite ones).
    dropped_points : (K,) non-finite points dropped from the scan.
    region_velocities : (K, n_regions, p) m/s, the velocities of the regions the controller
        was handed at each step (the regions' true ones for ``prediction="oracle"``, the
        tracker's estimates for ``"kalman"``); ``None`` for ``"static"`` (the paper: the
        regions are taken to stay where they are seen).
    set_points : (K, p) m, the set-point y_t the guide handed the controller at each step
        (``guide.planner`` ``"grid"``); ``None`` when it is the active target (the paper).
    y : (K+1, p) m, the output y = h(x) of every state of ``x``: the point that keeps clear
        and tracks the targets (the quadrotor's position). ``None`` in a result saved before
        it was stored; :attr:`positions` then reads the quadrotor's x[:, :3].
    scan_points, scan_sizes, scan_index : the scans the controller was handed, each distinct
        scan once (:class:`~paper_repro.sim.perception.ScanLog`); :meth:`scan` reads the one
        of a step. ``None`` in a result saved before they were stored.
    targets : (k, 3) m.   reached : (k,) step at which each target was reached (−1 if not).
    outcome : one of :data:`OUTCOMES`.
    scene : the :class:`~paper_repro.world.scene.Scene` flown, clouds and motions included (saved
        with the result, so a run always redraws against its own points; for moving regions,
        ``scene.clouds_at(t)`` gives them at time t).
    config : the :class:`~paper_repro.config.Config` of the run.
    meta : versions, machine, and ``meta["vehicle"]``: the names of the states and inputs
        (:meth:`~paper_repro.vehicles.base.VehicleModel.description`).
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
    dropped_points: np.ndarray
    targets: np.ndarray
    reached: np.ndarray
    outcome: str
    scene: Scene
    config: Config
    meta: dict = field(default_factory=dict)
    region_velocities: np.ndarray | None = None
    set_points: np.ndarray | None = None
    y: np.ndarray | None = None
    scan_points: np.ndarray | None = None
    scan_sizes: np.ndarray | None = None
    scan_index: np.ndarray | None = None
    _scan_starts: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def positions(self) -> np.ndarray:
        """(K+1, p) m: the output y of every state (see ``y``)."""
        return self.y if self.y is not None else self.x[:, :3]

    def has(self, name: str) -> bool:
        """Whether the result holds ``name``: an array of :data:`OPTIONAL_ARRAYS`, or
        ``"scan"`` (the scans of :meth:`scan`). A run holds ``region_velocities`` only with
        a prediction of moving regions and ``set_points`` only with a guide; a result saved
        by an older version may lack ``y`` or the scans."""
        if name == "scan":
            return self.scan_index is not None
        if name not in OPTIONAL_ARRAYS:
            raise ValueError(f"name must be 'scan' or one of {OPTIONAL_ARRAYS}, got {name!r}")
        return getattr(self, name) is not None

    def scan(self, k: int) -> list[np.ndarray]:
        """The points the controller was handed at step ``k`` (0 ≤ k < K): one (k_i, p) array
        per region, m (views into the stored scans: read them, do not write them). Raises
        ``ValueError`` for a result saved before the scans were stored: fly it again."""
        if not self.has("scan"):
            raise ValueError(f"this result of {self.scene.name!r} was saved before the scans "
                             "were stored; fly the run again to draw what its controller saw")
        if not (isinstance(k, (int, np.integer)) and 0 <= k < len(self.scan_index)):
            raise ValueError(f"k must be a step 0..{len(self.scan_index) - 1}, got {k!r}")
        if self._scan_starts is None:  # where each distinct scan starts in scan_points
            self._scan_starts = np.concatenate([[0], np.cumsum(self.scan_sizes.sum(axis=1))])
        s = int(self.scan_index[k])
        sizes, start = self.scan_sizes[s], int(self._scan_starts[s])
        if sizes.size == 0:
            return []
        return np.split(self.scan_points[start:start + int(sizes.sum())], np.cumsum(sizes)[:-1])

    @property
    def steps(self) -> int:
        return len(self.t)

    @property
    def failures(self) -> int:
        return int(np.sum(~self.success))

    @property
    def completed(self) -> bool:
        """Every target reached (mission) or the finish line crossed (passage)."""
        return self.outcome == "completed"

    def summary(self) -> str:
        """One line: run, outcome, steps, targets reached, clearance, solve times, failures."""
        st = self.solve_time * 1e3
        sim = self.config.simulation
        reached = int(np.sum(self.reached >= 0))
        return (f"{self.scene.name}/{self.config.distance.metric} ({sim.kind}): {self.outcome} "
                f"after {self.steps} steps ({self.steps * self.config.nmpc.ts:.2f} s "
                f"simulated), targets reached {reached}/{len(self.targets)}, min clearance "
                f"{self.clearance.min():.3f} m, solve median {np.median(st):.2g} ms p95 "
                f"{np.percentile(st, 95):.2g} ms, failed solves {self.failures}")

    def to_frame(self):
        """One row per step: t, the state, the inputs, the artificial equilibrium's position
        and inputs, solver data. Columns are named by the vehicle
        (:attr:`~paper_repro.vehicles.base.VehicleModel.state_names`; the quadrotor's
        x … p_psi, f1 … f4, x_a, y_a, z_a, f1_a … f4_a), ``x0 …``, ``u0 …`` where it names
        none."""
        import pandas as pd

        vehicle = self.meta.get("vehicle") or _saved_before_names(self.x, self.u)
        names, inputs = vehicle["states"], vehicle["inputs"]
        rest = [(f"{names[i]}_a", i) for i in vehicle["position"]]
        data = {"t": self.t}
        data.update({n: self.x[:-1, i] for i, n in enumerate(names)})
        data.update({n: self.u[:, i] for i, n in enumerate(inputs)})
        data.update({n: self.x_a[:, i] for n, i in rest})
        data.update({f"{n}_a": self.u_a[:, i] for i, n in enumerate(inputs)})
        data.update({"solve_time": self.solve_time, "iterations": self.iterations,
                     "success": self.success, "status": self.status,
                     "clearance": self.clearance, "target_index": self.target_index,
                     "visible_points": self.visible_points,
                     "dropped_points": self.dropped_points})
        return pd.DataFrame(data)

    def save(self, directory) -> Path:
        """Write ``result.npz`` (arrays and the scene's clouds), ``config.json`` (config,
        scene description and fingerprint, outcome, versions, commit, machine) and, last,
        ``manifest.json`` (the SHA-256 of both: :func:`verify_result` checks them)."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        arrays = {k: getattr(self, k) for k in RESULT_ARRAYS}
        clouds = {f"cloud_{i}": c for i, c in enumerate(self.scene.clouds)}
        for name in OPTIONAL_ARRAYS:
            if getattr(self, name) is not None:
                arrays[name] = getattr(self, name)
        np.savez_compressed(out / "result.npz", status=self.status.astype(str),
                            targets=self.targets, reached=self.reached, **arrays, **clouds)
        payload = {"config": self.config.to_dict(), "scene": self.scene.to_dict(),
                   "outcome": self.outcome, "meta": self.meta}
        (out / "config.json").write_text(json.dumps(payload, indent=2, default=str) + "\n")
        write_manifest(out)
        return out

    @classmethod
    def load(cls, directory) -> SimulationResult:
        """Read a result written by :meth:`save`; the scene is rebuilt from its stored clouds
        (checked against the stored fingerprint), never regenerated.

        A damaged or incomplete folder raises :class:`DamagedResult`, naming the folder, the
        file and what is wrong: missing, truncated or not an archive, not valid JSON, an array
        missing, or a file that no longer matches ``manifest.json``.
        """
        d = Path(directory)
        for name in _FILES:
            if not (d / name).is_file():
                raise DamagedResult(d, name, "is missing")
        payload = _read_config(d)  # what is wrong, said as precisely as it can be
        n_regions = len(payload["scene"]["regions"])
        arrays = _read_arrays(d, n_regions)
        _check_manifest(d)  # and what reads but changed since it was saved
        clouds = [arrays.pop(f"cloud_{i}") for i in range(n_regions)]
        try:
            scene = Scene.from_dict(payload["scene"], clouds)
            config = Config.from_dict(payload["config"])
        except (ValueError, KeyError, TypeError) as exc:
            raise DamagedResult(d, "config.json", f"does not describe its arrays ({exc})") from None
        return cls(config=config, meta=payload.get("meta", {}), outcome=payload["outcome"],
                   scene=scene, **arrays)


def _saved_before_names(x: np.ndarray, u: np.ndarray) -> dict:
    """The vehicle of a result saved before ``meta["vehicle"]`` was stored: the quadrotor, by
    its shape, or unnamed columns."""
    from paper_repro.vehicles.quadrotor import N_INPUTS, N_STATES, STATE_NAMES

    if x.shape[1] == N_STATES and u.shape[1] == N_INPUTS:
        return {"states": list(STATE_NAMES), "inputs": [f"f{i + 1}" for i in range(N_INPUTS)],
                "position": [0, 1, 2]}
    return {"states": [f"x{i}" for i in range(x.shape[1])],
            "inputs": [f"u{i}" for i in range(u.shape[1])], "position": []}


class DamagedResult(ValueError):
    """A saved result that cannot be read as one. ``folder``, ``file`` and ``what`` say where
    and what is wrong; the message says all three."""

    def __init__(self, folder, file: str, what: str):
        self.folder, self.file, self.what = Path(folder), file, what
        super().__init__(f"{folder}: {file} {what}")


MANIFEST = "manifest.json"
"""The file :meth:`SimulationResult.save` writes last: the SHA-256 of every other file."""

_FILES = ("result.npz", "config.json")
_REQUIRED = (*RESULT_ARRAYS, "status", "targets", "reached")


def write_manifest(directory) -> Path:
    """Write ``manifest.json`` (atomically) with the SHA-256 of the result's files."""
    d = Path(directory)
    data = {"sha256": {name: sha256_of(d / name) for name in _FILES}}
    atomic_text(d / MANIFEST, json.dumps(data, indent=1) + "\n")
    return d / MANIFEST


def verify_result(directory) -> None:
    """Raise :class:`DamagedResult` unless ``directory`` holds an intact result: its files
    match ``manifest.json``; a folder without one (saved before results had manifests) is
    read in full, and when it reads its manifest is written, so the next check is a hash."""
    d = Path(directory)
    if (d / MANIFEST).is_file():
        _check_manifest(d)
        return
    SimulationResult.load(d)
    write_manifest(d)


def _check_manifest(d: Path) -> None:
    for name in _FILES:
        if not (d / name).is_file():
            raise DamagedResult(d, name, "is missing")
    if not (d / MANIFEST).is_file():
        return
    try:
        recorded = json.loads((d / MANIFEST).read_text())["sha256"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DamagedResult(d, MANIFEST, f"is not a manifest ({exc})") from None
    for name in _FILES:
        if recorded.get(name) != sha256_of(d / name):
            raise DamagedResult(d, name, "does not match its manifest (SHA-256 differs: "
                                         "changed or damaged since it was saved)")


def _read_config(d: Path) -> dict:
    try:
        payload = json.loads((d / "config.json").read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise DamagedResult(d, "config.json", f"is not valid JSON ({exc})") from None
    if not isinstance(payload, dict) or "scene" not in payload:
        raise DamagedResult(d, "config.json", "was saved before results stored their scene "
                                              "(or is not a result's); simulate it again")
    for key in ("config", "outcome"):
        if key not in payload:
            raise DamagedResult(d, "config.json", f"lacks {key!r}")
    return payload


def read_arrays(directory, *names: str) -> dict[str, np.ndarray]:
    """The arrays ``names`` of the result saved in ``directory``, those it holds, without
    reading the rest (its scene, its config); unchecked, unlike :meth:`SimulationResult.load`.
    """
    with np.load(Path(directory) / "result.npz") as z:
        return {k: z[k] for k in names if k in z.files}


def _read_arrays(d: Path, n_regions: int) -> dict:
    try:
        with np.load(d / "result.npz") as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error) as exc:
        raise DamagedResult(d, "result.npz", f"is truncated or not a NumPy archive "
                                             f"({type(exc).__name__}: {exc})") from None
    for name in (*_REQUIRED, *(f"cloud_{i}" for i in range(n_regions))):
        if name not in arrays:
            raise DamagedResult(d, "result.npz", f"lacks the array {name!r}")
    return arrays




def run_metadata() -> dict:
    """Package versions, git commit and machine, stored beside every result."""
    from importlib.metadata import version

    import casadi
    import scipy

    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).parent, timeout=5).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"paper_repro": version("paper_repro"), "python": sys.version.split()[0],
            "numpy": np.__version__, "scipy": scipy.__version__, "casadi": casadi.__version__,
            "git_commit": commit, "machine": platform.platform(), "processor": platform.machine(),
            "cpu_count": __import__("os").cpu_count()}

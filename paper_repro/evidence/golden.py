"""The golden flights, and the stamp that ties every committed evidence set to them.

The first rule of this package: every committed figure and table is what this commit's code
makes. Two things enforce it.

* **Golden flights** (:data:`GOLDEN_FLIGHTS`): a few short canonical closed loops (the paper
  mission with each metric, the encounter with each metric, a random passage, the moving
  ``crossing``, the IPOPT reference at one instant-rich window, the ground robot; in the
  ``"map"`` layer (:data:`LAYERS`), the noisy LiDAR through the local map; in the
  ``"guide"`` layer, the same with the guide; in the ``"riccati"`` layer, the crossing on
  the active-set QP chain without a budget (HPIPM where it runs out), the default until the
  interior point took the tail; in the ``"sweep"`` layer, the crossing with the region's
  swept path and a crossing flown with the moving-obstacle study's design). Their
  states and inputs are committed in ``figures/golden/<name>.npy`` and
  ``figures/golden/golden.json`` holds the SHA-256 of each file and of the whole set, the
  *golden hash*. ``tests/test_evidence.py``
  flies them and compares against the committed arrays (:func:`check_golden`,
  :data:`POSITION_TOLERANCE`): a change of code that moves a flight fails there.
* **Evidence stamps**: each committed evidence set (``figures/``, the ``paper-timeline``
  preset, the timeline flights, every study folder, the tuning outputs, the fidelity table)
  has an ``evidence.json`` that records the golden hash it was made with (:func:`stamp`,
  written by the command that makes the set). A test fails when a stamp differs from the
  current golden hash, so after ``python -m paper_repro golden --write`` every evidence set
  must be regenerated too, in the same submission. The golden hash also enters every run's
  cache key (:func:`paper_repro.studies.runs.run_key`), so regenerating the golden flights retires
  every cached run and nothing stale is ever redrawn. A layer's flights enter only the hash
  of that layer and of the layers built on it: the runs and sets that read the local map carry the
  ``"map"`` hash and the guided ones the ``"guide"`` hash, so a change to the map retires
  them all, a change to the guide only the guided ones, and every other run and set stays as
  it is. Likewise the runs that solve their QPs with the ``"riccati"`` chain (no budget,
  HPIPM as the fallback) carry that layer's hash, and those that sweep a moving region's path
  the ``"sweep"`` hash.

A pure refactor leaves every golden flight within tolerance: the committed files, the hash,
the stamps and the cache keys stay as they are, and nothing needs re-flying.

**Machine copies.** Besides the code, two things set a flight's last bits: the instruction set
the C is built for, and the OpenBLAS kernel NumPy and IPOPT run (:mod:`paper_repro._blas`).
:func:`machine_signature` names both; ``golden.json`` records the signature of the machine
that wrote the flights. Most flights absorb a last bit within tolerance; a flight whose solver
makes a discrete choice on it (an active set, an interior point's iteration count) does not.
On a machine of another signature, a flight flown with the same code is kept as a *machine
copy* (``golden --machine-copy``), in ``figures/golden/machines/<signature>/``, tied to the
SHA-256 of the committed file it stands for. :func:`check_golden` compares with the copy
there, and with the committed file wherever the copy is missing or stands for another file:
a code change still moves the flight against its reference. The copies enter no hash: the
evidence was made on the machine that wrote the golden flights.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from paper_repro import paths
from paper_repro.evidence.sets import EVIDENCE_SETS, record_wall_time
from paper_repro.paths import atomic_text, atomic_write, golden_dir, json_hash, sha256_of

POSITION_TOLERANCE = 1e-9
"""m: the largest position difference between a flight and its committed golden copy that
still counts as the same flight (flights repeat bit for bit on one machine; the margin is for
rounding between machines of the same kind)."""

MACHINES = "machines"
"""The folder of ``figures/golden/`` that holds the machine copies, one folder per signature."""

INPUT_TOLERANCE = 1e-6
"""N (or the vehicle's input unit): the same for the inputs, whose rounding is amplified by
the solver's conditioning."""


@dataclass(frozen=True)
class GoldenFlight:
    """One canonical flight.

    Attributes
    ----------
    name : file stem in ``figures/golden/``.
    description : what it exercises.
    scenario, kind, seed, metric, steps, solver, prediction : the run (see
        :class:`~paper_repro.config.SimulationParams`, :class:`~paper_repro.config.NMPCParams`).
    line_search : the damped real-time iteration (``SolverParams.line_search``).
    start : ``(other flight, step)``: start from the state that flight reached at that step
        (a window rich in obstacles, flown with a slow solver); ``None``: the scene's start.
    qp_solver : the real-time iteration's QP chain (``SolverParams.qp_solver``).
    vehicle : ``"quadrotor"`` or ``"unicycle"`` (the ground robot's planar L-wall).
    barrier : ``(field, value)`` pairs of :class:`~paper_repro.config.BarrierParams` that
        differ from the paper's (the moving design's swept path and margin).
    prediction_ts : the prediction step (``NMPCParams.prediction_ts``; ``None``: T_s).
    floor : m, the lowest altitude of 𝒳 (``QuadrotorParams.state_lower[2]``; ``None``: the
        paper's ground, 0), as the moving study's design keeps it.
    approach_time : the pace of a ``random-crossing`` (``SimulationParams.approach_time``;
        ``None``: the printed set-up's).
    layer : ``""`` (the core), ``"map"`` (the noisy LiDAR read through the local map),
        ``"guide"`` (the same with the guide), ``"riccati"`` (the active-set QP chain
        without a budget) or ``"sweep"`` (the swept path of a moving region)
        (:data:`LAYERS`), or names of them joined by ``"+"`` for a flight that needs each:
        its file enters the hash of a layer that covers them all.
    """

    name: str
    description: str
    scenario: str = "paper"
    kind: str = "mission"
    seed: int = 7
    metric: str = "smooth"
    steps: int = 300
    solver: str = "rti"
    prediction: str = "static"
    line_search: bool = False
    qp_solver: str = "riccati-ipm"
    start: tuple[str, int] | None = None
    vehicle: str = "quadrotor"
    barrier: tuple = ()
    prediction_ts: float | None = None
    approach_time: float | None = None
    floor: float | None = None
    layer: str = ""

    def config(self):
        """The :class:`~paper_repro.config.Config` this flight flies."""
        from paper_repro.config import Config

        if self.vehicle == "unicycle":
            from paper_repro.vehicles.unicycle import unicycle_config

            cfg = unicycle_config(self.metric)
        else:
            cfg = Config()
            cfg = dataclasses.replace(
                cfg, distance=dataclasses.replace(cfg.distance, metric=self.metric),
                simulation=dataclasses.replace(
                    cfg.simulation, scenario=self.scenario, kind=self.kind, seed=self.seed,
                    max_steps=self.steps, **({} if self.approach_time is None
                                             else {"approach_time": self.approach_time})),
                nmpc=dataclasses.replace(cfg.nmpc, prediction=self.prediction,
                                         prediction_ts=self.prediction_ts),
                quadrotor=dataclasses.replace(cfg.quadrotor,
                                              state_lower=self._state_lower(cfg.quadrotor)),
                barrier=dataclasses.replace(cfg.barrier, **dict(self.barrier)))
        if self.layer in ("map", "guide"):
            from paper_repro.config import GuideParams
            from paper_repro.world.lidar import NOISY_LIDAR
            from paper_repro.world.local_map import MAP_VOXEL

            cfg = dataclasses.replace(cfg, sensor=(
                dataclasses.replace(NOISY_LIDAR, seed=self.seed, map_voxel=MAP_VOXEL)))
        if self.layer == "guide":
            cfg = dataclasses.replace(cfg, guide=GuideParams(planner="grid"))
        return dataclasses.replace(cfg, solver=dataclasses.replace(
            cfg.solver, nlp_solver=self.solver, line_search=self.line_search,
            qp_solver=self.qp_solver))


    def _state_lower(self, quadrotor) -> tuple:
        """𝒳's lower bounds, with the altitude's at ``floor`` when one is given."""
        lower = list(quadrotor.state_lower)
        if self.floor is not None:
            lower[2] = self.floor
        return tuple(lower)


GOLDEN_FLIGHTS: tuple[GoldenFlight, ...] = (
    GoldenFlight("paper-smooth", "the paper mission's first 3 s, smoothed D (cruise: model, "
                 "plant, tracking terms, the artificial equilibrium)"),
    GoldenFlight("paper-euclidean", "the same with the Euclidean ½·min d²", metric="euclidean"),
    GoldenFlight("encounter-smooth", "the encounter, a region in view from step 316: the "
                 "smoothed penalty, the LiDAR, the capacity ladder", scenario="encounter",
                 steps=700),
    GoldenFlight("encounter-euclidean", "the same with the Euclidean metric, which switches "
                 "its nearest point", scenario="encounter", metric="euclidean", steps=700),
    GoldenFlight("reference-encounter-smooth", "IPOPT (the paper's solver) for 40 steps from "
                 "step 600 of encounter-smooth", scenario="encounter", steps=40,
                 solver="reference", start=("encounter-smooth", 600)),
    GoldenFlight("passage-smooth-s003", "a random passage (nonconvex regions, finish line)",
                 scenario="random", kind="passage", seed=3, steps=600),
    GoldenFlight("passage-smooth-s014", "a random passage into its densest scans: from step "
                 "1,944 a region shows 49-50 points, so every rung of the capacity ladder up "
                 "to the largest a random passage reaches is flown (each is its own compiled "
                 "function)", scenario="random", kind="passage", seed=14, steps=2400),
    GoldenFlight("passage-euclidean-s014", "the same with the Euclidean metric (its own "
                 "compiled rungs)", scenario="random", kind="passage", seed=14,
                 metric="euclidean", steps=2400),
    GoldenFlight("crossing-smooth", "a region moving across the line, predicted by the "
                 "oracle (velocities in the scan), the damped RTI on the default QP chain "
                 "(the active set, then the interior point where it runs out)",
                 scenario="crossing", steps=900, prediction="oracle", line_search=True),
    GoldenFlight("ground-robot-smooth", "the unicycle round the L-wall (another vehicle, "
                 "another output dimension)", steps=200, vehicle="unicycle"),
    GoldenFlight("passage-map-noisy-s010", "the first 15 s of a random passage with the "
                 "noisy LiDAR read through the local map: a wall in range for half the flight, "
                 "spurious returns that never confirm, dropouts that erase nothing",
                 scenario="random", kind="passage", seed=10, steps=1500, layer="map"),
    GoldenFlight("passage-map-guide-noisy-s010", "the same passage with the guide: up to 21 "
                 "map points in range, the guide re-planning round what the map has "
                 "confirmed, its set-point filtered",
                 scenario="random", kind="passage", seed=10, steps=1500, layer="guide"),
    GoldenFlight("crossing-smooth-riccati", "the crossing on the active-set chain without a "
                 "budget (HPIPM where it runs out: 12 QPs here), as the solver-speed "
                 "benchmarks fly it", scenario="crossing", steps=900, prediction="oracle",
                 line_search=True, qp_solver="riccati", layer="riccati"),
    GoldenFlight("crossing-smooth-sweep", "the crossing with the region's swept path (1 s) "
                 "on the default QP chain, as the levers that sweep fly it", scenario="crossing",
                 steps=900, prediction="oracle", line_search=True,
                 barrier=(("sweep_time", 1.0),), layer="sweep"),
    GoldenFlight("crossing-smooth-design", "a random crossing timed to the moving study's "
                 "design, flown with it (smoothed metric): the regions' swept paths and wider "
                 "margin in view for most of its 15 s, the 0.525 s prediction, the damped RTI "
                 "(the interior point for a third of its QPs)", scenario="random-crossing",
                 kind="passage", seed=1, approach_time=27.0, steps=1500, prediction="oracle",
                 line_search=True, prediction_ts=0.015, floor=0.5,
                 barrier=(("moving_d_min", 3.0), ("sweep_time", 1.0)), layer="sweep"),
)

LAYERS = ("", "map", "guide", "riccati", "sweep")
"""The layers of the golden flights. The core (``""``) covers what every run flies; the
``"map"`` layer the local map (``sensor.map_voxel`` > 0), the ``"guide"`` layer the guide on
the map (``guide.planner`` other than ``"none"``), the ``"riccati"`` layer the active-set QP
chain without a budget (``solver.qp_solver``), which only the solver benchmarks choose, and
the ``"sweep"`` layer the swept path of a region predicted to move (``barrier.sweep_time`` >
0). A flight of several layers (``"riccati+sweep"``, say) enters the hash of a layer that
covers them all. A layer's hash covers its flights and those of the
layers it is built on (:data:`LAYER_BASES`), and a combined layer's those of its parts and the
flights of the combination. A run's
cache key and an evidence set's stamp hold the golden hash of the layers they use
(:func:`golden_hash`, :func:`layer_of`): a change to the map retires the cached runs and
stamps that use the map (guided or not), a change to the guide those that use the guide, a
change to the active-set chain's fallback those that choose it, and the others stay as they
are."""

LAYER_BASES = {"": (), "map": ("",), "guide": ("", "map"), "riccati": ("",), "sweep": ("",)}
"""Layer → the layers it is built on."""


def layer_of(*configs) -> str:
    """The golden layers runs of ``configs`` use, joined by ``"+"``: ``"guide"`` when any is
    guided, else ``"map"`` when any reads the local map; ``"riccati"`` when any solves its
    QPs with that chain; and ``"sweep"`` when any sweeps a moving region's path. The core
    ``""`` when none of these."""
    used = []
    if any(c.guide.planner != "none" for c in configs):
        used.append("guide")
    elif any(c.sensor.map_voxel > 0 for c in configs):
        used.append("map")
    if any(c.solver.qp_solver == "riccati" for c in configs):
        used.append("riccati")
    if any(c.barrier.sweep_time > 0 for c in configs):
        used.append("sweep")
    return "+".join(used)


def covered_layers(layer: str) -> set[str]:
    """The layers whose flights ``layer``'s hash covers: its parts (``"+"``-joined names of
    :data:`LAYERS`) and the layers they are built on. ``ValueError`` for an unknown name."""
    parts = layer.split("+") if layer else []
    unknown = [p for p in parts if p not in LAYERS[1:]]
    if unknown:
        raise ValueError(f"layer must be '' or names of {LAYERS[1:]} joined by '+', "
                         f"got {layer!r}")
    return {""}.union(*({p, *LAYER_BASES[p]} for p in parts))


def fly_golden(flight: GoldenFlight, flown: dict | None = None) -> np.ndarray:
    """Fly one golden flight; (K, n_x + n_u) array, row k = (x_k, u_k).

    ``flown`` : arrays of flights already flown this call (for ``start``); the committed
    copy of the parent is used when it is missing."""
    from paper_repro.sim.loop import simulate
    from paper_repro.solvers.factory import make_controller

    cfg = flight.config()
    if flight.vehicle == "unicycle":
        from paper_repro.vehicles.unicycle import unicycle_model
        from paper_repro.world.planar import planar_scene

        result = simulate(cfg, make_controller(cfg, unicycle_model()), max_steps=flight.steps,
                          progress=False, scene=planar_scene())
        return np.hstack([result.x[:-1], result.u])
    initial = None
    if flight.start is not None:
        parent, step = flight.start
        rows = (flown or {}).get(parent)
        if rows is None:
            rows = np.load(golden_dir() / f"{parent}.npy")
        initial = rows[step, :12]
    result = simulate(cfg, max_steps=flight.steps, progress=False, initial_state=initial)
    return np.hstack([result.x[:-1], result.u])


def check_golden(names=None) -> list[dict]:
    """Fly the golden flights (all, or ``names``) and compare them with the committed copies.

    Returns one dict per flight: ``name``, ``steps`` (flown / committed), ``position_error``
    (m, max over the flight), ``input_error``, ``identical`` (bit for bit), ``ok`` (same
    length, within :data:`POSITION_TOLERANCE` and :data:`INPUT_TOLERANCE`) and
    ``reference``, the file compared with (:func:`reference_path`)."""
    flown, rows = {}, []
    for flight in _select(names):
        new = flown[flight.name] = fly_golden(flight, flown)
        path = reference_path(flight.name)
        old = np.load(path) if path.is_file() else np.zeros((0, new.shape[1]))
        npos = 3 if flight.vehicle == "quadrotor" else 2
        nx = 12 if flight.vehicle == "quadrotor" else 3
        same_shape = old.shape == new.shape
        pos = float(np.abs(new[:, :npos] - old[:, :npos]).max()) if same_shape else np.inf
        inp = float(np.abs(new[:, nx:] - old[:, nx:]).max()) if same_shape else np.inf
        rows.append({"name": flight.name, "steps": f"{len(new)}/{len(old)}",
                     "position_error": pos, "input_error": inp,
                     "identical": bool(same_shape and np.array_equal(new, old)),
                     "ok": bool(pos <= POSITION_TOLERANCE and inp <= INPUT_TOLERANCE),
                     "reference": path, "flown": new})
    return rows


def machine_signature() -> str:
    """This machine's signature (module docstring, "Machine copies"): the ``-march`` the C is
    built for (:func:`paper_repro._native.arch_flags`) and the kernel of NumPy's OpenBLAS
    (:func:`paper_repro._blas.numpy_kernel`), e.g. ``c-x86-64-v3_blas-Haswell``."""
    from paper_repro import _blas
    from paper_repro._native import arch_flags

    arch = arch_flags()[0].removeprefix("-march=")
    return f"c-{arch}_blas-{_blas.numpy_kernel() or 'other'}"


def golden_signature() -> str:
    """The signature of the machine that wrote the committed golden flights
    (``golden.json``)."""
    stored = json.loads((golden_dir() / "golden.json").read_text())
    return stored.get("machine", "unknown")


def reference_path(name: str) -> Path:
    """The file a flight is compared with on this machine: its machine copy when this
    machine's signature is not the one that wrote the golden flights and a copy stands for
    the committed file as it is now; the committed file otherwise."""
    main = golden_dir() / f"{name}.npy"
    signature = machine_signature()
    if not main.is_file() or signature == golden_signature():
        return main
    copies = _machine_copies(signature)
    entry = copies.get("files", {}).get(name)
    copy = golden_dir() / MACHINES / signature / f"{name}.npy"
    if (entry is None or entry.get("of") != sha256_of(main) or not copy.is_file()
            or entry.get("sha256") != sha256_of(copy)):
        return main
    return copy


def write_machine_copies(names) -> list[dict]:
    """Fly ``names`` and keep each as this machine's copy (module docstring): for flights the
    code flies as the committed file does on the machine that wrote it, moved here only by
    this machine's arithmetic. Refused on that machine itself, whose flights are the committed
    files."""
    signature = machine_signature()
    if signature == golden_signature():
        raise ValueError(f"this machine ({signature}) wrote the golden flights: use --write")
    folder = golden_dir() / MACHINES / signature
    folder.mkdir(parents=True, exist_ok=True)
    copies = _machine_copies(signature)
    files = copies.setdefault("files", {})
    rows = check_golden(names)
    for row in rows:
        path = folder / f"{row['name']}.npy"
        _atomic_save(path, row["flown"])
        files[row["name"]] = {"of": sha256_of(golden_dir() / f"{row['name']}.npy"),
                              "sha256": sha256_of(path)}
        row["written"] = True
    atomic_text(folder / "copies.json", json.dumps(copies, indent=1, sort_keys=True) + "\n")
    return rows


def _machine_copies(signature: str) -> dict:
    path = golden_dir() / MACHINES / signature / "copies.json"
    return json.loads(path.read_text()) if path.is_file() else {"machine": signature}


def write_golden(names=None, force: bool = False) -> list[dict]:
    """Fly the golden flights and commit-ready write the ones that moved (or all, ``force``),
    then ``golden.json``. A flight within tolerance keeps its file, so the golden hash only
    changes when a flight does."""
    folder = golden_dir()
    folder.mkdir(parents=True, exist_ok=True)
    rows = check_golden(names)
    for row in rows:
        if force or not row["ok"]:
            _atomic_save(folder / f"{row['name']}.npy", row["flown"])
            row["written"] = True
    files = {f.name: sha256_of(folder / f"{f.name}.npy") for f in GOLDEN_FLIGHTS
             if (folder / f"{f.name}.npy").is_file()}
    payload = {"hash": set_hash(_layer_files(files, "")), "files": files,
               "layers": {layer: set_hash(_layer_files(files, layer))
                          for layer in LAYERS if layer},
               "position_tolerance_m": POSITION_TOLERANCE, "input_tolerance": INPUT_TOLERANCE,
               "machine": machine_signature(),
               "flights": {f.name: f.description for f in GOLDEN_FLIGHTS}}
    atomic_text(folder / "golden.json", json.dumps(payload, indent=1) + "\n")
    return rows


def golden_hash(layer: str = "") -> str:
    """The committed golden hash of ``layer`` (:data:`LAYERS`, or several joined by ``"+"``,
    :func:`layer_of`; ``figures/golden/golden.json``): the core flights' for ``""``, those of
    the layers it covers (:func:`covered_layers`) for another, or ``"none"`` before the golden
    flights exist."""
    covered_layers(layer)
    path = golden_dir() / "golden.json"
    if not path.is_file():
        return "none"
    stored = json.loads(path.read_text())
    if not layer:
        return stored["hash"]
    if layer in stored["layers"]:
        return stored["layers"][layer]
    return set_hash(_layer_files(stored["files"], layer))


def recomputed_golden_hash(layer: str = "") -> str:
    """The golden hash of ``layer`` computed from the committed ``.npy`` files (equal to
    :func:`golden_hash` unless a file was changed by hand)."""
    folder = golden_dir()
    return set_hash(_layer_files({f.name: sha256_of(folder / f"{f.name}.npy")
                                  for f in GOLDEN_FLIGHTS
                                  if (folder / f"{f.name}.npy").is_file()}, layer))


def _layer_files(files: dict, layer: str) -> dict:
    """The files of the flights of the layers ``layer`` covers (:func:`covered_layers`): a
    flight of several layers when it covers each."""
    covered = covered_layers(layer)
    wanted = {f.name for f in GOLDEN_FLIGHTS if covered_layers(f.layer) <= covered}
    return {name: digest for name, digest in files.items() if name in wanted}


def stamp(folder, made_by: str, layer: str = "") -> Path:
    """Write ``folder/evidence.json``: the golden hash of ``layer`` (:func:`layer_of`: the
    layers the set's runs use) the set was made with, and the command that made it. Call it
    last, after every file of the set is written. A set whose command records no wall time
    gets the time this process has run (:func:`~paper_repro.evidence.sets.record_wall_time`),
    so the contributor page shows the last run, by hand or by ``regenerate``."""
    from paper_repro import _blas

    _blas.check_kernel()
    out = Path(folder) / "evidence.json"
    record = {"golden": golden_hash(layer), "made_by": made_by}
    if layer:
        record["layer"] = layer
    text = json.dumps(record, indent=1) + "\n"
    atomic_text(out, text)
    seconds = process_wall_time()
    if seconds is not None:
        record_wall_time(Path(folder), seconds)
    return out


def process_wall_time() -> float | None:
    """s since this process started, from Linux's ``/proc`` (to its clock tick, 10 ms);
    ``None`` where it cannot be read."""
    try:
        fields = Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()
        started = int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22: starttime, ticks
        return max(float(Path("/proc/uptime").read_text().split()[0]) - started, 0.0)
    except (OSError, ValueError, IndexError):
        return None


def command_line() -> str:
    """The command this process runs, as a user would type it (for :func:`stamp`)."""
    import sys

    argv = sys.argv[1:] if sys.argv and sys.argv[0].endswith("__main__.py") else sys.argv
    head = "python -m paper_repro" if argv is not sys.argv else "python"
    return " ".join([head, *argv])


def stamped_hash(folder) -> str | None:
    """The golden hash recorded in ``folder/evidence.json`` (``None`` without a stamp)."""
    path = Path(folder) / "evidence.json"
    return json.loads(path.read_text())["golden"] if path.is_file() else None


def stamped_layer(folder) -> str:
    """The golden layer recorded in ``folder/evidence.json`` (``""``, the core, by default)."""
    path = Path(folder) / "evidence.json"
    return json.loads(path.read_text()).get("layer", "") if path.is_file() else ""


def stale_evidence() -> list[str]:
    """The evidence sets present in ``figures/`` whose stamp is missing or differs from the
    golden hash of its layer, or whose ``study.json`` was made with another (the engine
    writes there the hash of the layer its runs use, so a study of map runs stamped with the
    core's hash is stale). A set that is not there is missing, not stale: it shows
    nothing."""
    stale = []
    for name in EVIDENCE_SETS:
        folder = paths.figures_dir() / name
        if not folder.is_dir():
            continue
        layer, study = stamped_layer(folder), folder / "study.json"
        meta = json.loads(study.read_text()) if study.is_file() else None
        if (not _known_layer(layer) or stamped_hash(folder) != golden_hash(layer)
                or meta is not None and (_study_layer(meta) != layer
                                         or meta["golden"] != golden_hash(layer))):
            stale.append(name or "figures")
    return stale


def _known_layer(layer: str) -> bool:
    try:
        covered_layers(layer)
    except ValueError:
        return False
    return True


def _study_layer(meta: dict) -> str:
    """The golden layer a study's runs use (:func:`layer_of`), from its ``study.json``."""
    base = meta["base_config"]
    return layer_of(study_run_config(base, {}),
                    *(study_run_config(base, spec["config_changes"]) for spec in meta["specs"]))


def study_run_config(base_config: dict, changes: dict):
    """A run's :class:`~paper_repro.config.Config` as its study's ``study.json`` records it:
    the ``base_config`` (as a key sees it) with the run's ``config_changes``
    (``{"part.field": value}``) applied, read by :meth:`Config.from_dict`."""
    from paper_repro.config import Config

    data = {part: dict(fields) for part, fields in base_config.items()}
    for key, value in changes.items():
        part, name = key.split(".", 1)
        data.setdefault(part, {})[name] = value
    return Config.from_dict(data)


def set_hash(files: dict) -> str:
    """The hash of a set of golden files, ``{name: SHA-256}`` (:func:`paths.json_hash`)."""
    return json_hash(files)


def _atomic_save(path: Path, array: np.ndarray) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.save(fh, np.ascontiguousarray(array, dtype="<f8"))

    atomic_write(path, write)


def _select(names) -> list[GoldenFlight]:
    if not names:
        return list(GOLDEN_FLIGHTS)
    known = {f.name: f for f in GOLDEN_FLIGHTS}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"unknown golden flight(s) {unknown}; choose from {sorted(known)}")
    # A flight that starts from another needs its parent flown first, in the same call.
    wanted = set(names) | {known[n].start[0] for n in names if known[n].start}
    return [f for f in GOLDEN_FLIGHTS if f.name in wanted]

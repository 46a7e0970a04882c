"""Studies: many closed-loop runs described as data, flown on Dask, gathered into one table.

A :class:`Study` is a name and a tuple of :class:`~paper_repro.runs.RunSpec` (config
overrides × scene seeds × metric), each a small picklable value. :func:`run_study` executes it:

* every run goes through the run cache (:mod:`paper_repro.runs`), keyed by the hash of its
  spec and written atomically, so a re-run, or a study whose driver was killed, flies only
  what is missing;
* execution uses ``dask.distributed``: by default an embedded ``LocalCluster`` with one
  single-threaded worker process per core; ``scheduler="tcp://HOST:PORT"`` sends the same
  tasks to an existing cluster (``dask scheduler`` / ``dask worker``, or dask-jobqueue on
  SLURM) and nothing else changes. A worker builds a controller once per distinct
  configuration and reuses it (:func:`run_task`); the compiled C is cached on disk;
* a run that raises becomes a *failed* row carrying its error, a worker that dies has its
  tasks rescheduled by Dask, and the study always finishes;
* the rows (spec labels + :func:`~paper_repro.metrics.summary_row`) form one tidy pandas
  table, saved as Parquet (and CSV when small) with ``study.json`` (every spec's config, the
  machine, the versions, the wall time) beside it.

The studies of the package are :func:`monte_carlo` and :func:`eta_sweep` (:data:`STUDIES`);
``python -m paper_repro study NAME`` runs one.

Why passages. Under the printed weights the UAV's speed is about (distance to target)/150 s,
so a 20 m mission lasts ≈600 s of flight (60,000 steps). A *passage* (start 4 m before a random
obstacle field, target 40 m beyond it, the run ends 2 m past the field) crosses the same field
at the same speed in 40-60 s of flight: this is what makes 100-scene studies affordable.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from . import metrics, paths
from .config import Config, SensorParams, SimulationParams
from .reproduce import duration
from .runs import RunSpec, ensure_result

PASSAGE_STEPS = 15_000
"""Step limit of a passage (150 s of flight): about three times the 40-60 s a passage takes, so
only a stall or a very long detour reaches it."""

QUICK_STEPS = 400
"""Step limit of a ``--quick`` study's runs (4 s of flight): exercises every part, proves
nothing."""

CSV_ROWS = 5_000
"""Tables up to this many rows are also written as CSV (readable in a diff)."""

TIMING_COLUMNS = (*metrics.TIMING_COLUMNS, "task_time_s", "worker", "simulated", "result_dir")
"""Columns that depend on the machine, the load or the cache, not on the flight."""


@dataclass(frozen=True)
class Study:
    """A named list of runs.

    Attributes
    ----------
    name : folder name of the study's output (``monte_carlo``).
    specs : the runs; names must be unique.
    description : one paragraph, stored in ``study.json``.
    """

    name: str
    specs: tuple
    description: str = ""

    def __post_init__(self):
        if not self.name or "/" in self.name:
            raise ValueError(f"name must be a non-empty folder name, got {self.name!r}")
        if not self.specs or not all(isinstance(s, RunSpec) for s in self.specs):
            raise ValueError("specs must be a non-empty sequence of RunSpec")
        names = [s.name for s in self.specs]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"specs must have unique names, repeated: {dup[:5]}")
        object.__setattr__(self, "specs", tuple(self.specs))


@dataclass
class StudyResult:
    """What :func:`run_study` produced: the table (one row per spec, in spec order) and where
    it was saved."""

    study: Study
    table: object  # pandas.DataFrame
    directory: Path
    wall_time_s: float

    @property
    def failed(self):
        """The rows of runs that raised (``status == "failed"``)."""
        return self.table[self.table["status"] == "failed"]


# --- the studies ----------------------------------------------------------------------------

def passage_config(base: Config | None = None, seed: int = 0, max_steps: int = PASSAGE_STEPS,
                   scenario: str = "random", **distance) -> Config:
    """``base`` flying a passage through the random scene of ``seed`` (``scenario``:
    ``"random"``, or ``"random-crossing"`` whose regions move across the line); ``distance``
    overrides fields of :class:`~paper_repro.config.DistanceParams` (``metric``, ``eta``,
    ``sigma``)."""
    base = base or Config()
    return dataclasses.replace(
        base, distance=dataclasses.replace(base.distance, **distance),
        simulation=dataclasses.replace(base.simulation, scenario=scenario, kind="passage",
                                       seed=int(seed), max_steps=int(max_steps)))


def passage_spec(seed: int, metric: str = "smooth", eta: float | None = None,
                 sigma: float | None = None, max_steps: int = PASSAGE_STEPS,
                 base: Config | None = None, tag: str = "", scenario: str = "random"
                 ) -> RunSpec:
    """A passage through random scene ``seed``; the name says what differs from ``base`` (and
    ``tag`` anything else a study varies), so the same flight has the same name (and cache
    folder) in every study that asks for it."""
    base = base or Config()
    over = {"metric": metric}
    if metric == "smooth":
        over.update(eta=base.distance.eta if eta is None else eta,
                    sigma=base.distance.sigma if sigma is None else sigma)
    cfg = passage_config(base, seed, max_steps, scenario, **over)
    name = (f"passage-smooth-eta{cfg.distance.eta:g}-sigma{cfg.distance.sigma:g}"
            if metric == "smooth" else f"passage-{metric}") + (f"-{tag}" if tag else "") + \
        f"-s{seed:03d}"
    labels = (("metric", metric),
              ("eta", cfg.distance.eta if metric == "smooth" else 0.0),
              ("sigma", cfg.distance.sigma if metric == "smooth" else float("nan")),
              ("scene_seed", seed))
    return RunSpec(name, cfg, max_steps, labels)


def monte_carlo(quick: bool = False, scenes: int | None = None,
                base: Config | None = None) -> Study:
    """The paper's claim over random scenes: ``scenes`` passages (100; 3 with ``quick``) ×
    {smoothed, Euclidean}, everything else as printed."""
    n = scenes if scenes is not None else (3 if quick else 100)
    _require_count("scenes", n)
    steps = QUICK_STEPS if quick else PASSAGE_STEPS
    specs = [passage_spec(seed, metric, max_steps=steps, base=base)
             for metric in ("smooth", "euclidean") for seed in range(n)]
    return Study("monte_carlo" + ("-quick" if quick else ""), tuple(specs),
                 f"{n} random passages x {{smooth, euclidean}}, printed parameters")


ETAS = (0.05, 0.1, 0.2, 0.3, 0.5, 0.8)
"""η values of :func:`eta_sweep`, m (the paper's 0.3 in the middle)."""

SIGMAS = (0.4, 0.8, 1.6)
"""σ values of :func:`eta_sweep`, m (the paper's 0.8 in the middle)."""


def eta_sweep(quick: bool = False, scenes: int | None = None, etas: Sequence[float] = ETAS,
              sigmas: Sequence[float] = SIGMAS, grid: bool = False,
              base: Config | None = None) -> Study:
    """η and σ over ``scenes`` random passages (20; 2 with ``quick``), plus the Euclidean
    baseline (the η → 0 limit) on the same scenes.

    By default one factor at a time about the printed point (η = 0.3 m, σ = 0.8 m): every η
    of ``etas`` at the printed σ, every σ of ``sigmas`` at the printed η (9 configurations with
    the baseline). ``grid=True`` flies the full η × σ grid (19).
    """
    n = scenes if scenes is not None else (2 if quick else 20)
    _require_count("scenes", n)
    base = base or Config()
    if quick:
        etas, sigmas = (0.1, 0.3), (0.8,)
    for name, values in (("etas", etas), ("sigmas", sigmas)):
        if not values or not all(math.isfinite(v) and v > 0 for v in values):
            raise ValueError(f"{name} must be a non-empty sequence of finite values > 0 (m), "
                             f"got {values!r}")
    eta0, sigma0 = base.distance.eta, base.distance.sigma
    pairs = ([(e, s) for s in sigmas for e in etas] if grid else
             [(e, sigma0) for e in etas] + [(eta0, s) for s in sigmas if s != sigma0])
    pairs = list(dict.fromkeys(pairs))  # unique, in order
    steps = QUICK_STEPS if quick else PASSAGE_STEPS
    specs = [passage_spec(seed, "smooth", eta, sigma, steps, base)
             for eta, sigma in pairs for seed in range(n)]
    specs += [passage_spec(seed, "euclidean", max_steps=steps, base=base) for seed in range(n)]
    return Study("eta_sweep" + ("-quick" if quick else ""), tuple(specs),
                 f"(eta, sigma) in {pairs} and the Euclidean baseline over {n} random "
                 "passages")


NOISY_LIDAR = SensorParams(range_noise=0.05, dropout=0.2, spurious_rate=2.0)
"""The sensor of :func:`sensor_noise`: 5 cm range noise (1σ), one point in five lost, two
spurious returns per scan on average; seeded per scene."""


def sensor_noise(quick: bool = False, scenes: int | None = None,
                 base: Config | None = None) -> Study:
    """Smooth against Euclidean with a perfect and a noisy LiDAR (:data:`NOISY_LIDAR`), on
    ``scenes`` random passages (8; 2 with ``quick``; the perfect runs are those of
    :func:`monte_carlo`). The smoothed distance averages many points where the Euclidean one
    follows the nearest, so noise should widen the gap."""
    n, base, steps = _passages(quick, scenes, 8, base)
    specs = []
    for level, sensor in (("perfect", base.sensor), ("noisy", NOISY_LIDAR)):
        for metric in ("smooth", "euclidean"):
            for seed in range(n):
                cfg = dataclasses.replace(base, sensor=dataclasses.replace(sensor, seed=seed)
                                          if level == "noisy" else sensor)
                spec = passage_spec(seed, metric, max_steps=steps, base=cfg,
                                    tag="" if level == "perfect" else "noisy")
                specs.append(dataclasses.replace(spec, labels=spec.labels
                                                 + (("sensor", level),)))
    return Study("sensor_noise" + ("-quick" if quick else ""), tuple(specs),
                 f"smooth vs euclidean, perfect vs noisy LiDAR ({NOISY_LIDAR}), {n} passages")


SENSING_WINDOWS = (0.0, 0.5, 1.0)
"""Widths w (m) of the smooth sensing window flown by :func:`sensing_window` (0: the paper's
hard cut-off at r_s = 3 m)."""


def sensing_window(quick: bool = False, scenes: int | None = None,
                   base: Config | None = None) -> Study:
    """The smooth metric with the sensing window of each width in :data:`SENSING_WINDOWS`, on
    ``scenes`` random passages (12; 2 with ``quick``; w = 0 are the runs of
    :func:`monte_carlo`). Do thrust steps at changes of the visible set disappear, and at what
    cost in clearance and completion?"""
    n, base, steps = _passages(quick, scenes, 12, base)
    specs = []
    for width in SENSING_WINDOWS:
        cfg = dataclasses.replace(base, distance=dataclasses.replace(base.distance,
                                                                     window=width))
        for seed in range(n):
            spec = passage_spec(seed, "smooth", max_steps=steps, base=cfg,
                                tag="" if width == 0 else f"w{width:g}")
            specs.append(dataclasses.replace(spec, labels=spec.labels + (("window_m", width),)))
    return Study("sensing_window" + ("-quick" if quick else ""), tuple(specs),
                 f"smooth metric, sensing window w in {SENSING_WINDOWS} m, {n} passages")


PREDICTIONS = ("static", "oracle", "kalman")
"""How the NMPC predicts a moving region (``SimulationParams.prediction``): not at all (the
paper), with its true velocity, or with a Kalman filter on its visible centroid."""


def moving_obstacles(quick: bool = False, scenes: int | None = None,
                     base: Config | None = None) -> Study:
    """Random crossings (``"random-crossing"``: every region moves across the line at
    0.5–1.5 m/s) × the predictions of :data:`PREDICTIONS` × {smoothed, Euclidean}, on
    ``scenes`` passages (30; 2 with ``quick``). Does the static assumption collide where
    prediction does not?

    Flown with the damped real-time iteration (``nmpc.line_search = True``): where a region
    moves at the vehicle the full Gauss-Newton steps fall into a period-2 oscillation of the
    thrusts between their bounds that the converged controller (IPOPT) does not show, and the
    damped iteration stays within millimetres of IPOPT there (``benchmarks/fidelity.py``)."""
    n, base, steps = _passages(quick, scenes, 30, base)
    base = dataclasses.replace(base, nmpc=dataclasses.replace(base.nmpc, line_search=True))
    specs = []
    for prediction in PREDICTIONS:
        cfg = dataclasses.replace(base, simulation=dataclasses.replace(
            base.simulation, prediction=prediction))
        for metric in ("smooth", "euclidean"):
            for seed in range(n):
                spec = passage_spec(seed, metric, max_steps=steps, base=cfg,
                                    tag=f"crossing-{prediction}", scenario="random-crossing")
                specs.append(dataclasses.replace(
                    spec, labels=spec.labels + (("prediction", prediction),)))
    return Study("moving_obstacles" + ("-quick" if quick else ""), tuple(specs),
                 f"random crossings, prediction in {PREDICTIONS} x both metrics, {n} passages")


def timeline_flights(quick: bool = False, scenes: int | None = None,
                     base: Config | None = None) -> Study:
    """The paper mission under each reading of the printed set-up that could set its clock
    (:func:`paper_repro.timeline.timeline_study`); ``scenes`` does not apply."""
    from .timeline import timeline_study

    if scenes is not None:
        raise ValueError("scenes does not apply to the timeline study (it flies the paper "
                         "mission)")
    return timeline_study(quick=quick, base=base)


STUDIES: dict[str, Callable[..., Study]] = {"monte_carlo": monte_carlo, "eta_sweep": eta_sweep,
                                            "sensor_noise": sensor_noise,
                                            "sensing_window": sensing_window,
                                            "moving_obstacles": moving_obstacles,
                                            "timeline": timeline_flights}
"""The studies ``python -m paper_repro study NAME`` knows."""


def make_study(name: str, quick: bool = False, base: Config | None = None,
               scenes: int | None = None) -> Study:
    """The study of :data:`STUDIES` called ``name``, its runs built on ``base`` (default
    :class:`Config`, e.g. a :func:`paper_repro.presets.preset`), over ``scenes`` random
    passages (default: the study's own)."""
    if name not in STUDIES:
        raise ValueError(f"study must be one of {sorted(STUDIES)}, got {name!r}")
    return STUDIES[name](quick=quick, base=base, scenes=scenes)


# --- running a study ------------------------------------------------------------------------

def run_study(study: Study, out=None, workers: int | None = None, scheduler: str | None = None,
              client=None, force: bool = False, progress: bool | None = None, runs_dir=None,
              log: Callable[[str], None] = print,
              on_row: Callable[[int, dict], None] | None = None) -> StudyResult:
    """Fly every run of ``study`` that is not cached, gather the table, save it.

    Parameters
    ----------
    study : the runs.
    out : output folder (default ``results/studies/<study.name>``): ``table.parquet``,
        ``table.csv`` (up to :data:`CSV_ROWS` rows) and ``study.json``.
    runs_dir : the run cache (default ``<out>/runs``): one folder per run.
    workers : worker processes of the embedded ``LocalCluster`` (default: one per core);
        ``0`` runs in this process without Dask (debugging).
    scheduler : address of an existing Dask scheduler (``tcp://host:8786``); then ``workers``
        is ignored and the cluster's workers fly the runs. They must reach ``out`` (a shared
        file system on a real cluster).
    client : an existing ``distributed.Client`` to use instead (e.g. from a notebook).
    force : fly every run again.
    progress : a progress bar (default: when standard error is a terminal); otherwise a plain
        line every 30 s.
    log : receives the plain lines.
    on_row : called with (spec index, row) as each run finishes.

    A run that raises is a row with ``status = "failed"`` and its ``error``; nothing is dropped.
    """
    import pandas as pd

    if workers is not None and not (isinstance(workers, int) and workers >= 0):
        raise ValueError(f"workers must be an integer >= 0, got {workers!r}")
    if scheduler is not None and not (isinstance(scheduler, str) and "://" in scheduler):
        raise ValueError(f"scheduler must be an address like 'tcp://host:8786', got "
                         f"{scheduler!r}")
    out = Path(out) if out is not None else paths.results_dir() / "studies" / study.name
    runs_dir = Path(runs_dir) if runs_dir is not None else out / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows: list[dict | None] = [None] * len(study.specs)
    bar = _Progress(study.name, len(study.specs), progress, log)

    def done(i: int, row: dict) -> None:
        rows[i] = row
        bar.update(row)
        if on_row is not None:
            on_row(i, row)

    try:
        if client is None and scheduler is None and workers == 0:
            for i, spec in enumerate(study.specs):
                done(i, run_task(spec, str(runs_dir), force))
        else:
            _run_on_dask(study.specs, str(runs_dir), force, done, workers, scheduler, client,
                         log)
    finally:
        bar.close()
    wall = time.perf_counter() - start
    table = pd.DataFrame(rows)
    _save(study, table, out, wall)
    failed = int((table["status"] == "failed").sum())
    log(f"study {study.name}: {len(table)} runs ({int(table['simulated'].sum())} flown, "
        f"{failed} failed) in {duration(wall)} -> {out}")
    return StudyResult(study, table, out, wall)


def run_task(spec: RunSpec, runs_dir: str, force: bool = False) -> dict:
    """One task: the run from the cache, or flown now; its row. Never raises.

    This is what a Dask worker executes. The controller comes from :func:`_controller`, built
    once per configuration in each worker process.
    """
    from .metrics import summary_row
    from .simulation import SimulationResult

    t0 = time.perf_counter()
    row = {"name": spec.name, "key": spec.key[:12], **dict(spec.labels)}
    try:
        controller = _controller(_controller_key(spec.config))
        directory, simulated = ensure_result(spec, runs_dir, force=force, controller=controller)
        row.update(summary_row(SimulationResult.load(directory)))
        row.update(status="ok", error="", simulated=simulated, result_dir=str(directory))
    except Exception as exc:  # a failed run is a row, never a lost study
        row.update(_failure(exc))
    row["task_time_s"] = time.perf_counter() - t0
    row["worker"] = f"{os.uname().nodename}:{os.getpid()}"
    return row


def load_table(directory, timings: bool = True):
    """The table saved by :func:`run_study` in ``directory``: the flight columns
    (``table.parquet``) joined, by run ``name``, with this machine's :data:`TIMING_COLUMNS`
    (``timings.csv``) unless ``timings=False``."""
    import pandas as pd

    directory = Path(directory)
    table = pd.read_parquet(directory / "table.parquet")
    path = directory / "timings.csv"
    if timings and path.is_file():
        table = table.merge(pd.read_csv(path), on="name", how="left", validate="one_to_one")
    return table


# --- the command ----------------------------------------------------------------------------

def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro study NAME``."""
    parser.add_argument("name", choices=sorted(STUDIES), help="which study")
    parser.add_argument("--quick", action="store_true",
                        help="a few short runs (what CI executes); output under figures/quick/")
    from .reproduce import non_negative_int, positive_int

    parser.add_argument("--workers", type=non_negative_int, default=None,
                        help="worker processes of the embedded Dask cluster (default: one per "
                             "core; 0: no Dask, in this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="send the runs to an existing Dask scheduler (tcp://host:8786) "
                             "instead; its workers must see the output folders")
    parser.add_argument("--out", default=None,
                        help="where the table, study.json and the figures go (default: "
                             "figures/studies/NAME, or figures/quick/studies/NAME)")
    parser.add_argument("--scenes", type=positive_int, default=None,
                        help="random passages (scene seeds 0..N-1; default: the study's own, "
                             "100 for monte_carlo, 20 for eta_sweep, 8 for sensor_noise)")
    parser.add_argument("--force", action="store_true", help="fly every run again")
    parser.add_argument("--no-figures", action="store_true",
                        help="only the table: do not execute the study's notebook")
    parser.add_argument("--no-progress", action="store_true", help="plain progress lines")
    parser.add_argument("--preset", default="paper", metavar="NAME",
                        help="named set-up the runs start from (paper_repro.presets; default "
                             "'paper', the printed parameters); another preset's output goes "
                             "to figures/presets/NAME/studies/")


def main(args) -> int:
    """Run ``python -m paper_repro study``: the study (cached runs are only loaded), its table,
    then its notebook, which draws the figures from the saved table."""
    from .evidence import command_line, stamp
    from .presets import DEFAULT, preset

    study = make_study(args.name, quick=args.quick, base=preset(args.preset),
                       scenes=args.scenes)
    out = Path(args.out) if args.out else study_dir(args.name, args.quick)
    if args.out is None and args.preset != DEFAULT:
        out = paths.figures_dir(args.quick) / "presets" / args.preset / "studies" / args.name
    result = run_study(study, out=out, workers=args.workers, scheduler=args.scheduler,
                       force=args.force, runs_dir=paths.results_dir() / "runs",
                       progress=False if args.no_progress else None,
                       log=lambda line: print(line, flush=True))
    if not args.no_figures:
        from .reproduce import execute_notebook, notebook_path

        notebook = STUDY_NOTEBOOKS[args.name]
        t0 = time.perf_counter()
        params = {"study_dir": str(result.directory),
                  **(STUDY_NOTEBOOK_QUICK.get(args.name, {}) if args.quick else {})}
        execute_notebook(notebook_path(notebook),
                         paths.executed_dir(args.quick) / f"{notebook}.ipynb", params)
        print(f"notebook {notebook}: figures in {result.directory} "
              f"({duration(time.perf_counter() - t0)})", flush=True)
        # Last, once the table and every figure are in place: the set is this code's.
        stamp(result.directory, command_line())
    return 0


STUDY_NOTEBOOKS = {"monte_carlo": "09_monte_carlo", "eta_sweep": "10_eta_sweep",
                   "sensor_noise": "13_sensor_noise", "sensing_window": "15_smooth_sensing",
                   "moving_obstacles": "16_moving_obstacles", "timeline": "11_timeline"}
"""The notebook that draws each study's figures from its saved table."""

STUDY_NOTEBOOK_QUICK = {"sensing_window": {"mission": "encounter", "mission_steps": 3000},
                        "moving_obstacles": {"crossing_steps": 1500}, "timeline": {"quick": True}}
"""Notebook parameters of a ``--quick`` study beyond its table (notebook 15 also flies one
mission with and without the window: the encounter's first 30 s instead of the paper's;
notebook 16 flies the crossing scene with each prediction: its first 15 s, past the meeting,
instead of the whole passage; notebook 11 sweeps fewer values per lever)."""


def study_dir(name: str, quick: bool = False) -> Path:
    """Committed home of a study's table and figures: ``figures/studies/<name>`` (or
    ``figures/quick/studies/<name>``, git-ignored)."""
    return paths.figures_dir(quick) / "studies" / name


# --- helpers --------------------------------------------------------------------------------

def _run_on_dask(specs, runs_dir: str, force: bool, done, workers, scheduler, client,
                 log) -> None:
    """Submit every spec as a task, hand each row to ``done`` as it arrives."""
    from distributed import Client, LocalCluster, as_completed

    cluster = own_client = None
    if client is None:
        if scheduler is not None:
            client = own_client = Client(scheduler)
        else:
            n = workers if workers else (os.cpu_count() or 1)
            # One single-threaded process per core: the closed loop is CPU-bound Python + C.
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=40)
            client = own_client = Client(cluster)
    log(f"dask: {len(client.scheduler_info()['workers'])} worker(s), dashboard "
        f"{client.dashboard_link}")
    try:
        # Build each distinct controller once first, the configurations spread over the
        # workers: compiling one takes a minute, and every worker would otherwise compile the
        # same C at the same time. The libraries land in the disk cache the runs load from.
        keys = sorted({_controller_key(s.config) for s in specs})
        client.gather(client.map(_warm, keys, pure=False, key=[f"build-{i}" for i in
                                                                range(len(keys))]),
                      errors="skip")
        futures = [client.submit(run_task, spec, runs_dir, force, pure=False, retries=1,
                                 key=f"run-{spec.name}-{spec.key[:12]}")
                   for spec in specs]
        index = {f.key: i for i, f in enumerate(futures)}
        for future in as_completed(futures):
            i = index[future.key]
            try:
                row = future.result()
            except Exception as exc:  # the task never returned (its worker kept dying)
                row = {"name": specs[i].name, "key": specs[i].key[:12], **dict(specs[i].labels),
                       **_failure(exc), "task_time_s": float("nan"), "worker": ""}
            done(i, row)
    finally:
        if own_client is not None:
            own_client.close()
        if cluster is not None:
            cluster.close()


def _passages(quick: bool, scenes: int | None, default: int, base: Config | None):
    """(number of scenes, base config, steps per passage) of a passage study: ``default``
    scenes, 2 with ``quick`` (and the short quick passages), unless ``scenes`` says."""
    n = scenes if scenes is not None else (2 if quick else default)
    _require_count("scenes", n)
    return n, base or Config(), QUICK_STEPS if quick else PASSAGE_STEPS


@functools.lru_cache(maxsize=8)
def _controller(key: str):
    """The controller of a configuration, built once per worker process.

    Building costs seconds (the NLP, the C linearisation loaded from the disk cache), flying a
    passage a few, so each worker keeps the last few it built; ``simulate`` resets a controller
    before every flight, so reuse cannot change a trajectory.
    """
    from .controllers import make_controller

    return make_controller(Config.from_dict(json.loads(key)))


def _warm(key: str) -> None:
    """Build (and so compile and cache) a controller; a failure shows up again in its runs."""
    try:
        _controller(key)
    except Exception:  # noqa: BLE001 - each run of this configuration records the error
        pass


def _controller_key(config: Config) -> str:
    """What a controller depends on: the configuration without its ``sensor`` part and the
    ``simulation`` fields that are the closed loop's (scene, run kind, limits). It keeps the
    two the problem reads: ``prediction`` (moving regions carry velocities in the scan's
    layout) and ``lidar_range`` (the sensing window's r_s)."""
    sim = config.simulation
    neutral = dataclasses.replace(
        config, sensor=SensorParams(),
        simulation=SimulationParams(prediction=sim.prediction, lidar_range=sim.lidar_range))
    return json.dumps(neutral.to_dict(), sort_keys=True, default=str)


def _failure(exc: BaseException) -> dict:
    return {"status": "failed", "error": f"{type(exc).__name__}: {exc}", "simulated": False,
            "result_dir": "", "traceback": "".join(traceback.format_exception(exc))[-4000:]}


def _save(study: Study, table, out: Path, wall: float) -> None:
    """The study's files, each written atomically, in two groups:

    * what the flights determine, byte-stable on any machine of the same kind:
      ``table.parquet`` (+ ``table.csv`` when small), every column but :data:`TIMING_COLUMNS`,
      and ``study.json`` (the runs, their configurations, the golden hash);
    * what the machine determines: ``timings.csv`` (:data:`TIMING_COLUMNS` per run, by
      ``name``) and ``timings.json`` (wall time, versions, commit, machine).

    :func:`load_table` joins the two again."""
    from .evidence import golden_hash
    from .simulation import run_metadata

    flight, timings = metrics.split_timings(table, TIMING_COLUMNS)
    timing = list(timings.columns)
    _atomic(out / "table.parquet", lambda p: flight.to_parquet(p, index=False))
    if len(table) <= CSV_ROWS:
        _atomic(out / "table.csv", lambda p: flight.to_csv(p, index=False))
    _atomic(out / "timings.csv", lambda p: table[["name", *timing]].to_csv(p, index=False))
    base = study.specs[0].config.to_dict()
    meta = {"name": study.name, "description": study.description,
            "runs": len(study.specs), "golden": golden_hash(), "base_config": base,
            "specs": [{"name": s.name, "key": s.key, "max_steps": s.max_steps,
                       "labels": dict(s.labels),
                       "config_changes": _changes(base, s.config.to_dict())}
                      for s in study.specs]}
    text = json.dumps(meta, indent=1, default=str) + "\n"
    _atomic(out / "study.json", lambda p: p.write_text(text))
    machine = json.dumps({"wall_time_s": wall, "meta": run_metadata()}, indent=1,
                         default=str) + "\n"
    _atomic(out / "timings.json", lambda p: p.write_text(machine))


def _atomic(path: Path, write) -> None:
    """``write(tmp)`` then rename ``tmp`` to ``path``: a reader never sees half a file."""
    tmp = path.with_name(f".{path.stem}.{os.getpid()}{path.suffix}")
    write(tmp)
    os.replace(tmp, path)


def _changes(base: dict, config: dict) -> dict:
    """``{"part.field": value}`` where ``config`` differs from ``base`` (both
    ``Config.to_dict()``): with the base, every spec's full configuration."""
    return {f"{part}.{name}": value for part, fields in config.items()
            for name, value in fields.items() if base.get(part, {}).get(name) != value}


class _Progress:
    """Runs done / total, failures, ETA: a tqdm bar on a terminal, else a line every 30 s."""

    def __init__(self, name: str, total: int, progress: bool | None, log, interval=30.0):
        self.name, self.total, self.log, self.interval = name, total, log, interval
        self.done = self.failed = 0
        self.start = self.last = time.perf_counter()
        tty = sys.stderr.isatty() if progress is None else progress
        self.bar = None
        if tty:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="run", desc=f"study {name}", smoothing=0.1)
        else:
            log(f"study {name}: {total} runs")

    def update(self, row: dict) -> None:
        self.done += 1
        self.failed += row.get("status") == "failed"
        now = time.perf_counter()
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix(failed=self.failed)
        elif now - self.last >= self.interval or self.done == self.total:
            self.last = now
            elapsed = now - self.start
            eta = elapsed / self.done * (self.total - self.done)
            self.log(f"study {self.name}: {self.done}/{self.total} runs, {self.failed} failed, "
                     f"{duration(elapsed)} elapsed, ETA {duration(eta)}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _require_count(name: str, n) -> None:
    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"{name} must be an integer >= 1, got {n!r}")


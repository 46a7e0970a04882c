"""One command regenerates every figure and the summary: ``python -m paper_repro reproduce``.

Two stages, each printed with its duration:

1. **simulate** — the paper mission (``paper`` scene) once per metric, smoothed and Euclidean.
   Runs go through the run cache (:mod:`paper_repro.studies.runs`, shared with ``study``): a result
   lives in ``results/<run>-<hash>/``, the hash covering the full configuration, the step
   limit and the scene's fingerprint, so a second call only redraws; a changed parameter (the
   solver choice included) gives a new folder. The hash also covers the golden hash
   (:mod:`paper_repro.evidence.golden`), so a change of code that moves a flight retires every
   cached run once the golden flights are written again. The two missions fly in parallel,
   one process each.
2. **notebooks** — every notebook of :data:`NOTEBOOKS` (the study notebooks run with their
   studies, ``python -m paper_repro study NAME``) is executed with papermill, its parameters
   checked against the ones the notebook declares (a wrong name raises ``ValueError``), into
   the git-ignored ``notebooks/executed/``. The notebooks write ``figures/*.pdf``, ``*.png``,
   ``flight.gif`` and ``summary.csv``.

``--quick`` flies a short mission (:data:`QUICK_STEPS` steps per metric) and writes into the
git-ignored ``figures/quick/``, so a quick look never overwrites the committed figures.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from paper_repro import paths
from paper_repro.config import Config
from paper_repro.progress import PrefixedLines, duration, heartbeat, print_now
from paper_repro.sim.result import read_arrays
from paper_repro.studies.runs import RunSpec, ensure_result, holds, usable_or_set_aside

DESCRIPTION = """\
Regenerate every figure of the paper and the summary table.

1. simulate: the paper mission once per metric (smoothed, Euclidean), cached in
   results/<run>-<config hash>/, so a second call only redraws;
2. notebooks: every figure notebook executed with papermill (parameters checked) into
   notebooks/executed/; they write figures/*.pdf, *.png, flight.gif and summary.csv.
   Last, figures/evidence.json records the golden flights the set was made with.

--quick flies a short mission and writes into figures/quick/ (git-ignored)."""

METRICS = ("smooth", "euclidean")
"""The two runs of Section V: the smoothed distance (Figs. 1-5) and the Euclidean baseline
(Figs. 6-8)."""

QUICK_STEPS = 300
"""Steps per metric of a ``--quick`` run (3 s of flight; about a minute of IPOPT per metric)."""

_QUIET_KERNEL = "--IPKernelApp.log_level=CRITICAL"
"""The kernel's own log (a transport warning at every start) is noise here: errors in a cell
reach us as papermill exceptions, a dead kernel as ``DeadKernelError``."""


@dataclass(frozen=True)
class NotebookSpec:
    """A notebook of ``notebooks/`` and what :func:`reproduce` passes to it.

    Attributes
    ----------
    name : file stem (``01_flight_3d`` for ``notebooks/01_flight_3d.ipynb``).
    title : what it reproduces.
    runs : the metrics whose result folders it reads, passed as ``<metric>_dir``.
    outputs : files it writes into ``figures_dir``.
    quick : extra parameters of a quick run (e.g. fewer animation frames).
    """

    name: str
    title: str
    runs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    quick: dict = field(default_factory=dict)


def _figure(*stems: str) -> tuple[str, ...]:
    return tuple(f"{s}.{ext}" for s in stems for ext in ("pdf", "png"))


NOTEBOOKS = (
    NotebookSpec("01_flight_3d", "Fig. 1, 3-D flight", ("smooth",), _figure("fig01_flight_3d")),
    NotebookSpec("02_projections", "Figs. 2 and 3, XZ and XY projections", ("smooth",),
                 _figure("fig02_projection_xz", "fig03_projection_xy")),
    NotebookSpec("03_thrusts", "Fig. 4, thrusts", ("smooth",),
                 _figure("fig04_thrusts", "fig04_thrusts_zoom")),
    NotebookSpec("04_tracking_errors", "Fig. 5, tracking errors", ("smooth",),
                 _figure("fig05_tracking_errors", "fig05_tracking_errors_signed",
                         "fig05_tracking_errors_log", "fig05_tracking_errors_zoom",
                         "fig06_smooth_states", "fig06_smooth_states_zoom")),
    NotebookSpec("05_euclidean", "Figs. 6-8, Euclidean run", ("euclidean",),
                 _figure("fig06_euclidean_states", "fig06_euclidean_states_zoom",
                         "fig07_euclidean_tracking_errors",
                         "fig07_euclidean_tracking_errors_zoom",
                         "fig08_euclidean_thrusts", "fig08_euclidean_thrusts_zoom")),
    NotebookSpec("06_summary", "summary table (solve times, chattering)", METRICS,
                 ("summary.csv", "summary_timings.csv",
                  *_figure("summary_solve_times", "summary_input_spectrum"))),
    NotebookSpec("07_distance_tutorial", "tutorial, the smoothed distance", (),
                 _figure("tutorial_distance_slice", "tutorial_eta_sigma",
                         "tutorial_gradient_field", "tutorial_half_squared_limit"),
                 quick={"grid_points": 60}),
    NotebookSpec("08_animation", "animation of the flight", ("smooth",), ("flight.gif",),
                 quick={"frames": 20}),
    NotebookSpec("14_controller_tutorial", "tutorial, the controller: problem (21), RTI and IPOPT, "
                 "a ground robot", (),
                 _figure("tutorial_barrier_penalty", "tutorial_controller_plan",
                         "tutorial_controller_ground_robot"),
                 quick={"robot_steps": 200, "timing_repeats": 2}),
)
"""Every notebook, in the order :func:`reproduce` executes them."""


# --- runs -----------------------------------------------------------------------------------

def run_specs(quick: bool = False, max_steps: int | None = None,
              config: Config | None = None) -> list[RunSpec]:
    """The paper mission once per metric (:data:`METRICS`).

    Parameters
    ----------
    quick : fly :data:`QUICK_STEPS` steps instead of the config's ``max_steps``.
    max_steps : explicit step limit (overrides ``quick``).
    config : base configuration (default :class:`Config`); its metric and scenario are set
        here (``paper``), everything else is kept.
    """
    base = config or Config()
    steps = max_steps if max_steps is not None else (
        QUICK_STEPS if quick else base.simulation.max_steps)
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"max_steps must be an integer >= 1, got {steps!r}")
    specs = []
    for metric in METRICS:
        cfg = dataclasses.replace(
            base,
            distance=dataclasses.replace(base.distance, metric=metric),
            simulation=dataclasses.replace(base.simulation, scenario="paper", max_steps=steps),
        )
        specs.append(RunSpec(f"paper-{metric}", cfg, steps))
    return specs


def default_result_dir(metric: str) -> Path:
    """Cache folder of the full paper mission for ``metric`` (what the notebooks read when run
    by hand without parameters)."""
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")
    return {s.config.distance.metric: s for s in run_specs()}[metric].directory()


# --- notebooks ------------------------------------------------------------------------------

def notebook_path(name: str) -> Path:
    """``notebooks/<name>.ipynb``."""
    return paths.notebooks_dir() / f"{name}.ipynb"


def notebook_parameters(spec: NotebookSpec, result_dirs: dict, figures_dir,
                        quick: bool = False, overrides: dict | None = None) -> dict:
    """Parameters :func:`reproduce` passes to a notebook.

    ``result_dirs`` maps a metric to its result folder; every notebook gets ``figures_dir``,
    those that read runs get ``<metric>_dir``; quick runs add ``spec.quick``; ``overrides``
    come last.
    """
    params = {f"{m}_dir": str(result_dirs[m]) for m in spec.runs}
    params["figures_dir"] = str(figures_dir)
    if quick:
        params.update(spec.quick)
    params.update(overrides or {})
    return params


def declared_parameters(notebook) -> dict:
    """Names and defaults of the ``parameters``-tagged cell (papermill's inspection).

    Raises ``ValueError`` when the notebook has no such cell.
    """
    import papermill

    notebook = Path(notebook)
    declared = papermill.inspect_notebook(str(notebook))
    if not declared and not _has_parameters_cell(notebook):
        raise ValueError(f"{notebook.name} has no cell tagged 'parameters'")
    return declared


def check_parameters(notebook, parameters: dict) -> None:
    """Raise ``ValueError`` naming every parameter the notebook does not declare.

    Papermill itself only logs a warning and injects the value anyway, where it would be
    silently ignored.
    """
    declared = declared_parameters(notebook)
    unknown = sorted(set(parameters) - set(declared))
    if unknown:
        raise ValueError(f"{Path(notebook).name}: unknown parameter(s) {unknown}; it declares "
                         f"{sorted(declared)}")


def execute_notebook(notebook, output, parameters: dict | None = None) -> Path:
    """Check the parameters, then execute ``notebook`` with papermill into ``output``.

    The kernel runs in ``notebooks/``; the notebooks find everything through
    :mod:`paper_repro.paths` or their parameters, so the working directory does not matter.
    """
    import papermill

    parameters = dict(parameters or {})
    check_parameters(notebook, parameters)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    papermill.execute_notebook(str(notebook), str(output), parameters=parameters,
                               progress_bar=False, log_output=False,
                               cwd=str(Path(notebook).parent),
                               extra_arguments=[_QUIET_KERNEL])
    return output


# --- the command ----------------------------------------------------------------------------

@dataclass
class ReproduceReport:
    """What :func:`reproduce` did: result folders, executed notebooks, files written, timings."""

    result_dirs: dict
    simulated: list
    executed: list
    figures_dir: Path
    outputs: list
    timings: dict
    total_seconds: float

    @property
    def summary_csv(self) -> Path:
        return self.figures_dir / "summary.csv"


def reproduce(quick: bool = False, max_steps: int | None = None, force: bool = False,
              notebooks=None, config: Config | None = None, figures_dir=None,
              results_dir=None, executed_dir=None, overrides: dict | None = None,
              progress: bool | None = None, log=print,
              preset: str | None = None, workers: int | None = None) -> ReproduceReport:
    """Simulate what is missing, execute the notebooks, write the figures and the summary.

    Parameters
    ----------
    quick : short mission (:data:`QUICK_STEPS`) into ``figures/quick``.
    max_steps : explicit step limit per run (default: the config's, i.e. the whole mission).
    force : re-simulate even when a cached result exists.
    notebooks : names of the notebooks to execute (default: all of :data:`NOTEBOOKS`).
    config : base configuration of the runs (default :class:`Config`).
    figures_dir, results_dir, executed_dir : override the folders of :mod:`paper_repro.paths`.
    overrides : extra notebook parameters, passed to every notebook that declares them.
    progress : closed-loop progress bar (default: when writing to a terminal).
    log : called with one line per stage.
    preset : a name of :data:`paper_repro.presets.PRESETS`, applied to ``config``; any but
        ``"paper"`` (the printed parameters) writes into ``figures/presets/<name>/`` (and
        ``notebooks/executed/presets/<name>/``) unless the folders are given.
    workers : processes that fly the missions (default: one per mission, at most one per
        core); ``0`` flies them one after the other in this process (debugging, tests).
    """
    if workers is not None and not (isinstance(workers, int) and workers >= 0):
        raise ValueError(f"workers must be an integer >= 0, got {workers!r}")
    start = time.perf_counter()
    config, figures, executed = _folders(preset, config, quick, figures_dir, executed_dir)
    specs = run_specs(quick=quick, max_steps=max_steps, config=config)
    selected = _select_notebooks(notebooks)
    needed = {m for nb in selected for m in nb.runs}
    todo = [s for s in specs if s.config.distance.metric in needed]
    total = len(todo) + len(selected)
    log(f"reproduce: paper mission, {len(todo)} run(s) of at most {specs[0].max_steps} steps, "
        f"{len(selected)} notebook(s) -> {paths.in_repo(figures)}")
    result_dirs, timings = _fly_missing(todo, total, force, results_dir, progress, workers, log)
    simulated = list(timings)

    def run_notebook(i: int, nb: NotebookSpec) -> float:
        params = notebook_parameters(nb, result_dirs, figures, quick=quick)
        if overrides:
            declared = declared_parameters(notebook_path(nb.name))
            params.update({k: v for k, v in overrides.items() if k in declared})
        step = f"[{i}/{total}] notebook {nb.name} ({nb.title})"
        log(f"{step} ...")
        t0 = time.perf_counter()
        with heartbeat(PrefixedLines(log, f"{step}: "), "executing"):
            execute_notebook(notebook_path(nb.name), executed / f"{nb.name}.ipynb", params)
        seconds = time.perf_counter() - t0
        missing = [f for f in nb.outputs if not (figures / f).is_file()]
        if missing:
            raise RuntimeError(f"notebook {nb.name} did not write {missing} into {figures}")
        log(f"{step}: done in {duration(seconds)}")
        return seconds

    # The notebooks only read the cache and write their own files: as many at once as the
    # missions had processes (each kernel is a process of its own).
    outputs, ran = [], []
    with _threads(len(selected), workers) as pool:
        futures = [(nb, pool.submit(run_notebook, i, nb))
                   for i, nb in enumerate(selected, len(todo) + 1)]
        for nb, future in futures:
            timings[nb.name] = future.result()
            outputs += [figures / f for f in nb.outputs]
            ran.append(nb.name)
    _note_partial_missions(result_dirs, log)

    elapsed = time.perf_counter() - start
    if notebooks is None and max_steps is None and not quick:
        _stamp_figures(figures, preset, elapsed, timings)
    log(f"done in {duration(elapsed)}: {len(outputs)} file(s) in {paths.in_repo(figures)}, "
        f"executed notebooks in {paths.in_repo(executed)}")
    return ReproduceReport(result_dirs, simulated, ran, figures, outputs, timings, elapsed)


def _folders(preset: str | None, config: Config | None, quick: bool, figures_dir,
             executed_dir) -> tuple[Config | None, Path, Path]:
    """The configuration (``preset`` applied) and the folders of the figures and of the
    executed notebooks: ``figures/presets/<name>/`` for a preset other than ``paper``."""
    if preset is not None:
        from paper_repro import presets as _presets

        config = _presets.preset(preset, base=config)
        if preset != _presets.DEFAULT:
            sub = Path("presets") / preset
            figures_dir = figures_dir if figures_dir is not None else (
                paths.figures_dir(quick) / sub)
            executed_dir = executed_dir if executed_dir is not None else (
                paths.executed_dir(quick) / sub)
    figures = Path(figures_dir) if figures_dir is not None else paths.figures_dir(quick)
    executed = Path(executed_dir) if executed_dir is not None else paths.executed_dir(quick)
    return config, figures, executed


def _fly_missing(todo: list[RunSpec], total: int, force: bool, results_dir, progress,
                 workers: int | None, log) -> tuple[dict, dict]:
    """Each mission of ``todo`` from the cache, or flown (one process each, up to one per
    core): the result folder of each metric, and the wall time of each flight flown."""
    result_dirs, timings, flights = {}, {}, []
    for i, spec in enumerate(todo, 1):
        out = spec.directory(results_dir)
        step = f"[{i}/{total}] simulate {spec.name}"
        result_dirs[spec.config.distance.metric] = out
        if not force and usable_or_set_aside(out, log) and holds(out, spec, ("scan",)):
            log(f"{step}: cached in {paths.in_repo(out)}")
        else:
            log(f"{step}: flying up to {spec.max_steps} steps ...")
            flights.append((step, spec))
    # Not on a terminal (a log, CI): plain lines instead of a silent minute.
    lines = "lines" if progress is None and not sys.stderr.isatty() else progress
    with _pool(len(flights), workers) as pool:
        futures = [(step, spec, pool.submit(_fly, spec, results_dir, lines))
                   for step, spec in flights]
        for step, spec, future in futures:
            out, seconds = future.result()
            timings[spec.name] = seconds
            log(f"{step}: done in {duration(seconds)} -> {paths.in_repo(out)}")
    return result_dirs, timings


def _note_partial_missions(result_dirs: dict, log) -> None:
    """Say which mission stopped before its last target (its figures show the partial
    mission)."""
    for metric, directory in result_dirs.items():
        saved = read_arrays(directory, "reached", "t")
        reached, steps = saved["reached"], len(saved["t"])
        if np.any(reached < 0):
            log(f"note: the {metric} run stopped after {steps} steps with "
                f"{int(np.sum(reached >= 0))}/{len(reached)} targets reached; its figures "
                "show the partial mission")


def _stamp_figures(figures: Path, preset: str | None, elapsed: float, timings: dict) -> None:
    """Write what this machine measured (``timings.json``, expected to change), then, last,
    once every figure is in place, the stamp: this set is what this code makes."""
    from paper_repro.evidence.golden import stamp
    from paper_repro.sim.result import run_metadata

    text = json.dumps({"wall_time_s": elapsed, "stages_s": timings,
                       "meta": run_metadata()}, indent=1, default=str) + "\n"
    paths.atomic_text(figures / "timings.json", text)
    stamp(figures, "python -m paper_repro reproduce" + (
        f" --preset {preset}" if preset not in (None, "paper") else ""))


def _fly(spec: RunSpec, results_dir, progress) -> tuple[Path, float]:
    """One mission into the cache (a worker process's task): its folder and its wall time.

    ``progress`` : as for :func:`~paper_repro.sim.loop.simulate`, or ``"lines"``: plain
    progress lines, and while nothing else is printed (building the controller compiles C on
    a new machine) a line every :data:`HEARTBEAT_S` that says the worker is alive."""
    t0 = time.perf_counter()
    if progress != "lines":
        out, _ = ensure_result(spec, results_dir, force=True, progress=progress)
        return out, time.perf_counter() - t0
    lines = PrefixedLines(print_now, f"{spec.name}: ")
    with heartbeat(lines, "building the controller, or between progress lines"):
        out, _ = ensure_result(spec, results_dir, force=True, progress=lines)
    return out, time.perf_counter() - t0


def _threads(jobs: int, workers: int | None):
    """Threads for ``jobs`` notebooks: ``workers`` (default one per core), or with
    ``workers=0`` none: one after the other in this thread."""
    from concurrent.futures import ThreadPoolExecutor

    if workers == 0:
        return _pool(jobs, 0)
    return ThreadPoolExecutor(max(1, min(jobs, workers or os.cpu_count() or 1)))


def _pool(flights: int, workers: int | None):
    """Where the missions fly: ``workers`` processes (default: one per flight, at most one
    per core), forked so that a worker sees this process's modules as they are; or, with
    ``workers=0``, this process, one flight after the other."""
    import multiprocessing
    from concurrent.futures import Executor, Future, ProcessPoolExecutor

    class _Here(Executor):
        def submit(self, fn, /, *args, **kwargs):
            future = Future()
            future.set_result(fn(*args, **kwargs))
            return future

    if workers == 0:
        return _Here()
    n = workers or max(1, min(flights, os.cpu_count() or 1))
    return ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork"))


# --- helpers --------------------------------------------------------------------------------

def _select_notebooks(names) -> list[NotebookSpec]:
    if names is None:
        return list(NOTEBOOKS)
    by_name = {nb.name: nb for nb in NOTEBOOKS}
    unknown = sorted(set(names) - set(by_name))
    if unknown:
        raise ValueError(f"unknown notebook(s) {unknown}; available: {sorted(by_name)}")
    return [nb for nb in NOTEBOOKS if nb.name in set(names)]


def _has_parameters_cell(notebook: Path) -> bool:
    data = json.loads(Path(notebook).read_text())
    return any("parameters" in c.get("metadata", {}).get("tags", []) for c in data["cells"])

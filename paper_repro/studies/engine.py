"""Studies: many closed-loop runs described as data, flown on Dask, gathered into one table.

A :class:`Study` is a name and a tuple of :class:`~paper_repro.studies.runs.RunSpec` (config
overrides × scene seeds × metric), each a small picklable value. :func:`run_study` executes it:

* every run goes through the run cache (:mod:`paper_repro.studies.runs`), keyed by the hash of its
  spec and written atomically, so a re-run, or a study whose driver was killed, flies only
  what is missing;
* execution uses ``dask.distributed``: by default an embedded ``LocalCluster`` with one
  single-threaded worker process per core; ``scheduler="tcp://HOST:PORT"`` sends the same
  tasks to an existing cluster (``dask scheduler`` / ``dask worker``, or dask-jobqueue on
  SLURM) and nothing else changes. A worker builds a controller once per distinct
  configuration and reuses it (:func:`run_task`); the compiled C is cached on disk;
* a run that raises becomes a *failed* row carrying its error, a worker that dies has its
  tasks rescheduled by Dask, and the study always finishes;
* the rows (spec labels + :func:`~paper_repro.analysis.metrics.summary_row`) form one tidy pandas
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
import os
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from paper_repro import paths
from paper_repro.analysis import metrics
from paper_repro.config import Config, GuideParams, PlantParams, SensorParams, SimulationParams
from paper_repro.paths import atomic_write
from paper_repro.progress import duration
from paper_repro.studies.catalogue import Study
from paper_repro.studies.cluster import dask_client
from paper_repro.studies.runs import RunSpec, ensure_result

CSV_ROWS = 5_000
"""Tables up to this many rows are also written as CSV (readable in a diff)."""

TIMING_COLUMNS = (*metrics.TIMING_COLUMNS, "task_time_s", "worker", "simulated", "result_dir",
                  "controller_builds", "cache_damaged")
"""Columns that depend on the machine, the load or the cache, not on the flight
(``controller_builds``: controllers the run's worker process had built when it finished the
run, a worker builds one per configuration; ``cache_damaged``: the run's cache entry was
damaged, moved aside and the run flown again, which the study's log names)."""


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
        note = row.pop("damage_note", "")
        if note:
            log(f"study {study.name}: {note}")
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
    from paper_repro.analysis.metrics import summary_row
    from paper_repro.sim.result import SimulationResult

    t0 = time.perf_counter()
    row = {"name": spec.name, "key": spec.key[:12], **dict(spec.labels)}
    try:
        controller = _controller(controller_key(spec.config))
        damage = []
        directory, simulated = ensure_result(spec, runs_dir, force=force, controller=controller,
                                             warn=damage.append)
        row["cache_damaged"], row["damage_note"] = bool(damage), "; ".join(damage)
        row.update(summary_row(SimulationResult.load(directory)))
        row.update(status="ok", error="", simulated=simulated, result_dir=str(directory))
    except Exception as exc:  # a failed run is a row, never a lost study
        row.update(_failure(exc))
    row["task_time_s"] = time.perf_counter() - t0
    row["worker"] = f"{os.uname().nodename}:{os.getpid()}"
    row["controller_builds"] = _controller.cache_info().misses  # this worker's, so far
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



def saved_table(study: Study, directory):
    """The table :func:`run_study` saved in ``directory`` for exactly ``study``, or ``None``.

    It is returned (as :func:`load_table` reads it) only when ``study.json`` lists the same runs
    under the same keys (a key covers a run's whole configuration and the golden hash it is
    flown with) and every row is ``ok``. A command that saves a study per group can so carry
    its finished groups to another machine without their run cache, and fly only the rest."""
    directory = Path(directory)
    try:
        meta = json.loads((directory / "study.json").read_text())
        table = load_table(directory)
    except (OSError, ValueError):
        return None
    keys = [s.get("key") for s in meta.get("specs", [])]
    if keys != [s.key for s in study.specs] or len(table) != len(keys):
        return None
    if not (table["status"] == "ok").all():
        return None
    return table

# --- helpers --------------------------------------------------------------------------------

def _run_on_dask(specs, runs_dir: str, force: bool, done, workers, scheduler, client,
                 log) -> None:
    """Submit every spec as a task, hand each row to ``done`` as it arrives."""
    from distributed import as_completed

    with dask_client(workers, scheduler, client, log) as client:
        # Build each distinct controller once first, the configurations spread over the
        # workers: compiling one takes a minute, and every worker would otherwise compile the
        # same C at the same time. The libraries land in the disk cache the runs load from.
        keys = sorted({controller_key(s.config) for s in specs})
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


@functools.lru_cache(maxsize=8)
def _controller(key: str):
    """The controller of a configuration, built once per worker process.

    Building costs seconds (the NLP, the C linearisation loaded from the disk cache), flying a
    passage a few, so each worker keeps the last few it built; ``simulate`` resets a controller
    before every flight, so reuse cannot change a trajectory.
    """
    from paper_repro.solvers.factory import make_controller

    return make_controller(Config.from_dict(json.loads(key)))


def _warm(key: str) -> None:
    """Build (and so compile and cache) a controller; a failure shows up again in its runs."""
    try:
        _controller(key)
    except Exception:  # noqa: BLE001 - each run of this configuration records the error
        pass


def controller_key(config: Config) -> str:
    """What a controller depends on: the configuration without its mission (``simulation``:
    scene, run kind, limits), its sensor's imperfections and map, the guide that hands it its
    set-points and the plant it flies (it predicts with its nominal model whatever the plant).
    It keeps the one sensor setting the problem reads, ``sensor.range`` (the sensing window's
    r_s)."""
    neutral = dataclasses.replace(config, simulation=SimulationParams(),
                                  sensor=SensorParams(range=config.sensor.range),
                                  guide=GuideParams(), plant=PlantParams())
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
      ``name``) and ``timings.json`` (wall time, versions, commit, machine). A call that flew
      nothing (every run cached) keeps the ones already there when they are of the same runs:
      they record the flights, and a re-run that only loads the cache would record the
      cache's speed as the study's. Only where each run's result lives (``result_dir``) is
      brought up to date, as when the cache has been re-keyed.

    :func:`load_table` joins the two again."""
    from paper_repro.sim.result import run_metadata

    flight, timings = metrics.split_timings(table, TIMING_COLUMNS)
    timing = list(timings.columns)
    atomic_write(out / "table.parquet", lambda p: flight.to_parquet(p, index=False))
    if len(table) <= CSV_ROWS:
        atomic_write(out / "table.csv", lambda p: flight.to_csv(p, index=False))
    flew = "simulated" not in table or bool(table["simulated"].fillna(False).any())
    keep = (not flew and (out / "timings.csv").is_file() and (out / "timings.json").is_file()
            and _same_runs(out / "timings.csv", table))
    if not keep:
        atomic_write(out / "timings.csv", lambda p: table[["name", *timing]].to_csv(p, index=False))
    else:
        _current_locations(out / "timings.csv", table)
    text = study_record(study)
    atomic_write(out / "study.json", lambda p: p.write_text(text))
    if not keep:
        machine = json.dumps({"wall_time_s": wall, "meta": run_metadata()}, indent=1,
                             default=str) + "\n"
        atomic_write(out / "timings.json", lambda p: p.write_text(machine))


def study_record(study: Study) -> str:
    """The text of ``study.json``: the runs, their configurations and the golden hash. The base
    is the configuration as a run's key sees it (:meth:`Config.key_dict`); each run's changes
    give its whole configuration back (:func:`config_changes`)."""
    from paper_repro.evidence.golden import golden_hash, layer_of

    base = study.specs[0].config.key_dict()
    meta = {"name": study.name, "description": study.description,
            "runs": len(study.specs),
            "golden": golden_hash(layer_of(*(s.config for s in study.specs))),
            "base_config": base,
            "specs": [{"name": s.name, "key": s.key, "max_steps": s.max_steps,
                       "labels": dict(s.labels),
                       "config_changes": config_changes(base, s.config)}
                      for s in study.specs]}
    return json.dumps(meta, indent=1, default=str) + "\n"


def _same_runs(timings: Path, table) -> bool:
    """``timings`` (a study's ``timings.csv``) holds the runs of ``table``, in its order."""
    import pandas as pd

    return list(pd.read_csv(timings)["name"]) == list(table["name"])


def _current_locations(timings: Path, table) -> None:
    """Rewrite the ``result_dir`` column of ``timings`` (kept, of the same runs) with ``table``'s
    where they differ; the timings themselves are left as they were measured."""
    import pandas as pd

    kept = pd.read_csv(timings)
    if "result_dir" not in kept or "result_dir" not in table:
        return
    now = table["result_dir"].astype(str).to_numpy()
    if list(kept["result_dir"].astype(str)) != list(now):
        kept["result_dir"] = now
        atomic_write(timings, lambda p: kept.to_csv(p, index=False))


def config_changes(base: dict, config: Config) -> dict:
    """``{"part.field": value}``: what ``config`` changes in ``base`` (a ``Config.key_dict()``),
    so that :func:`~paper_repro.evidence.golden.study_run_config` gives ``config`` back. First
    the settings that differ from the base's; then those that a part the changes bring in
    would read back otherwise (a setting of ``config_history.ADDED`` reads back at its
    neutral value, not at its default). Settings are named where the base names them
    (:func:`~paper_repro.config_history.as_keyed`)."""
    from paper_repro.config_history import as_keyed
    from paper_repro.evidence.golden import study_run_config

    full = as_keyed(config.to_dict())
    start = as_keyed(study_run_config(base, {}).to_dict())
    changes = {f"{part}.{name}": value for part, fields in full.items()
               for name, value in fields.items() if start[part][name] != value}
    back = as_keyed(study_run_config(base, changes).to_dict())
    changes.update({f"{part}.{name}": value for part, fields in full.items()
                    for name, value in fields.items() if back[part][name] != value})
    return changes


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


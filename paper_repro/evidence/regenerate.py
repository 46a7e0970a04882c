"""Make the evidence sets again after a change that moves a flight, one job per core.

``python -m paper_repro regenerate`` plans the stale sets (those whose stamp names another
golden hash, :func:`~paper_repro.evidence.golden.stale_evidence`) and every set that reads
one of them (:attr:`~paper_repro.evidence.sets.EvidenceSet.after`), then runs their commands
(:data:`~paper_repro.evidence.sets.SETS`) from the repository's root:

1. the sets that fly, as many at once as there are job slots (``jobs``, one core each; a
   command of two cores takes two), each as soon as the sets it reads are made;
2. then the speed tables (``timed``), one at a time with nothing else running, so that their
   times are the machine's and not a neighbour's;
3. then ``python -m paper_repro readme``, which formats the README's and the book's tables
   from the new ones.

Each command's output goes to ``results/regenerate/<set>.log``. A set whose command does not
record its own wall time gets the one measured here in its ``timings.json``
(:func:`~paper_repro.evidence.sets.record_wall_time`), for the next dry run to show. A command
that fails is recorded, the sets that read it are skipped, and the others go on: nothing
already made is lost, and a second call plans only what is still stale. Flights come from the
run cache where they were flown before, so a call stopped half-way loses at most the runs in
flight.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from paper_repro import paths
from paper_repro.evidence.golden import stale_evidence
from paper_repro.evidence.sets import SETS, EvidenceSet, record_wall_time

README = "python -m paper_repro readme"
"""Run last, when every planned set was made."""


def plan(names=None, sets: tuple[EvidenceSet, ...] = SETS) -> list[EvidenceSet]:
    """The sets to make, in the order of ``sets``: ``names`` (folders under ``figures/``, or
    ``None`` for the stale ones) and, transitively, every set that reads one of them. Raises
    ``ValueError`` naming an unknown set."""
    by_folder = {s.folder: s for s in sets}
    if names is None:
        names = ["" if n == "figures" else n for n in stale_evidence()]
    unknown = [n for n in names if n not in by_folder]
    if unknown:
        raise ValueError(f"unknown evidence set(s) {unknown}; the sets are folders under "
                         f"figures/: {', '.join(repr(s.folder) for s in sets)}")
    wanted, grew = set(names), True
    while grew:
        more = {s.folder for s in sets if set(s.after) & wanted} - wanted
        wanted |= more
        grew = bool(more)
    return [s for s in sets if s.folder in wanted]


def command_of(item: EvidenceSet) -> list[str]:
    """The command's arguments, ``python`` being this interpreter, with its one-core
    options."""
    args = shlex.split(item.command) + shlex.split(item.one_core)
    return [sys.executable if a == "python" else a for a in args]


@dataclass
class Job:
    """One command of the regeneration and what came of it."""

    item: EvidenceSet
    name: str = ""  # what the messages call it (default: the set's folder)
    status: str = "waiting"  # waiting, running, made, failed (exit status), skipped
    log: Path | None = None
    wall_s: float = 0.0
    note: str = ""
    _process: subprocess.Popen | None = field(default=None, repr=False)
    _started: float = 0.0

    @property
    def label(self) -> str:
        return self.name or self.item.label


def run(items: list[EvidenceSet], jobs: int = 2, root: Path | None = None,
        log_dir: Path | None = None, readme: bool = True, poll_s: float = 1.0,
        echo=print) -> list[Job]:
    """Run the commands of ``items`` (:func:`plan`) as described in the module's docstring,
    ``jobs`` at a time; return one :class:`Job` per item (and one for ``readme``, when every
    item was made). ``root``: the repository's root; ``log_dir``: where the logs go."""
    if not (isinstance(jobs, int) and jobs >= 1):
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    root = Path(root) if root is not None else paths.repo_root()
    log_dir = Path(log_dir) if log_dir is not None else paths.results_dir() / "regenerate"
    log_dir.mkdir(parents=True, exist_ok=True)
    todo = [Job(item) for item in items]
    planned = {j.item.folder for j in todo}
    done: set[str] = set()  # made, or not planned (already current)
    while any(j.status in ("waiting", "running") for j in todo):
        for job in todo:
            if job.status == "running" and job._process.poll() is not None:
                _finish(job, echo)
                if job.status == "made":
                    done.add(job.item.folder)
                    record_wall_time(root / "figures" / job.item.folder, job.wall_s)
        for job in todo:  # a set whose input failed or was skipped is skipped
            if job.status == "waiting":
                lost = [a for a in job.item.after if a in planned and a not in done
                        and _status(todo, a) in ("failed", "skipped")]
                if lost:
                    job.status, job.note = "skipped", f"needs {', '.join(lost)}"
                    echo(f"skipped {job.label}: {job.note}")
        busy = sum(min(j.item.cores, jobs) for j in todo if j.status == "running")
        timed_running = any(j.status == "running" and j.item.timed for j in todo)
        untimed_left = any(j.status in ("waiting", "running") and not j.item.timed for j in todo)
        for job in todo:
            if job.status != "waiting" or timed_running:
                continue
            if any(a in planned and a not in done for a in job.item.after):
                continue
            need = min(job.item.cores, jobs)
            if job.item.timed:
                if untimed_left or busy:
                    continue  # alone, after every flight
                need = jobs
            if busy + need > jobs:
                continue
            _start(job, root, log_dir, echo)
            busy += need
            if job.item.timed:
                timed_running = True
        if any(j.status == "running" for j in todo):
            time.sleep(poll_s)
    if readme and todo and all(j.status == "made" for j in todo):
        last = Job(EvidenceSet("", README), name="the README's and the book's tables")
        _start(last, root, log_dir, echo, log_name="readme")
        if last.status == "running":
            last._process.wait()
            _finish(last, echo)
        todo.append(last)
    return todo


def _status(todo: list[Job], folder: str) -> str:
    return next(j.status for j in todo if j.item.folder == folder)


def _start(job: Job, root: Path, log_dir: Path, echo, log_name: str | None = None) -> None:
    item = job.item
    for name in item.fresh:  # files the command would resume from
        (root / "figures" / item.folder / name).unlink(missing_ok=True)
    job.log = log_dir / f"{log_name or item.folder.replace('/', '__') or 'figures'}.log"
    # one thread per job; the output unbuffered, so that the log shows a long command's progress
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "PYTHONUNBUFFERED": "1"}
    job._started = time.monotonic()
    try:
        with open(job.log, "w") as out:
            job._process = subprocess.Popen(command_of(item), cwd=root, stdout=out,
                                            stderr=subprocess.STDOUT, env=env)
    except OSError as exc:  # a command that cannot start is a failure like any other
        job.status, job.note = "failed", f"could not start: {exc}"
        echo(f"failed {job.label}: {job.note}")
        return
    job.status = "running"
    echo(f"started {job.label}: {item.command} {item.one_core}".rstrip())


def _finish(job: Job, echo) -> None:
    job.wall_s = time.monotonic() - job._started
    code = job._process.returncode
    job.status = "made" if code == 0 else "failed"
    job.note = "" if code == 0 else f"exit status {code}, see {job.log}"
    echo(f"{job.status} {job.label} in {job.wall_s / 60:.1f} min"
         + (f": {job.note}" if job.note else ""))

"""The regeneration (``python -m paper_repro regenerate``): which sets it plans, and the order
and company in which it runs their commands (on stand-in commands that only record when they
ran)."""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys

import pandas as pd
import pytest

from paper_repro import paths
from paper_repro.cli.parser import main as cli
from paper_repro.evidence import regenerate as R
from paper_repro.evidence.golden import process_wall_time, stamp
from paper_repro.evidence.sets import (
    EVIDENCE_SETS,
    RECORDED_BY,
    SETS,
    EvidenceSet,
    last_wall_time_s,
    record_wall_time,
    resumed,
)


def test_every_set_reads_only_listed_sets_made_before_it():
    """The ``after`` lists name listed sets and have no cycle: a set's inputs come before it in
    a topological order, and a speed table never waits for itself."""
    folders = set(EVIDENCE_SETS)
    assert len(folders) == len(SETS)
    order, left = [], {s.folder: set(s.after) for s in SETS}
    while left:
        ready = [f for f, after in left.items() if after <= set(order)]
        assert ready, f"a cycle among {sorted(left)}"
        order += ready
        for f in ready:
            del left[f]
    for s in SETS:
        assert set(s.after) <= folders, s.folder


def test_every_command_names_a_script_that_exists():
    for s in SETS:
        args = shlex.split(s.command)
        assert args[0] == "python", s.command
        if args[1] != "-m":
            assert (paths.repo_root() / args[1]).is_file(), s.command


def _bare(command: str) -> str:
    """A command without the options that choose how many cores it uses."""
    command = re.sub(r"\s--(workers|jobs) \d+", "", command)
    return command.replace(" --no-progress", "").strip()


def test_each_committed_set_was_made_by_its_listed_command():
    """The stamp of every committed set names the command the list gives for it (up to the
    options that choose the cores), so the contributor page's commands are the ones that made
    the evidence."""
    for s in SETS:
        stamp = paths.figures_dir() / s.folder / "evidence.json"
        if stamp.is_file():
            assert _bare(json.loads(stamp.read_text())["made_by"]) == _bare(s.command), s.folder


def test_the_plan_adds_every_set_that_reads_a_planned_one():
    planned = [s.folder for s in R.plan(["studies/moving_heldout"])]
    assert {"studies/moving_heldout", "studies/moving_speeds", "studies/avoidability",
            "studies/qp_failures"} == set(planned)
    chained = {s.folder for s in R.plan(["studies/monte_carlo"])}
    # monte_carlo -> moving_levers, guidance, tuning; guidance -> guide_filter
    assert {"studies/moving_levers", "studies/guidance", "guide_filter",
            "tuning"} <= chained
    assert "studies/moving_speeds" not in chained


def test_an_unknown_set_is_named_before_anything_runs():
    with pytest.raises(ValueError, match="studies/nope"):
        R.plan(["studies/nope"])
    assert cli(["regenerate", "studies/nope", "--dry-run"]) == 2


def test_the_dry_run_says_how_long_each_set_took_last_time(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(paths.ROOT_ENV, str(tmp_path))
    folder = tmp_path / "figures" / "studies" / "timeline"
    folder.mkdir(parents=True)
    (folder / "timings.json").write_text(json.dumps({"wall_time_s": 150.0}))
    assert cli(["regenerate", "studies/timeline", "fidelity", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "figures/studies/timeline (at once; last run 2.5 min)" in out
    assert "figures/fidelity (at once; last run not recorded)" in out
    assert "add up to 0.0 h" in out  # 150 s
    assert not (tmp_path / "results").exists()  # nothing ran


def _recorder(tmp_path, name: str, seconds: float = 0.3, code: int = 0) -> str:
    """A command that writes its start and end times to ``tmp_path/name.json``."""
    out = tmp_path / f"{name}.json"
    return ("python -c " + shlex.quote(
        f"import json, os, sys, time; t = time.time(); time.sleep({seconds}); "
        f"env = [os.environ.get(k) for k in ('OPENBLAS_NUM_THREADS', 'PYTHONUNBUFFERED')]; "
        f"open({str(out)!r}, 'w').write(json.dumps([t, time.time(), env])); sys.exit({code})"))


def _times(tmp_path, name):
    return json.loads((tmp_path / f"{name}.json").read_text())


def test_inputs_first_speed_tables_last_and_alone(tmp_path):
    sets = (EvidenceSet("a", _recorder(tmp_path, "a", 1.0)),
            EvidenceSet("b", _recorder(tmp_path, "b", 1.0)),
            EvidenceSet("c", _recorder(tmp_path, "c", 0.1), after=("a",)),
            EvidenceSet("t1", _recorder(tmp_path, "t1", 0.1), timed=True),
            EvidenceSet("t2", _recorder(tmp_path, "t2", 0.1), after=("t1",), timed=True))
    jobs = R.run(list(sets), jobs=2, root=tmp_path, log_dir=tmp_path / "logs", readme=False,
                 poll_s=0.02, echo=lambda *_: None)
    assert [j.status for j in jobs] == ["made"] * 5
    a, b, c, t1, t2 = (_times(tmp_path, n) for n in ("a", "b", "c", "t1", "t2"))
    assert b[0] < a[1] and a[0] < b[1]  # two jobs at once
    assert c[0] >= a[1]  # after what it reads
    untimed_end = max(a[1], b[1], c[1])
    assert t1[0] >= untimed_end and t2[0] >= t1[1]  # last, one at a time
    assert a[2] == ["1", "1"]  # one thread each, the output unbuffered (a live log)


def test_a_set_that_records_no_wall_time_gets_the_measured_one(tmp_path):
    """The regeneration writes the wall time it measured into the ``timings.json`` of a set
    whose command writes none, replaces it on the next call, and leaves a command's own
    ``timings.json`` as the command wrote it."""
    own = tmp_path / "figures" / "own"
    own.mkdir(parents=True)
    writes_own = ("python -c " + shlex.quote(
        f"import json; open({str(own / 'timings.json')!r}, 'w').write("
        f"json.dumps({{'wall_time_s': 7.0}}))"))
    sets = [EvidenceSet("own", writes_own), EvidenceSet("bare", _recorder(tmp_path, "b", 0.2))]
    for _ in range(2):
        jobs = R.run(sets, jobs=2, root=tmp_path, log_dir=tmp_path / "logs", readme=False,
                     poll_s=0.02, echo=lambda *_: None)
        bare = json.loads((tmp_path / "figures" / "bare" / "timings.json").read_text())
        assert bare["recorded_by"] == RECORDED_BY and "machine" in bare["meta"]
        assert bare["wall_time_s"] == jobs[1].wall_s >= 0.2
        assert last_wall_time_s(tmp_path / "figures" / "bare") == jobs[1].wall_s
        assert json.loads((own / "timings.json").read_text()) == {"wall_time_s": 7.0}
    assert not record_wall_time(own, 1.0)  # the command's own record stays
    with pytest.raises(ValueError, match="seconds"):
        record_wall_time(own, -1.0)


def test_a_set_made_by_hand_records_its_own_wall_time(tmp_path):
    """A set made by hand shows its own run, not the last regeneration's: its stamp records
    the time its process has run, and leaves a command's own ``timings.json`` alone."""
    bare, own = tmp_path / "bare", tmp_path / "own"
    bare.mkdir()
    own.mkdir()
    (own / "timings.json").write_text(json.dumps({"wall_time_s": 7.0}))
    for folder in (bare, own):
        stamp(folder, "python benchmarks/a_benchmark.py --save")
    record = json.loads((bare / "timings.json").read_text())
    assert record["recorded_by"] == RECORDED_BY and "machine" in record["meta"]
    assert 0 < record["wall_time_s"] <= process_wall_time()  # the process's time so far
    assert json.loads((own / "timings.json").read_text()) == {"wall_time_s": 7.0}
    # The process's wall time counts from its start: a process that slept 1 s has run >= 1 s.
    slept = subprocess.run(
        [sys.executable, "-c", "import time; time.sleep(1.0); from paper_repro.evidence."
         "golden import process_wall_time as p; print(p())"],
        capture_output=True, text=True, check=True)
    assert 1.0 <= float(slept.stdout) < 120


def test_a_failure_skips_what_reads_it_and_nothing_else(tmp_path):
    (tmp_path / "figures" / "tuning").mkdir(parents=True)
    storage = tmp_path / "figures" / "tuning" / "tuning.db"
    storage.write_text("old trials")
    sets = (EvidenceSet("bad", _recorder(tmp_path, "bad", 0.05, code=3)),
            EvidenceSet("reader", _recorder(tmp_path, "reader", 0.05), after=("bad",)),
            EvidenceSet("reader2", _recorder(tmp_path, "reader2", 0.05), after=("reader",)),
            EvidenceSet("tuning", _recorder(tmp_path, "tuning", 0.05), fresh=("tuning.db",)),
            EvidenceSet("absent", "no-such-program-of-this-test"))
    jobs = R.run(list(sets), jobs=1, root=tmp_path, log_dir=tmp_path / "logs", readme=True,
                 poll_s=0.02, echo=lambda *_: None)
    status = {j.item.folder: j.status for j in jobs}
    assert status == {"bad": "failed", "reader": "skipped", "reader2": "skipped",
                      "tuning": "made", "absent": "failed"}  # and no README step after it
    assert "could not start" in jobs[-1].note
    assert "exit status 3" in jobs[0].note and jobs[0].log.is_file()
    assert not storage.exists()  # deleted before the command, which would resume from it
    assert not (tmp_path / "reader.json").exists()


def test_jobs_must_be_positive():
    with pytest.raises(ValueError, match="jobs"):
        R.run([], jobs=0)


def test_a_resumed_study_counts_the_flights_of_its_cached_runs(tmp_path):
    """A study's last call that found runs cached says how many it flew, and how much longer
    an empty cache would take: the cached runs' own flight times shared among the cores."""
    study = tmp_path / "study"
    study.mkdir()
    (study / "timings.json").write_text(json.dumps({"wall_time_s": 60.0,
                                                    "meta": {"cpu_count": 2}}))
    pd.DataFrame({"name": list("abcd"), "simulated": [True, False, True, False],
                  "wall_time_s": [10.0, 30.0, 20.0, 50.0]}).to_csv(study / "timings.csv")
    assert resumed(study) == (2, 4, 40.0)  # (30 + 50) s over 2 cores
    pd.DataFrame({"name": list("ab"), "simulated": [True, True],
                  "wall_time_s": [1.0, 2.0]}).to_csv(study / "timings.csv")
    assert resumed(study) is None  # every run flown: the wall time says it all
    pd.DataFrame({"run": ["x"], "wall": [3.0]}).to_csv(study / "timings.csv")
    assert resumed(study) is None  # not a study's timings
    assert resumed(tmp_path) is None

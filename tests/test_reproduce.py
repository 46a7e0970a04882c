"""``python -m paper_repro reproduce``: run specs, the run cache, the whole pipeline.

The closed loop is replaced by a hand-made result here (``runs.fly`` is the single place that
flies a run); test_notebooks.py runs the notebooks on real closed-loop runs.
"""

import dataclasses
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from paper_repro import Config, DistanceParams, NMPCParams, paths
from paper_repro.cli import reproduce as reproduce_command
from paper_repro.cli.parser import main
from paper_repro.progress import PrefixedLines, heartbeat
from paper_repro.sim.perception import ScanLog
from paper_repro.sim.result import SimulationResult
from paper_repro.studies import reproduce as R
from paper_repro.studies import runs


def _fake_result(spec, controller=None, progress=None, steps=None):
    """A straight climb from the start at 1 m/s with hover thrusts plus a small wobble, of
    ``steps`` steps (default: the spec's, at most 200)."""
    steps = min(spec.max_steps, 200) if steps is None else steps
    k = np.arange(steps + 1)
    x = np.zeros((steps + 1, 12))
    x[:, :3] = np.array([22.0, -22.0, 0.0]) + np.outer(k * 0.01, [0.0, 0.0, 1.0])
    u = 5.49 + 0.01 * np.sin(k[:-1] * 0.1)[:, None] * np.ones(4)
    scene = spec.scene()
    scans = ScanLog(len(scene.clouds), 3)  # nothing in view, as the clearance says
    for _ in range(steps):
        scans.add([np.empty((0, 3))] * len(scene.clouds))
    return SimulationResult(
        t=k[:-1] * 0.01, x=x, u=u, x_a=x[:-1], u_a=np.full((steps, 4), 5.49),
        solve_time=np.full(steps, 0.05), iterations=np.full(steps, 8),
        success=np.ones(steps, bool), status=np.full(steps, "Solve_Succeeded"),
        clearance=np.full(steps, 11.0), target_index=np.zeros(steps, int),
        visible_points=np.zeros(steps, int), dropped_points=np.zeros(steps, int),
        targets=np.array([[-12.0, 18, 11], [-21, 18, 0]]), reached=np.array([-1, -1]),
        outcome="step_limit", scene=scene, config=spec.config,
        meta={"wall_time_s": 1.0}, **scans.arrays())


@pytest.fixture
def fake_simulation(monkeypatch):
    calls = []

    def fake(spec, controller=None, progress=None):
        calls.append(spec.name)
        return _fake_result(spec)

    monkeypatch.setattr(runs, "fly", fake)
    return calls


def test_run_key_is_stable_and_changes_with_any_parameter():
    spec = R.run_specs(max_steps=1000)[0]
    h = spec.key
    again = runs.RunSpec(spec.name, Config.from_dict(spec.config.to_dict()), 1000)
    assert len(h) == 64 and h == again.key
    assert h != runs.RunSpec(spec.name, spec.config, 1001).key
    other = dataclasses.replace(spec.config, nmpc=NMPCParams(horizon=20))
    assert h != runs.RunSpec(spec.name, other, 1000).key
    eta = dataclasses.replace(spec.config, distance=DistanceParams(eta=0.31))
    assert h != runs.RunSpec(spec.name, eta, 1000).key


def test_run_key_follows_the_scene_geometry(monkeypatch):
    """The key holds the scene's fingerprint: a generator that now builds other clouds (or
    another seed) gives a new folder instead of an old flight among new clouds."""
    spec = R.run_specs(max_steps=1000)[0]
    reseeded = dataclasses.replace(spec.config, simulation=dataclasses.replace(
        spec.config.simulation, seed=8))
    assert runs.RunSpec(spec.name, reseeded, 1000).key != spec.key
    h = spec.key
    monkeypatch.setattr(runs, "run_key", lambda c, m, fp: fp)
    fresh = runs.RunSpec(spec.name, spec.config, spec.max_steps)  # keys are computed once
    assert fresh.key == spec.scene().fingerprint() != h


def test_run_specs_fly_the_paper_mission_for_both_metrics():
    full = R.run_specs()
    assert [s.name for s in full] == ["paper-smooth", "paper-euclidean"]
    assert [s.config.distance.metric for s in full] == list(R.METRICS)
    assert all(s.config.simulation.scenario == "paper" for s in full)
    # Not quick: enough steps to complete the mission (the config's limit).
    assert all(s.max_steps == Config().simulation.max_steps for s in full)
    assert all(s.max_steps == R.QUICK_STEPS for s in R.run_specs(quick=True))
    assert all(s.max_steps == 77 for s in R.run_specs(quick=True, max_steps=77))
    small = Config(nmpc=NMPCParams(region_slots=1))
    assert all(s.config.nmpc.region_slots == 1 for s in R.run_specs(config=small))
    assert len({s.key for s in full}) == 2
    with pytest.raises(ValueError, match="max_steps"):
        R.run_specs(max_steps=0)


def test_cache_folder_is_named_by_run_and_hash(tmp_path):
    spec = R.run_specs(quick=True)[0]
    d = spec.directory(tmp_path)
    assert d.parent == tmp_path and d.name == f"paper-smooth-{spec.key[:runs.HASH_LENGTH]}"
    assert spec.directory().parent == paths.results_dir()
    assert R.default_result_dir("smooth") == R.run_specs()[0].directory()
    with pytest.raises(ValueError, match="metric"):
        R.default_result_dir("manhattan")


def test_ensure_result_simulates_once_then_reuses_the_cache(tmp_path, fake_simulation):
    spec = R.run_specs(max_steps=50)[0]
    d, simulated = runs.ensure_result(spec, tmp_path)
    assert simulated and runs.is_cached(d) and fake_simulation == ["paper-smooth"]
    assert SimulationResult.load(d).config == spec.config
    assert runs.ensure_result(spec, tmp_path) == (d, False)
    assert fake_simulation == ["paper-smooth"]
    assert runs.ensure_result(spec, tmp_path, force=True) == (d, True)
    assert len(fake_simulation) == 2
    assert [p.name for p in tmp_path.iterdir()] == [d.name]  # no .partial left behind


def test_a_failed_simulation_leaves_nothing_that_looks_cached(tmp_path, monkeypatch):
    def crash(spec, controller=None, progress=None):
        raise RuntimeError("solver exploded")

    monkeypatch.setattr(runs, "fly", crash)
    spec = R.run_specs(max_steps=50)[1]
    with pytest.raises(RuntimeError):
        runs.ensure_result(spec, tmp_path)
    assert not runs.is_cached(spec.directory(tmp_path))


def test_reproduce_simulates_missing_runs_then_only_redraws_byte_identical_figures(
        tmp_path, fake_simulation):
    kw = dict(quick=True, notebooks=["02_projections", "06_summary"],
              results_dir=tmp_path / "results", figures_dir=tmp_path / "figures",
              executed_dir=tmp_path / "executed", progress=False, workers=0)
    first_log, second_log = [], []
    first = R.reproduce(log=first_log.append, **kw)
    snapshot = {p.name: p.read_bytes() for p in first.outputs}
    second = R.reproduce(log=second_log.append, **kw)

    assert fake_simulation == ["paper-smooth", "paper-euclidean"]  # the second run reused
    assert first.simulated == ["paper-smooth", "paper-euclidean"] and second.simulated == []
    assert any("simulate paper-smooth: done in" in line for line in first_log)
    assert any("simulate paper-smooth: cached" in line for line in second_log)
    assert any("[4/4] notebook 06_summary" in line and "done in" in line for line in second_log)
    assert any("note: the smooth run stopped after 200 steps" in line for line in second_log)
    assert second_log[-1].startswith("done in")

    names = {p.name for p in second.outputs}
    assert {"fig02_projection_xz.pdf", "fig03_projection_xy.png", "summary.csv"} <= names
    for p in second.outputs:  # byte-stable: PDFs carry no creation date
        assert p.read_bytes() == snapshot[p.name], p.name
    assert (tmp_path / "executed" / "06_summary.ipynb").is_file()
    table = pd.read_csv(second.summary_csv, index_col="run")
    assert list(table.index) == ["paper/smooth", "paper/euclidean"]
    assert set(second.timings) == {"02_projections", "06_summary"}


def test_reproduce_rejects_unknown_notebooks():
    with pytest.raises(ValueError, match="nope"):
        R.reproduce(notebooks=["nope"], log=lambda line: None)


def test_quick_runs_write_into_a_git_ignored_folder():
    assert paths.figures_dir(quick=True).parent == paths.figures_dir()
    root = paths.repo_root()
    folders = (paths.results_dir(), paths.executed_dir(), paths.figures_dir(quick=True))
    if shutil.which("git") is None or not (root / ".git").exists():  # a copy without git
        rules = {line.strip().strip("/") for line in (root / ".gitignore").read_text().split()}
        for folder in folders:
            assert paths.in_repo(folder).strip("/") in rules, paths.in_repo(folder)
        assert "figures" not in rules
        return
    for folder in folders:
        probe = folder / "probe.npz"
        ignored = subprocess.run(["git", "check-ignore", "-q", str(probe)],
                                 cwd=root, check=False)
        assert ignored.returncode == 0, paths.in_repo(folder)
    tracked = subprocess.run(["git", "check-ignore", "-q",
                              str(paths.figures_dir() / "probe.csv")],
                             cwd=root, check=False)
    assert tracked.returncode == 1, "figures/ itself must stay tracked"


def test_paths_follow_the_root_override(monkeypatch, tmp_path):
    monkeypatch.setenv(paths.ROOT_ENV, str(tmp_path))
    assert paths.repo_root() == tmp_path.resolve()
    assert paths.results_dir() == tmp_path.resolve() / "results"
    monkeypatch.delenv(paths.ROOT_ENV)
    assert (paths.repo_root() / "pyproject.toml").is_file()
    assert Path(paths.notebooks_dir()).is_dir()


def test_cli_reproduce_quick_runs_the_tutorial(tmp_path, monkeypatch, capsys):
    # The tutorial reads no simulation: the command goes straight to the notebook.
    monkeypatch.setattr(paths, "executed_dir", lambda quick=False: tmp_path / "executed")
    figures = tmp_path / "figures"
    code = main(["reproduce", "--quick", "--notebooks", "07_distance_tutorial",
                 "--figures-dir", str(figures)])
    out = capsys.readouterr().out
    assert code == 0
    assert "[1/1] notebook 07_distance_tutorial" in out and "done in" in out
    assert (figures / "tutorial_eta_sigma.pdf").is_file()
    assert (tmp_path / "executed" / "07_distance_tutorial.ipynb").is_file()


def test_cli_solver_option_reaches_the_runs(tmp_path, monkeypatch, fake_simulation):
    seen = []
    original = R.reproduce

    def spy(**kwargs):
        seen.append(kwargs["config"].solver.nlp_solver)
        return original(**{**kwargs, "notebooks": ["06_summary"]})

    monkeypatch.setattr(reproduce_command, "reproduce", spy)
    monkeypatch.setattr(paths, "results_dir", lambda: tmp_path / "results")
    monkeypatch.setattr(paths, "executed_dir", lambda quick=False: tmp_path / "executed")
    assert main(["reproduce", "--quick", "--solver", "reference", "--no-progress",
                 "--figures-dir", str(tmp_path / "figures")]) == 0
    assert seen == ["reference"]
    table = pd.read_csv(tmp_path / "figures" / "summary.csv", index_col="run")
    assert list(table["solver"]) == ["reference", "reference"]


def test_cli_rejects_unknown_notebook_names(capsys):
    assert main(["reproduce", "--notebooks", "99_nothing"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "99_nothing" in err and "\n" not in err


def test_a_silent_stage_still_prints_a_line_every_heartbeat(monkeypatch):
    """No stage of reproduce is silent for longer than HEARTBEAT_S (here 0.2 s)."""
    import time

    stamps = []
    lines = PrefixedLines(lambda line: stamps.append((time.perf_counter(), line)), "stage: ")
    with heartbeat(lines, "testing", interval=0.2):
        time.sleep(0.5)
        lines("a progress line")  # resets the clock
        time.sleep(0.5)
    beats = [line for _, line in stamps if "elapsed (testing)" in line]
    assert len(beats) >= 2 and all(line.startswith("stage: ") for _, line in stamps)
    # The progress line reset the clock: no beat within the heartbeat after it.
    after = [t for t, line in stamps if line == "stage: a progress line"][0]
    assert all(t - after >= 0.2 for t, line in stamps if t > after)


def test_reproduce_flies_again_a_damaged_cache_entry(tmp_path, fake_simulation):
    """A truncated result in the cache is named in one line, moved aside and flown again;
    the run goes on."""
    kw = dict(quick=True, notebooks=["06_summary"], results_dir=tmp_path / "results",
              figures_dir=tmp_path / "figures", executed_dir=tmp_path / "executed",
              progress=False, workers=0)
    R.reproduce(log=lambda line: None, **kw)
    spec = R.run_specs(quick=True)[0]
    npz = spec.directory(tmp_path / "results") / "result.npz"
    npz.write_bytes(npz.read_bytes()[:100])
    log = []
    again = R.reproduce(log=log.append, **kw)
    damaged = [line for line in log if "damaged cache entry" in line]
    assert len(damaged) == 1 and "result.npz" in damaged[0]
    assert again.simulated == [spec.name]
    assert (npz.parent.parent / f"{npz.parent.name}.damaged").is_dir()


def _figures_of(*names):
    return [f for nb in R.NOTEBOOKS if nb.name in names for f in nb.outputs]


@pytest.mark.parametrize("steps", [300])
def test_a_mission_cut_at_any_step_limit_draws_its_figures(tmp_path, monkeypatch, steps):
    """A run stopped by a step limit: at 300 steps the climb ends exactly r_s = 3 m above its
    start, where the last LiDAR sphere would be drawn at the state after the last step."""
    monkeypatch.setattr(runs, "fly", lambda spec, controller=None, progress=None:
                        _fake_result(spec, steps=spec.max_steps))
    kw = dict(quick=True, max_steps=steps, notebooks=["01_flight_3d"],
              results_dir=tmp_path / "results", figures_dir=tmp_path / "figures",
              executed_dir=tmp_path / "executed", progress=False, workers=0, log=lambda _: None)
    R.reproduce(**kw)
    assert all((tmp_path / "figures" / f).is_file() for f in _figures_of("01_flight_3d"))


@pytest.mark.parametrize("stage", ["flights", "notebooks"])
def test_a_reproduce_interrupted_then_run_again_writes_every_figure(tmp_path, monkeypatch,
                                                                   stage):
    """Ctrl-C during the second flight, or during the second notebook: the next run keeps
    what was finished, makes the rest, and writes every figure of its notebooks."""
    names = ["01_flight_3d", "05_euclidean"]
    kw = dict(quick=True, notebooks=names, results_dir=tmp_path / "results",
              figures_dir=tmp_path / "figures", executed_dir=tmp_path / "executed",
              progress=False, workers=0, log=lambda _: None)
    flown, executed = [], []
    execute = R.execute_notebook

    def fly(spec, controller=None, progress=None):
        if stage == "flights" and flown:
            raise KeyboardInterrupt
        flown.append(spec.name)
        return _fake_result(spec)

    def interrupted(notebook, output, parameters=None):
        if executed:
            raise KeyboardInterrupt
        executed.append(Path(notebook).stem)
        return execute(notebook, output, parameters)

    monkeypatch.setattr(runs, "fly", fly)
    if stage == "notebooks":
        monkeypatch.setattr(R, "execute_notebook", interrupted)
    with pytest.raises(KeyboardInterrupt):
        R.reproduce(**kw)
    monkeypatch.setattr(runs, "fly", _fake_result)
    monkeypatch.setattr(R, "execute_notebook", execute)
    second = R.reproduce(**kw)
    assert second.simulated == ([] if stage == "notebooks" else ["paper-euclidean"])
    assert all((tmp_path / "figures" / f).is_file() for f in _figures_of(*names))

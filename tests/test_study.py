"""The study engine: specs as data, the shared run cache, Dask execution, failures as rows.

The runs are tiny passages (a few dozen steps through random scenes, one LiDAR slot of 64
points) so that the properties, not the flights, are what is tested: the same rows with one
worker or two, bit-identical trajectories, a killed worker or driver losing nothing.
"""

import dataclasses
import os
import signal
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from paper_repro import Config, NMPCParams
from paper_repro import studies as S
from paper_repro.config import PREDICTIONS
from paper_repro.sim.loop import simulate
from paper_repro.sim.result import SimulationResult
from paper_repro.solvers.factory import make_controller
from paper_repro.studies import runs
from paper_repro.studies.catalogue import Study, make_study, passage_config, passage_spec
from paper_repro.world import random_scenes

TINY = Config(nmpc=NMPCParams(region_slots=1, points_per_region=64))
STEPS = 60


def _study(n=3, name="tiny", steps=STEPS):
    specs = [passage_spec(seed, metric, max_steps=steps, base=TINY)
             for metric in ("smooth", "euclidean") for seed in range(n)]
    return Study(name, tuple(specs))


def _flight_columns(table):
    return table.drop(columns=[c for c in S.TIMING_COLUMNS if c in table.columns])


# --- specs ----------------------------------------------------------------------------------

def test_studies_are_data_with_unique_names_and_one_name_per_flight():
    mc, sweep = S.monte_carlo(), S.eta_sweep()
    assert len(mc.specs) == 200 and len(sweep.specs) == 9 * 20
    assert len(S.eta_sweep(grid=True).specs) == 19 * 20
    # The same flight (printed η, σ; the Euclidean baseline) has the same name and key in
    # both studies, so they share its cache folder.
    shared = {s.name: s.key for s in mc.specs} | {}
    both = [s for s in sweep.specs if s.name in shared]
    assert len(both) == 2 * 20 and all(shared[s.name] == s.key for s in both)
    assert all(s.config.simulation.kind == "passage" for s in mc.specs + sweep.specs)


def test_the_moving_study_flies_each_crossing_with_every_prediction_and_the_design():
    """Random crossings x {static, oracle, kalman} x both metrics with the paper's barrier, then
    x {oracle, kalman} x both metrics with the design barrier; the paper's rows are keyed as
    before the design existed (its setting at its neutral value), the design's differ."""
    from paper_repro.studies.catalogue import (
        MOVING_APPROACH_TIME,
        MOVING_DESIGN,
        MOVING_PREDICTION_TS,
    )

    study = S.moving_obstacles(scenes=3)
    assert len(study.specs) == 3 * 3 * 2 + 3 * 2 * 2
    assert {s.config.simulation.scenario for s in study.specs} == {"random-crossing"}
    labels = [dict(s.labels) for s in study.specs]
    predictions = [s.config.nmpc.prediction for s in study.specs]
    assert [lab["prediction"] for lab in labels] == predictions
    paper = [s for s, lab in zip(study.specs, labels) if lab["barrier"] == "paper"]
    design = [s for s, lab in zip(study.specs, labels) if lab["barrier"] == "design"]
    assert {s.config.nmpc.prediction for s in paper} == set(PREDICTIONS)
    assert {s.config.nmpc.prediction for s in design} == set(PREDICTIONS[1:])
    assert all(s.config.barrier == Config().barrier for s in paper)
    assert all(getattr(s.config.barrier, k) == v for s in design
               for k, v in MOVING_DESIGN[s.config.distance.metric].items())
    assert all("equilibrium_lookahead" not in s.config.key_dict()["barrier"] for s in paper)
    # The design predicts further (a longer step) and flies crossings timed to its own pace;
    # the paper's rows keep the printed step and the crossings of the printed set-up.
    assert {s.config.nmpc.prediction_ts for s in design} == {MOVING_PREDICTION_TS}
    assert {s.config.simulation.approach_time for s in design} == {MOVING_APPROACH_TIME}
    assert {s.config.nmpc.prediction_ts for s in paper} == {None}
    assert all("approach_time" not in s.config.key_dict()["simulation"] for s in paper)
    assert design[0].scene().name.endswith(f"@{MOVING_APPROACH_TIME:g}s")
    assert design[0].scene().fingerprint() != paper[0].scene().fingerprint()
    assert len({s.name for s in study.specs}) == len(study.specs)
    assert study.specs[0].scene().is_moving
    # The damped RTI on the default (interior-point) chain; the design's runs and the study's
    # stamp carry the swept path's golden hash, so a change to it retires them.
    from paper_repro.evidence.golden import layer_of

    assert all(s.config.solver.line_search for s in study.specs)
    assert all(s.config.solver.qp_solver == "riccati-ipm" for s in study.specs)
    assert {layer_of(s.config) for s in paper} == {""}
    assert {layer_of(s.config) for s in design} == {"sweep"}
    # One controller per worker and configuration: the prediction and the barrier are part of
    # the problem (the scan carries velocities), the scene and the seed are not.
    keys = {(lab["barrier"], lab["prediction"]): S.controller_key(s.config)
            for s, lab in zip(study.specs, labels)}
    assert len(set(keys.values())) == 5
    same = {S.controller_key(s.config) for s, lab in zip(study.specs, labels)
            if lab["prediction"] == "oracle" and lab["metric"] == "smooth"
            and lab["barrier"] == "paper"}
    assert len(same) == 1


@pytest.mark.parametrize("name", sorted(S.STUDIES))
def test_study_json_gives_every_run_its_whole_configuration_back(name):
    """What ``study.json`` records of a run (the keyed base and the run's changes) reads back
    as the run's configuration, a setting added later with a default other than its neutral
    value (the guide's set-point filter) included."""
    from paper_repro.evidence.golden import study_run_config
    from paper_repro.studies.engine import config_changes

    study = make_study(name, quick=True)
    base = study.specs[0].config.key_dict()
    for spec in study.specs:
        assert study_run_config(base, config_changes(base, spec.config)) == spec.config, spec.name


def test_bad_study_input_is_named():
    with pytest.raises(ValueError, match="scenes"):
        S.monte_carlo(scenes=0)
    with pytest.raises(ValueError, match="etas"):
        S.eta_sweep(etas=(0.1, -0.2))
    with pytest.raises(ValueError, match="unique"):
        spec = passage_spec(0)
        Study("x", (spec, spec))
    with pytest.raises(ValueError, match="workers"):
        S.run_study(_study(1), workers=-1)
    with pytest.raises(ValueError, match="scheduler"):
        S.run_study(_study(1), scheduler="localhost")
    with pytest.raises(ValueError, match="study must be one of"):
        make_study("nope")


# --- results carry their scene --------------------------------------------------------------

def test_a_saved_random_run_redraws_against_its_own_clouds_after_the_generator_changes(
        tmp_path, monkeypatch):
    cfg = passage_config(TINY, seed=4, max_steps=20)
    result = simulate(cfg, progress=False)
    result.save(tmp_path / "run")
    flown = [c.copy() for c in result.scene.clouds]
    # The generator's defaults change (denser clouds): the scene rebuilt by name differs ...
    denser = dataclasses.replace(random_scenes.RandomSceneParams(), density=4.0)
    monkeypatch.setattr(random_scenes, "RandomSceneParams", lambda: denser)
    rebuilt = runs.RunSpec("x", cfg, 20).scene()
    assert rebuilt.fingerprint() != result.scene.fingerprint()
    # ... but the saved run still carries the clouds it flew among, point for point.
    loaded = SimulationResult.load(tmp_path / "run")
    assert loaded.scene.fingerprint() == result.scene.fingerprint()
    assert all(np.array_equal(a, b) for a, b in zip(loaded.scene.clouds, flown, strict=True))
    np.testing.assert_array_equal(loaded.x, result.x)


# --- execution ------------------------------------------------------------------------------

def test_two_workers_give_exactly_the_rows_and_trajectories_of_one(tmp_path):
    """Controllers are reused across flights in a worker and reset before each, so neither
    the number of workers nor the order of the runs changes a single bit."""
    one = S.run_study(_study(), out=tmp_path / "one", workers=1, progress=False,
                      log=lambda line: None)
    two = S.run_study(_study(), out=tmp_path / "two", workers=2, progress=False,
                      log=lambda line: None)
    assert (one.table["status"] == "ok").all() and (two.table["status"] == "ok").all()
    assert two.table["worker"].nunique() == 2  # both workers flew
    pd.testing.assert_frame_equal(_flight_columns(one.table), _flight_columns(two.table))
    for a, b in zip(one.table["result_dir"], two.table["result_dir"], strict=True):
        ra, rb = SimulationResult.load(a), SimulationResult.load(b)
        assert np.array_equal(ra.x, rb.x) and np.array_equal(ra.u, rb.u)
    assert (tmp_path / "one" / "table.parquet").is_file()
    pd.testing.assert_frame_equal(S.load_table(tmp_path / "one"), one.table, check_like=True)
    # What the flights determine is saved apart from what the machine measured, and the
    # two studies wrote the same flight table, byte for byte.
    flight = S.load_table(tmp_path / "one", timings=False)
    assert not set(S.TIMING_COLUMNS) & set(flight.columns)
    assert ((tmp_path / "one" / "table.csv").read_bytes()
            == (tmp_path / "two" / "table.csv").read_bytes())


def test_a_killed_worker_loses_nothing(tmp_path):
    """One worker process is SIGKILLed after the first row: Dask reschedules its task, the
    study completes with every row present once."""
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address="127.0.0.1:0", silence_logs=40) as cluster, \
            Client(cluster) as client:
        pids = list(client.run(os.getpid).values())
        killed = []

        def kill_one(i, row):
            if not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        result = S.run_study(_study(4, steps=120), out=tmp_path / "s", client=client,
                             progress=False, log=lambda line: None, on_row=kill_one)
    assert killed
    table = result.table
    assert len(table) == 8 and table["name"].is_unique
    assert (table["status"] == "ok").all(), table["error"].tolist()


def test_an_interrupted_study_redoes_only_the_unfinished_runs(tmp_path):
    study = _study(3)

    class DriverKilled(Exception):
        pass

    def stop_after_two(i, row):
        if sum(runs.is_cached(s.directory(tmp_path / "runs")) for s in study.specs) >= 2:
            raise DriverKilled

    with pytest.raises(DriverKilled):
        S.run_study(study, out=tmp_path, workers=0, progress=False, log=lambda line: None,
                    on_row=stop_after_two)
    done_before = sum(runs.is_cached(s.directory(tmp_path / "runs")) for s in study.specs)
    assert 2 <= done_before < len(study.specs)
    again = S.run_study(study, out=tmp_path, workers=0, progress=False, log=lambda line: None)
    assert int(again.table["simulated"].sum()) == len(study.specs) - done_before
    assert (again.table["status"] == "ok").all()
    # A third call flies nothing: the tables are rewritten byte for byte, and the timings of
    # the call that flew the runs stay (the cache's speed is not the study's).
    files = {n: (tmp_path / n).read_bytes() for n in ("table.parquet", "timings.csv",
                                                      "timings.json", "study.json")}
    cached = S.run_study(study, out=tmp_path, workers=0, progress=False, log=lambda line: None)
    assert not cached.table["simulated"].any()
    assert {n: (tmp_path / n).read_bytes() for n in files} == files
    # Fewer runs, all cached: the old timings are not these runs', so they are rewritten.
    fewer = Study(study.name, study.specs[:2])
    S.run_study(fewer, out=tmp_path, workers=0, progress=False, log=lambda line: None)
    import pandas as pd

    assert list(pd.read_csv(tmp_path / "timings.csv")["name"]) == [s.name for s in
                                                                    study.specs[:2]]
    # The cache moved (re-keyed): the measured timings stay, the locations follow the cache.
    measured = pd.read_csv(tmp_path / "timings.csv")
    moved = tmp_path / "moved"
    (tmp_path / "runs").rename(moved)
    again = S.run_study(fewer, out=tmp_path, workers=0, progress=False, log=lambda line: None,
                        runs_dir=moved)
    assert not again.table["simulated"].any()
    kept = pd.read_csv(tmp_path / "timings.csv")
    assert [Path(d).parent for d in kept["result_dir"]] == [moved, moved]
    pd.testing.assert_frame_equal(kept.drop(columns="result_dir"),
                                  measured.drop(columns="result_dir"))



def test_a_saved_study_is_read_back_only_for_exactly_its_runs(tmp_path):
    """``saved_table`` returns the saved table without the run cache (another machine), and
    nothing for other runs, other keys or a failed row."""
    study = _study(1)
    flown = S.run_study(study, out=tmp_path / "out", runs_dir=tmp_path / "runs", workers=0,
                        progress=False, log=lambda line: None).table
    (tmp_path / "runs").rename(tmp_path / "elsewhere")  # the cache is gone
    saved = S.saved_table(study, tmp_path / "out")
    pd.testing.assert_frame_equal(saved[flown.columns], flown)
    assert S.saved_table(_study(2), tmp_path / "out") is None  # more runs
    longer = Study(study.name, tuple(dataclasses.replace(s, max_steps=STEPS + 1)
                                     for s in study.specs))
    assert [s.key for s in longer.specs] != [s.key for s in study.specs]
    assert S.saved_table(longer, tmp_path / "out") is None  # same names, other keys
    assert S.saved_table(study, tmp_path / "nowhere") is None
    table = pd.read_parquet(tmp_path / "out" / "table.parquet")
    table.loc[0, "status"] = "failed"
    table.to_parquet(tmp_path / "out" / "table.parquet", index=False)
    assert S.saved_table(study, tmp_path / "out") is None  # a failed row is flown again

def test_a_run_that_raises_inside_a_worker_is_a_failed_row(tmp_path, monkeypatch):
    """In-process Dask workers (threads) share the monkeypatched closed loop; the failure
    becomes a row with its message and the other runs complete."""
    from distributed import Client, LocalCluster

    real_fly = runs.fly

    def fly(spec, controller=None, progress=None):
        if spec.name.endswith("s001") and "euclidean" in spec.name:
            raise FloatingPointError("the plant diverged")
        return real_fly(spec, controller=controller, progress=progress)

    monkeypatch.setattr(runs, "fly", fly)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address="127.0.0.1:0", silence_logs=40) as cluster, \
            Client(cluster) as client:
        result = S.run_study(_study(2), out=tmp_path, client=client, progress=False,
                             log=lambda line: None)
    failed = result.failed
    assert list(failed["name"]) == ["passage-euclidean-s001"]
    assert failed["error"].iloc[0] == "FloatingPointError: the plant diverged"
    assert (result.table.drop(failed.index)["status"] == "ok").all()
    assert len(result.table) == 4


def test_progress_lines_when_not_a_terminal(tmp_path):
    lines = []
    S.run_study(_study(1), out=tmp_path, workers=0, progress=False, log=lines.append)
    assert lines[0] == "study tiny: 2 runs"
    assert any(line.startswith("study tiny: 2/2 runs, 0 failed") for line in lines)
    assert "2 runs (2 flown, 0 failed)" in lines[-1]


def test_the_noise_study_shares_its_perfect_runs_and_perturbs_the_others():
    noise = S.sensor_noise()
    mc = {s.name: s.key for s in S.monte_carlo(scenes=8).specs}  # the same 8 scenes
    perfect = [s for s in noise.specs if dict(s.labels)["sensor"] == "perfect"]
    noisy = [s for s in noise.specs if dict(s.labels)["sensor"] == "noisy"]
    assert len(perfect) == len(noisy) == 16
    assert all(mc.get(s.name) == s.key for s in perfect)  # the same flights, one cache folder
    assert not any(s.name in mc for s in noisy)
    # The noisy sensor changes what the controller sees, reproducibly per scene.
    cfg = noisy[0].config
    ctl = make_controller(cfg)  # the sensor is not the controller's: one serves all
    a, b = (simulate(cfg, ctl, max_steps=40, progress=False) for _ in range(2))
    clean = simulate(perfect[0].config, ctl, max_steps=40, progress=False)
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.visible_points, clean.visible_points)


def test_a_worker_builds_each_controller_once(tmp_path):
    """Six passages of two configurations on two workers: each worker process builds at most
    one controller per configuration, however many runs it flies (one worker: exactly two,
    for six runs)."""
    for workers in (1, 2):
        res = S.run_study(_study(), out=tmp_path / str(workers), workers=workers,
                          progress=False, log=lambda line: None)
        assert (res.table["status"] == "ok").all() and len(res.table) == 6
        builds = res.table.groupby("worker")["controller_builds"].max()
        assert len(builds) == workers and (builds <= 2).all(), builds
        if workers == 1:
            assert builds.iloc[0] == 2


def test_the_embedded_cluster_listens_on_this_machine_only():
    """Every socket the embedded cluster listens on, its scheduler's, its dashboard's and its
    worker processes', is bound to the loopback address."""
    import psutil

    from paper_repro.studies.cluster import LOOPBACK, dask_client

    with dask_client(workers=1, log=lambda line: None) as client:
        me = psutil.Process()
        processes = [me, *me.children(recursive=True)]
        listening = [c.laddr for p in processes for c in p.net_connections(kind="inet")
                     if c.status == psutil.CONN_LISTEN]
        assert client.scheduler.address.startswith(f"tcp://{LOOPBACK}:")
        assert all(w.startswith(f"tcp://{LOOPBACK}:") for w in client.scheduler_info()["workers"])
    assert len(listening) >= 3  # the scheduler, its dashboard, a worker (and its nanny)
    assert {a.ip for a in listening} == {LOOPBACK}, listening

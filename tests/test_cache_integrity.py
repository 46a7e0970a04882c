"""A damaged cache entry never crashes a run or passes for a result: it is named, moved
aside and flown again, and what is flown again is the run a fresh cache gives."""

import dataclasses
import json
import warnings

import numpy as np
import pytest

from paper_repro import Config, NMPCParams, SimulationParams, SolverParams
from paper_repro._native import DamagedLibraryWarning, cache_dir, load_library
from paper_repro.sim.result import MANIFEST, DamagedResult, SimulationResult, verify_result
from paper_repro.studies import Study, run_study
from paper_repro.studies.runs import DamagedCacheWarning, RunSpec, ensure_result, is_cached

CONFIG = Config(nmpc=NMPCParams(region_slots=1, points_per_region=32),
                simulation=SimulationParams(scenario="encounter"))
SPEC = RunSpec("damage", CONFIG, 40)


def _truncate(path):
    path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])


def _bad_json(path):
    path.write_text(path.read_text()[:-20])


def _drop_array(directory):
    with np.load(directory / "result.npz") as z:
        arrays = {k: z[k] for k in z.files if k != "clearance"}
    np.savez_compressed(directory / "result.npz", **arrays)


def _edit_config(path):
    data = json.loads(path.read_text())
    data["outcome"] = "completed" if data["outcome"] != "completed" else "stalled"
    path.write_text(json.dumps(data))


DAMAGE = {
    "truncated result.npz": ("result.npz", lambda d: _truncate(d / "result.npz"),
                             "truncated or not a NumPy archive"),
    "config.json not JSON": ("config.json", lambda d: _bad_json(d / "config.json"),
                             "not valid JSON"),
    "an array missing": ("result.npz", _drop_array, "lacks the array 'clearance'"),
    "manifest mismatch": ("config.json", lambda d: _edit_config(d / "config.json"),
                          "does not match its manifest"),
}


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """The run flown into an empty cache: what every recovery must give back."""
    root = tmp_path_factory.mktemp("fresh")
    directory, simulated = ensure_result(SPEC, root, progress=False)
    assert simulated and is_cached(directory)
    return SimulationResult.load(directory)


def _damaged_copy(fresh, tmp_path, damage):
    directory = SPEC.directory(tmp_path)
    fresh.save(directory)
    damage(directory)
    return directory


@pytest.mark.parametrize("kind", sorted(DAMAGE))
def test_a_damaged_result_is_named_and_flown_again(kind, fresh, tmp_path):
    file, damage, what = DAMAGE[kind]
    directory = _damaged_copy(fresh, tmp_path, damage)
    with pytest.raises(DamagedResult, match=what) as info:
        SimulationResult.load(directory)
    assert info.value.folder == directory and info.value.file == file
    assert str(directory) in str(info.value) and file in str(info.value)
    assert not is_cached(directory)
    with pytest.warns(DamagedCacheWarning, match=f"{directory.name}.*{file}"):
        again, simulated = ensure_result(SPEC, tmp_path, progress=False)
    assert simulated and again == directory and is_cached(again)
    assert (tmp_path / f"{directory.name}.damaged").is_dir()  # moved aside, never deleted
    flown = SimulationResult.load(again)
    for name in ("x", "u", "clearance", "iterations", "success"):
        np.testing.assert_array_equal(getattr(flown, name), getattr(fresh, name))


def test_an_array_missing_without_a_manifest_is_named(fresh, tmp_path):
    """A folder saved before manifests existed is read in full: a missing array is named."""
    directory = _damaged_copy(fresh, tmp_path, _drop_array)
    (directory / MANIFEST).unlink()
    with pytest.raises(DamagedResult, match="lacks the array 'clearance'"):
        verify_result(directory)


def test_an_old_intact_folder_gets_its_manifest(fresh, tmp_path):
    directory = _damaged_copy(fresh, tmp_path, lambda d: (d / MANIFEST).unlink())
    assert is_cached(directory) and (directory / MANIFEST).is_file()


def test_a_study_records_the_damaged_entry_and_still_completes(fresh, tmp_path):
    runs = tmp_path / "runs"
    directory = _damaged_copy(fresh, runs, lambda d: _truncate(d / "result.npz"))
    lines = []
    res = run_study(Study("damage", (SPEC,)), out=tmp_path / "study", workers=0,
                    runs_dir=runs, progress=False, log=lines.append)
    row = res.table.iloc[0]
    assert row["status"] == "ok" and row["simulated"] and row["cache_damaged"]
    assert "damage_note" not in res.table
    named = [line for line in lines if "damaged cache entry" in line]
    assert len(named) == 1 and directory.name in named[0] and "result.npz" in named[0]


@pytest.mark.parametrize("record", [True, False], ids=["recorded", "older cache"])
def test_a_truncated_compiled_library_is_built_again(record, tmp_path, monkeypatch):
    """Truncated on disk before it is loaded (a library in use is never rewritten): it is
    refused (its SHA-256 differs from the record, or without a record the loader refuses it),
    moved aside and built again, and the rebuilt one computes."""
    import ctypes

    from paper_repro._native import build_library

    monkeypatch.setenv("PAPER_REPRO_CACHE", str(tmp_path))
    source = f"double twice_{int(record)}(double x) {{ return 2 * x; }}\n".encode()
    path = build_library(f"twice_{int(record)}", source)
    if not record:
        path.with_name(f"{path.name}.sha256").unlink()
    data = path.read_bytes()
    path.unlink()
    path.write_bytes(data[: len(data) // 3])
    with pytest.warns(DamagedLibraryWarning, match=path.name):
        lib = load_library(f"twice_{int(record)}", source)
    fn = getattr(lib, f"twice_{int(record)}")
    fn.restype, fn.argtypes = ctypes.c_double, [ctypes.c_double]
    assert fn(1.5) == 3.0
    assert any(p.name.endswith(".damaged") for p in cache_dir().iterdir())
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # intact now: loaded without a word
        load_library(f"twice_{int(record)}", source)


def test_a_damaged_tuning_storage_is_moved_aside_and_the_study_starts_anew(tmp_path):
    from paper_repro.studies import tuning as T
    from paper_repro.studies.tuning_space import finished_trials

    out = tmp_path / "tuning"
    out.mkdir()
    (out / "tuning.db").write_bytes(b"not a database " * 100)
    lines = []
    settings = T.TuningSettings(1, quick=True, space={"sigma": (0.5, 2.0)}, seeds=(0,),
                                max_steps=30, base=CONFIG, out=out, runs_dir=tmp_path / "runs")
    res = T.tune(settings, workers=0, log=lines.append)
    assert (out / "tuning.db.damaged").read_bytes().startswith(b"not a database")
    assert sum("damaged storage" in line and "tuning.db" in line for line in lines) == 1
    assert len(finished_trials(res.study)) == 1


def test_a_result_saved_without_its_scans_is_flown_again_only_for_who_needs_them(tmp_path):
    """A result saved before the loop logged its scans still serves a table; a figure that
    draws the scans (``needs=("scan",)``) has it flown again, once, and the flight is the
    same."""
    from paper_repro.sim.result import write_manifest

    runs = tmp_path / "runs"
    out, flown = ensure_result(SPEC, runs, progress=False)
    before = SimulationResult.load(out)
    with np.load(out / "result.npz") as z:  # as an older version saved it
        older = {k: z[k] for k in z.files if not k.startswith("scan_")}
    np.savez_compressed(out / "result.npz", **older)
    write_manifest(out)
    assert not SimulationResult.load(out).has("scan")
    assert ensure_result(SPEC, runs, progress=False) == (out, False)
    again, flown = ensure_result(SPEC, runs, progress=False, needs=("scan",))
    assert again == out and flown
    after = SimulationResult.load(again)
    assert after.has("scan") and np.array_equal(after.x, before.x)
    assert ensure_result(SPEC, runs, progress=False, needs=("scan",)) == (out, False)


# --- re-keying the cache after a layout change that moves no flight ---------------------------

def _former_layout(config: dict) -> dict:
    """``config`` as the code before the solver options moved wrote it."""
    old = json.loads(json.dumps(config, default=str))
    solver = old.pop("solver")
    old["nmpc"].update(solver=solver["nlp_solver"], sqp_iterations=solver["sqp_iterations"],
                       line_search=solver["line_search"], qp_solver=solver["qp_solver"])
    old["simulation"].update(lidar_range=old["sensor"].pop("range"),
                             prediction=old["nmpc"].pop("prediction"))
    for name in QUADROTOR_BOX:
        old["nmpc"][name] = old["quadrotor"].pop(name)
    return old


QUADROTOR_BOX = ("state_lower", "state_upper", "input_lower", "input_upper")


def test_the_quadrotor_box_moved_to_the_vehicle_and_every_key_stays():
    """𝒳 and 𝒰 live with the quadrotor's other data; a ``config.json`` that gives them in the
    ``nmpc`` part loads into the same configuration, and a run's key still hashes them where
    they were (the committed tables hold those keys); both places at once are refused."""
    from paper_repro import paths
    from paper_repro.config_history import without_added
    from paper_repro.presets import moving_design_controller
    from paper_repro.studies.catalogue import make_study
    from paper_repro.studies.engine import study_record

    cfg = moving_design_controller(Config(nmpc=NMPCParams(prediction="oracle")), "smooth")
    assert cfg.quadrotor.state_lower[2] > 0 and not hasattr(cfg.nmpc, "state_lower")
    former = json.loads(json.dumps(cfg.to_dict(), default=str))
    for name in QUADROTOR_BOX:
        former["nmpc"][name] = former["quadrotor"].pop(name)
    assert Config.from_dict(former) == cfg == Config.from_dict(cfg.to_dict())
    keyed = json.loads(json.dumps(cfg.key_dict(), default=str))
    assert keyed == without_added(former, Config().to_dict())
    # A study's record, byte for byte as committed: the moving study's runs change the box.
    study = make_study("moving_obstacles")
    assert study_record(study) == (paths.study_dir("moving_obstacles") / "study.json").read_text()
    assert Config.from_dict(cfg.key_dict()) == cfg
    both = json.loads(json.dumps(cfg.to_dict(), default=str))
    both["nmpc"]["state_lower"] = both["quadrotor"]["state_lower"]
    with pytest.raises(ValueError, match=r"nmpc\.state_lower .*quadrotor\.state_lower"):
        Config.from_dict(both)


def _as_written_by_former_code(folder, golden):
    """Rewrite a cached run as the former code left it: its config in the former layout,
    its folder named by the key that code computed."""
    import hashlib

    from paper_repro.sim.result import write_manifest

    payload = json.loads((folder / "config.json").read_text())
    payload["config"] = _former_layout(payload["config"])
    (folder / "config.json").write_text(json.dumps(payload, indent=2))
    write_manifest(folder)
    spec_config = json.loads(json.dumps(payload["config"]))
    spec_config["simulation"]["max_steps"] = Config().simulation.max_steps
    text = json.dumps({"config": spec_config, "max_steps": SPEC.max_steps,
                       "scene": payload["scene"]["fingerprint"], "golden": golden},
                      sort_keys=True, separators=(",", ":"))
    old = folder.with_name(f"{SPEC.name}-{hashlib.sha256(text.encode()).hexdigest()[:12]}")
    folder.rename(old)
    return old


def test_rekey_keeps_a_result_of_the_former_layout_and_only_one_it_can_prove(tmp_path):
    """A result written under the former layout is moved to today's key, loads as the same
    run, and is not flown again; one whose key it cannot prove (another golden set: another
    code's flight) stays where it is and is flown again."""
    from paper_repro.evidence.golden import golden_hash
    from paper_repro.studies.runs import rekey

    # a run the former code could fly: the settings added since at the values they were
    # added with (config_history.ADDED), which its layout leaves out
    spec = dataclasses.replace(SPEC, config=dataclasses.replace(
        CONFIG, solver=SolverParams(relaxed_qp=False, cold_start="rti", shared_barrier=False),
        simulation=dataclasses.replace(CONFIG.simulation, workspace_exit=None)))
    runs = tmp_path / "runs"
    out, flown = ensure_result(spec, runs, progress=False)
    assert flown
    before = SimulationResult.load(out)
    old = _as_written_by_former_code(out, golden_hash())
    assert not out.exists()
    assert rekey(runs) == {"moved": 1, "current": 0, "unproven": 0, "duplicate": 0,
                           "damaged": 0}
    again, flown = ensure_result(spec, runs, progress=False)
    assert again == out and not flown and not old.exists()
    after = SimulationResult.load(again)
    assert after.config == before.config and np.array_equal(after.x, before.x)
    assert rekey(runs)["current"] == 1  # a second call moves nothing

    other = _as_written_by_former_code(again, "another-golden-set")
    assert rekey(runs)["unproven"] == 1 and other.exists()
    assert ensure_result(spec, runs, progress=False)[1]  # flown again, under today's key

"""The committed evidence is what this commit's code makes (paper_repro.evidence.golden).

* the golden flights, flown now, equal their committed copies;
* ``golden.json`` is the hash of those copies;
* every committed evidence set carries that hash, so a change that moves a flight fails here
  until the golden flights and every evidence set are regenerated;
* the machinery itself: a stamp goes stale when the golden set changes, and the run cache's
  keys follow the golden hash.
"""

import json
import shutil

import numpy as np
import pytest

from paper_repro import Config, paths
from paper_repro.config import GuideParams
from paper_repro.evidence import golden as evidence
from paper_repro.studies.runs import run_key


@pytest.fixture(scope="module")
def golden_check():
    """Every golden flight flown once (a parent before the flight that starts from it)."""
    return {row["name"]: row for row in evidence.check_golden()}


@pytest.mark.parametrize("flight", evidence.GOLDEN_FLIGHTS, ids=lambda f: f.name)
def test_golden_flight_equals_its_committed_copy(flight, golden_check):
    row = golden_check[flight.name]
    committed = np.load(paths.golden_dir() / f"{flight.name}.npy")
    assert row["flown"].shape == committed.shape == (flight.steps, row["flown"].shape[1])
    assert row["position_error"] <= evidence.POSITION_TOLERANCE, (
        f"{flight.name} moved by {row['position_error']:.3g} m: regenerate the golden flights "
        "(python -m paper_repro golden --write) and every evidence set")
    assert row["input_error"] <= evidence.INPUT_TOLERANCE
    assert np.isfinite(row["flown"]).all()


def test_golden_flights_exercise_what_they_claim(golden_check):
    """The obstacle flights see their regions; the IPOPT window starts where its parent was."""
    encounter = golden_check["encounter-smooth"]["flown"]
    reference = golden_check["reference-encounter-smooth"]["flown"]
    np.testing.assert_array_equal(reference[0, :12], encounter[600, :12])
    # Inside the LiDAR's 3 m of the encounter's cloud for the last few hundred steps.
    from paper_repro.world.scenarios import make_scene

    cloud = make_scene("encounter").all_points
    near = np.linalg.norm(encounter[:, None, :3] - cloud[None], axis=2).min(axis=1)
    assert (near[400:] < 3.0).all() and near[0] > 3.0


def test_the_golden_design_flight_flies_the_moving_study_design():
    """``crossing-smooth-design`` is a crossing of the study's design flown with
    ``studies.catalogue.moving_design`` (smoothed metric: its controller, on crossings timed to
    it), on the study's chain: the golden layer that guards the design's runs flies the
    design itself, with regions in view (their swept paths in the linearisation)."""
    import dataclasses

    from paper_repro.studies.catalogue import moving_design
    from paper_repro.world.lidar import Lidar
    from paper_repro.world.scenarios import mission_scene

    flight = next(f for f in evidence.GOLDEN_FLIGHTS if f.name == "crossing-smooth-design")
    plain = dataclasses.replace(flight, barrier=(), prediction_ts=None,
                                approach_time=None).config()
    assert flight.config() == moving_design(plain, "smooth")
    assert evidence.layer_of(flight.config()) == "sweep"
    # The committed flight sees a region for most of its steps (the LiDAR, not the plan).
    rows = np.load(paths.golden_dir() / f"{flight.name}.npy")
    scene = mission_scene(flight.config().simulation)
    lidar = Lidar(scene.clouds, flight.config().sensor.range, motions=scene.motions)
    ts = flight.config().nmpc.ts
    seen = sum(any(len(v) for v in lidar.scan(row[:3], k * ts)) for k, row in enumerate(rows))
    assert seen > len(rows) // 2


def test_golden_json_is_the_hash_of_the_committed_files():
    stored = json.loads((paths.golden_dir() / "golden.json").read_text())
    assert set(stored["files"]) == {f.name for f in evidence.GOLDEN_FLIGHTS}
    assert evidence.recomputed_golden_hash() == stored["hash"] == evidence.golden_hash()
    for layer in evidence.LAYERS[1:]:
        assert (evidence.recomputed_golden_hash(layer) == stored["layers"][layer]
                == evidence.golden_hash(layer) != evidence.golden_hash())


def _rewrite_golden(folder, name):
    """Move golden flight ``name`` by 1e-6 and rewrite golden.json as ``golden --write``
    would."""
    path = folder / f"{name}.npy"
    np.save(path, np.load(path) + 1e-6)
    files = {f.name: evidence.sha256_of(folder / f"{f.name}.npy")
             for f in evidence.GOLDEN_FLIGHTS}
    layers = {layer: evidence.set_hash(evidence._layer_files(files, layer))
              for layer in evidence.LAYERS[1:]}
    (folder / "golden.json").write_text(json.dumps(
        {"hash": evidence.set_hash(evidence._layer_files(files, "")), "files": files,
         "layers": layers}))


@pytest.mark.parametrize("layer", ["map", "guide", "riccati", "sweep"])
def test_a_change_to_a_layer_retires_only_what_uses_it(tmp_path, monkeypatch, layer):
    """A layer's golden flight moved: the runs and evidence sets that use the layer, or one
    built on it, go stale (the map's change retires the guided runs too, the guide's leaves
    the map-only runs alone, the active-set chain's only the runs that choose it, mapped or
    not, the swept path's the runs that sweep, on either chain); the others keep their keys
    and stamps."""
    import dataclasses

    shutil.copytree(paths.golden_dir(), tmp_path / "figures" / "golden")
    monkeypatch.setenv(paths.ROOT_ENV, str(tmp_path))
    mapped = dataclasses.replace(Config(), sensor=dataclasses.replace(Config().sensor,
                                                                      map_voxel=0.5))
    guided = dataclasses.replace(mapped, guide=GuideParams(planner="grid"))

    def ipm(cfg):  # the active-set chain without a budget (HPIPM in the tail)
        return dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver,
                                                                   qp_solver="riccati"))

    def swept(cfg):
        return dataclasses.replace(
            cfg, nmpc=dataclasses.replace(cfg.nmpc, prediction="oracle"),
            barrier=dataclasses.replace(cfg.barrier, sweep_time=1.0))

    configs = {"": Config(), "map": mapped, "guide": guided, "riccati": ipm(Config()),
               "map+riccati": ipm(mapped), "sweep": swept(Config()),
               "riccati+sweep": swept(ipm(Config()))}
    assert [evidence.layer_of(*c) for c in ((Config(),), (Config(), mapped), (mapped, guided),
                                            (Config(), ipm(Config())), (guided, ipm(mapped)),
                                            (swept(Config()),))
            ] == ["", "map", "guide", "riccati", "guide+riccati", "sweep"]
    # The swept path is a layer of its own, on the core; a set of both covers both.
    assert evidence.covered_layers("sweep") == {"", "sweep"}
    assert len({evidence.golden_hash(x) for x in ("sweep", "riccati", "riccati+sweep")}) == 3
    assert all(evidence.layer_of(cfg) == used for used, cfg in configs.items())
    sets = {"": "studies/monte_carlo", "map": "studies/sensor_noise", "guide": "guidance_cost",
            "riccati": "solver_speed/crossing", "map+riccati": "studies/sensing_window",
            "sweep": "studies/moving_heldout", "riccati+sweep": "studies/moving_levers"}
    for used, name in sets.items():
        (tmp_path / "figures" / name).mkdir(parents=True)
        evidence.stamp(tmp_path / "figures" / name, "test", used)
    keys = {used: run_key(cfg, 100, "fp") for used, cfg in configs.items()}
    assert not set(sets.values()) & set(evidence.stale_evidence())
    hashes = {used: evidence.golden_hash(used) for used in configs}
    assert len(set(hashes.values())) == len(hashes)

    moved = next(f.name for f in evidence.GOLDEN_FLIGHTS if f.layer == layer)
    _rewrite_golden(tmp_path / "figures" / "golden", moved)
    parts = evidence.covered_layers(layer)
    retired = {used for used in configs if parts <= evidence.covered_layers(used)}
    assert any(set(layer.split("+")) <= set(used.split("+")) for used in retired)
    assert "" not in retired
    stale = set(evidence.stale_evidence())
    for used, cfg in configs.items():
        assert (evidence.golden_hash(used) != hashes[used]) == (used in retired)
        assert (run_key(cfg, 100, "fp") != keys[used]) == (used in retired)
        assert (sets[used] in stale) == (used in retired)


def test_an_unknown_layer_is_refused():
    with pytest.raises(ValueError, match="layer must be"):
        evidence.golden_hash("lidar")
    with pytest.raises(ValueError, match="layer must be"):
        evidence.covered_layers("map+")


def test_a_study_of_map_runs_stamped_with_the_core_hash_is_stale(tmp_path, monkeypatch):
    shutil.copytree(paths.golden_dir(), tmp_path / "figures" / "golden")
    monkeypatch.setenv(paths.ROOT_ENV, str(tmp_path))
    study = tmp_path / "figures" / "studies" / "guidance"
    study.mkdir(parents=True)
    meta = {"golden": evidence.golden_hash(), "base_config": Config().to_dict(),
            "specs": [{"config_changes": {}}, {"config_changes": {"sensor.map_voxel": 0.5}}]}
    (study / "study.json").write_text(json.dumps(meta, default=str))
    evidence.stamp(study, "test")
    assert "studies/guidance" in evidence.stale_evidence()
    meta["golden"] = evidence.golden_hash("map")
    (study / "study.json").write_text(json.dumps(meta, default=str))
    evidence.stamp(study, "test", "map")
    assert "studies/guidance" not in evidence.stale_evidence()


def test_every_committed_evidence_set_was_made_with_the_current_golden_flights():
    stale = evidence.stale_evidence()
    assert not stale, (f"evidence made with another golden set: {stale}; regenerate them "
                       "(docs/contributing.md)")


def test_the_paper_evidence_is_there():
    """The paper's figures, the preset that matches its clock and the fidelity table exist
    (a missing set is not stale, so this is asked on its own)."""
    for name in ("", "presets/paper-timeline", "fidelity"):
        assert (paths.figures_dir() / name / "evidence.json").is_file(), name


def test_every_evidence_folder_is_listed():
    """A folder of figures/ that holds a stamp, or a study table, is a listed evidence set."""
    root = paths.figures_dir()
    stamped = {str(p.parent.relative_to(root)).replace(".", "") for p in
               root.rglob("evidence.json") if "quick" not in p.parts}
    tables = {str(p.parent.relative_to(root)) for p in root.rglob("study.json")
              if "quick" not in p.parts}
    assert stamped | tables <= set(evidence.EVIDENCE_SETS)


def test_a_stamp_goes_stale_when_the_golden_set_changes(tmp_path, monkeypatch):
    shutil.copytree(paths.golden_dir(), tmp_path / "figures" / "golden")
    monkeypatch.setenv(paths.ROOT_ENV, str(tmp_path))
    study = tmp_path / "figures" / "studies" / "monte_carlo"
    study.mkdir(parents=True)
    evidence.stamp(study, "test")
    before = evidence.golden_hash()
    assert evidence.stamped_hash(study) == before
    assert "studies/monte_carlo" not in evidence.stale_evidence()
    key = run_key(Config(), 100, "fp")

    # A flight moved: one golden file rewritten, golden.json with it.
    _rewrite_golden(tmp_path / "figures" / "golden", "paper-smooth")
    assert evidence.golden_hash() != before
    assert "studies/monte_carlo" in evidence.stale_evidence()
    assert run_key(Config(), 100, "fp") != key  # every cached run is retired with it
    evidence.stamp(study, "test")
    assert "studies/monte_carlo" not in evidence.stale_evidence()


def test_unknown_golden_flight_is_named():
    with pytest.raises(ValueError, match="unknown golden flight.*paper-smoth"):
        evidence.check_golden(["paper-smoth"])


@pytest.mark.slow
def test_the_paper_summary_regenerates_byte_for_byte(tmp_path):
    """The flight columns of figures/summary.csv are what this code flies: both paper
    missions (about a minute each, in parallel) and the summary notebook, into a fresh
    folder, give the committed file byte for byte."""
    from paper_repro.studies.reproduce import reproduce

    report = reproduce(notebooks=["06_summary"], figures_dir=tmp_path / "figures",
                       results_dir=tmp_path / "results", executed_dir=tmp_path / "executed",
                       progress=False, log=lambda line: None)
    assert sorted(report.simulated) == ["paper-euclidean", "paper-smooth"]
    committed = (paths.figures_dir() / "summary.csv").read_bytes()
    assert (tmp_path / "figures" / "summary.csv").read_bytes() == committed


def test_a_machine_copy_stands_only_for_the_committed_file_it_was_flown_for(tmp_path,
                                                                              monkeypatch):
    """On a machine of another signature the flight is compared with its machine copy, and
    only while the copy stands for the committed file as it is: a moved committed file (a
    code change written with ``--write``), a copy changed by hand, or the machine that wrote
    the golden flights compare with the committed file."""
    from paper_repro.evidence import golden

    shutil.copytree(paths.golden_dir(), tmp_path / "figures" / "golden")
    monkeypatch.setenv(paths.ROOT_ENV, str(tmp_path))
    folder, name = paths.golden_dir(), "paper-smooth"
    main = folder / f"{name}.npy"
    copy_dir = folder / golden.MACHINES / "c-test_blas-test"
    copy_dir.mkdir(parents=True)
    copy = copy_dir / f"{name}.npy"
    np.save(copy, np.load(main) + 1e-3)
    entry = {"of": golden.sha256_of(main), "sha256": golden.sha256_of(copy)}
    (copy_dir / "copies.json").write_text(json.dumps({"files": {name: entry}}))

    monkeypatch.setattr(golden, "machine_signature", lambda: "c-test_blas-test")
    assert golden.reference_path(name) == copy
    assert golden.reference_path("paper-euclidean") == folder / "paper-euclidean.npy"
    np.save(copy, np.load(copy) + 1e-3)  # changed by hand: no longer the recorded copy
    assert golden.reference_path(name) == main
    np.save(copy, np.load(main) + 1e-3)
    assert golden.reference_path(name) == copy
    np.save(main, np.load(main) + 1e-6)  # the committed flight moved: the copy is retired
    assert golden.reference_path(name) == main

    monkeypatch.setattr(golden, "machine_signature", golden.golden_signature)
    assert golden.reference_path(name) == main
    with pytest.raises(ValueError, match="wrote the golden flights: use --write"):
        golden.write_machine_copies([name])


def test_the_machine_signature_names_the_c_level_and_the_blas_kernel():
    from paper_repro import _blas
    from paper_repro._native import arch_flags
    from paper_repro.evidence.golden import golden_signature, machine_signature

    c, kernel = machine_signature().split("_blas-")
    assert c == "c-" + arch_flags()[0].removeprefix("-march=")
    assert kernel == (_blas.numpy_kernel() or "other")
    assert golden_signature().startswith("c-") and "_blas-" in golden_signature()


def _kernel_in_a_new_process(code: str, **env) -> str:
    import os
    import subprocess
    import sys

    environ = {k: v for k, v in os.environ.items() if k != "PAPER_REPRO_BLAS"} | env
    done = subprocess.run([sys.executable, "-c", code], env=environ, capture_output=True,
                          text=True, timeout=120)
    return (done.stdout + done.stderr).strip()


def test_importing_paper_repro_first_pins_one_blas_kernel():
    from paper_repro import _blas

    assert _blas.wanted_kernel(frozenset({"avx2", "fma", "avx512f"})) == "Haswell"
    assert _blas.wanted_kernel(frozenset({"sse2", "avx", "avx2"})) is None
    wanted = _blas.wanted_kernel()
    if wanted is None:
        pytest.skip("OpenBLAS chooses alone on this CPU (not Linux x86-64 with AVX2 and FMA)")
    show = "import paper_repro._blas as b; print(b.numpy_kernel())"
    assert _kernel_in_a_new_process(show, OPENBLAS_CORETYPE="Sandybridge") == wanted
    assert _kernel_in_a_new_process(show, PAPER_REPRO_BLAS="Sandybridge") == "Sandybridge"
    assert _kernel_in_a_new_process(show, PAPER_REPRO_BLAS="system",
                                    OPENBLAS_CORETYPE="Sandybridge") == "Sandybridge"
    # NumPy loaded first keeps the kernel the environment gave it: no evidence is stamped.
    late = ("import numpy; import paper_repro._blas as b\n"
            "try:\n    b.check_kernel(); print('stamped')\n"
            "except RuntimeError as e:\n    print('refused', e)")
    said = _kernel_in_a_new_process(late, OPENBLAS_CORETYPE="Sandybridge")
    assert said.startswith("refused") and "OPENBLAS_CORETYPE" in said
    # A kernel OpenBLAS does not know is refused when paper_repro is imported, by name.
    said = _kernel_in_a_new_process("import paper_repro", PAPER_REPRO_BLAS="Skylake-X")
    assert "PAPER_REPRO_BLAS must be 'system' or one of" in said and "'Skylake-X'" in said


def test_a_run_flown_with_another_blas_kernel_is_cached_under_another_key(monkeypatch):
    from paper_repro import Config, _blas
    from paper_repro.evidence.golden import golden_hash, layer_of
    from paper_repro.paths import json_hash
    from paper_repro.studies.runs import run_key

    # with the kernel asked for, a run keeps the key it had before kernels were pinned
    monkeypatch.setattr(_blas, "other_kernel", lambda: None)
    asked = run_key(Config(), 100, "scene")
    assert asked == json_hash({"config": Config().key_dict(), "max_steps": 100,
                               "scene": "scene", "golden": golden_hash(layer_of(Config()))})
    monkeypatch.setattr(_blas, "other_kernel", lambda: "Sandybridge")
    other = run_key(Config(), 100, "scene")
    monkeypatch.setattr(_blas, "other_kernel", lambda: "Zen")
    assert len({asked, other, run_key(Config(), 100, "scene")}) == 3

"""The notebooks: stored without outputs, parameterised, and executable through papermill.

Every notebook runs here with a quick parameter set on a tiny closed-loop run of the paper
mission (150 steps per metric, one LiDAR slot of 64 points), so the notebooks cannot rot.
"""

import json

import nbformat
import numpy as np
import pandas as pd
import pytest

from paper_repro import Config, NMPCParams
from paper_repro.analysis import metrics
from paper_repro.config import PREDICTIONS
from paper_repro.paths import notebooks_dir
from paper_repro.sim.result import SimulationResult
from paper_repro.studies import engine as S
from paper_repro.studies import reproduce as R
from paper_repro.studies.catalogue import SENSING_WINDOWS, STUDY_NOTEBOOK_QUICK, make_study
from paper_repro.studies.catalogue import STUDY_NOTEBOOKS as NOTEBOOK_OF_STUDY
from paper_repro.studies.runs import ensure_result

NOTEBOOK_FILES = sorted(notebooks_dir().glob("*.ipynb"))
SPECS = {nb.name: nb for nb in R.NOTEBOOKS}
TINY = Config(nmpc=NMPCParams(region_slots=1, points_per_region=64))
TINY_STEPS = 150
# On top of each notebook's own quick parameters: fewer frames, a coarser tutorial grid.
CI_OVERRIDES = {"08_animation": {"frames": 4}, "07_distance_tutorial": {"grid_points": 40}}


@pytest.fixture(scope="session")
def executed_copies(tmp_path_factory):
    """Where every notebook test leaves its executed copy: the quick run the book is built
    from (``test_the_book_builds_from_the_quick_run``, last in this module)."""
    folder = tmp_path_factory.getbasetemp() / "executed"
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(scope="session")
def tiny_results(tmp_path_factory):
    """Result folders of both metrics, simulated once per session through the cache."""
    cache = tmp_path_factory.getbasetemp() / "tiny-results"
    return {spec.config.distance.metric: ensure_result(spec, cache, progress=False)[0]
            for spec in R.run_specs(max_steps=TINY_STEPS, config=TINY)}


STUDY_NOTEBOOKS = {nb: name for name, nb in NOTEBOOK_OF_STUDY.items()}


def shown_images(notebook) -> int:
    """Image outputs (PNG or GIF) of an executed notebook: the figures its page shows."""
    nb = nbformat.read(notebook, as_version=4)
    return sum(any(k.startswith("image/") for k in o.get("data", {}))
               for c in nb.cells if c.cell_type == "code" for o in c.outputs)


def pictures(files) -> int:
    """How many of ``files`` are pictures a page can show (PNG, GIF)."""
    return sum(str(f).endswith((".png", ".gif")) for f in files)
STUDY_OUTPUTS = {
    "09_monte_carlo": ("mc_summary.csv", "mc_outcome_rates.png", "mc_paired_chattering.png",
                       "mc_clearance_ecdf.png", "mc_solve_times.png"),
    "10_eta_sweep": ("eta_sweep_settings.csv", "eta_sweep_eta.png", "eta_sweep_sigma.png"),
    "13_sensor_noise": ("sensor_noise_paired.csv", "sensor_noise_cost.csv",
                        "sensor_noise_ratios.png"),
    "15_smooth_sensing": ("sensing_window_psi.png", "sensing_window_thrusts.png",
                          "sensing_window_du.png", "sensing_window_study.png",
                          "sensing_window_mission.csv", "sensing_window_rates.csv",
                          "sensing_window_summary.csv", "sensing_window_paired.csv"),
    "16_moving_obstacles": ("moving_obstacles_crossing.csv", "moving_obstacles_clearance.png",
                            "moving_obstacles_thrusts.png", "moving_obstacles_crossing.png",
                            "moving_obstacles.gif", "moving_obstacles_rates.csv",
                            "moving_obstacles_rates.png", "moving_obstacles_summary.csv",
                            "moving_obstacles_paired.csv", "moving_obstacles_paired.png",
                            "moving_obstacles_design_paired.csv"),
    "17_guidance": ("guidance_rates.csv", "guidance_rates.png", "guidance_paired.csv",
                    "guidance_times.csv", "guidance_scene.csv", "guidance_scene.png",
                    "guidance_scene_thrusts.png"),
    "11_timeline": ("timeline_levers.csv", "timeline_levers.png", "timeline_flights.csv",
                    "timeline_flights.png"),
    "18_hardware": ("hardware_cells.csv", "hardware_cells.png", "hardware_margins.csv",
                    "hardware_paired.csv", "hardware_thrusts_wind.csv",
                    "hardware_thrusts_wind.png", "hardware_thrusts_estimate.csv",
                    "hardware_thrusts_estimate.png"),
}
# Study notebooks that also fly: a short mission, cached in the test's folder.
STUDY_OVERRIDES = {"15_smooth_sensing": {"mission": "encounter", "mission_steps": 3000},
                   "16_moving_obstacles": {"crossing_steps": 1500, "frames": 8},
                   "11_timeline": {"quick": True}, "17_guidance": {"scene_steps": 400},
                   "18_hardware": {"passage_steps": 400}}


@pytest.fixture(scope="session")
def quick_studies(tmp_path_factory):
    """Both studies with --quick parameters, their runs in one shared cache."""
    base = tmp_path_factory.getbasetemp() / "studies"
    return {name: S.run_study(make_study(name, quick=True), out=base / name, workers=0,
                              runs_dir=base / "runs", progress=False, log=lambda line: None)
            for name in NOTEBOOK_OF_STUDY}


def test_every_notebook_is_registered_and_every_registered_one_exists():
    assert NOTEBOOK_FILES, "no notebook found"
    assert {p.stem for p in NOTEBOOK_FILES} == set(SPECS) | set(STUDY_NOTEBOOKS) | {TUNING}


@pytest.mark.parametrize("path", NOTEBOOK_FILES, ids=lambda p: p.stem)
def test_source_is_valid_and_carries_no_outputs(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    assert nb.metadata["kernelspec"]["name"] == "python3"
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [], f"{path.name}: a code cell has outputs"
            assert cell.execution_count is None, f"{path.name}: a code cell has a count"
            assert "sys.path" not in cell.source
    assert nb.cells[0].cell_type == "markdown" and nb.cells[0].source.startswith("# ")


@pytest.mark.parametrize("path", NOTEBOOK_FILES, ids=lambda p: p.stem)
def test_exactly_one_parameters_cell_and_reproduce_passes_only_declared_names(path):
    nb = nbformat.read(path, as_version=4)
    tagged = [c for c in nb.cells if "parameters" in c.metadata.get("tags", [])]
    assert len(tagged) == 1 and tagged[0].cell_type == "code"
    declared = R.declared_parameters(path)
    assert "figures_dir" in declared
    if path.stem == TUNING:
        assert "tuning_dir" in declared
        return
    if path.stem in STUDY_NOTEBOOKS:
        assert "study_dir" in declared
        study = next(s for s, nb in NOTEBOOK_OF_STUDY.items() if nb == path.stem)
        # what a --quick study and these tests pass it, it declares
        R.check_parameters(path, {**STUDY_NOTEBOOK_QUICK.get(study, {}),
                                  **STUDY_OVERRIDES.get(path.stem, {})})
        return
    spec = SPECS[path.stem]
    dirs = {m: f"/results/{m}" for m in R.METRICS}
    for quick in (False, True):
        R.check_parameters(path, R.notebook_parameters(spec, dirs, "/figures", quick=quick))


@pytest.mark.parametrize("name", [nb.name for nb in R.NOTEBOOKS])
def test_notebook_executes_with_quick_parameters(name, tiny_results, executed_copies, tmp_path):
    spec = SPECS[name]
    figures = tmp_path / "figures"
    params = R.notebook_parameters(spec, tiny_results, figures, quick=True,
                                   overrides=CI_OVERRIDES.get(name))
    out = R.execute_notebook(R.notebook_path(name), executed_copies / f"{name}.ipynb", params)

    executed = nbformat.read(out, as_version=4)
    code = [c for c in executed.cells if c.cell_type == "code"]
    assert all(c.execution_count is not None for c in code)
    assert not any(o.get("output_type") == "error" for c in code for o in c.outputs)
    assert executed.metadata["papermill"]["parameters"] == json.loads(json.dumps(params))
    for f in spec.outputs:
        assert (figures / f).is_file() and (figures / f).stat().st_size > 0, f
    # every picture it writes is on its page, whatever matplotlib's backend (CI: Agg)
    assert shown_images(out) >= pictures(spec.outputs) >= 1
    if name == "06_summary":
        table = pd.read_csv(figures / "summary.csv", index_col="run")
        timings = pd.read_csv(figures / "summary_timings.csv", index_col="run")
        assert list(table.index) == list(timings.index) == ["paper/smooth", "paper/euclidean"]
        # What the machine measured lives apart from what the flight determines.
        assert not set(metrics.TIMING_COLUMNS) & set(table.columns)
        assert set(timings.columns) == set(metrics.TIMING_COLUMNS)
        assert (table["steps"] == TINY_STEPS).all()
        # Each row against its saved result, recounted here: 1.5 s from the start, far from
        # every cloud, every solve converges and no target is reached.
        for run, row in table.iterrows():
            saved = SimulationResult.load(tiny_results[run.split("/")[1]])
            assert row["failed_solves"] == np.sum(~saved.success) == 0, run
            assert row["outcome"] == saved.outcome == "step_limit" and not row["completed"]
            assert row["targets_reached"] == f"0/{len(saved.targets)}"
            assert np.isnan(row["mission_time_s"]) and np.isnan(row["time_to_complete_s"])
            assert row["min_clearance_m"] == pytest.approx(saved.clearance.min(), rel=1e-5)
            assert row["min_clearance_m"] > 3.0 and not row["collision"]
            assert timings.loc[run, "solve_median_ms"] == pytest.approx(
                1e3 * np.median(saved.solve_time), rel=1e-3)
            assert row["tv_u_N"] == pytest.approx(np.abs(np.diff(saved.u, axis=0)).sum(),
                                                  rel=1e-5)


@pytest.mark.parametrize("name", sorted(STUDY_NOTEBOOKS))
def test_study_notebook_draws_from_the_saved_table(name, quick_studies, executed_copies,
                                                   tmp_path):
    study = quick_studies[STUDY_NOTEBOOKS[name]]
    assert (study.table["status"] == "ok").all(), study.failed["error"].tolist()
    figures = tmp_path / "figures"
    figures.mkdir()
    params = {"study_dir": str(study.directory), "figures_dir": str(figures)}
    if name in STUDY_OVERRIDES:
        params.update(STUDY_OVERRIDES[name])
        if "runs_dir" in R.declared_parameters(R.notebook_path(name)):  # it flies, too
            params["runs_dir"] = str(tmp_path / "runs")
    out = R.execute_notebook(R.notebook_path(name), executed_copies / f"{name}.ipynb", params)
    code = [c for c in nbformat.read(out, as_version=4).cells if c.cell_type == "code"]
    assert not any(o.get("output_type") == "error" for c in code for o in c.outputs)
    for f in STUDY_OUTPUTS[name]:
        assert (figures / f).is_file() and (figures / f).stat().st_size > 0, f
    assert shown_images(out) >= pictures(STUDY_OUTPUTS[name]) >= 1
    if name == "09_monte_carlo":
        rates = pd.read_csv(figures / "mc_summary.csv").query("kind == 'rate'")
        assert set(rates["metric"]) == {"smooth", "euclidean"} and (rates["n"] == 3).all()
        # every run in exactly one class
        per_metric = rates[rates["event"] != "collision"].groupby("metric")["k"].sum()
        assert (per_metric == 3).all()
    elif name == "10_eta_sweep":
        settings = pd.read_csv(figures / "eta_sweep_settings.csv")
        assert len(settings) == 3 and (settings["runs"] == 2).all()
    elif name == "13_sensor_noise":
        paired = pd.read_csv(figures / "sensor_noise_paired.csv")
        assert set(paired["sensor"]) == {"perfect", "noisy", "noisy-map"}
        assert (paired["scenes"] == 2).all()
    elif name == "17_guidance":
        rates = pd.read_csv(figures / "guidance_rates.csv")
        assert set(rates["arm"]) == {"paper", "map", "map+guide"} and (rates["n"] == 2).all()
        per_group = rates[rates["event"] != "collision"].groupby(["arm", "metric"])["k"]
        assert len(per_group) == 6 and (per_group.sum() == 2).all()  # one class per run
        scene = pd.read_csv(figures / "guidance_scene.csv")
        assert list(scene["arm"]) == ["paper", "map", "map+guide"]
        assert (scene["steps"] == 400).all() and scene["set_point_moves"].iloc[:2].eq(0).all()
    elif name == "18_hardware":
        cells = pd.read_csv(figures / "hardware_cells.csv")
        assert set(cells["metric"]) == {"smooth", "euclidean"} and (cells["runs"] == 2).all()
        assert (cells["unsafe_rate"] >= cells["collision_rate"]).all()  # a collision is unsafe
        windy = pd.read_csv(figures / "hardware_thrusts_wind.csv")
        assert list(windy["metric"]) == ["smooth", "euclidean"] and (windy["steps"] <= 400).all()
        noisy = pd.read_csv(figures / "hardware_thrusts_estimate.csv")
        assert list(noisy["cell"]) == ["state estimate mocap", "state estimate mocap, filtered"]
        assert (noisy["metric"] == "smooth").all() and (noisy["steps"] <= 400).all()
    elif name == "16_moving_obstacles":
        rates = pd.read_csv(figures / "moving_obstacles_rates.csv")
        assert set(rates["prediction"]) == set(PREDICTIONS) and (rates["n"] == 2).all()
        assert set(rates["metric"]) == {"smooth", "euclidean"}
        assert set(rates.loc[rates["barrier"] == "design", "prediction"]) == {"oracle", "kalman"}
        per_group = rates[rates["event"] != "collision"].groupby(
            ["barrier", "prediction", "metric"])["k"]
        assert len(per_group) == 10 and (per_group.sum() == 2).all()  # one class per run
        # the crossing flown with each prediction, past the meeting (t = 8 s)
        crossing = pd.read_csv(figures / "moving_obstacles_crossing.csv")
        assert list(crossing["prediction"]) == list(PREDICTIONS)
        # (a run may end before its 1,500 steps: without prediction it can leave the workspace)
        assert (crossing["steps"] <= 1500).all() and (crossing["min_clearance_m"] < 1.0).all()
        assert set(crossing["outcome"]) <= {"step_limit", "left_workspace", "completed"}
        assert crossing["t_closest_s"].between(7.0, 10.0).all()
        paired = pd.read_csv(figures / "moving_obstacles_paired.csv")
        assert set(paired["prediction"]) == {"oracle", "kalman"} and (paired["scenes"] == 2).all()
        design = pd.read_csv(figures / "moving_obstacles_design_paired.csv")
        assert set(design["prediction"]) == {"oracle", "kalman"} and (design["scenes"] == 2).all()
    elif name == "11_timeline":
        from paper_repro.studies.catalogue import CANDIDATES
        from paper_repro.studies.catalogue import TIMELINE_QUICK_STEPS as QUICK_STEPS

        flights = pd.read_csv(figures / "timeline_flights.csv")
        assert list(flights["candidate"]) == list(CANDIDATES)
        assert (flights["steps"] == QUICK_STEPS).all()  # read from the quick study's table
        levers = pd.read_csv(figures / "timeline_levers.csv")
        assert set(levers["lever"]) == {"T", "R", "rate weights", "N", "prediction_ts"}
    else:
        rates = pd.read_csv(figures / "sensing_window_rates.csv")
        assert set(rates["window_m"]) == set(SENSING_WINDOWS) and (rates["n"] == 2).all()
        per_width = rates[rates["event"] != "collision"].groupby("window_m")["k"].sum()
        assert (per_width == 2).all()  # every run in exactly one class
        # the encounter flown with and without the window: points enter and leave the sphere
        mission = pd.read_csv(figures / "sensing_window_mission.csv")
        assert list(mission["window_m"]) == [0.0, 0.5] and (mission["steps"] == 3000).all()
        assert (mission["scan_changes"] > 0).all()
        assert abs(mission["min_clearance_m"].diff().iloc[1]) < 0.05


TUNING = "12_tuning"
TUNING_OUTPUTS = ("tuning_front.png", "tuning_importances.png", "tuning_heldout.png",
                  "tuning_pareto.csv", "tuning_importances.csv", "tuning_heldout_summary.csv")


@pytest.fixture(scope="session")
def quick_tuning(tmp_path_factory):
    """A quick tuning study (σ and d_min on two 60-step passages: at most one new C build),
    its held-out flights on two scenes, all in the test's folders."""
    from paper_repro.studies import tuning
    from paper_repro.studies.tuning_results import run_heldout

    base = tmp_path_factory.getbasetemp() / "tuning"
    settings = tuning.TuningSettings(3, quick=True, base=TINY, seeds=(0, 1), max_steps=60,
                                     space={"sigma": None, "d_min": (1.0, 1.5, 0.5)},
                                     out=base / "out", runs_dir=base / "runs")
    res = tuning.tune(settings, workers=0, log=lambda line: None)
    run_heldout(res, 2, runs_dir=base / "runs", log=lambda line: None)
    return res


def test_tuning_notebook_draws_from_the_saved_study(quick_tuning, executed_copies, tmp_path):
    figures = tmp_path / "figures"
    out = R.execute_notebook(R.notebook_path(TUNING), executed_copies / f"{TUNING}.ipynb",
                             {"tuning_dir": str(quick_tuning.directory),
                              "figures_dir": str(figures), "n_resamples": 200})
    code = [c for c in nbformat.read(out, as_version=4).cells if c.cell_type == "code"]
    assert not any(o.get("output_type") == "error" for c in code for o in c.outputs)
    for f in TUNING_OUTPUTS:
        assert (figures / f).is_file() and (figures / f).stat().st_size > 0, f
    assert shown_images(out) >= pictures(TUNING_OUTPUTS) >= 1
    summary = pd.read_csv(figures / "tuning_heldout_summary.csv")
    rates = summary[summary["kind"] == "rate"]
    assert set(rates["setup"]) == {"printed", "best_chattering", "safest"}
    assert (rates["n"] == 2).all()


def test_unknown_parameter_raises_before_execution(tmp_path):
    out = tmp_path / "never.ipynb"
    with pytest.raises(ValueError, match="smooth_dri") as info:
        R.execute_notebook(R.notebook_path("03_thrusts"), out,
                           {"smooth_dri": "/x", "figures_dir": str(tmp_path)})
    assert "smooth_dir" in str(info.value)  # the message lists what the notebook declares
    assert not out.exists()


def test_notebook_without_parameters_cell_is_rejected(tmp_path):
    path = tmp_path / "untagged.ipynb"
    nbformat.write(nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("a = 1")]), path)
    with pytest.raises(ValueError, match="parameters"):
        R.check_parameters(path, {"a": 2})


def test_study_notebooks_draw_the_committed_figures_from_the_committed_tables(tmp_path):
    """What ``book`` does on a machine where no study was flown: each study notebook executed
    on its committed folder, flying nothing and writing nothing under figures/, draws every
    committed figure and table it makes again byte for byte, and shows its figures."""
    from paper_repro import paths
    from paper_repro.book.site import committed_folder, draw_from_tables

    names = sorted([*STUDY_NOTEBOOKS, TUNING])
    figures, results = paths.figures_dir(), paths.results_dir()

    def snapshot(folder):
        return {p: p.stat().st_mtime_ns for p in folder.rglob("*")} if folder.exists() else {}

    before = snapshot(figures), snapshot(results)
    drawn = draw_from_tables(names, tmp_path / "drawn", log=lambda _: None)
    assert (snapshot(figures), snapshot(results)) == before  # nothing flown, nothing written
    for name in names:
        d = drawn[name]
        assert not d.reused and d.differing == (), (name, d.differing)
        committed = {p.name for p in committed_folder(name).iterdir()}
        made = [p.name for p in d.figures.iterdir()]
        assert pictures(set(made) & committed) >= 1, name  # it drew committed figures again
        code = [c for c in nbformat.read(d.notebook, as_version=4).cells if c.cell_type == "code"]
        assert not any(o.get("output_type") == "error" for c in code for o in c.outputs)
        shown = pictures(committed - {"evidence.json"})  # its own and the flights' figures
        assert shown_images(d.notebook) >= shown, name
    again = draw_from_tables(names[:1], tmp_path / "drawn", log=lambda _: None)
    assert again[names[0]].reused  # same notebook, tables and code: the copy is kept


@pytest.fixture(scope="module")
def quick_book(executed_copies, tmp_path_factory):
    """The book, built (warnings are errors) from the notebooks the tests above executed."""
    from paper_repro.book.site import build

    return build(quick=True, executed=executed_copies, out=tmp_path_factory.mktemp("book"),
                 log=lambda _: None, strict=True)


def test_the_book_builds_from_the_quick_run(quick_book):
    """A page per notebook with its outputs and figures, every page of docs/, the API
    reference. Run alone, it fails naming the notebooks that were not executed and the command
    for each."""
    from paper_repro.book.site import notebook_names

    html = quick_book.parent
    for name in notebook_names():
        page = (html / "notebooks" / f"{name}.html").read_text()
        assert "cell_output" in page, f"{name}: the page shows no output"
        assert "<img" in page, f"{name}: the page shows no figure"
    for page in ("reproduction", "method", "solvers", "usage", "own_model", "failures",
                 "contributing", "api", "studies/index", "studies/monte_carlo"):
        assert (html / f"{page}.html").is_file(), page
    assert list((html / "generated").glob("paper_repro.solvers.rti.html"))


def test_every_notebook_page_shows_a_figure_in_a_browser(quick_book, site_check, tmp_path):
    """docs/check_site.py on the quick book: every image loads, every notebook page shows a
    figure, no console error, every internal link resolves."""
    from paper_repro.book.site import notebook_names

    html = quick_book.parent
    assert site_check.check_site(html, tmp_path / "shots") == []
    shots = {p.stem for p in (tmp_path / "shots").glob("*.png")}
    assert {f"notebooks_{name}" for name in notebook_names()} <= shots

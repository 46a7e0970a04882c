"""Issue 10: bad input is refused before anything flies, with one line naming the parameter
and its accepted range; shapes are checked, never reshaped; the LiDAR's imperfections."""

import dataclasses
import math

import numpy as np
import pytest

from paper_repro import (
    Config,
    DistanceParams,
    NMPCParams,
    SimulationParams,
    SolverParams,
    make_scene,
)
from paper_repro.config import BarrierParams, QuadrotorParams, SensorParams
from paper_repro.problem.ocp import OCP
from paper_repro.problem.scan import check_visible
from paper_repro.sim.checks import check_setup, setup_hazards
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.solvers.rti import RealTimeNMPC
from paper_repro.world.lidar import Lidar
from paper_repro.world.scene import Region
from paper_repro.world.shapes import Box, Cylinder, Difference, Union

SMALL = NMPCParams(region_slots=1, points_per_region=48)


def _one_line(exc_info) -> str:
    message = str(exc_info.value)
    assert "\n" not in message
    return message


@pytest.fixture(scope="module")
def encounter():
    return make_scene("encounter")


# --- config: cross-field and type checks ----------------------------------------------------

@pytest.mark.parametrize("lower, upper, index", [
    ("state_lower", "state_upper", 2), ("state_lower", "state_upper", 7),
    ("input_lower", "input_upper", 1)])
def test_bounds_must_be_ordered(lower, upper, index):
    """lower > upper (or equal) in 𝒳 or 𝒰 is refused, naming the index and both fields (it
    used to be accepted and to fail inside HPIPM at the first solve)."""
    p = QuadrotorParams()
    lo = list(getattr(p, lower))
    hi = list(getattr(p, upper))
    lo[index], hi[index] = hi[index] + 1.0, lo[index]
    with pytest.raises(ValueError) as exc:
        QuadrotorParams(**{lower: tuple(lo), upper: tuple(hi)})
    assert f"{lower}[{index}]" in _one_line(exc) and f"{upper}[{index}]" in str(exc.value)


def test_hover_must_be_an_admissible_input():
    """An input box that does not hold the hover thrust has no artificial equilibrium."""
    with pytest.raises(ValueError, match=r"input_lower/input_upper .*hover thrust") as exc:
        Config(quadrotor=QuadrotorParams(input_upper=(5.0, 5.0, 5.0, 5.0)))
    _one_line(exc)


@pytest.mark.parametrize("make, name", [
    (lambda: NMPCParams(horizon=True), "horizon"),
    (lambda: NMPCParams(ts=True), "ts"),
    (lambda: NMPCParams(lam="0.99"), "lam"),
    (lambda: NMPCParams(q=(1.0,) * 11 + (True,)), "q"),
    (lambda: QuadrotorParams(mass=True), "mass"),
    (lambda: QuadrotorParams(inertia=1.0), "inertia"),
    (lambda: BarrierParams(delta="0.5"), "delta"),
    (lambda: SimulationParams(max_steps=True), "max_steps"),
    (lambda: SimulationParams(scenario=""), "scenario"),
    (lambda: Config(nmpc={"horizon": 35}), "nmpc"),
])
def test_fields_are_type_checked(make, name):
    """Every public field is checked, types included (a bool is not an integer setting)."""
    with pytest.raises(ValueError) as exc:
        make()
    assert _one_line(exc).startswith(name)


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_simulation_seed_names_itself(seed):
    """A bad seed names ``seed`` and the range (it used to surface from numpy as 'expected
    non-negative integer')."""
    with pytest.raises(ValueError, match=r"^seed must be an integer >= 0") as exc:
        SimulationParams(seed=seed)
    _one_line(exc)


def test_old_config_without_sensor_loads_with_a_perfect_sensor():
    data = Config().to_dict()
    del data["sensor"]
    cfg = Config.from_dict(data)
    assert cfg.sensor == SensorParams() and cfg.sensor.perfect
    assert Config.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError, match="unknown parts"):
        Config.from_dict({**data, "sensors": {}})


# --- safety: the mission before it flies ----------------------------------------------------

@pytest.mark.parametrize("start, field", [((22.0, -22.0, -0.5), "scene.start[2]"),
                                          ((26.0, 0.0, 2.0), "scene.start[0]")])
def test_start_outside_the_admissible_state_set(encounter, start, field):
    """A start below the floor or outside the workspace is refused (every step used to be
    ``qp_failed``)."""
    scene = dataclasses.replace(encounter, start=start, clouds=encounter.clouds)
    with pytest.raises(ValueError) as exc:
        check_setup(Config(), scene)
    assert _one_line(exc).startswith(field) and "[" in str(exc.value)


def test_target_outside_the_workspace(encounter):
    """A target above the ceiling is refused (it used to be flown without a word)."""
    scene = dataclasses.replace(encounter, targets=((0.0, 0.0, 30.0),), clouds=encounter.clouds)
    pattern = r"^scene\.targets\[0\]\[2\] .*\[0, 25\] m.*workspace"
    with pytest.raises(ValueError, match=pattern) as exc:
        check_setup(Config(), scene)
    _one_line(exc)


def test_setup_hazards_reports_an_unsafe_start_and_target(encounter):
    """A start inside a region and a target on a cloud point are allowed but reported."""
    cloud = encounter.clouds[0]
    start = tuple(cloud.mean(axis=0))
    target = tuple(cloud[0])
    scene = dataclasses.replace(encounter, start=start, targets=(target, (20.0, 0.0, 2.0)),
                                clouds=encounter.clouds)
    for metric in ("smooth", "euclidean"):
        cfg = Config(distance=DistanceParams(metric=metric))
        h = setup_hazards(cfg, scene)
        assert h["start_unsafe"] and h["targets_unsafe"] == [True, False]
        assert h["target_clearance_m"][0] == 0.0
        assert h["start_distance_m2"] < cfg.barrier.d_min
        assert len(h["warnings"]) == 2 and all("\n" not in w for w in h["warnings"])
    clean = setup_hazards(Config(), encounter)
    assert not clean["start_unsafe"] and clean["warnings"] == []


def test_setup_hazards_reports_an_unreachable_target(encounter):
    """A target on the wall farther than the tolerance from λ(𝒳) cannot be reached."""
    cfg = Config(nmpc=NMPCParams(lam=0.9))  # λ(𝒳) ends 1.25 m below the 25 m ceiling
    scene = dataclasses.replace(encounter, targets=((0.0, 0.0, 25.0),), clouds=encounter.clouds)
    h = setup_hazards(cfg, scene)
    assert h["targets_unreachable"] == [True] and "cannot be reached" in h["warnings"][0]


# --- scene: shapes, regions, LiDAR ----------------------------------------------------------

@pytest.mark.parametrize("make, name", [
    (lambda: Box((0.0, 0.0, 1.0), (1.0, -2.0, 1.0)), "Box.size"),
    (lambda: Box((0.0, 0.0, 1.0), (1.0, 0.0, 1.0)), "Box.size"),
    (lambda: Box((0.0, math.nan, 1.0), (1.0, 1.0, 1.0)), "Box.center"),
    (lambda: Box((0.0, 1.0), (1.0, 1.0, 1.0)), "Box.center"),
    (lambda: Cylinder((0.0, 0.0, 0.0), -1.0, 2.0), "Cylinder.radius"),
    (lambda: Cylinder((0.0, 0.0, 0.0), 1.0, math.inf), "Cylinder.height"),
    (lambda: Union(()), "Union.parts"),
    (lambda: Union((Box((0, 0, 0), (1, 1, 1)), "box")), "Union.parts[1]"),
    (lambda: Difference(Box((0, 0, 0), (1, 1, 1)), None), "Difference.inner"),
    (lambda: Region("", Box((0, 0, 0), (1, 1, 1))), "Region.name"),
    (lambda: Region("r", Box((0, 0, 0), (1, 1, 1)), density=True), "density"),
])
def test_shapes_and_regions_are_checked_at_construction(make, name):
    """A negative size or radius is refused when the shape is made, naming the field (it used
    to surface later as scipy's 'Bounds are not consistent')."""
    with pytest.raises(ValueError) as exc:
        make()
    assert _one_line(exc).startswith(name)


def test_scene_seed_is_checked(encounter):
    with pytest.raises(ValueError, match=r"^seed must be an integer >= 0"):
        dataclasses.replace(encounter, seed=-1, clouds=None)


def test_lidar_cloud_with_nan_rows_names_the_cloud(encounter):
    """A NaN row names ``clouds[i]`` and the row (it used to say 'data must be finite')."""
    bad = encounter.clouds[0].copy()
    bad[5, 1] = np.nan
    with pytest.raises(ValueError, match=r"^clouds\[1\] .*finite.*row 5") as exc:
        Lidar([encounter.clouds[0], bad])
    _one_line(exc)


def test_lidar_never_reshapes_a_cloud():
    """A (3, 2) cloud is refused with its shape (it used to be read as (2, 3)); a bare
    array of clouds is refused too."""
    with pytest.raises(ValueError, match=r"^clouds\[0\] .*\(m, 3\).*\(3, 2\)"):
        Lidar([np.zeros((3, 2))])
    with pytest.raises(ValueError, match=r"^clouds must be a sequence.*wrap"):
        Lidar(np.zeros((4, 3)))


# --- the one form of `visible` --------------------------------------------------------------

def _config(solver):
    return Config(simulation=SimulationParams(scenario="encounter"), nmpc=SMALL,
                  solver=SolverParams(nlp_solver=solver))


@pytest.mark.parametrize("visible, pattern", [
    (np.full((5, 3), 1.0), r"^visible must be a list or tuple .*wrap"),
    ([np.zeros((3, 2))], r"^visible\[0\] must be a \(k, 3\) array .*\(3, 2\)"),
    ([np.zeros((0, 3)), np.zeros(6)], r"^visible\[1\] .*\(6,\)"),
    ([np.array([[0.0, np.nan, 1.0]])], r"^visible\[0\] must hold finite"),
    ([["a", "b", "c"]], r"^visible\[0\]"),
])
def test_pack_scan_accepts_one_form_only(visible, pattern):
    """A bare (k, 3) array is refused (it used to become k regions of one point each), and a
    (3, 2) region is refused rather than read as (2, 3)."""
    with pytest.raises(ValueError, match=pattern):
        OCP(_config("rti")).scan.pack(visible, np.zeros(3))


def test_check_visible_accepts_the_documented_form_without_copying():
    a, b = np.ones((4, 3)), np.zeros((0, 3))
    checked = check_visible([a, b])
    assert checked[0] is a and checked[1] is b
    assert check_visible(checked) is checked
    assert check_visible(()) == () and check_visible([[[1, 2, 3]]])[0].shape == (1, 3)


@pytest.mark.parametrize("make", [lambda c: RealTimeNMPC(c),
                                  lambda c: TrackingNMPC(dataclasses.replace(
                                      c, solver=SolverParams(nlp_solver="reference")))])
def test_solvers_refuse_a_bare_array(make, encounter):
    """Both solvers refuse a bare (k, 3) array before solving (the RTI solver used to return
    success=True with u0 ≈ [11.7, 3.6, 0, 0] N)."""
    ctl = make(_config("rti"))
    x0 = np.zeros(12)
    x0[:3] = (-18.0, 0.5, 2.0)
    with pytest.raises(ValueError, match="wrap"):
        ctl.solve(x0, (20.0, 0.0, 2.0), encounter.clouds[0][:10])
    with pytest.raises(ValueError, match=r"visible\[0\]"):
        ctl.solve(x0, (20.0, 0.0, 2.0), [encounter.clouds[0][:10].T.copy()])


# --- command line ---------------------------------------------------------------------------

def test_cli_out_existing_file_fails_before_flying(tmp_path, capsys):
    """``--out`` naming an existing file is refused at once (it used to fly the mission and
    then die with a FileExistsError traceback)."""
    from paper_repro.cli.parser import main

    existing = tmp_path / "result"
    existing.write_text("")
    assert main(["run", "--scenario", "encounter", "--max-steps", "1", "--out",
                 str(existing), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --out must be a directory") and "\n" not in err


@pytest.mark.parametrize("argv, name", [
    (["run", "--max-steps", "0", "--out", "x"], "--max-steps"),
    (["run", "--scenario", "moon", "--out", "x"], "--scenario"),
    (["run"], "--out"),
])
def test_cli_option_errors_are_one_line(argv, name, capsys):
    """argparse's errors print one line ``error: ...`` and return 2 (no usage dump)."""
    from paper_repro.cli.parser import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and name in err and "\n" not in err


# --- sensor model ---------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, name", [
    (dict(range_noise=-0.1), "range_noise"), (dict(range_noise=math.nan), "range_noise"),
    (dict(dropout=1.0), "dropout"), (dict(dropout=-0.1), "dropout"),
    (dict(spurious_rate=math.inf), "spurious_rate"), (dict(seed=-1), "seed"),
    (dict(seed=True), "seed"),
])
def test_sensor_params_are_checked(kwargs, name):
    with pytest.raises(ValueError) as exc:
        SensorParams(**kwargs)
    assert _one_line(exc).startswith(name)


def _positions(scene, rng, n=30):
    pts = scene.all_points
    return pts[rng.choice(len(pts), n)] + rng.normal(scale=1.0, size=(n, 3))


def test_perfect_sensor_is_the_clean_scan(encounter, rng):
    """Off by default: no noise argument, or default SensorParams, give the clean scan."""
    clean = Lidar(encounter.clouds, 3.0)
    default = Lidar(encounter.clouds, 3.0, noise=SensorParams(seed=9))
    for p in _positions(encounter, rng):
        for a, b, cloud in zip(clean.scan(p), default.scan(p), encounter.clouds, strict=True):
            expected = cloud[np.linalg.norm(cloud - p, axis=1) <= 3.0]
            np.testing.assert_array_equal(a, expected)
            np.testing.assert_array_equal(b, expected)


def test_noisy_scans_are_seeded_and_reset_replays_them(encounter, rng):
    noise = SensorParams(range_noise=0.05, dropout=0.2, spurious_rate=2.0, seed=3)
    positions = _positions(encounter, rng, 10)
    a, b = Lidar(encounter.clouds, 3.0, noise), Lidar(encounter.clouds, 3.0, noise)
    first = [a.scan(p) for p in positions]
    again = [b.scan(p) for p in positions]
    a.reset()
    replay = [a.scan(p) for p in positions]
    other = Lidar(encounter.clouds, 3.0, dataclasses.replace(noise, seed=4))
    different = [other.scan(p) for p in positions]
    for s1, s2, s3 in zip(first, again, replay, strict=True):
        for x, y, z in zip(s1, s2, s3, strict=True):
            np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(x, z)
    assert any(not np.array_equal(x, y) for s1, s4 in zip(first, different, strict=True)
               for x, y in zip(s1, s4, strict=True))


def test_dropout_rate_and_range_noise_are_as_configured(encounter):
    """Over many scans the kept fraction is 1 − dropout, and the measured ranges differ from
    the true ones by 𝒩(0, σ²) along the ray (the direction is exact)."""
    cloud = encounter.clouds[0]
    p = cloud.mean(axis=0) + np.array([0.0, -2.0, 0.0])
    truth = Lidar(encounter.clouds, 3.0).scan(p)[0]
    assert len(truth) > 10

    dropout = Lidar(encounter.clouds, 3.0, SensorParams(dropout=0.3, seed=1))
    scans = 400
    kept = sum(len(dropout.scan(p)[0]) for _ in range(scans))
    n = scans * len(truth)
    assert abs(kept / n - 0.7) < 4 * math.sqrt(0.3 * 0.7 / n)

    sigma = 0.05
    noisy = Lidar(encounter.clouds, 3.0, SensorParams(range_noise=sigma, seed=2))
    errors = []
    for _ in range(scans):
        got = noisy.scan(p)[0]
        assert got.shape == truth.shape
        ray, measured = truth - p, got - p
        np.testing.assert_allclose(np.cross(ray, measured), 0.0, atol=1e-12)
        errors.append(np.linalg.norm(measured, axis=1) - np.linalg.norm(ray, axis=1))
    errors = np.concatenate(errors)
    assert abs(errors.mean()) < 4 * sigma / math.sqrt(len(errors))
    assert errors.std() == pytest.approx(sigma, rel=0.05)


def test_spurious_returns_lie_in_the_sphere_and_go_to_the_nearest_region():
    """K ~ Poisson(rate) spurious points per scan, uniform in the sensing ball, each given to
    the region whose cloud holds the nearest point."""
    clouds = [np.array([[10.0, 0.0, 5.0]]), np.array([[-10.0, 0.0, 5.0]])]
    rate, r_s, scans = 3.0, 2.0, 600
    lidar = Lidar(clouds, r_s, SensorParams(spurious_rate=rate, seed=5))
    counts, radii = [], []
    for _ in range(scans):
        p = np.array([np.random.default_rng(len(counts)).uniform(-3, 3), 0.0, 5.0])
        left, right = lidar.scan(p)
        assert np.all(left[:, 0] - p[0] > -r_s) and np.all(right[:, 0] - p[0] < r_s)
        assert np.all(np.abs(left[:, 0] - 10.0) <= np.abs(left[:, 0] + 10.0))
        assert np.all(np.abs(right[:, 0] + 10.0) <= np.abs(right[:, 0] - 10.0))
        both = np.vstack([left, right])
        counts.append(len(both))
        radii.append(np.linalg.norm(both - p, axis=1))
    radii = np.concatenate(radii)
    assert np.all(radii <= r_s)
    assert np.mean(counts) == pytest.approx(rate, abs=4 * math.sqrt(rate / scans))
    # uniform in volume: P(r ≤ r_s/2) = 1/8
    assert np.mean(radii <= r_s / 2) == pytest.approx(1 / 8, abs=0.03)


@pytest.mark.parametrize("state", [np.zeros(11), np.full(12, np.nan), [[0.0] * 12]])
def test_initial_state_is_checked_before_anything_is_built(state, monkeypatch):
    from paper_repro.sim import loop as sim

    monkeypatch.setattr(sim, "make_controller", lambda *a, **k: pytest.fail("built"))
    with pytest.raises(ValueError, match="initial_state must be a finite \\(12,\\) state"):
        sim.simulate(max_steps=1, progress=False, initial_state=state)

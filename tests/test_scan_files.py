"""Your own scene from scan files: every format reads back the points it was written with, the
stated rules (placement, regions, thinning) hold, bad files are refused naming the file, the
command line reaches every setting, and a scan flies."""

from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np
import pytest

from paper_repro import cli
from paper_repro.analysis.metrics import COLLISION_CLEARANCE
from paper_repro.cli.parser import COMMANDS
from paper_repro.config import Config
from paper_repro.sim.result import SimulationResult
from paper_repro.world.scan_files import SCANS_INSTALL, MissingExtraError, read_scan
from paper_repro.world.scan_regions import (
    FINEST_SIDE,
    fit_region,
    fits,
    max_ball_count,
    place_scan,
    scan_regions,
    scan_scene,
    split_regions,
    voxel_centroids,
)

plyfile = pytest.importorskip("plyfile")
pypcd4 = pytest.importorskip("pypcd4")


# --- writers (the well-kept libraries' own, so the readers meet real files) ------------------

def write_ply(path, points, text: bool, names=("x", "y", "z")):
    vertex = np.array([tuple(p) for p in points], dtype=[(n, "f8") for n in names])
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")], text=text).write(str(path))
    return path


def write_pcd(path, points, encoding: str, names=("x", "y", "z")):
    cloud = pypcd4.PointCloud.from_points(np.asarray(points, np.float64), names,
                                          [np.float64] * len(names))
    cloud.save(path, encoding=pypcd4.Encoding(encoding))
    return path


def box_points(rng, lower, size=1.0, n=200) -> np.ndarray:
    """``n`` points uniform in the cube [lower, lower + size]³, m, on a 1 mm grid (exact in
    text)."""
    return np.round(rng.uniform(0, size, (n, 3)) + np.asarray(lower, float), 3)


def partition(groups) -> set:
    return {frozenset(map(int, g)) for g in groups}


# --- every format reads back its points --------------------------------------------------------

@pytest.mark.parametrize("kind", ["ply-ascii", "ply-binary", "pcd-ascii", "pcd-binary",
                                  "pcd-binary_compressed", "npy", "npy-structured", "npz",
                                  "npz-xyz", "csv", "csv-header", "xyz", "txt"])
def test_every_format_reads_back_the_points_it_was_written_with(kind, tmp_path, rng):
    points = box_points(rng, (1.0, -2.0, 3.0), 2.0, 50)
    if kind.startswith("ply"):
        path = write_ply(tmp_path / "s.ply", points, text=kind == "ply-ascii")
    elif kind.startswith("pcd"):
        path = write_pcd(tmp_path / "s.pcd", points, kind.split("-")[1])
    elif kind == "npy":
        path = tmp_path / "s.npy"
        np.save(path, points)
    elif kind == "npy-structured":
        path = tmp_path / "s.npy"
        arr = np.zeros(len(points), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"),
                                           ("intensity", "f4")])
        for i, k in enumerate("xyz"):
            arr[k] = points[:, i]
        np.save(path, arr)
    elif kind == "npz":
        path = tmp_path / "s.npz"
        np.savez(path, points=points, intensity=np.ones(len(points)))
    elif kind == "npz-xyz":
        path = tmp_path / "s.npz"
        np.savez(path, x=points[:, 0], y=points[:, 1], z=points[:, 2])
    elif kind == "csv-header":  # columns in another order, and one more
        path = tmp_path / "s.csv"
        rows = [f"{p[2]},{7},{p[0]},{p[1]}" for p in points]
        path.write_text("# a comment\nZ,intensity,X,Y\n" + "\n".join(rows) + "\n")
    else:
        path = tmp_path / f"s.{kind}"
        sep = {"csv": ", ", "xyz": " ", "txt": "\t"}[kind]
        path.write_text("\n".join(sep.join(f"{v:.3f}" for v in (*p, 0.5)) for p in points))
    read = read_scan(path)
    assert read.shape == points.shape and read.dtype == np.float64
    np.testing.assert_allclose(read, points, rtol=0, atol=1e-12)


def test_a_missing_extra_is_named_with_its_install_command(tmp_path, rng, monkeypatch):
    path = write_ply(tmp_path / "s.ply", box_points(rng, (0, 0, 0)), text=True)
    pcd = write_pcd(tmp_path / "s.pcd", box_points(rng, (0, 0, 0)), "ascii")
    monkeypatch.setitem(sys.modules, "plyfile", None)  # import plyfile now fails
    monkeypatch.setitem(sys.modules, "pypcd4", None)
    for file in (path, pcd):
        with pytest.raises(MissingExtraError, match="extra 'scans'") as info:
            read_scan(file)
        assert SCANS_INSTALL in str(info.value) and str(file) in str(info.value)
        assert isinstance(info.value, ValueError)


# --- bad files are refused, naming the file ----------------------------------------------------

def _bad_files(tmp_path, rng):
    good = box_points(rng, (0, 0, 0))
    with_nan = good.copy()
    with_nan[3, 1] = np.nan
    files = {}
    files["missing"] = (tmp_path / "nothere.ply", "does not exist")
    (tmp_path / "scan.las").write_bytes(b"LASF")
    files["extension"] = (tmp_path / "scan.las", "unknown extension '.las'")
    (tmp_path / "empty.csv").write_text("# only a comment\n")
    files["empty text"] = (tmp_path / "empty.csv", "holds no point")
    np.save(tmp_path / "empty.npy", np.zeros((0, 3)))
    files["empty array"] = (tmp_path / "empty.npy", "holds no point")
    np.save(tmp_path / "nan.npy", with_nan)
    files["non-finite array"] = (tmp_path / "nan.npy", "non-finite coordinate.*index 3")
    (tmp_path / "inf.csv").write_text("0,0,0\n1,inf,2\n")
    files["non-finite text"] = (tmp_path / "inf.csv", "non-finite coordinate.*index 1")
    files["non-finite ply"] = (write_ply(tmp_path / "nan.ply", with_nan, text=False),
                               "non-finite")
    np.save(tmp_path / "flat.npy", good[:, :2])
    files["two columns"] = (tmp_path / "flat.npy", r"shape \(m, 3\)")
    np.savez(tmp_path / "keys.npz", a=good, b=good)
    files["npz keys"] = (tmp_path / "keys.npz", "'points'")
    (tmp_path / "header.csv").write_text("a,b,c\n1,2,3\n")
    files["text header"] = (tmp_path / "header.csv", "must name columns x, y and z")
    (tmp_path / "short.xyz").write_text("1 2 3\n4 5\n")
    files["text row"] = (tmp_path / "short.xyz", "line 2 has 2 column")
    (tmp_path / "word.txt").write_text("1 2 3\n4 five 6\n")
    files["text value"] = (tmp_path / "word.txt", "line 2 holds a value that is not a number")
    files["ply fields"] = (write_ply(tmp_path / "xyw.ply", good, text=True, names="xyw"),
                           "properties x, y and z")
    files["pcd fields"] = (write_pcd(tmp_path / "xyi.pcd", good, "binary", ("x", "y", "i")),
                           "fields x, y and z")
    (tmp_path / "junk.ply").write_bytes(b"this is not a ply file\n")
    files["junk ply"] = (tmp_path / "junk.ply", "cannot be read as PLY")
    (tmp_path / "junk.pcd").write_bytes(b"\x00\x01garbage")
    files["junk pcd"] = (tmp_path / "junk.pcd", "cannot be read as PCD")
    return files


def test_every_bad_file_is_refused_naming_the_file_and_what_is_wrong(tmp_path, rng, capsys):
    for case, (path, why) in _bad_files(tmp_path, rng).items():
        with pytest.raises(ValueError, match=why) as info:
            read_scan(path)
        assert str(path) in str(info.value), case
        # the same refusal from the command line: one line, exit 2, nothing flown
        assert cli.main(["run", "--cloud", str(path), "--start=-5,0,3", "--target",
                         "20,0,3", "--out", str(tmp_path / "out")]) == 2, case
        err = capsys.readouterr().err
        assert str(path) in err and len(err.strip().splitlines()) == 1, case


def test_a_region_that_cannot_fit_is_refused_before_any_solve(tmp_path, rng, capsys):
    dense = np.round(rng.uniform(0, 4, (4000, 3)) + [2, 2, 2], 3)
    path = tmp_path / "dense.npy"
    np.save(path, dense)
    tight = dataclasses.replace(Config(), nmpc=dataclasses.replace(Config().nmpc,
                                                                   points_per_region=5))
    with pytest.raises(ValueError, match="cannot fit a region slot") as info:
        scan_regions([path], tight)
    assert str(path) in str(info.value) and "nmpc.points_per_region" in str(info.value)
    assert cli.main(["run", "--cloud", str(path), "--start=-5,0,3", "--target", "20,0,3",
                     "--set", "nmpc.points_per_region=5", "--out", str(tmp_path / "o")]) == 2
    assert "cannot fit" in capsys.readouterr().err


@pytest.mark.parametrize("start, target, why", [
    ("2.5,2.5,2.5", "20,2.5,2.5", "--start lies .* within the rotor radius"),
    ("-5,0,3", "30,0,3", r"scene.targets\[0\]\[0\] \(x\) must lie in \[-25, 25\]"),
    ("-5,0,-1", "20,0,3", r"scene.start\[2\] \(z\) must lie in"),
    ("-5,0,3", "3,0,3", "target must lie more than 2 m past the farthest cloud point")])
def test_a_start_or_target_inside_the_clouds_or_outside_the_workspace_is_refused(
        start, target, why, tmp_path, rng, capsys):
    path = tmp_path / "box.npy"
    np.save(path, box_points(rng, (2, 2, 2), 1.0, 100))
    assert cli.main(["run", "--cloud", str(path), f"--start={start}", f"--target={target}",
                     "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and len(err.strip().splitlines()) == 1
    assert __import__("re").search(why, err), err


# --- the rules: regions, thinning, placement ----------------------------------------------------

def test_two_separated_boxes_are_two_regions_and_one_box_is_one(rng):
    a, b = box_points(rng, (0, 0, 0)), box_points(rng, (3.5, 0, 0))
    both = np.concatenate([a, b])
    assert partition(split_regions(both, 1.0)) == {frozenset(range(200)),
                                                    frozenset(range(200, 400))}
    assert len(split_regions(a, 1.0)) == 1
    # points closer than h share a region: the same boxes 0.5 m apart are one at h = 1 m
    near = np.concatenate([a, a + [1.5, 0, 0]])
    assert len(split_regions(near, 1.0)) == 1
    # ... and two regions are more than h apart
    for h in (0.3, 0.7, 1.5):
        groups = split_regions(both, h)
        for i, g in enumerate(groups):
            for other in groups[i + 1:]:
                gap = np.min(np.linalg.norm(both[g][:, None] - both[other][None], axis=2))
                assert gap > h


def test_the_regions_do_not_depend_on_the_order_of_the_points(rng):
    both = np.concatenate([box_points(rng, (0, 0, 0)), box_points(rng, (0, 4, 1))])
    order = rng.permutation(len(both))
    assert partition(order[g] for g in split_regions(both[order], 1.0)) == partition(
        split_regions(both, 1.0))


def test_thinning_keeps_each_centroid_in_a_voxel_of_its_points_and_fits_the_slot(rng):
    cloud = rng.uniform(0, 2, (3000, 3))
    for side in (0.1, 0.37, 1.0):
        centroids = voxel_centroids(cloud, side)
        keys = {tuple(k) for k in np.floor(cloud / side).astype(int)}
        assert {tuple(k) for k in np.floor(centroids / side).astype(int)} == keys
        assert len(centroids) == len(keys)
        for c in centroids[:20]:  # each is the mean of its voxel's points
            inside = np.all(np.floor(cloud / side).astype(int) == np.floor(c / side), axis=1)
            np.testing.assert_allclose(c, cloud[inside].mean(axis=0))
    kept, side = fit_region(cloud, 120, 3.0, math.sqrt(2.0))
    assert 0 < side and max_ball_count(kept, 3.0, 120) <= 120 < len(cloud)
    finer = side / math.sqrt(2)  # the next side of the ladder does not fit
    assert finer >= FINEST_SIDE and not fits(voxel_centroids(cloud, finer), 120, 3.0)
    # a region that fits keeps its points
    sparse = cloud[:100]
    assert fit_region(sparse, 120, 3.0, math.sqrt(2.0))[1] == 0.0
    np.testing.assert_array_equal(fit_region(sparse, 120, 3.0, math.sqrt(2.0))[0], sparse)


def test_placement_scales_then_offsets_and_the_regions_move_with_it(rng, tmp_path):
    points = np.concatenate([box_points(rng, (0, 0, 0), 1.0, 60),
                             box_points(rng, (0, 3.5, 0), 1.0, 60)])
    scale, h = 2.5, 1.0
    offset = np.array([3.0, -2.0, 1.0]) * h * scale  # whole voxels of the placed grid
    placed = place_scan(points, scale, offset)
    np.testing.assert_allclose(placed, scale * points + offset)
    np.testing.assert_allclose(place_scan(points), points)
    # the partition is invariant: scale the voxel with the scan, offset by whole voxels
    assert partition(split_regions(placed, scale * h)) == partition(split_regions(points, h))
    # a scene's regions move with the offset (regions under the capacity keep their points)
    np.save(tmp_path / "s.npy", points)
    start, target = np.array([-4.0, 2.0, 3.0]), np.array([15.0, 2.0, 3.0])
    base = scan_scene([tmp_path / "s.npy"], start, target)
    moved = scan_scene([tmp_path / "s.npy"], start + [1, 2, 3], target + [1, 2, 3],
                       offset=(1, 2, 3))
    assert len(base.clouds) == len(moved.clouds) == 2
    for a, b in zip(base.clouds, moved.clouds, strict=True):
        np.testing.assert_allclose(b, a + [1, 2, 3])
    np.testing.assert_allclose(np.asarray(moved.finish[0]), np.asarray(base.finish[0]) + [1, 2, 3])
    for bad, name in ((0.0, "scale"), (-1.0, "scale"), (math.inf, "scale")):
        with pytest.raises(ValueError, match=name):
            place_scan(points, bad)
    with pytest.raises(ValueError, match="offset"):
        place_scan(points, 1.0, (1, 2))


# --- the command line reaches the whole configuration -----------------------------------------

def _run_args(*argv):
    import argparse

    parser = argparse.ArgumentParser()
    COMMANDS["run"].add_arguments(parser)
    return parser.parse_args(["--out", "unused", *argv])


def test_set_reaches_any_field_as_the_dataclasses_take_it():
    from paper_repro.cli.run import run_config

    cfg = run_config(_run_args("--set", "distance.eta=0.2", "--set", "nmpc.q=[1,1,1,0.1,0.1,1,"
                               "1,1,1,10,10,2]", "--set", "solver.line_search=true",
                               "--set", "distance.metric=euclidean",
                               "--set", "nmpc.prediction_ts=null", "--set", "distance.eta=0.25",
                               "--guide", "grid", "--map-voxel", "0.5"))
    printed = Config()
    assert cfg == dataclasses.replace(
        printed,
        distance=dataclasses.replace(printed.distance, eta=0.25, metric="euclidean"),
        nmpc=dataclasses.replace(printed.nmpc, q=(1, 1, 1, 0.1, 0.1, 1, 1, 1, 1, 10, 10, 2)),
        solver=dataclasses.replace(printed.solver, line_search=True),
        sensor=dataclasses.replace(printed.sensor, map_voxel=0.5),
        guide=dataclasses.replace(printed.guide, planner="grid"))
    assert isinstance(cfg.nmpc.q, tuple)


@pytest.mark.parametrize("assignment, named", [
    ("distanc.eta=1", "unknown section 'distanc'"),
    ("distance.et=1", "distance has no field 'et'"),
    ("distance.eta=-1", "distance.eta must be a finite number > 0"),
    ("nmpc.horizon=3.5", "nmpc.horizon must be an integer >= 1"),
    ("solver.line_search=yes", "solver.line_search must be True or False"),
    ("barrier.sweep_time=1", "barrier.sweep_time needs nmpc.prediction"),
    ("guide.planner=grid", "guide.planner 'grid' plans on the local map"),
    ("distance.eta", "must be section.field=value")])
def test_set_errors_name_the_field(assignment, named, tmp_path, capsys):
    assert cli.main(["run", "--set", assignment, "--max-steps", "1", "--out",
                     str(tmp_path), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and named in err and len(err.strip().splitlines()) == 1
    if "=" in assignment:
        assert f"--set {assignment.split('=')[0]}" in err


# --- a scan flies -------------------------------------------------------------------------------

def test_a_ply_and_a_pcd_fly_through_run_cloud_and_stay_clear(tmp_path, rng, capsys):
    """Two boxes 1.5 m either side of the line from the start to the target, one written as
    binary PLY, one as ASCII PCD, both in a sensor's frame 3 m below the flight (placed by
    --cloud-offset): the passage crosses its finish line, the LiDAR saw the boxes, and the
    rotors stayed clear of every point."""
    left = write_ply(tmp_path / "left.ply", box_points(rng, (1.5, 1.5, -0.5), 1.0, 150),
                     text=False)
    right = write_pcd(tmp_path / "right.pcd", box_points(rng, (1.5, -2.5, -0.5), 1.0, 150),
                      "ascii")
    out = tmp_path / "flight"
    argv = ["run", "--cloud", str(left), "--cloud", str(right), "--cloud-offset", "0,0,3",
            "--start", "0,0,3", "--target", "20,0,3", "--max-steps", "8000",
            "--no-progress", "--out", str(out)]
    assert cli.main(argv) == 0, capsys.readouterr().err
    result = SimulationResult.load(out)
    assert result.completed and result.config.simulation.kind == "passage"
    assert result.scene.name == "scan" and len(result.scene.clouds) == 2
    assert {round(float(c[:, 1].mean())) for c in result.scene.clouds} == {-2, 2}
    assert all(np.all((c[:, 2] > 2.4) & (c[:, 2] < 3.6)) for c in result.scene.clouds)
    assert result.visible_points.max() > 0
    assert result.clearance.min() > COLLISION_CLEARANCE
    assert result.x[-1, 0] >= result.scene.finish[0][0] - 0.05


def test_the_pages_example_runs_and_prints_what_the_page_says(capsys):
    """docs/own_scene.md: its Python block writes a PLY of two boxes and builds their scene."""
    import re
    from pathlib import Path

    page = (Path(__file__).parents[1] / "docs" / "own_scene.md").read_text()
    (block,) = re.findall(r"```python\n(.*?)```", page, re.S)
    exec(compile(block, "docs/own_scene.md", "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in printed] == ["scan-0", "scan-1"]
    assert "`scan-0` and `scan-1`" in page

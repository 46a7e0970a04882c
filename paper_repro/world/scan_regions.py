"""Your own scene from scan files: the scans placed in the workspace, split into regions, and
each region thinned until the controller's region slot holds what the LiDAR sees of it.

Three stated rules turn scan files (:func:`~paper_repro.world.scan_files.read_scan`) into a
:class:`~paper_repro.world.scene.Scene`:

* **Placement** (:func:`place_scan`). A scan given in its sensor's frame is scaled, then
  offset: y = s·p + o, with the scale s > 0 (e.g. 0.001 for millimetres) and the offset
  o (3,), m. Every file of a scene is placed by the same transform.
* **Regions** (:func:`split_regions`). The placed points of all files are binned into cubic
  voxels of side h (``region_voxel``, :data:`REGION_VOXEL` by default) with a corner at the
  origin. Two occupied voxels are neighbours when they share a face, an edge or a corner
  (26-connectivity). A region is one connected set of occupied voxels, with its points. So
  two points closer than h always share a region, and two regions are more than h apart.
* **Thinning** (:func:`fit_region`). A region *fits* when no ball of radius r_s (the LiDAR's
  range, ``sensor.range``) centred on one of its points holds more than
  ``nmpc.points_per_region`` points: the vehicle flies outside the cloud, so a scan from there
  holds fewer. A region that fits keeps its points. One that does not is replaced by
  voxel-grid centroids: the mean of its points in each occupied voxel of side s. The sides
  tried are s_k = s_max·2^(−k/2), k = 0, 1, …, down to :data:`FINEST_SIDE`; from the
  coarsest down, the last that fits is kept. The coarsest side is the barrier's safe distance
  s_max = √(2·d_min) (``barrier.d_min``): coarser centroids could leave gaps the vehicle is
  let through. A region that does not fit at s_max is refused.

The mission flies from ``start`` to ``target`` as a *passage*: it ends at a finish line
:data:`FINISH_MARGIN` past the farthest cloud point along the line from the start to the
target, as a random scene's does.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from paper_repro.config import Config
from paper_repro.validation import as_vector, require_int, require_positive
from paper_repro.world.random_scenes import RandomSceneParams
from paper_repro.world.scan_files import read_scan
from paper_repro.world.scene import Region, Scene

REGION_VOXEL = 1.0
"""m, the default voxel side h of the rule that splits a scan into regions."""

FINEST_SIDE = 0.02
"""m, the finest voxel side tried when a region is thinned (below it, the raw points)."""

FINISH_MARGIN = RandomSceneParams.finish_margin
"""m, how far past the farthest cloud point (along the flight) a scan's finish line lies."""

SCAN_SCENARIO = "scan"
"""``simulation.scenario`` of a run through scan files (the scene is saved with the result)."""


class ScanRegion(NamedTuple):
    """One region of a scan.

    Attributes
    ----------
    points : (m, 3) what the scene holds, m: the raw points, or their voxel-grid centroids.
    raw : number of the region's points in the files.
    side : voxel side of the centroids, m (0: the raw points, not thinned).
    """

    points: np.ndarray
    raw: int
    side: float


def scan_scene(paths: Sequence, start, target, config: Config | None = None,
               scale: float = 1.0, offset=(0.0, 0.0, 0.0),
               region_voxel: float = REGION_VOXEL) -> Scene:
    """A scene of the regions of scan files, flown from ``start`` past them towards ``target``.

    Parameters
    ----------
    paths : one or more scan files (:func:`~paper_repro.world.scan_files.read_scan`).
    start, target : (3,) positions, m, in the workspace frame.
    config : the run's configuration; its LiDAR range, slot capacity and d_min set the
        thinning (default: the printed one).
    scale, offset : the placement y = scale·p + offset (:func:`place_scan`).
    region_voxel : h, m, the voxel side of :func:`split_regions`.

    Returns
    -------
    :class:`~paper_repro.world.scene.Scene` named ``"scan"``, one region ``"scan-<k>"`` per
    region (shape ``None``, points given), one target and a finish line.

    Raises
    ------
    ValueError : a bad file or placement (naming the file or parameter), a region that cannot
        fit (naming its file), or a target not past the clouds by more than
        :data:`FINISH_MARGIN`.
    """
    config = config or Config()
    regions = scan_regions(paths, config, scale, offset, region_voxel)
    start = as_vector("start", start, 3)
    target = as_vector("target", target, 3)
    length = float(np.linalg.norm(target - start))
    if length == 0:
        raise ValueError(f"target must differ from start, got {target.tolist()} for both")
    u = (target - start) / length
    points = np.concatenate([r.points for r in regions])
    reach = max(float(np.max((points - start) @ u)), 0.0) + FINISH_MARGIN
    if reach >= length:
        raise ValueError(f"target must lie more than {FINISH_MARGIN:g} m past the farthest "
                         f"cloud point along the line from the start, i.e. more than "
                         f"{reach:.3g} m from the start, got {length:.3g} m")
    finish = (tuple(float(v) for v in start + reach * u), tuple(float(v) for v in u))
    return Scene(SCAN_SCENARIO, tuple(Region(f"scan-{k}", None) for k in range(len(regions))),
                 tuple(float(v) for v in start), (tuple(float(v) for v in target),),
                 config.simulation.seed, finish, tuple(r.points for r in regions))


def scan_regions(paths: Sequence, config: Config | None = None, scale: float = 1.0,
                 offset=(0.0, 0.0, 0.0), region_voxel: float = REGION_VOXEL
                 ) -> tuple[ScanRegion, ...]:
    """The regions of scan files, placed, split and thinned by the module's rules.

    Parameters
    ----------
    paths : one or more scan files.  config : as :func:`scan_scene`.
    scale, offset : the placement (:func:`place_scan`).  region_voxel : h, m.

    Returns
    -------
    tuple of :class:`ScanRegion`, ordered by their smallest voxel (x, then y, then z).
    """
    config = config or Config()
    if isinstance(paths, (str, Path)) or not len(paths):
        raise ValueError(f"paths must be a non-empty list of scan files, got {paths!r}")
    clouds = [place_scan(read_scan(p), scale, offset) for p in paths]
    origin = np.concatenate([np.full(len(c), i) for i, c in enumerate(clouds)])
    points = np.concatenate(clouds)
    regions = []
    for index in split_regions(points, region_voxel):
        files = sorted({str(paths[i]) for i in origin[index]})
        try:
            kept, side = fit_region(points[index], config.nmpc.points_per_region,
                                    config.sensor.range, math.sqrt(2 * config.barrier.d_min))
        except ValueError as exc:
            raise ValueError(f"scan file(s) {', '.join(map(repr, files))}: {exc}") from None
        regions.append(ScanRegion(kept, len(index), side))
    return tuple(regions)


def place_scan(points, scale: float = 1.0, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """y = scale·p + offset: points from a sensor's frame (and units) to the workspace.

    Parameters
    ----------
    points : (m, 3) array.  scale : s > 0.  offset : (3,), m.

    Returns
    -------
    (m, 3) float array, m.
    """
    require_positive("scale", scale)
    offset = as_vector("offset", offset, 3)
    return float(scale) * np.asarray(points, float) + offset


def split_regions(points, voxel: float = REGION_VOXEL) -> list[np.ndarray]:
    """The regions of a cloud: connected sets of occupied voxels (26-connectivity).

    Parameters
    ----------
    points : (m, 3) array, m.  voxel : h > 0, m, the voxel side (voxels have a corner at 0).

    Returns
    -------
    list of index arrays into ``points``, one per region, each sorted; ordered by the
    region's smallest voxel.
    """
    require_positive("region_voxel", voxel)
    keys = np.floor(np.asarray(points, float) / voxel).astype(np.int64)
    voxels, inverse = np.unique(keys, axis=0, return_inverse=True)
    # Occupied voxels one step apart in every axis (Chebyshev distance 1) touch.
    pairs = cKDTree(voxels).query_pairs(1.0, p=np.inf, output_type="ndarray")
    n = len(voxels)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    per_point = labels[np.ravel(inverse)]
    return [np.flatnonzero(per_point == k) for k in range(count)]


def fit_region(points, capacity: int, sensor_range: float, max_side: float
               ) -> tuple[np.ndarray, float]:
    """A region thinned until it fits a slot of ``capacity`` points (see the module's rule).

    Parameters
    ----------
    points : (m, 3) array, m.  capacity : points per region slot (``nmpc.points_per_region``).
    sensor_range : r_s, m.  max_side : s_max, m, the coarsest voxel side.

    Returns
    -------
    (points (k, 3), side): the raw points and side 0, or voxel-grid centroids and their side.

    Raises
    ------
    ValueError : the region does not fit even at ``max_side``.
    """
    require_int("capacity", capacity, 1)
    require_positive("sensor_range", sensor_range)
    require_positive("max_side", max_side)
    points = np.asarray(points, float)
    if fits(points, capacity, sensor_range):
        return points, 0.0
    kept = None
    sides = [max_side * 2.0 ** (-k / 2)
             for k in range(int(2 * math.log2(max_side / FINEST_SIDE)) + 1)]
    for side in sides:
        centroids = voxel_centroids(points, side)
        if not fits(centroids, capacity, sensor_range):
            break
        kept = (centroids, side)
    if kept is None:
        worst = max_ball_count(voxel_centroids(points, max_side), sensor_range, capacity)
        raise ValueError(
            f"a region of {len(points)} points near {np.round(points.mean(axis=0), 2).tolist()} "
            f"m cannot fit a region slot: its centroids at the coarsest voxel side "
            f"√(2·d_min) = {max_side:.3g} m still put more than {capacity} points "
            f"(nmpc.points_per_region) within r_s = {sensor_range:g} m of one of them "
            f"({worst}); raise nmpc.points_per_region or split the scan")
    return kept


def voxel_centroids(points, side: float) -> np.ndarray:
    """The mean of the points in each occupied voxel of side ``side`` (a corner at 0).

    Returns
    -------
    (k, 3) array, m, one point per occupied voxel, ordered by voxel; each lies in its voxel.
    """
    require_positive("side", side)
    points = np.asarray(points, float)
    keys = np.floor(points / side).astype(np.int64)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = np.ravel(inverse)
    counts = np.bincount(inverse)
    return np.column_stack([np.bincount(inverse, weights=points[:, j]) / counts
                            for j in range(3)])


def fits(points, capacity: int, radius: float) -> bool:
    """True when no ball of ``radius`` centred on a point holds more than ``capacity`` points."""
    points = np.asarray(points, float)
    if len(points) <= capacity:
        return True
    tree = cKDTree(points)
    # One crowded ball is enough to refuse: every 50th centre first, all of them only then.
    if max_ball_count(points, radius, capacity, tree, points[::50]) > capacity:
        return False
    return max_ball_count(points, radius, capacity, tree) <= capacity


def max_ball_count(points, radius: float, cap: int, tree=None, centres=None) -> int:
    """The most points a ball of ``radius`` centred on one of ``centres`` (default: the points
    themselves) holds, counted up to ``cap + 1`` (the search stops there, so a dense scan
    costs m·(cap + 1) at most). ``tree`` is ``points``' :class:`~scipy.spatial.cKDTree`."""
    points = np.asarray(points, float)
    tree = cKDTree(points) if tree is None else tree
    centres = points if centres is None else centres
    k = min(cap + 1, len(points))
    most = 0
    for chunk in range(0, len(centres), 20_000):  # bounded memory: 20,000 × k distances
        d, _ = tree.query(centres[chunk:chunk + 20_000], k=k, distance_upper_bound=radius)
        most = max(most, int(np.isfinite(np.reshape(d, (len(d), -1))).sum(axis=1).max()))
    return most

"""A local map built from the LiDAR's scans: what a robot remembers of what it has seen.

The paper's controller reads the raw scan, so a wall is forgotten as soon as it leaves the
3 m sphere, and a noisy sensor hands it a new visible set at every scan. :class:`VoxelMap`
keeps a bounded, persistent map instead. Space is cut into cubic voxels of side ``voxel``
(m), and each voxel holds the log-odds L of being occupied, as in OctoMap (Hornung et al.,
2013):

* a **hit** (a return in the voxel, counted once per scan) adds ``hit``, a **miss** adds
  ``miss`` (< 0), and L is clamped to [``clamp_low``, ``clamp_high``], so that a voxel seen
  for a long time still changes its state within a few scans;
* a voxel **becomes occupied** when L reaches ``occupied``. From the prior 0 that takes
  ⌈occupied / hit⌉ hits in a row (3 with the defaults), so one spurious return never gets
  there (``hit`` < ``occupied`` is checked). Spurious returns fall uniformly in the sphere
  (about 900 voxels of 0.5 m), so that three land in one voxel in a row is rare;
* an occupied voxel **stays occupied** until L falls below ``release`` (< ``occupied``): a
  hysteresis, so that a voxel whose hits and misses balance near the threshold does not
  enter and leave the controller's set scan after scan;
* a miss is a scan that sees the voxel and returns nothing in it. The virtual LiDAR has no
  occlusion: it returns every point within r_s. So an occupied voxel is seen when all of it
  lies within the sensing sphere (centre within r_s − √3·voxel/2): the part of a wall just
  beyond the range is not erased as the vehicle moves away. A voxel not yet occupied is seen
  as soon as any of it is (centre within r_s + √3·voxel/2), so that stray returns in the
  sphere's outer shell decay as fast as inner ones. A dropped return is then a miss, and a
  confirmed voxel survives many in a row: from ``clamp_high`` it takes
  ⌊(clamp_high − release) / −miss⌋ + 1 misses in a row to clear it (21 with the defaults;
  with 20 % dropout, a one-point voxel loses 21 returns in a row with probability 2e-15);
* voxels outside the sensing sphere are left as they are: **points behind the vehicle
  persist**. A voxel unseen for ``max_age`` s is forgotten. So is any voxel farther than
  ``keep_radius`` m from the vehicle, and the oldest ones beyond a budget of ``max_voxels``.
  Memory is bounded by ``max_voxels``.

Each occupied voxel hands the controller one **representative point**: the mean of the returns
it received (over the last ``mean_window`` hits at most). Range noise therefore averages down,
by 1/√n after n hits, instead of moving the point at every scan. A return counts for the voxel
whose representative lies within ``merge_radius`` of it, when there is one, and for the voxel
it falls in otherwise: the noisy returns of a point near a voxel face would otherwise fall on
both sides and make two representatives, one of them entering and leaving the set as the hits
on its side come and go. The smoothed distance weighs every point (its sum over the cloud and
the volume V_σ), so such a duplicate moves D and ∇D at every change, where the Euclidean
minimum does not see it. Two cloud points closer than ``merge_radius`` become one, at their
mean: 1.5 % of the points of the scenes' 3 points/m³ Halton clouds have a neighbour within the
default 0.2 m (their median spacing is 0.48 m). Each voxel also keeps the region label of its
latest return, so that :meth:`VoxelMap.regions` groups the map's points by region as
:meth:`paper_repro.world.lidar.Lidar.scan` does.

Moving regions do not belong in a map of static space: a voxel map smears them into a wall
along their path. :meth:`VoxelMap.update` takes an ``exclude`` mask of regions, so that their
returns never enter. The caller hands those regions to the controller from the raw scan (and
to the tracker) instead.

The update and the read-out are a short C file (``_voxel_map.c``), built once per machine as
the QP solver is. OctoMap itself would be a compiled C++ dependency, for a map of a few
hundred voxels; the same rules written with numpy arrays take tens of array operations per
scan, which cost about ten times the C per closed-loop step (measured on the scans of a noisy
passage; the map's cost per step is reported by ``benchmarks/guidance_cost.py``).
"""

from __future__ import annotations

import ctypes
import functools
import math
from importlib import resources

import numpy as np

from paper_repro._native import load_library
from paper_repro.validation import require_int, require_positive, require_time

MAPPED_SPEED = 0.1
"""m/s: the closed loop (``sensor.map_voxel``) keeps a region predicted to move faster than
this out of the map, and hands the controller its raw scan."""

MAP_VOXEL = 0.5
"""Voxel side (m) of the local map the studies fly (``sensor.map_voxel``): below the clouds'
0.7 m spacing, so that a wall stays a wall of points."""



class VoxelMap:
    """A bounded log-odds voxel map of LiDAR returns, with one representative point per
    voxel.

    Parameters
    ----------
    voxel : voxel side, m (> 0): about the clouds' spacing (0.7 m for the scenes' Halton
        clouds of 3 points/m³).
    sensing_range : r_s of the LiDAR, m (> 0): voxels that lie entirely inside the sphere of
        this radius are seen by every scan.
    hit, miss : log-odds added per hit (> 0) and per miss (< 0).
    occupied : log-odds threshold of an occupied voxel (> ``hit``, so that one return never
        makes a voxel occupied).
    clamp_low, clamp_high : bounds of the log-odds (clamp_low ≤ 0 < occupied ≤ clamp_high).
    release : log-odds below which an occupied voxel is released (clamp_low ≤ release ≤
        occupied; equal to ``occupied`` for no hysteresis).
    merge_radius : m, in [0, voxel): a return within this distance of a voxel's
        representative counts for that voxel (0: every return counts for the voxel it falls
        in). 0.2 m is four standard deviations of the 5 cm range noise of the studies.
    mean_window : representative point: the mean of the last this-many hits (≥ 1).
    max_age : s (> 0, or inf): a voxel unseen this long is forgotten.
    keep_radius : m (≥ sensing_range): voxels farther from the vehicle are forgotten.
    max_voxels : the most voxels kept (≥ 1); the ones seen least recently go first.
    """

    def __init__(self, voxel: float = 0.5, sensing_range: float = 3.0, hit: float = 0.85,
                 miss: float = -0.25, occupied: float = 2.0, clamp_low: float = -2.0,
                 clamp_high: float = 4.0, release: float = -1.0,
                 merge_radius: float = 0.2, mean_window: int = 1000,
                 max_age: float = math.inf, keep_radius: float = 10.0,
                 max_voxels: int = 20000):
        require_positive("voxel", voxel)
        require_positive("sensing_range", sensing_range)
        require_positive("hit", hit)
        if not (math.isfinite(miss) and miss < 0):
            raise ValueError(f"miss must be a finite number < 0 (log-odds), got {miss!r}")
        if not (math.isfinite(occupied) and occupied > hit):
            raise ValueError(f"occupied must be a finite number > hit = {hit} (one return "
                             f"must not make a voxel occupied), got {occupied!r}")
        if not (clamp_low <= 0 and occupied <= clamp_high < math.inf):
            raise ValueError(f"need clamp_low <= 0 and occupied <= clamp_high < inf, got "
                             f"clamp_low={clamp_low!r}, clamp_high={clamp_high!r}")
        if not (clamp_low <= release <= occupied):
            raise ValueError(f"release must lie in [clamp_low, occupied] = [{clamp_low}, "
                             f"{occupied}] (log-odds), got {release!r}")
        if not (math.isfinite(merge_radius) and 0 <= merge_radius < voxel):
            raise ValueError(f"merge_radius must lie in [0, voxel = {voxel}) m, got "
                             f"{merge_radius!r}")
        require_int("mean_window", mean_window, 1)
        if not (max_age > 0):
            raise ValueError(f"max_age must be > 0 (s, inf for never), got {max_age!r}")
        if not (math.isfinite(keep_radius) and keep_radius >= sensing_range):
            raise ValueError(f"keep_radius must be a finite number >= sensing_range = "
                             f"{sensing_range} m, got {keep_radius!r}")
        require_int("max_voxels", max_voxels, 1)
        self.voxel, self.sensing_range = float(voxel), float(sensing_range)
        self.hit, self.miss, self.occupied = float(hit), float(miss), float(occupied)
        self.clamp = (float(clamp_low), float(clamp_high))
        self.release, self.merge_radius = float(release), float(merge_radius)
        self.mean_window, self.max_age = int(mean_window), float(max_age)
        self.keep_radius, self.max_voxels = float(keep_radius), int(max_voxels)
        self._params = np.array([self.voxel, self.sensing_range, self.hit, self.miss,
                                 self.occupied, self.release, *self.clamp, self.merge_radius,
                                 self.mean_window, self.max_age, self.keep_radius,
                                 self.max_voxels], float)  # in the order of _voxel_map.c
        self._n = 0
        self.reset()

    def reset(self) -> None:
        """Forget every voxel."""
        self._n = 0
        self._room(64)

    def __len__(self) -> int:
        return self._n

    # The voxels, sorted by key, as views of the first len(self) rows of the buffers the
    # compiled update works in.
    keys = property(lambda self: self._keys[:self._n], doc="packed voxel indices, sorted")
    centre = property(lambda self: self._centre[:self._n], doc="(n, 3) voxel centres, m")
    log_odds = property(lambda self: self._log_odds[:self._n], doc="(n,) log-odds")
    point = property(lambda self: self._point[:self._n],
                     doc="(n, 3) representative points, m")
    count = property(lambda self: self._count[:self._n], doc="(n,) hits in the mean")
    label = property(lambda self: self._label[:self._n], doc="(n,) region of the voxel")
    seen = property(lambda self: self._seen[:self._n], doc="(n,) last time seen, s")
    state = property(lambda self: self._state[:self._n].view(bool),
                     doc="(n,) occupied (with the hysteresis)")

    _FIELDS = {"keys": (np.int64, ()), "centre": (float, (3,)), "log_odds": (float, ()),
               "point": (float, (3,)), "count": (np.int64, ()), "label": (np.int64, ()),
               "seen": (float, ()), "state": (np.uint8, ())}

    def _room(self, cap: int) -> None:
        """Buffers for ``cap`` voxels, the first len(self) kept."""
        for name, (dtype, shape) in self._FIELDS.items():
            buffer = np.zeros((cap, *shape), dtype)
            if self._n:
                buffer[:self._n] = getattr(self, "_" + name)[:self._n]
            setattr(self, "_" + name, buffer)
        self._cap = cap
        self._pointers = {name: getattr(self, "_" + name).ctypes.data for name in self._FIELDS}

    # --- the update -----------------------------------------------------------------------

    def update(self, scan, position, t: float, exclude=None) -> None:
        """Take one scan: ``scan`` a list with one (k_i, 3) array of returns per region (as
        :meth:`Lidar.scan` gives), ``position`` the sensor's (3,) position, m, ``t`` s, and
        ``exclude`` an optional boolean per region (True: its returns stay out of the map).

        The rules of the module's docstring, in C (``_voxel_map.c``, built once per machine
        like the QP solver): a Python loop over the voxels would cost more than the rest of
        the closed-loop step."""
        p = np.ascontiguousarray(position, float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"position must be a finite (3,) array, got {position!r}")
        require_time(t)
        if exclude is not None and len(exclude) != len(scan):
            raise ValueError(f"exclude must have one flag per region ({len(scan)}), got "
                             f"{len(exclude)}")
        kept = [i for i in range(len(scan)) if exclude is None or not exclude[i]]
        parts = [np.asarray(scan[i], float).reshape(-1, 3) for i in kept]
        points = np.ascontiguousarray(np.concatenate(parts) if parts else np.zeros((0, 3)))
        if not np.isfinite(points).all():
            raise ValueError("scan must hold finite returns (m); drop the non-finite ones "
                             "first, as the closed loop does")
        labels = np.repeat(np.array(kept, np.int64), [len(q) for q in parts])
        if self._n + len(points) > self._cap:
            self._room(max(2 * self._cap, self._n + len(points)))
        n = _library().voxel_map_update(
            self._n, self._cap, *self._pointers.values(), len(points), points.ctypes.data,
            labels.ctypes.data, p.ctypes.data, float(t), self._params.ctypes.data)
        if n < 0:
            raise MemoryError("the voxel map's update could not allocate its workspace")
        self._n = n

    # --- the read-out ---------------------------------------------------------------------

    @property
    def occupied_mask(self) -> np.ndarray:
        return self.state

    def regions(self, position, radius: float, n_regions: int) -> list[np.ndarray]:
        """The representative points of the occupied voxels within ``radius`` (m) of
        ``position``, grouped by region: a list of ``n_regions`` (k_i, 3) arrays."""
        require_int("n_regions", n_regions, 0)
        p = np.ascontiguousarray(position, float)
        out, counts = np.empty((self._n, 3)), np.empty(n_regions, np.int64)
        at = self._pointers
        if _library().voxel_map_regions(self._n, at["point"], at["label"], at["state"],
                                        p.ctypes.data, float(radius), n_regions,
                                        out.ctypes.data, counts.ctypes.data) < 0:
            raise MemoryError("the voxel map's read-out could not allocate its workspace")
        ends = np.cumsum(counts).tolist()
        return [out[a:b] for a, b in zip([0, *ends[:-1]], ends)]


@functools.cache
def _library() -> ctypes.CDLL:
    """The compiled update and read-out (``_voxel_map.c``), built once per machine."""
    source = resources.files("paper_repro.world").joinpath("_voxel_map.c").read_bytes()
    lib = load_library("voxel_map", source, flags=("-ffp-contract=off",))
    ptr, i = ctypes.c_void_p, ctypes.c_int
    lib.voxel_map_update.restype = i
    lib.voxel_map_update.argtypes = [i, i, *[ptr] * 8, i, ptr, ptr, ptr, ctypes.c_double, ptr]
    lib.voxel_map_regions.restype = i
    lib.voxel_map_regions.argtypes = [i, ptr, ptr, ptr, ptr, ctypes.c_double, i, ptr, ptr]
    return lib

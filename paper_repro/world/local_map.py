"""A local map built from the LiDAR's scans: what a robot remembers of what it has seen.

The paper's controller reads the raw scan, so a wall is forgotten as soon as it leaves the
3 m sphere, and a noisy sensor hands it a new visible set at every scan. :class:`VoxelMap`
keeps a bounded, persistent map instead. Space is cut into cubic voxels of side ``voxel``
(m), and each voxel holds the log-odds L of being occupied, as in OctoMap (Hornung et al.,
2013):

* a **hit** (a return in the voxel, counted once per scan) adds ``hit``, a **miss** adds
  ``miss`` (< 0), and L is clamped to [``clamp_low``, ``clamp_high``], so that a voxel seen
  for a long time still changes its state within a few scans;
* a voxel is **occupied** while L ≥ ``occupied``. From the prior 0 that takes
  ⌈occupied / hit⌉ hits in a row (3 with the defaults), so one spurious return never gets
  there (``hit`` < ``occupied`` is checked). Spurious returns fall uniformly in the sphere
  (about 900 voxels of 0.5 m), so that three land in one voxel in a row is rare;
* a miss is a scan that sees the voxel and returns nothing in it. The virtual LiDAR has no
  occlusion: it returns every point within r_s. So an occupied voxel is seen when all of it
  lies within the sensing sphere (centre within r_s − √3·voxel/2): the part of a wall just
  beyond the range is not erased as the vehicle moves away. A voxel not yet occupied is seen
  as soon as any of it is (centre within r_s + √3·voxel/2), so that stray returns in the
  sphere's outer shell decay as fast as inner ones. A dropped return is then a miss, and a
  confirmed voxel survives a few in a row: from ``clamp_high`` it takes
  ⌊(clamp_high − occupied) / −miss⌋ + 1 misses in a row to clear it (9 with the defaults;
  with 20 % dropout, a one-point voxel loses 9 returns in a row with probability 5e-7);
* voxels outside the sensing sphere are left as they are: **points behind the vehicle
  persist**. A voxel unseen for ``max_age`` s is forgotten. So is any voxel farther than
  ``keep_radius`` m from the vehicle, and the oldest ones beyond a budget of ``max_voxels``.
  Memory is bounded by ``max_voxels``.

Each occupied voxel hands the controller one **representative point**: the mean of the
returns it received, over the last ``mean_window`` hits at most. Range noise therefore
averages down instead of moving the point at every scan. Each voxel also keeps the region
label of its latest return, so that :meth:`VoxelMap.regions` groups the map's points by
region as :meth:`paper_repro.world.lidar.Lidar.scan` does.

Moving regions do not belong in a map of static space: a voxel map smears them into a wall
along their path. :meth:`VoxelMap.update` takes an ``exclude`` mask of regions, so that their
returns never enter. The caller hands those regions to the controller from the raw scan (and
to the tracker) instead.
"""

from __future__ import annotations

import math

import numpy as np

from paper_repro.validation import require_int, require_positive, require_time

MAPPED_SPEED = 0.1
"""m/s: the closed loop (``sensor.map_voxel``) keeps a region predicted to move faster than
this out of the map, and hands the controller its raw scan."""

_OFFSET = 1 << 20  # voxel indices are packed as three 21-bit fields (±1 M voxels per axis)


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
    mean_window : representative point: the mean of the last this-many hits (≥ 1).
    max_age : s (> 0, or inf): a voxel unseen this long is forgotten.
    keep_radius : m (≥ sensing_range): voxels farther from the vehicle are forgotten.
    max_voxels : the most voxels kept (≥ 1); the ones seen least recently go first.
    """

    def __init__(self, voxel: float = 0.5, sensing_range: float = 3.0, hit: float = 0.85,
                 miss: float = -0.25, occupied: float = 2.0, clamp_low: float = -2.0,
                 clamp_high: float = 4.0, mean_window: int = 20, max_age: float = math.inf,
                 keep_radius: float = 10.0, max_voxels: int = 20000):
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
        self.mean_window, self.max_age = int(mean_window), float(max_age)
        self.keep_radius, self.max_voxels = float(keep_radius), int(max_voxels)
        self.reset()

    def reset(self) -> None:
        """Forget every voxel."""
        self.keys = np.zeros(0, np.int64)         # packed voxel indices, sorted
        self.centre = np.zeros((0, 3))            # voxel centres, m
        self.log_odds = np.zeros(0)
        self.point = np.zeros((0, 3))             # representative point, m
        self.count = np.zeros(0, np.int64)        # hits in the representative mean
        self.label = np.zeros(0, np.int64)        # region of the latest return
        self.seen = np.zeros(0)                   # last time seen (hit or miss), s

    def __len__(self) -> int:
        return len(self.keys)

    # --- the update -----------------------------------------------------------------------

    def update(self, scan, position, t: float, exclude=None) -> None:
        """Take one scan: ``scan`` a list with one (k_i, 3) array of returns per region (as
        :meth:`Lidar.scan` gives), ``position`` the sensor's (3,) position, m, ``t`` s, and
        ``exclude`` an optional boolean per region (True: its returns stay out of the map)."""
        p = np.asarray(position, float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"position must be a finite (3,) array, got {position!r}")
        require_time(t)
        if exclude is not None and len(exclude) != len(scan):
            raise ValueError(f"exclude must have one flag per region ({len(scan)}), got "
                             f"{len(exclude)}")
        parts = [(np.asarray(pts, float).reshape(-1, 3), i) for i, pts in enumerate(scan)
                 if exclude is None or not exclude[i]]
        points = np.concatenate([q for q, _ in parts]) if parts else np.zeros((0, 3))
        labels = (np.concatenate([np.full(len(q), i) for q, i in parts]) if parts
                  else np.zeros(0, np.int64))
        hit_keys, first, inverse = np.unique(self._key(points), return_index=True,
                                             return_inverse=True)
        inverse = inverse.ravel()
        at = np.searchsorted(self.keys, hit_keys)
        known = at < len(self.keys)
        known[known] = self.keys[at[known]] == hit_keys[known]
        # Misses: voxels already in the map, seen by this scan and without a return in it. An
        # occupied voxel is seen when all of it is in the sphere; one not (yet) occupied as
        # soon as any of it is, so that stray returns at the sphere's edge decay too.
        reach = np.linalg.norm(self.centre - p, axis=1)
        half_diagonal = math.sqrt(3.0) * self.voxel / 2
        missed = np.where(self.log_odds >= self.occupied,
                          reach <= self.sensing_range - half_diagonal,
                          reach <= self.sensing_range + half_diagonal)
        missed[at[known]] = False
        self.log_odds[missed] = np.maximum(self.log_odds[missed] + self.miss, self.clamp[0])
        self.seen[missed] = t
        # Hits: new voxels enter at the prior 0, then every hit voxel gains ``hit`` once.
        if not known.all():
            reach = self._insert(hit_keys[~known], reach, p)
        where = np.searchsorted(self.keys, hit_keys)
        self.log_odds[where] = np.minimum(self.log_odds[where] + self.hit, self.clamp[1])
        self.seen[where] = t
        self.label[where] = labels[first]
        sums = np.zeros((len(hit_keys), 3))
        np.add.at(sums, inverse, points)
        k = np.bincount(inverse, minlength=len(hit_keys))
        n = np.minimum(self.count[where], self.mean_window - 1)
        self.point[where] = (self.point[where] * n[:, None] + sums) / (n + k)[:, None]
        self.count[where] = np.minimum(n + k, self.mean_window)
        self._forget(reach, t)

    _FIELDS = ("keys", "centre", "log_odds", "point", "count", "label", "seen")

    def _forget(self, reach: np.ndarray, t: float) -> None:
        """Drop voxels that are too old, too far (``reach``: each one's distance from the
        vehicle, m), back at the floor of a free voxel, or beyond the budget (least recently
        seen first)."""
        keep = ((t - self.seen <= self.max_age) & (reach <= self.keep_radius)
                & (self.log_odds > self.clamp[0]))
        if keep.sum() > self.max_voxels:
            order = np.argsort(-np.where(keep, self.seen, -np.inf), kind="stable")
            keep = np.zeros_like(keep)
            keep[order[:self.max_voxels]] = True
        if not keep.all():
            for name in self._FIELDS:
                setattr(self, name, getattr(self, name)[keep])

    def _insert(self, keys: np.ndarray, reach: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Add voxels at the prior (keys kept sorted); returns ``reach`` for the new order."""
        centre = self._centre(keys)
        order = np.argsort(np.concatenate([self.keys, keys]), kind="stable")
        m = len(keys)
        added = {"keys": keys, "centre": centre, "log_odds": np.zeros(m),
                 "point": np.zeros((m, 3)), "count": np.zeros(m, np.int64),
                 "label": np.zeros(m, np.int64), "seen": np.zeros(m)}
        for name in self._FIELDS:
            setattr(self, name, np.concatenate([getattr(self, name), added[name]])[order])
        return np.concatenate([reach, np.linalg.norm(centre - p, axis=1)])[order]

    # --- the read-out ---------------------------------------------------------------------

    @property
    def occupied_mask(self) -> np.ndarray:
        return self.log_odds >= self.occupied

    def regions(self, position, radius: float, n_regions: int) -> list[np.ndarray]:
        """The representative points of the occupied voxels within ``radius`` (m) of
        ``position``, grouped by region: a list of ``n_regions`` (k_i, 3) arrays."""
        require_int("n_regions", n_regions, 0)
        p = np.asarray(position, float)
        near = self.occupied_mask & (np.linalg.norm(self.point - p, axis=1) <= radius)
        pts, lab = self.point[near], self.label[near]
        return [pts[lab == i] for i in range(n_regions)]

    # --- voxel indices --------------------------------------------------------------------

    def _key(self, points: np.ndarray) -> np.ndarray:
        ijk = np.floor(points / self.voxel).astype(np.int64) + _OFFSET
        return (ijk[:, 0] << 42) | (ijk[:, 1] << 21) | ijk[:, 2]

    def _centre(self, keys: np.ndarray) -> np.ndarray:
        mask = (1 << 21) - 1
        ijk = np.stack([(keys >> 42) & mask, (keys >> 21) & mask, keys & mask], axis=1)
        return (ijk - _OFFSET + 0.5) * self.voxel

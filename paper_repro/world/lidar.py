"""The virtual LiDAR: the cloud points within range of the vehicle, with optional noise,
dropout and spurious returns. What it cannot see (the regions' true velocities, the true
clearance) is in :mod:`paper_repro.world.truth`."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from paper_repro.config import SensorParams
from paper_repro.validation import is_number, require_time
from paper_repro.world.scene import checked_motions, cloud_array
from paper_repro.world.truth import region_offsets

# --- LiDAR ----------------------------------------------------------------------------------

NOISY_LIDAR = SensorParams(range_noise=0.05, dropout=0.2, spurious_rate=2.0)
"""The noisy sensor of the sensor-noise study (and of the map's golden flight): 5 cm range
noise (1σ), one point in five lost, two spurious returns per scan on average; seeded per
scene."""


class Lidar:
    """Virtual spherical LiDAR of range r_s (m) over a scene's clouds, perfect or imperfect.

    Parameters
    ----------
    clouds : sequence with one (m_i, 3) finite array per region, m (m_i ≥ 0). Shapes are
        checked, never reshaped: a bare (m, 3) array is rejected (wrap it in a list).
    range_ : r_s > 0, m.
    noise : :class:`~paper_repro.config.SensorParams`, or ``None`` for a perfect sensor (as
        is a ``SensorParams`` with its defaults). See :meth:`scan` for the model.
    motions : ``None`` (static regions), or one :class:`Motion` or ``None`` per region (as
        :attr:`Scene.motions`): region i is seen at ``clouds[i] + motions[i].offset(t)``.
    dim : p, the dimension of the points and of the sensor's position: 3, or 2 for a planar
        scene (a 2-D LiDAR).

    Static regions: one KD-tree over all points is built at construction and :meth:`scan` is
    one ball query. With motions: one KD-tree per region, each queried at the sensor's
    position less the region's offset, so a moving region costs what a static one does.
    """

    def __init__(self, clouds, range_: float = 3.0, noise: SensorParams | None = None,
                 motions=None, dim: int = 3):
        if not (is_number(range_) and math.isfinite(range_) and range_ > 0):
            raise ValueError(f"lidar range must be a finite number > 0 (m), got {range_!r}")
        if isinstance(clouds, np.ndarray) or not isinstance(clouds, (tuple, list)):
            raise ValueError("clouds must be a sequence (list or tuple) with one (m, 3) array "
                             f"per region, got {type(clouds).__name__}"
                             + (f" of shape {clouds.shape}; wrap a single cloud in a list"
                                if isinstance(clouds, np.ndarray) else ""))
        if noise is not None and not isinstance(noise, SensorParams):
            raise ValueError(f"noise must be a SensorParams or None, got {noise!r}")
        self.range = float(range_)
        if dim not in (2, 3):
            raise ValueError(f"dim must be 3 (or 2 for a planar scene), got {dim!r}")
        self.dim = dim
        self.clouds = tuple(cloud_array(f"clouds[{i}]", c, allow_empty=True, dim=self.dim)
                            for i, c in enumerate(clouds))
        self.motions = checked_motions("lidar motions", motions, len(self.clouds))
        self.noise = noise if noise is not None else SensorParams()
        self._labels = np.concatenate(
            [np.full(len(c), i) for i, c in enumerate(self.clouds)] or [np.zeros(0, int)])
        points = np.concatenate(self.clouds) if self.clouds else np.zeros((0, self.dim))
        self._points = points
        # one past each region's last row of `points` (the clouds are stacked in region order)
        self._ends = np.cumsum([len(c) for c in self.clouds], dtype=np.intp)
        self._tree = cKDTree(points) if len(points) else None
        if self.motions is not None:
            self._first = self._ends - [len(c) for c in self.clouds]  # each region's first row
            self._trees = [cKDTree(c) if len(c) else None for c in self.clouds]
        self.reset()

    def reset(self) -> None:
        """Reseed the noise generator with ``noise.seed``: the next scans replay the same
        noise as after construction (a clean slate for a rerun)."""
        self._rng = np.random.default_rng(self.noise.seed)

    def scan(self, position, t: float = 0.0) -> list[np.ndarray]:
        """Visible points of each region at time ``t`` (s; only moving regions depend on it):
        a list (one entry per region) of (k_i, 3) arrays, k_i = 0 for a region out of range.

        A perfect sensor (the default) returns exactly the points within r_s, in their cloud
        order, and never draws from the generator; a moving region's points are returned
        where they are at ``t`` (stored points + c_i(t)). With ``noise``, per scan, in this
        order:

        * **dropout**: each point within r_s is lost with probability ``dropout``;
        * **range noise**: each kept point p is moved along its ray from the sensor s to
          s + max(0, ‖p − s‖ + ε)·(p − s)/‖p − s‖, ε ~ 𝒩(0, ``range_noise``²) (so a
          noisy point may lie slightly beyond r_s, as a real return would);
        * **spurious returns**: K ~ Poisson(``spurious_rate``) points uniform in the ball of
          radius r_s about s, each appended to the region whose cloud holds the point
          nearest to it (the region a segmentation by nearest obstacle would give it). A
          scene without any point has no region to give them to, and they are dropped.
        """
        p = np.asarray(position, float)
        if p.shape != (self.dim,) or not np.isfinite(p).all():
            raise ValueError(f"position must be a finite ({self.dim},) array, got {p!r}")
        require_time(t)
        if self._tree is None:
            return [np.zeros((0, self.dim)) for _ in self.clouds]
        if self.motions is not None:
            return self._moving_scan(p, t)
        idx = np.asarray(self._tree.query_ball_point(p, self.range, return_sorted=True),
                         dtype=np.intp)
        if not self.noise.perfect:
            return self._noisy_scan(p, idx)
        # The clouds are stacked in region order, so the sorted indices fall into one run per
        # region: cut the points at the regions' ends rather than mask them region by region.
        points = self._points[idx]
        cuts = np.searchsorted(idx, self._ends).tolist()
        return [points[a:b] for a, b in zip([0, *cuts[:-1]], cuts)]

    def _moving_scan(self, p: np.ndarray, t: float) -> list[np.ndarray]:
        """:meth:`scan` with motions: region i's tree is queried at p − c_i(t) and its points
        are shifted by + c_i(t)."""
        shifts = region_offsets(self.motions, len(self.clouds), self.dim, t)
        local = [np.zeros(0, int) if tree is None else
                 np.asarray(tree.query_ball_point(p - shifts[i], self.range,
                                                  return_sorted=True), dtype=np.intp)
                 for i, tree in enumerate(self._trees)]
        if not self.noise.perfect:
            idx = np.concatenate([self._first[i] + li for i, li in enumerate(local)])
            return self._noisy_scan(p, idx, shifts)
        return [c[li] + shifts[i] if len(li) else np.zeros((0, 3))
                for i, (c, li) in enumerate(zip(self.clouds, local, strict=True))]

    def _nearest_region(self, points: np.ndarray, shifts: np.ndarray) -> np.ndarray:
        """Region holding the nearest point (where it is now) to each of ``points``."""
        best = np.full(len(points), np.inf)
        label = np.zeros(len(points), int)
        for i, tree in enumerate(self._trees):
            if tree is None:
                continue
            d, _ = tree.query(points - shifts[i])
            closer = d < best
            best[closer], label[closer] = d[closer], i
        return label

    def _noisy_scan(self, p: np.ndarray, idx: np.ndarray,
                    shifts: np.ndarray | None = None) -> list[np.ndarray]:
        noise, rng = self.noise, self._rng
        # Every draw is made whatever the parameters, so that the stream a given seed produces
        # does not depend on which imperfections are switched on.
        kept = rng.random(len(idx)) >= noise.dropout
        eps = rng.standard_normal(len(idx)) * noise.range_noise
        idx, eps = idx[kept], eps[kept]
        labels = self._labels[idx]
        where = self._points[idx] if shifts is None else self._points[idx] + shifts[labels]
        ray = where - p
        dist = np.linalg.norm(ray, axis=1)
        scale = np.divide(np.maximum(dist + eps, 0.0), dist, out=np.ones_like(dist),
                          where=dist > 0)
        points = p + ray * scale[:, None]

        k = int(rng.poisson(noise.spurious_rate))
        direction = rng.standard_normal((k, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = self.range * rng.random(k) ** (1.0 / 3.0)  # uniform in volume
        spurious = p + direction * radius[:, None]
        if k:
            if shifts is None:
                _, nearest = self._tree.query(spurious)
                spurious_labels = self._labels[nearest]
            else:
                spurious_labels = self._nearest_region(spurious, shifts)
            points = np.vstack([points, spurious])
            labels = np.concatenate([labels, spurious_labels])
        return [points[labels == i] for i in range(len(self.clouds))]



"""Motion of the obstacles estimated from the scans alone: what a real vehicle has.

The LiDAR labels its returns by region (:meth:`paper_repro.world.lidar.Lidar.scan` returns one
(k_i, 3) array per region), so each region can be tracked on its own. :class:`RegionTracker`
runs one constant-velocity Kalman filter per region on the region's *visible centroid*
(:func:`centroid_of`), and returns one velocity estimate per region, m/s.

Model, per axis (the axes are independent and share one 2 × 2 covariance, since the process
and measurement noises are isotropic; every axis is updated at once)::

    state (p, v),   F(dt) = [[1, dt], [0, 1]],   Q(dt) = q·[[dt³/3, dt²/2], [dt²/2, dt]]
    measurement z = p + noise (the visible centroid),   H = [1, 0]

with q = ``accel_noise``²·T_s (m²/s³): continuous white acceleration of the power of an
acceleration of standard deviation ``accel_noise`` held over each controller period T_s
(the two differ by σ_a²·T_s³·dt/12 in the position variance only), so that an elapsed time dt
that is a multiple of T_s (skipped scans) or not is predicted consistently.

**The visible-subset bias.** The centroid of the visible points moves when the *subset* in
view changes (points crossing the LiDAR's range as the sensor or the region moves), not only
when the region moves: a region entering view shows its near face first, and its visible
centroid recedes from the sensor as more of it comes into range, although it may be at rest.
The shift is a step in the measurement's bias, and it persists as long as the subset does.
Inflating the *measurement* noise of the one scan where it happens only delays it: the next
scan, with the same subset and the nominal noise, pulls it into the state through the
velocity gain as before (measured below: no better than nothing). The tracker models it as
what it is, a step of unknown size in the measured position: when the number of visible
points changes from k to k′, the position variance gains, per axis, before the update::

    (subset_jump · |k′ − k| / k′ · s)²,   s² = mean squared distance of the points from
                                              their centroid per axis (the larger set's)

the expected size of the shift: the points that came or went are |k′ − k| of k′, and they lie
at the edge of the visible set. Measured over regions entering, passing and leaving view
(Halton clouds of 3 and 20 points/m³), the shift per axis is 1.1–1.2 of |k′ − k| / k′ · s at
the median, 1.5–1.6 at the 90th percentile and 2.0 at the 99th: ``subset_jump`` = 2 covers
it. A large position variance makes the filter absorb the step in the position (gain ≈ 1)
and not in the velocity (gain ≈ 0); a small change of a large subset inflates little, so a
dense cloud still informs the velocity at every scan. Subset changes that leave the count
unchanged (one point in, one out; a spurious return replacing a point) are caught by a
**gate**: the normalised innovation ν·ν/S of a scan is tested against the chi-square quantile
of ``gate_probability`` with ``dim`` degrees of freedom, and a scan beyond it is not rejected
(a real change of course, or an offset that persists, would then be rejected for ever and the
track lost) but softened, its noise scaled so that it lies on the gate: one scan pulls the
state by at most the gate's radius, a persistent change gets through in a few scans.

Measured (``tests/test_tracking.py``): a 2 × 2 × 3 m region at rest that a sensor approaches
at 1 m/s, its visible subset growing from 1 point to the full depth in range, the visible
centroid receding by ≈ 0.9 m in 3 s. Largest velocity error from first sight, at 3 / 20
points/m³: 0.09 / 0.34 m/s with the mitigation (at 20 points/m³ the subset grows by a point
or two at almost every scan: a slow drift that no centroid filter can tell from motion
without matching points between scans); 2.3 / 5.4 m/s with the gate alone; 3.9 / 8.0 m/s
with neither; 2.3 / 5.2 m/s inflating instead the measurement noise ×100 for the scans where
the count changes by more than 10 % (×10⁴ at every change: the same). The price: a count
change is always read as a subset change, so a sensor that **drops returns at random**
(``SensorParams.dropout``) changes the count at every scan and starves the velocity of
information: with 20 % dropout and 5 cm range noise, a region in full view at 1.2 m/s is
tracked to 1.3 m/s rms (0.2 m/s without the step model). Set ``centroid_noise`` to the
centroid's actual jitter for such a sensor (0.1 m: 0.26 m/s rms), or ``subset_jump=0`` for
regions that stay in full view.

Entering and leaving view: a region seen for the first time (or again after being forgotten)
starts at its centroid with zero velocity and a velocity standard deviation
``velocity_prior``; the second sight gives the velocity from the difference of the two
centroids, weighted by the filter. A region out of view (k_i = 0) keeps being predicted, its
velocity kept and its covariance growing, until ``forget_after`` seconds have passed since it
was last seen; then it is forgotten (velocity zero) and, if it comes back, starts afresh.

Only NumPy: the chi-square quantile of the gate is computed here by bisection.
"""

from __future__ import annotations

import math

import numpy as np

from paper_repro.config import TrackerParams
from paper_repro.validation import is_number, require_positive


def centroid_of(points) -> np.ndarray:
    """Centroid (mean) of a region's visible points. ``points`` : (k, p) finite array, k ≥ 1.

    Returns (p,), m. Raises ``ValueError`` for an empty or malformed array.
    """
    arr = np.asarray(points, float)
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"points must be a (k, p) array with k >= 1, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("points must hold finite coordinates only")
    return arr.mean(axis=0)


class RegionTracker:
    """One constant-velocity Kalman filter per region, on the region's visible centroid.

    Parameters
    ----------
    ts : T_s > 0, s. The controller's sampling period (the paper's 0.01 s); sets the scale of
        the process noise (q = ``accel_noise``²·T_s, see the module docstring). Updates may be
        any time apart.
    dim : p, 3 (the quadrotor) or 2 (a planar robot); any integer ≥ 1.
    accel_noise : σ_a > 0, m/s², *chosen* 3. The white-acceleration process noise of the
        constant-velocity model. With the measurement noise r it sets the filter's bandwidth,
        ω ≈ √(σ_a / r) = 12 rad/s (a velocity time constant ≈ √2/ω ≈ 0.12 s). The studies'
        obstacles move at 0.5–1.5 m/s, at constant velocity or piecewise-linearly, so the
        filter must follow a sudden change of velocity (a corner of the path) within a
        horizon (0.35 s) or so: it is within 10 % after 0.2–0.45 s, the longest for a
        reversal from 1.5 to −1.5 m/s (σ_a = 2 takes 0.68 s there). Its steady-state velocity
        standard deviation under white centroid noise r, (√2·q^¾·(r²T_s)^¼)^½ ≈ 0.1 m/s,
        moves the predicted obstacle by ≈ 3.5 cm over the horizon; a larger σ_a (4: 0.13
        m/s) also lets more of the visible-subset drift through.
    centroid_noise : r > 0, m, *chosen* 0.02. Standard deviation of the visible centroid as a
        measurement of the region's position, per axis, when the visible subset is unchanged.
        A perfect LiDAR on a rigid region gives the exact centroid; 2 cm covers range noise of
        the order of 5 cm averaged over the tens of points of a region's view (σ/√k). Subset
        changes are handled apart (module docstring). r sets the bandwidth with σ_a: a
        smaller r at the same ratio σ_a/r reads a growing subset better (its step variance
        then dominates r²: 0.01 m/s of error instead of 0.09 at r = 5 mm, σ_a = 0.75) but
        lets any noise of the sensor into the velocity, and the gate, which scales with r,
        then holds back real changes of velocity (a 90° corner at 1 m/s takes 0.85 s).
    forget_after : > 0, s, *chosen* 1. A region unseen this long is forgotten (velocity zero);
        when it comes back it starts afresh. Short gaps (a region flickering at the range's
        edge, lost scans) are bridged by prediction; after 1 s (about three horizons) the
        velocity's own uncertainty has grown by σ_a·√(T_s·1 s) ≈ 0.3 m/s, a fifth to a half of
        the obstacles' speed, and a stale velocity applied to a region that comes back is
        worse than starting from rest.
    velocity_prior : > 0, m/s, *chosen* 2. Standard deviation of the velocity at first sight
        (zero mean): above the fastest obstacle of the studies (1.5 m/s), so that the second
        sight sets the velocity from the difference of the centroids, weighted: a third of
        the raw difference over one period, which with r = 2 cm is worth 2.8 m/s of noise,
        and the next scans complete it. Finite, so that a subset jump between the first two
        sights (typically the largest: one point, then two) is not read as a velocity of tens
        of m/s.
    gate_probability : in (0, 1), *chosen* 0.999, or ``None`` (no gate). The innovation gate
        (chi-square, ``dim`` degrees of freedom; 16.3 for dim = 3): a scan beyond it is
        softened onto it, not rejected.
    subset_jump : ≥ 0, *chosen* 2 (0 turns the mitigation off). Scale of the position
        variance added when the number of visible points changes, in RMS radii of the visible
        set (module docstring).

    The closed loop reads these from ``Config.tracker``
    (:class:`~paper_repro.config.TrackerParams`, which checks them).

    Use: ``tracker.update(lidar.scan(y), t)`` once per scan, with t increasing; it returns one
    (dim,) velocity per region. :meth:`velocity_std` gives their uncertainty, :meth:`reset`
    forgets everything.
    """

    def __init__(self, ts: float, dim: int = 3, accel_noise: float = 3.0,
                 centroid_noise: float = 0.02, forget_after: float = 1.0, *,
                 velocity_prior: float = 2.0, gate_probability: float | None = 0.999,
                 subset_jump: float = 2.0):
        require_positive("ts", ts)
        if not (isinstance(dim, (int, np.integer)) and not isinstance(dim, (bool, np.bool_))
                and dim >= 1):
            raise ValueError(f"dim must be an integer >= 1, got {dim!r}")
        TrackerParams(accel_noise, centroid_noise, forget_after, velocity_prior,
                      gate_probability, subset_jump)  # checked there, by name
        self.ts = float(ts)
        self.dim = int(dim)
        self.accel_noise = float(accel_noise)
        self.centroid_noise = float(centroid_noise)
        self.forget_after = float(forget_after)
        self.velocity_prior = float(velocity_prior)
        self.gate_probability = None if gate_probability is None else float(gate_probability)
        self.subset_jump = float(subset_jump)
        self._q = self.accel_noise**2 * self.ts  # PSD of the white acceleration, m²/s³
        self._r2 = self.centroid_noise**2
        self._gate = (math.inf if gate_probability is None
                      else chi2_quantile(self.gate_probability, self.dim))
        self.reset()

    def reset(self) -> None:
        """Forget every region and the clock: the next :meth:`update` starts afresh."""
        self._t: float | None = None
        self._n_regions: int | None = None
        self._tracks: dict[int, _Track] = {}

    def velocity_std(self) -> list[float]:
        """Standard deviation of each velocity component (the same on every axis), m/s, per
        region at the last update's time: ``inf`` for a region never seen or forgotten."""
        if self._n_regions is None:
            return []
        return [math.sqrt(self._tracks[i].cov[1, 1]) if i in self._tracks else math.inf
                for i in range(self._n_regions)]

    def update(self, visible, t: float) -> list[np.ndarray]:
        """Take one scan at time ``t`` (s, greater than the previous update's) and return one
        (dim,) velocity estimate per region, m/s.

        ``visible`` : list with one (k_i, dim) array per region (the LiDAR's scan), k_i = 0
        when the region is out of view; the list index is the region's identity, so every
        scan must list the same regions. A region never seen, or forgotten, gets zeros; one in
        view is predicted to ``t`` and updated with its centroid; one out of view is predicted
        (its velocity kept, its covariance growing).
        """
        if not (is_number(t) and math.isfinite(t)):
            raise ValueError(f"t must be a finite number (s), got {t!r}")
        t = float(t)
        if self._t is not None and not t > self._t:
            raise ValueError(f"t must increase from one update to the next, got {t!r} after "
                             f"{self._t!r}")
        scans = self._check_scan(visible)
        self._t = t
        out = []
        for i, points in enumerate(scans):
            track = self._tracks.get(i)
            if track is not None and t - track.t_seen > self.forget_after:
                del self._tracks[i]
                track = None
            if track is not None:
                self._predict(track, t)
            if len(points):
                if track is None:
                    self._tracks[i] = track = self._start(points, t)
                else:
                    self._correct(track, points, t)
            out.append(np.zeros(self.dim) if track is None else track.velocity.copy())
        return out

    # --- filter steps ---------------------------------------------------------------------

    def _start(self, points: np.ndarray, t: float) -> _Track:
        z = centroid_of(points)
        spread2 = float(np.sum((points - z) ** 2)) / points.size
        cov = np.diag([self._r2, self.velocity_prior**2])
        return _Track(z, np.zeros(self.dim), cov, t, t, len(points), spread2)

    def _predict(self, track: _Track, t: float) -> None:
        dt = t - track.t
        if dt <= 0:
            return
        f = np.array([[1.0, dt], [0.0, 1.0]])
        q = self._q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
        track.position = track.position + dt * track.velocity
        track.cov = f @ track.cov @ f.T + q
        track.t = t

    def _correct(self, track: _Track, points: np.ndarray, t: float) -> None:
        z = centroid_of(points)
        k_new = len(points)
        spread2 = float(np.sum((points - z) ** 2)) / (k_new * self.dim)  # per axis, m²
        cov = track.cov.copy()
        if self.subset_jump > 0 and k_new != track.count:
            # The larger of the two sets holds the points that came or went.
            cov[0, 0] += ((self.subset_jump * abs(k_new - track.count) / k_new) ** 2
                          * max(spread2, track.spread2))
        innovation = z - track.position
        s = cov[0, 0] + self._r2
        d2 = float(innovation @ innovation) / s
        if d2 > self._gate:  # soften onto the gate: S scaled so that ν·ν/S = gate
            s *= d2 / self._gate
        gain = cov[:, 0] / s  # (position gain, velocity gain), the same on every axis
        track.position = track.position + gain[0] * innovation
        track.velocity = track.velocity + gain[1] * innovation
        # P ← P − K·S·Kᵀ, with S as used for the gain (softened by the gate or not).
        track.cov = cov - s * np.outer(gain, gain)
        track.t = t
        track.t_seen = t
        track.count = k_new
        track.spread2 = spread2

    def _check_scan(self, visible) -> list[np.ndarray]:
        if isinstance(visible, np.ndarray) or not isinstance(visible, (list, tuple)):
            raise ValueError("visible must be a list with one (k_i, dim) array per region, got "
                             f"{type(visible).__name__}")
        if self._n_regions is not None and len(visible) != self._n_regions:
            raise ValueError(f"visible must list the same {self._n_regions} regions at every "
                             f"scan, got {len(visible)} (reset() for another scene)")
        scans = []
        for i, pts in enumerate(visible):
            arr = np.asarray(pts, float)
            if arr.size == 0:
                scans.append(np.zeros((0, self.dim)))
                continue
            if arr.ndim != 2 or arr.shape[1] != self.dim:
                raise ValueError(f"visible[{i}] must be a (k, {self.dim}) array, got shape "
                                 f"{arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"visible[{i}] must hold finite coordinates only")
            scans.append(arr)
        self._n_regions = len(scans)  # fixed by the first valid scan
        return scans


class _Track:
    """The filter of one region: state (position, velocity), shared 2 × 2 covariance of
    (p, v) per axis, the time of the state, the time last seen, and the count of visible
    points then with their mean squared distance from their centroid per axis (m²)."""

    __slots__ = ("position", "velocity", "cov", "t", "t_seen", "count", "spread2")

    def __init__(self, position, velocity, cov, t, t_seen, count, spread2):
        self.position = position
        self.velocity = velocity
        self.cov = cov
        self.t = t
        self.t_seen = t_seen
        self.count = count
        self.spread2 = spread2


def chi2_quantile(p: float, dof: int) -> float:
    """Quantile of the chi-square distribution with ``dof`` degrees of freedom, by bisection
    on its CDF P(dof/2, x/2) (regularised lower gamma, by the recurrence from a = ½ or 1)."""

    def cdf(x: float) -> float:
        h = x / 2.0
        if dof % 2:
            a, value = 0.5, math.erf(math.sqrt(h))
        else:
            a, value = 1.0, -math.expm1(-h)
        while a < dof / 2.0:  # P(a + 1, h) = P(a, h) − h^a·e^-h / Γ(a + 1)
            value -= math.exp(a * math.log(h) - h - math.lgamma(a + 1.0)) if h > 0 else 0.0
            a += 1.0
        return value

    lo, hi = 0.0, 1.0
    while cdf(hi) < p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cdf(mid) < p else (lo, mid)
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)



"""The region tracker: velocity of each region from its visible centroid (issue 13, part 1)."""

import math

import numpy as np
import pytest

from paper_repro.world.shapes import Box, halton_cloud
from paper_repro.world.tracking import RegionTracker, centroid_of, chi2_quantile

TS = 0.01
R_S = 3.0


def _fly(tracker, cloud_at, sensor_at, duration, step=1):
    """Scan a single region every ``step`` periods for ``duration`` s; returns times, velocity
    estimates (n, dim), and the scans."""
    times, estimates, scans = [], [], []
    for i in range(0, int(round(duration / TS)), step):
        t = i * TS
        points, sensor = cloud_at(t), sensor_at(t)
        visible = points if sensor is None else points[
            np.linalg.norm(points - sensor, axis=1) <= R_S]
        times.append(t)
        scans.append(visible)
        estimates.append(tracker.update([visible], t)[0])
    return np.array(times), np.array(estimates), scans


# --- the two motions of the studies: constant velocity and piecewise-linear -------------------

@pytest.mark.parametrize("dim, step", [(3, 1), (2, 1), (3, 3)])
def test_a_region_in_full_view_at_constant_velocity_is_tracked_to_2_percent_in_1_s(
        l_cloud, dim, step):
    v = np.array([1.2, -0.6, 0.4])[:dim]
    cloud = l_cloud[:, :dim]
    tracker = RegionTracker(TS, dim=dim)
    times, est, _ = _fly(tracker, lambda t: cloud + v * t, lambda t: None, 1.5, step)
    error = np.linalg.norm(est - v, axis=1) / np.linalg.norm(v)
    assert error[0] == 1.0  # first sight: zero velocity
    assert np.all(error[times >= 1.0] < 0.02)  # measured: < 1e-5 (exact centroids)
    assert tracker.velocity_std()[0] < 0.2


@pytest.mark.parametrize("v1, v2", [((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),     # a 90° corner
                                    ((1.5, 0.0, 0.0), (-1.5, 0.0, 0.0)),    # a reversal
                                    ((0.5, 0.0, 0.0), (1.5, 0.3, 0.0))])    # a speed-up
def test_a_change_of_velocity_is_followed_within_half_a_second_to_10_percent(l_cloud, v1, v2):
    v1, v2 = np.array(v1), np.array(v2)

    def position(t):
        return v1 * t if t < 1.0 else v1 + v2 * (t - 1.0)

    times, est, _ = _fly(RegionTracker(TS), lambda t: l_cloud + position(t), lambda t: None,
                         2.5)
    error = np.linalg.norm(est - v2, axis=1) / np.linalg.norm(v2)
    # From 0.5 s after the corner on, the estimate stays within 10 % of the new velocity
    # (measured: within 10 % after 0.23 s for the corner, 0.45 s for the reversal of 3 m/s).
    assert np.all(error[times >= 1.5 - 1e-9] < 0.10)


# --- the visible-subset bias ------------------------------------------------------------------

def _approach(tracker, density, region_velocity=(0.0, 0.0, 0.0)):
    """A 2 × 2 × 3 m region enters the LiDAR's view progressively: the sensor approaches at
    1 m/s, or the region approaches the sensor at ``region_velocity``. Returns the velocity
    errors, m/s, from 0.5 s after first sight, and the counts of visible points."""
    cloud = halton_cloud(Box((0.0, 0.0, 0.0), (2.0, 2.0, 3.0)), density, seed=1)
    vr = np.array(region_velocity)
    sensor_velocity = vr + np.array([1.0, 0.0, 0.0])  # the same approach, relative
    start = np.array([-4.0, 1.0, 1.5])
    times, est, scans = _fly(tracker, lambda t: cloud + vr * t,
                             lambda t: start + sensor_velocity * t, 3.3)
    counts = np.array([len(s) for s in scans])
    first = times[np.argmax(counts > 0)]
    # From first sight for a region at rest (zero velocity is then right from the start),
    # from 0.5 s after it for a moving one (the filter's convergence from zero).
    judged = (times >= first + (0.5 if vr.any() else 0.0) - 1e-9) & (counts > 0)
    return np.linalg.norm(est - vr, axis=1)[judged], counts


@pytest.mark.parametrize("density, bound", [(3.0, 0.15), (20.0, 0.5)])
@pytest.mark.parametrize("region_velocity", [(0.0, 0.0, 0.0), (-1.0, 0.0, 0.0)])
def test_a_region_entering_view_is_not_read_as_moving_with_its_visible_centroid(
        density, bound, region_velocity):
    """As the sensor nears the region, its visible subset grows from a few points on the near
    face to the full depth within range, and the visible centroid recedes by ~0.9 m in 3 s
    while the region is at rest (or moves at exactly 1 m/s)."""
    error, counts = _approach(RegionTracker(TS), density, region_velocity)
    assert counts.max() > 5 * counts[counts > 0][0]  # the subset does grow
    # Measured max errors (m/s) at density 3 / 20, region at rest | moving: with the
    # mitigation 0.087 / 0.34 | 0.087 / 0.34; gate only 2.3 / 5.4 | 1.7 / 1.3; neither
    # 3.9 / 8.0 | 1.8 / 1.3 (the visible centroid drifts at ≈ 0.3 m/s and jumps by tens of
    # cm while the subset holds a few points).
    assert error.max() < bound
    gate_only, _ = _approach(RegionTracker(TS, subset_jump=0.0), density, region_velocity)
    neither, _ = _approach(RegionTracker(TS, subset_jump=0.0, gate_probability=None), density,
                           region_velocity)
    assert gate_only.max() > 1.0 and neither.max() > 1.0
    assert error.max() < 0.35 * min(gate_only.max(), neither.max())
    rms = math.sqrt(np.mean(error**2))
    assert rms < 0.5 * bound


def test_translating_the_whole_scene_does_not_change_the_velocities():
    cloud = halton_cloud(Box((0.0, 0.0, 0.0), (2.0, 2.0, 3.0)), 3.0, seed=1)
    _, est, scans = _fly(RegionTracker(TS), lambda t: cloud + np.array([0.0, 0.8, 0.0]) * t,
                         lambda t: np.array([-4.0, 1.0, 1.5]) + np.array([1.0, 0.0, 0.0]) * t,
                         3.3)
    shift = np.array([120.0, -75.0, 30.0])
    tracker = RegionTracker(TS)
    moved = np.array([tracker.update([s + shift], i * TS)[0] for i, s in enumerate(scans)])
    assert np.abs(moved - est).max() < 1e-8


# --- entering and leaving view ----------------------------------------------------------------

def _with_gap(gap_start, gap_end, duration, l_cloud, v):
    tracker = RegionTracker(TS, forget_after=1.0)
    out, stds = [], []
    for i in range(int(round(duration / TS))):
        t = i * TS
        visible = np.zeros((0, 3)) if gap_start <= t < gap_end else l_cloud + v * t
        out.append(tracker.update([visible], t)[0])
        stds.append(tracker.velocity_std()[0])
    return np.arange(len(out)) * TS, np.array(out), np.array(stds)


def test_a_region_out_of_view_briefly_is_predicted_with_its_velocity_kept(l_cloud):
    v = np.array([0.8, 0.5, 0.0])
    times, est, stds = _with_gap(1.0, 1.6, 2.5, l_cloud, v)
    gap = (times >= 1.0 - 1e-9) & (times < 1.6 - 1e-9)
    last = est[np.flatnonzero(gap)[0] - 1]
    assert np.array_equal(est[gap], np.broadcast_to(last, est[gap].shape))  # velocity kept
    assert np.all(np.diff(stds[gap]) > 0)  # the covariance grows
    # Back in view, the track continues (no restart from zero velocity) on the predicted
    # position: the region moved as predicted, so nothing jumps.
    after = times >= 1.6 - 1e-9
    assert np.all(np.linalg.norm(est[after] - v, axis=1) < 0.02 * np.linalg.norm(v))


def test_a_region_out_of_view_longer_than_forget_after_is_forgotten_and_starts_afresh(l_cloud):
    v = np.array([0.8, 0.5, 0.0])
    times, est, stds = _with_gap(1.0, 2.5, 4.0, l_cloud, v)
    seen_last = 0.99
    kept = (times >= 1.0 - 1e-9) & (times - seen_last <= 1.0 + 1e-9)
    forgotten = (times - seen_last > 1.0 + 1e-9) & (times < 2.5 - 1e-9)
    assert np.all(np.linalg.norm(est[kept] - v, axis=1) < 0.02)
    assert np.all(est[forgotten] == 0.0) and np.all(np.isinf(stds[forgotten]))
    back = np.flatnonzero(times >= 2.5 - 1e-9)[0]
    assert np.all(est[back] == 0.0)  # re-initialised: zero velocity at first sight
    assert stds[back] == pytest.approx(RegionTracker(TS).velocity_prior)
    assert np.linalg.norm(est[times >= 3.5 - 1e-9] - v, axis=1).max() < 0.02  # converges again


def test_regions_are_independent_and_never_seen_ones_report_zero(l_cloud):
    tracker = RegionTracker(TS)
    v = np.array([0.0, 1.0, 0.0])
    for i in range(120):
        t = i * TS
        out = tracker.update([np.zeros((0, 3)), l_cloud + v * t, l_cloud[:5] - 10.0], t)
    assert np.all(out[0] == 0.0) and tracker.velocity_std()[0] == math.inf
    assert np.allclose(out[1], v, atol=0.02) and np.allclose(out[2], 0.0, atol=1e-12)
    tracker.reset()
    assert tracker.velocity_std() == []
    assert np.all(tracker.update([l_cloud, l_cloud], 0.0)[1] == 0.0)  # any region count again


def test_the_second_sight_gives_the_velocity_from_the_difference(l_cloud):
    v = np.array([1.0, 0.0, 0.0])
    tracker = RegionTracker(TS)
    tracker.update([l_cloud], 0.0)
    second = tracker.update([l_cloud + v * TS], TS)[0]
    # Weighted by the filter: the prior (2 m/s) against two centroids of 2 cm each; a sensor
    # with a smaller centroid noise takes the difference itself.
    assert 0.3 < second[0] < 1.0 and np.allclose(second[1:], 0.0)
    sharp = RegionTracker(TS, centroid_noise=1e-4)
    sharp.update([l_cloud], 0.0)
    assert sharp.update([l_cloud + v * TS], TS)[0] == pytest.approx(v, rel=1e-2)


# --- parameters and inputs --------------------------------------------------------------------

@pytest.mark.parametrize("name, value", [
    ("ts", 0.0), ("ts", -0.01), ("ts", math.nan), ("dim", 0), ("dim", 2.0), ("dim", True),
    ("accel_noise", 0.0), ("accel_noise", math.inf), ("centroid_noise", -1.0),
    ("forget_after", 0.0), ("velocity_prior", 0.0), ("gate_probability", 1.0),
    ("gate_probability", 0.0), ("subset_jump", -1.0), ("subset_jump", math.inf),
    ("accel_noise", "3"),
])
def test_bad_parameters_raise_naming_the_parameter(name, value):
    kwargs = {"ts": TS, name: value}
    with pytest.raises(ValueError, match=name):
        RegionTracker(**kwargs)


def test_bad_scans_and_times_raise(l_cloud):
    tracker = RegionTracker(TS)
    with pytest.raises(ValueError, match="visible"):
        tracker.update(l_cloud, 0.0)  # a bare array, not a list of regions
    with pytest.raises(ValueError, match=r"visible\[0\]"):
        tracker.update([l_cloud[:, :2]], 0.0)
    with pytest.raises(ValueError, match=r"visible\[1\]"):
        tracker.update([l_cloud, np.full((2, 3), np.nan)], 0.0)
    tracker.update([l_cloud], 0.0)
    with pytest.raises(ValueError, match="t must increase"):
        tracker.update([l_cloud], 0.0)
    with pytest.raises(ValueError, match="t must be"):
        tracker.update([l_cloud], math.nan)
    with pytest.raises(ValueError, match="same 1 regions"):
        tracker.update([l_cloud, l_cloud], 0.01)


def test_centroid_of():
    assert np.array_equal(centroid_of([[0.0, 0.0, 0.0], [2.0, 4.0, -6.0]]), [1.0, 2.0, -3.0])
    for bad in (np.zeros((0, 3)), np.zeros(3), [[np.inf, 0.0, 0.0]]):
        with pytest.raises(ValueError, match="points"):
            centroid_of(bad)


def test_the_gate_is_the_chi_square_quantile():
    # Known values: χ²(0.999) with 1, 2, 3 degrees of freedom; 2 dof is −2 ln(1 − p).
    assert chi2_quantile(0.999, 1) == pytest.approx(10.827566, rel=1e-6)
    assert chi2_quantile(0.999, 2) == pytest.approx(-2 * math.log(0.001), rel=1e-9)
    assert chi2_quantile(0.999, 3) == pytest.approx(16.266236, rel=1e-6)
    assert chi2_quantile(0.5, 4) == pytest.approx(3.356694, rel=1e-6)

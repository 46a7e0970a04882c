"""Properties of the smoothed point-to-cloud distance, eq. (8)-(13), and its baseline."""

from __future__ import annotations

from itertools import pairwise

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from paper_repro.problem import distance as dist_mod
from paper_repro.problem.distance import (
    CloudWeights,
    clearance,
    euclidean_distance,
    euclidean_distance_symbolic,
    smooth_distance,
    smooth_distance_gradient,
    smooth_distance_symbolic,
    smooth_projection,
)

ETA, SIGMA = 0.3, 0.8  # paper values

# Query points around the L cloud of conftest (x ∈ [1, 3], y ∈ [-2, 0], z ∈ [3, 4]):
# inside the notch of the L, on its edge, just outside, a few metres away, and far away.
QUERIES = [
    (2.2, -0.8, 3.5),   # in the concave notch, several points almost equidistant
    (1.2, -1.2, 3.4),   # inside the cloud, between points
    (0.4, -2.3, 3.0),   # just outside a corner
    (3.5, -2.5, 4.6),   # outside the convex corner
    (6.0, 2.0, 1.0),    # a few metres away
    (-10.0, 7.0, 15.0),  # far (D dominated by the nearest point)
]


def _brute_half_sq(y, cloud):
    """½ min_j ‖y − a_j‖², one point at a time."""
    return 0.5 * min(float(np.sum((np.asarray(y) - a) ** 2)) for a in cloud)


def _casadi_function(points, log_weights, log_volume, eta):
    """CasADi function y -> (D, ∇D by AD) from the symbolic form of eq. (8)."""
    y = ca.SX.sym("y", 3)
    expr = smooth_distance_symbolic(y, ca.DM(points), ca.DM(log_weights), log_volume, eta)
    return ca.Function("d", [y], [expr, ca.gradient(expr, y)])


# --- exact identities -----------------------------------------------------------------------

@pytest.mark.parametrize("eta", [0.05, 0.3, 2.0])
@pytest.mark.parametrize("y", [(0.0, 0.0, 0.0), (1.0, -2.0, 0.5), (40.0, 30.0, -20.0),
                               (123.4, 0.0, 0.0)])
def test_single_point_cloud_is_half_squared_distance(y, eta):
    """With one point W = V = 1, so D = ½‖y − a‖² exactly, Π = a and ∇D = y − a."""
    a = np.array([[0.7, -1.1, 2.3]])
    y = np.asarray(y, float)
    expected = 0.5 * np.sum((y - a[0]) ** 2)
    assert smooth_distance(y, a, eta, SIGMA) == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(smooth_projection(y, a, eta, SIGMA), a[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(smooth_distance_gradient(y, a, eta, SIGMA), y - a[0],
                               rtol=1e-12, atol=1e-12)


def test_single_point_cloud_is_zero_on_the_point():
    """D vanishes at the point of a one-point cloud (the ½‖·‖² identity at y = a)."""
    a = np.array([[0.7, -1.1, 2.3]])
    assert smooth_distance(a[0], a, ETA, SIGMA) == 0.0


def test_cloud_weights_match_eq_9_to_11(l_cloud):
    """CloudWeights holds Cen = mean, ln W_j = −‖a_j − Cen‖²/(2σ²), ln V = ln Σ W_j, and using
    it gives the same D as passing the raw cloud."""
    w = CloudWeights.from_cloud(l_cloud, SIGMA)
    cen = l_cloud.mean(axis=0)
    np.testing.assert_allclose(w.centroid, cen, rtol=1e-14)
    np.testing.assert_allclose(
        w.log_weights, -np.sum((l_cloud - cen) ** 2, axis=1) / (2 * SIGMA**2), rtol=1e-14)
    assert w.log_volume == pytest.approx(np.log(np.sum(np.exp(w.log_weights))), rel=1e-14)
    ys = np.array(QUERIES)
    np.testing.assert_array_equal(smooth_distance(ys, w, ETA, SIGMA),
                                  smooth_distance(ys, l_cloud, ETA, SIGMA))


# --- gradient: eq. (13) --------------------------------------------------------------------

@pytest.mark.parametrize("y", QUERIES)
@pytest.mark.parametrize("eta", [0.3, 1.0])
def test_gradient_matches_central_differences(l_cloud, y, eta):
    """∇D = y − Π (eq. 13) equals central finite differences of D on a nonconvex cloud."""
    y = np.asarray(y, float)
    h = 1e-5
    fd = np.array([
        (smooth_distance(y + h * e, l_cloud, eta, SIGMA)
         - smooth_distance(y - h * e, l_cloud, eta, SIGMA)) / (2 * h)
        for e in np.eye(3)
    ])
    grad = smooth_distance_gradient(y, l_cloud, eta, SIGMA)
    # Truncation error h²·D'''/6 ≲ 1e-10·(d/η⁴) and rounding eps·D/h ≲ 1e-8 here.
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("y", QUERIES)
def test_numpy_and_casadi_agree(l_cloud, y):
    """The symbolic form (used by the NLP) has the NumPy value of D and, by AD, the gradient
    y − Π of eq. (13)."""
    w = CloudWeights.from_cloud(l_cloud, SIGMA)
    f = _casadi_function(w.points, w.log_weights, w.log_volume, ETA)
    d_sym, g_sym = (np.array(v).ravel() for v in f(y))
    assert d_sym[0] == pytest.approx(smooth_distance(y, w, ETA, SIGMA), rel=1e-12, abs=1e-10)
    np.testing.assert_allclose(g_sym, smooth_distance_gradient(y, w, ETA, SIGMA),
                               rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("where", ["end", "start", "interleaved"])
def test_symbolic_padding_slots_are_inert(l_cloud, rng, where):
    """Slots with ln W = −1e30 (the NLP's unused capacity) change neither D nor ∇D, wherever
    they sit and whatever finite coordinates they hold (even on top of y)."""
    w = CloudWeights.from_cloud(l_cloud, SIGMA)
    y = np.array(QUERIES[0])
    n_pad = 7
    pad_pts = rng.uniform(-1e3, 1e3, size=(n_pad, 3))
    pad_pts[0] = y  # a padding slot exactly at the query point
    pad_pts[1] = l_cloud[0]
    pts, logw = w.points, w.log_weights
    if where == "end":
        p_pts, p_logw = np.vstack([pts, pad_pts]), np.concatenate([logw, np.full(n_pad, -1e30)])
    elif where == "start":
        p_pts, p_logw = np.vstack([pad_pts, pts]), np.concatenate([np.full(n_pad, -1e30), logw])
    else:
        idx = np.sort(rng.choice(len(pts) + n_pad, size=n_pad, replace=False))
        is_pad = np.zeros(len(pts) + n_pad, bool)
        is_pad[idx] = True
        p_pts = np.empty((len(pts) + n_pad, 3))
        p_logw = np.empty(len(pts) + n_pad)
        p_pts[is_pad], p_logw[is_pad] = pad_pts, -1e30
        p_pts[~is_pad], p_logw[~is_pad] = pts, logw
    d0, g0 = (np.array(v).ravel() for v in _casadi_function(pts, logw, w.log_volume, ETA)(y))
    d1, g1 = (np.array(v).ravel() for v in _casadi_function(p_pts, p_logw, w.log_volume, ETA)(y))
    np.testing.assert_allclose(d1, d0, rtol=1e-14, atol=0)
    np.testing.assert_allclose(g1, g0, rtol=1e-14, atol=1e-14)
    assert np.all(np.isfinite(g1))


def test_euclidean_symbolic_ignores_masked_slots(l_cloud, rng):
    """Slots with mask 0 never attain the min, even when they are closer than every real point."""
    y_val = np.array(QUERIES[3])
    pads = np.vstack([y_val, y_val + 0.01, rng.uniform(-5, 5, size=(3, 3))])
    pts = np.vstack([pads[:2], l_cloud, pads[2:]])
    mask = np.ones(len(pts))
    mask[:2] = 0
    mask[-3:] = 0
    y = ca.SX.sym("y", 3)
    expr = euclidean_distance_symbolic(y, ca.DM(pts), ca.DM(mask))
    f = ca.Function("e", [y], [expr])
    got = float(f(y_val))
    assert got == pytest.approx(_brute_half_sq(y_val, l_cloud), rel=1e-12)
    assert got == pytest.approx(euclidean_distance(y_val, l_cloud), rel=1e-12)
    # with every slot unmasked the padding points win (the mask really is what excludes them)
    f_all = ca.Function("e", [y], [euclidean_distance_symbolic(y, ca.DM(pts),
                                                               ca.DM(np.ones(len(pts))))])
    assert float(f_all(y_val)) == 0.0


# --- limits and bounds ----------------------------------------------------------------------

@pytest.mark.parametrize("y", QUERIES[:5])
def test_eta_to_zero_approaches_half_squared_distance(l_cloud, y):
    """s_min ≤ D ≤ s_min + η² ln(V/W_{j*}) (s_min = ½ min‖y − a_j‖², j* the nearest point), and
    the gap D − s_min shrinks monotonically as η → 0 (D → ½·d², not d)."""
    y = np.asarray(y, float)
    w = CloudWeights.from_cloud(l_cloud, SIGMA)
    s = 0.5 * np.sum((l_cloud - y) ** 2, axis=1)
    j_star = int(np.argmin(s))
    s_min = s[j_star]
    log_v_over_w = w.log_volume - w.log_weights[j_star]
    gaps = []
    for eta in (0.3, 0.1, 0.03, 0.01):
        d = smooth_distance(y, w, eta, SIGMA)
        tol = 1e-12 * (1 + s_min)
        assert s_min - tol <= d <= s_min + eta**2 * log_v_over_w + tol
        gaps.append(d - s_min)
    assert all(a > b for a, b in pairwise(gaps)), gaps
    assert gaps[-1] < 1e-3


def test_far_from_cloud_is_finite_and_exact(l_cloud):
    """100 m from the cloud the shifted log-sum-exp gives the exact D, where the naive
    formula −η² ln(Σ W e^{−‖y−a‖²/(2η²)}/V) underflows (ln 0 → D = inf)."""
    y = l_cloud.mean(axis=0) + np.array([60.0, -80.0, 0.0])  # 100 m from the centroid
    sq = np.sum((l_cloud - y) ** 2, axis=1)
    cen = l_cloud.mean(axis=0)
    wts = np.exp(-np.sum((l_cloud - cen) ** 2, axis=1) / (2 * SIGMA**2))
    vol = wts.sum()
    s = 0.5 * sq
    s_min = s.min()
    reference = s_min - ETA**2 * np.log(np.sum(wts * np.exp(-(s - s_min) / ETA**2)) / vol)

    d = smooth_distance(y, l_cloud, ETA, SIGMA)
    assert np.isfinite(d)
    assert d == pytest.approx(reference, rel=1e-13)
    assert s_min <= d <= s_min + 1.0  # ≈ ½·(100 m)², within η² ln(V/W) of the nearest point
    grad = smooth_distance_gradient(y, l_cloud, ETA, SIGMA)
    assert np.all(np.isfinite(grad))

    with np.errstate(all="ignore"):
        naive = -ETA**2 * np.log(np.sum(wts * np.exp(-sq / (2 * ETA**2))) / vol)
    assert not np.isfinite(naive)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rigid_motion_invariance(l_cloud, seed):
    """D(Ry + t; R𝒜 + t) = D(y; 𝒜) and ∇D rotates with the scene: the metric only sees
    relative geometry (the centroid and weights move with the cloud)."""
    gen = np.random.default_rng(seed)
    rot = Rotation.random(random_state=seed).as_matrix()
    shift = gen.uniform(-20, 20, size=3)
    ys = np.array(QUERIES[:5])
    moved_cloud = l_cloud @ rot.T + shift
    moved_ys = ys @ rot.T + shift
    np.testing.assert_allclose(smooth_distance(moved_ys, moved_cloud, ETA, SIGMA),
                               smooth_distance(ys, l_cloud, ETA, SIGMA), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(smooth_distance_gradient(moved_ys, moved_cloud, ETA, SIGMA),
                               smooth_distance_gradient(ys, l_cloud, ETA, SIGMA) @ rot.T,
                               rtol=1e-9, atol=1e-10)


def test_projection_is_a_convex_combination(l_cloud):
    """Π is a weighted mean of the points: it lies in their bounding box, for any y."""
    ys = np.array(QUERIES)
    proj = smooth_projection(ys, l_cloud, ETA, SIGMA)
    assert np.all(proj >= l_cloud.min(axis=0) - 1e-12)
    assert np.all(proj <= l_cloud.max(axis=0) + 1e-12)


# --- shapes ---------------------------------------------------------------------------------

def test_vectorised_shapes_and_values(l_cloud, rng, monkeypatch):
    """y (3,) → float and (3,); y (n, 3) → (n,) and (n, 3); rows equal the per-point results,
    also when the evaluation is split into several chunks."""
    ys = np.vstack([np.array(QUERIES), rng.uniform(-5, 8, size=(20, 3))])
    d_single = smooth_distance(ys[0], l_cloud, ETA, SIGMA)
    assert isinstance(d_single, float)
    assert smooth_projection(ys[0], l_cloud, ETA, SIGMA).shape == (3,)
    assert smooth_distance_gradient(ys[0], l_cloud, ETA, SIGMA).shape == (3,)
    assert isinstance(euclidean_distance(ys[0], l_cloud), float)

    d = smooth_distance(ys, l_cloud, ETA, SIGMA)
    p = smooth_projection(ys, l_cloud, ETA, SIGMA)
    g = smooth_distance_gradient(ys, l_cloud, ETA, SIGMA)
    e = euclidean_distance(ys, l_cloud)
    assert d.shape == (len(ys),) and e.shape == (len(ys),)
    assert p.shape == (len(ys), 3) and g.shape == (len(ys), 3)
    np.testing.assert_allclose(d, [smooth_distance(y, l_cloud, ETA, SIGMA) for y in ys],
                               rtol=1e-14)
    np.testing.assert_allclose(p, [smooth_projection(y, l_cloud, ETA, SIGMA) for y in ys],
                               rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(e, [euclidean_distance(y, l_cloud) for y in ys], rtol=1e-14)

    # Force many small chunks: results must not depend on the chunking.
    monkeypatch.setattr(dist_mod, "_CHUNK_PAIRS", 3 * len(l_cloud))
    np.testing.assert_array_equal(smooth_distance(ys, l_cloud, ETA, SIGMA), d)
    # (BLAS may order the sums of the weighted mean differently per block: rounding only)
    np.testing.assert_allclose(smooth_projection(ys, l_cloud, ETA, SIGMA), p,
                               rtol=1e-13, atol=1e-14)
    np.testing.assert_array_equal(euclidean_distance(ys, l_cloud), e)


# --- Euclidean baseline ---------------------------------------------------------------------

def test_euclidean_baseline_and_clearance_brute_force(l_cloud, rng):
    """euclidean_distance = ½ min_j ‖y − a_j‖² and clearance = √(2·that) = min_j ‖y − a_j‖."""
    ys = np.vstack([np.array(QUERIES), rng.uniform(-10, 10, size=(30, 3))])
    brute = np.array([_brute_half_sq(y, l_cloud) for y in ys])
    np.testing.assert_allclose(euclidean_distance(ys, l_cloud), brute, rtol=1e-13)
    min_norm = np.array([np.min(np.linalg.norm(l_cloud - y, axis=1)) for y in ys])
    np.testing.assert_allclose(clearance(ys, l_cloud), min_norm, rtol=1e-12)
    assert clearance(ys[0], l_cloud) == pytest.approx(min_norm[0], rel=1e-12)
    assert euclidean_distance(l_cloud[5], l_cloud) == 0.0


# --- input validation -----------------------------------------------------------------------

GOOD_Y = np.array([1.0, 2.0, 3.0])
GOOD_CLOUD = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])


@pytest.mark.parametrize("func", [smooth_distance, smooth_projection, smooth_distance_gradient])
@pytest.mark.parametrize(
    ("y", "cloud", "eta", "sigma", "match"),
    [
        (GOOD_Y, GOOD_CLOUD, 0.0, SIGMA, "eta"),
        (GOOD_Y, GOOD_CLOUD, -0.3, SIGMA, "eta"),
        (GOOD_Y, GOOD_CLOUD, float("nan"), SIGMA, "eta"),
        (GOOD_Y, GOOD_CLOUD, float("inf"), SIGMA, "eta"),
        (GOOD_Y, GOOD_CLOUD, ETA, 0.0, "sigma"),
        (GOOD_Y, GOOD_CLOUD, ETA, -1.0, "sigma"),
        (GOOD_Y, GOOD_CLOUD, ETA, float("nan"), "sigma"),
        (GOOD_Y, np.zeros((0, 3)), ETA, SIGMA, "cloud"),
        (GOOD_Y, np.array([[0.0, np.nan, 0.0]]), ETA, SIGMA, "cloud"),
        (GOOD_Y, np.array([[0.0, np.inf, 0.0]]), ETA, SIGMA, "cloud"),
        (GOOD_Y, np.zeros((4, 2)), ETA, SIGMA, "cloud"),
        (GOOD_Y, np.zeros(3), ETA, SIGMA, "cloud"),
        (np.zeros(2), GOOD_CLOUD, ETA, SIGMA, "y"),
        (np.zeros((4, 2)), GOOD_CLOUD, ETA, SIGMA, "y"),
        (np.zeros((2, 3, 1)), GOOD_CLOUD, ETA, SIGMA, "y"),
        (np.array([0.0, np.nan, 1.0]), GOOD_CLOUD, ETA, SIGMA, "y"),
    ],
)
def test_bad_input_raises_value_error_naming_parameter(func, y, cloud, eta, sigma, match):
    """Invalid η, σ, cloud or y is rejected with a ValueError that names the culprit."""
    with pytest.raises(ValueError, match=match):
        func(y, cloud, eta, sigma)


@pytest.mark.parametrize(
    ("y", "cloud", "match"),
    [(GOOD_Y, np.zeros((0, 3)), "cloud"), (GOOD_Y, np.zeros((3, 2)), "cloud"),
     (np.zeros(4), GOOD_CLOUD, "y"), (np.full(3, np.inf), GOOD_CLOUD, "y")],
)
def test_euclidean_bad_input(y, cloud, match):
    """The baseline validates its arguments like the smooth metric."""
    with pytest.raises(ValueError, match=match):
        euclidean_distance(y, cloud)


@pytest.mark.parametrize("eta", [0.0, -1.0, float("nan")])
def test_symbolic_bad_eta(eta):
    """The symbolic builder rejects a non-positive or NaN η."""
    y = ca.SX.sym("y", 3)
    with pytest.raises(ValueError, match="eta"):
        smooth_distance_symbolic(y, ca.DM(GOOD_CLOUD), ca.DM.zeros(2), 0.0, eta)

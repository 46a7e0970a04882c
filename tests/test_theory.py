"""The theory pages (docs/theory/): the exercises' solutions, read from the page itself and run
here, and the claims the pages derive (bounds, Hessian, the shape of F, the horizon's g).

A solution is a fenced ``python`` block whose first line is ``# solution: NAME``; the blocks
of docs/theory/exercises.md run in page order in one namespace, as a reader runs them.
"""

from __future__ import annotations

import dataclasses
import math
import re

import matplotlib
import numpy as np
import pytest

from paper_repro import Config, paths
from paper_repro.problem.distance import (
    CloudWeights,
    clearance,
    euclidean_distance,
    smooth_distance,
    smooth_distance_gradient,
    smooth_projection,
)
from paper_repro.problem.ocp import OCP

matplotlib.use("Agg")

THEORY = paths.repo_root() / "docs" / "theory"
EXERCISES = THEORY / "exercises.md"
SOLUTIONS = ("lse-distance", "gradient-check", "distance-bounds", "cbf-decay")
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
_MARKER = re.compile(r"# solution: ([\w-]+)\n")


def page_blocks(page) -> list[tuple[str | None, str]]:
    """(solution name or None, code) of every fenced python block of ``page``, in order."""
    out = []
    for code in _BLOCK.findall(page.read_text()):
        marker = _MARKER.match(code)
        out.append((marker[1] if marker else None, code))
    return out


@pytest.fixture(scope="module")
def page():
    """The namespace after running every python block of the exercises page, in order."""
    namespace: dict = {}
    for _, code in page_blocks(EXERCISES):
        exec(compile(code, str(EXERCISES), "exec"), namespace)  # noqa: S102 - the page's code
    return namespace


@pytest.fixture(scope="module")
def ocp():
    return OCP(Config())


def _clouds(rng, n=6):
    """Random clouds (m, 3) of a few sizes and spreads, m."""
    return [rng.normal(scale=rng.uniform(0.3, 3.0), size=(int(rng.integers(1, 60)), 3))
            + rng.normal(scale=5.0, size=3) for _ in range(n)]


# --- the page itself ---------------------------------------------------------------------------

def test_the_page_holds_one_solution_block_per_exercise_in_order():
    names = [name for name, _ in page_blocks(EXERCISES) if name]
    assert names == list(SOLUTIONS)
    text = EXERCISES.read_text()
    assert text.index("## Solutions") < text.index("# solution: lse-distance")
    assert len(re.findall(r"^## Exercise \d", text, re.M)) == len(SOLUTIONS)


def test_the_theory_pages_show_committed_figures_only():
    for page in [*THEORY.glob("*.md"), paths.repo_root() / "docs" / "method.md"]:
        for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text()):
            figure = (page.parent / target).resolve()
            assert figure.is_file(), f"{page.name}: {target}"
            assert figure.parent == paths.figures_dir().resolve(), f"{page.name}: {target}"


@pytest.mark.parametrize("page_path", sorted(THEORY.glob("*.md")), ids=lambda p: p.stem)
def test_no_theory_page_is_longer_than_250_lines(page_path):
    assert len(page_path.read_text().splitlines()) <= 250


# --- exercise 1: D by log-sum-exp ----------------------------------------------------------------

def test_solution_1_equals_the_package_near_and_far(page):
    rng = np.random.default_rng(1)
    for cloud in _clouds(rng):
        for eta, sigma in ((0.3, 0.8), (0.05, 100.0), (1.0, 0.2)):
            ys = cloud.mean(axis=0) + rng.normal(scale=3.0, size=(8, 3))
            mine = [page["lse_distance"](y, cloud, eta, sigma) for y in ys]
            np.testing.assert_allclose(mine, smooth_distance(ys, cloud, eta, sigma),
                                       rtol=1e-12, atol=1e-12)


def test_solution_1_is_finite_where_the_printed_formula_underflows(page):
    cloud = np.random.default_rng(2).normal(size=(40, 3))
    far, eta, sigma = np.array([50.0, 0.0, 0.0]), 0.1, 0.8
    w = np.exp(-np.sum((cloud - cloud.mean(axis=0)) ** 2, axis=1) / (2 * sigma**2))
    with np.errstate(divide="ignore"):
        printed = -eta**2 * np.log(np.sum(w * np.exp(-np.sum((far - cloud) ** 2, axis=1)
                                                     / (2 * eta**2))) / w.sum())
    assert printed == np.inf
    mine = page["lse_distance"](far, cloud, eta, sigma)
    assert math.isfinite(mine) and mine == pytest.approx(smooth_distance(far, cloud, eta, sigma),
                                                         rel=1e-14)
    assert np.min(np.sum((far - cloud) ** 2, axis=1)) / (2 * eta**2) > 1e5  # as the page says


# --- exercise 2: ∇D = y − Π by central differences ----------------------------------------------

def test_solution_2_finds_y_minus_pi(page):
    rng = np.random.default_rng(3)
    for cloud in _clouds(rng):
        for y in cloud.mean(axis=0) + rng.normal(scale=2.0, size=(4, 3)):
            for fun in (lambda v, c=cloud: smooth_distance(v, c, 0.3, 0.8),
                        lambda v, c=cloud: page["lse_distance"](v, c, 0.3, 0.8)):
                fd = page["central_difference"](fun, y)
                np.testing.assert_allclose(fd, y - smooth_projection(y, cloud, 0.3, 0.8),
                                           atol=1e-9)


def test_central_differences_fail_on_a_wrong_gradient(page):
    """The check can fail: it separates y − Π from the gradient of ½‖y − Cen‖²."""
    cloud = np.random.default_rng(4).normal(size=(30, 3))
    y = np.array([1.5, 0.2, -0.4])
    fd = page["central_difference"](lambda v: smooth_distance(v, cloud, 0.3, 0.8), y)
    assert np.abs(fd - (y - cloud.mean(axis=0))).max() > 1e-3


def test_the_hessian_is_identity_minus_the_weighted_covariance_over_eta_squared(page):
    """distance.md: ∇²D = I − C/η², C the covariance of the points under the softmax p_j."""
    rng = np.random.default_rng(5)
    eta, sigma = 0.4, 1.5
    for cloud in _clouds(rng, 4):
        y = cloud.mean(axis=0) + rng.normal(scale=1.5, size=3)
        w = CloudWeights.from_cloud(cloud, sigma)
        e = w.log_weights - np.sum((y - cloud) ** 2, axis=1) / (2 * eta**2)
        p = np.exp(e - e.max())
        p /= p.sum()
        centred = cloud - p @ cloud
        hessian = np.eye(3) - (centred.T * p) @ centred / eta**2
        fd = np.column_stack([page["central_difference"](
            lambda v, k=k, c=cloud: smooth_distance_gradient(v, c, eta, sigma)[k], y)
            for k in range(3)])
        np.testing.assert_allclose(fd, hessian, atol=1e-6)


# --- exercise 3: ½d² ≤ D ≤ ½d² + η² ln(V/W_⋆) ---------------------------------------------------

def test_solution_3_bounds_hold_and_the_upper_one_is_within_the_uniform_constant(page):
    rng = np.random.default_rng(6)
    for cloud in _clouds(rng):
        w = CloudWeights.from_cloud(cloud, 0.8)
        for eta in (0.05, 0.3, 1.0):
            for y in cloud.mean(axis=0) + rng.normal(scale=3.0, size=(10, 3)):
                low, high = page["distance_bounds"](y, cloud, eta, 0.8)
                d = smooth_distance(y, cloud, eta, 0.8)
                assert low == pytest.approx(euclidean_distance(y, cloud), rel=1e-14)
                assert low - 1e-12 <= d <= high + 1e-12
                assert high <= low + eta**2 * (w.log_volume - w.log_weights.min()) + 1e-12
                # the constant's own bound: ln(V/W_⋆) <= ln m + ‖a_⋆ − Cen‖²/(2σ²)
                star = cloud[np.argmin(np.sum((y - cloud) ** 2, axis=1))]
                assert high - low <= eta**2 * (math.log(len(cloud)) + np.sum(
                    (star - w.centroid) ** 2) / (2 * 0.8**2)) + 1e-12
                assert math.sqrt(2 * low) == pytest.approx(clearance(y, cloud), rel=1e-12)


def test_the_lower_bound_is_attained_on_a_circle_and_the_upper_one_is_approached(page):
    y = np.array([1.0, -2.0, 0.5])
    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    ring = y + 1.3 * np.column_stack([np.cos(angles), np.sin(angles), np.zeros(12)])
    for sigma in (0.5, 100.0):
        assert smooth_distance(y, ring, 0.3, sigma) == pytest.approx(0.5 * 1.3**2, rel=1e-12)
    # One point near, the rest far: D tends to the upper bound.
    cloud = np.vstack([[0.0, 0.0, 0.0], 30.0 + np.random.default_rng(7).normal(size=(9, 3))])
    q = np.array([0.5, 0.0, 0.0])
    low, high = page["distance_bounds"](q, cloud, 0.3, 5.0)
    assert smooth_distance(q, cloud, 0.3, 5.0) == pytest.approx(high, abs=1e-12)
    assert high - low > 0.1  # the constant is not 0: the bound is approached, not trivial


def test_d_tends_to_half_the_squared_distance_like_eta_squared():
    rng = np.random.default_rng(8)
    cloud = rng.normal(scale=2.0, size=(50, 3))
    ys = rng.normal(scale=4.0, size=(30, 3))
    gaps = [np.max(smooth_distance(ys, cloud, eta, 0.8) - euclidean_distance(ys, cloud))
            for eta in (0.4, 0.2, 0.1, 0.05)]
    assert all(g >= -1e-12 for g in gaps)
    assert np.all(np.diff(gaps) < 0) and gaps[-1] < gaps[0] / 16 * 1.5  # O(η²)
    # ... and the limit is ½d², not d
    assert np.max(np.abs(smooth_distance(ys, cloud, 0.01, 0.8)
                         - 0.5 * clearance(ys, cloud) ** 2)) < 0.01


# --- exercise 4: the geometric decay ------------------------------------------------------------

def test_solution_4_sequences_that_keep_g_nonpositive_stay_above_the_bound(page, ocp):
    rng = np.random.default_rng(9)
    for c in (ocp.decay, 1 - ocp.decay, 0.5):
        for _ in range(20):
            beta0 = rng.uniform(0.01, 3.0)
            betas = [beta0]
            for _ in range(35):
                betas.append(c * betas[-1] + rng.exponential(0.05) * rng.integers(0, 2))
            betas = np.array(betas)
            g = page["violations"](betas, c)
            assert np.all(g <= 1e-15)
            assert np.all(betas >= page["decay_bound"](beta0, c, 35) * (1 - 1e-12))
            assert np.all(betas > 0)


def test_solution_4_violations_are_the_ocps_and_one_violation_crosses_zero(page, ocp):
    rng = np.random.default_rng(10)
    betas = rng.uniform(-1.0, 2.0, size=12)
    expected = [ocp.violation(b, b_next) for b, b_next in zip(betas[:-1], betas[1:])]
    np.testing.assert_allclose(page["violations"](betas, ocp.decay), expected, rtol=1e-15)
    # One step with g_j > c·β_j, from any β_j > 0: the next barrier is negative.
    for beta in rng.uniform(0.01, 3.0, size=10):
        g = ocp.decay * beta * rng.uniform(1.001, 3.0)
        pair = np.array([beta, ocp.decay * beta - g])
        assert page["violations"](pair, ocp.decay)[0] == pytest.approx(g, rel=1e-12)
        assert pair[1] < 0
    bound = page["decay_bound"](2.0, ocp.decay, 5)
    np.testing.assert_allclose(page["violations"](bound, ocp.decay), 0.0, atol=1e-15)


# --- barrier.md: g along the horizon and the shape of F -----------------------------------------

def test_g_at_the_equilibrium_and_the_last_step(ocp):
    """g_N pairs β(y_N) with β(y_a); at a solution y_N = y_a, so g_N = g_a = (c − 1)·β(y_a)."""
    betas = [1.4, 1.2, 0.9, 0.7, 0.7]          # β(y_0..y_N) with y_N = y_a, then β(y_a)
    gs = [float(g) for g in ocp.violations(betas + [betas[-1]])]
    assert len(gs) == len(betas) + 1
    assert gs[-2] == gs[-1] == pytest.approx((ocp.decay - 1) * betas[-1], rel=1e-15)
    assert float(ocp.equilibrium_violation(-0.1)) > 0 > float(ocp.equilibrium_violation(0.1))


def test_the_penalty_shape_stated_on_the_barrier_page():
    from paper_repro.plots.barrier import penalty_values

    config = Config()
    for kappa in (2.5, 10.0, 40.0):
        for eps in (1.0, 2.0, 3.0):
            f0 = penalty_values(config, [0.0], kappa=kappa, epsilon=eps)[0]
            assert f0 == pytest.approx(math.log(2) ** eps / kappa, rel=1e-14)
            g = np.linspace(-3.0, 3.0, 601)
            f = penalty_values(config, g, kappa=kappa, epsilon=eps)
            assert np.all(f > 0) and np.all(np.diff(f) > 0)           # positive, increasing
            assert np.all(np.diff(f, 2) > -1e-12)                      # convex
            # g ≪ 0: F ≈ e^(εκg)/κ, relative error within ε·e^(κg) (ln(1 + x) ≥ x − x²/2)
            tail = kappa * g < -3.0
            ratio = f[tail] / (np.exp(eps * kappa * g[tail]) / kappa)
            assert np.all(np.abs(ratio - 1) <= eps * np.exp(kappa * g[tail]) + 1e-13)
    g = np.array([0.1, 0.5, 2.0])
    for eps in (1.0, 2.0, 3.0):  # κ → ∞: κ^(ε−1)·max(0, g)^ε, max(0, g) only for ε = 1
        f = penalty_values(config, g, kappa=1e4, epsilon=eps)
        np.testing.assert_allclose(f, 1e4 ** (eps - 1) * g**eps, rtol=1e-3)
    g = np.linspace(-2.0, 2.0, 401)
    for kappa in (2.5, 10.0):  # ε = 1: 0 ≤ F − max(0, g) ≤ ln 2 / κ
        gap = penalty_values(config, g, kappa=kappa, epsilon=1.0) - np.maximum(g, 0)
        assert np.all(gap > 0) and np.all(gap <= math.log(2) / kappa + 1e-15)
    assert np.isfinite(penalty_values(config, [1e3], kappa=10.0)).all()  # no overflow


def test_the_penalty_figure_draws_the_ocps_values():
    import matplotlib.pyplot as plt

    from paper_repro.plots.barrier import penalty_values, plot_barrier_penalty

    config = Config()
    fig = plot_barrier_penalty(config, kappas=(2.5, 10.0), epsilons=(1.0, 3.0), n=51)
    ax_k, ax_e, ax_d = fig.axes
    solid = [line for line in ax_k.get_lines() if line.get_linestyle() == "-"]
    for line, kappa in zip(solid, (2.5, 10.0)):
        np.testing.assert_allclose(line.get_ydata(), penalty_values(
            config, line.get_xdata(), kappa=kappa))
    curves = [line for line in ax_e.get_lines() if line.get_linestyle() == "-"]
    for line, eps in zip(curves, (1.0, 3.0)):
        np.testing.assert_allclose(line.get_ydata(), penalty_values(
            config, line.get_xdata(), epsilon=eps))
    printed, definition = ax_d.get_lines()
    definition_form = OCP(dataclasses.replace(config, barrier=dataclasses.replace(
        config.barrier, form="definition"))).decay
    j = np.arange(config.nmpc.horizon + 1)
    np.testing.assert_allclose(printed.get_ydata(), OCP(config).decay ** j)
    np.testing.assert_allclose(definition.get_ydata(), definition_form ** j)
    assert OCP(config).decay == pytest.approx(1 - config.barrier.delta)
    assert definition_form == config.barrier.delta
    plt.close(fig)

"""Wind fields: Dryden turbulence with the requested σ and spectrum, reproducible from its seed;
1-cosine gusts with the exact peak and duration; MIL-F-8785C's low-altitude parameters; bad
input named."""

import math

import numpy as np
import pytest
from scipy.signal import welch

from paper_repro.world.wind import (
    FOOT,
    KNOT,
    LOW_ALTITUDE_CEILING,
    TURBULENCE_LEVELS,
    DrydenTurbulence,
    OneCosineGust,
    Wind,
    dryden_turbulence,
    low_altitude_dryden,
)

TS = 0.05        # s: coarse, to keep long records cheap (the samples are exact at any T_s)
RECORD = 10_000  # s: about 3000 correlation times of u at L_u = 15 m, V = 5 m/s


@pytest.fixture(scope="module")
def light():
    """Light turbulence at 2 m, seen at 5 m/s, and 10,000 s of it."""
    turbulence = dryden_turbulence("light", 2.0, airspeed=5.0, ts=TS, seed=7)
    return turbulence, turbulence.samples(round(RECORD / TS)).copy()


def test_the_turbulence_has_the_requested_sigma(light):
    """The sample σ of each component is within 4 standard errors of σ.

    The standard error follows from the record length: for a stationary Gaussian process
    var(σ̂²) ≈ (1/T)·∫S(f)² df (S one-sided, per Hz), and se(σ̂) = se(σ̂²)/(2σ). Here that is
    about 1 % of σ for u and v and 0.3 % for w (short L_w = h)."""
    turbulence, samples = light
    f = np.concatenate([[0.0], np.logspace(-5, 3, 20_000)])
    s2 = np.trapezoid(turbulence.spectrum(f) ** 2, f, axis=1)
    se = np.sqrt(s2 / RECORD) / (2 * turbulence.sigma)
    assert (se < 0.02 * turbulence.sigma).all()  # the record is long enough to mean something
    error = np.abs(samples.std(axis=0) - turbulence.sigma)
    assert (error < 4 * se).all(), (samples.std(axis=0), turbulence.sigma, se)


def test_the_turbulence_has_the_dryden_spectrum(light):
    """Welch's estimate, averaged over octave bands from 0.02 to 2.56 Hz, matches the Dryden
    spectrum of each component within the tolerance of :func:`band_ratios`."""
    turbulence, samples = light
    ratio, tolerance = band_ratios(samples, turbulence.spectrum)
    assert (np.abs(ratio - 1) < tolerance).all(), (ratio, tolerance)


def test_a_wrong_spectrum_would_be_caught(light):
    """The same check fails against the spectrum of half the scale lengths."""
    turbulence, samples = light
    other = DrydenTurbulence(turbulence.sigma, turbulence.length / 2, 5.0, TS)
    ratio, tolerance = band_ratios(samples, other.spectrum)
    assert (np.abs(ratio - 1) > tolerance).any(axis=1).all()


def band_ratios(samples, spectrum):
    """Welch's estimate over the model ``spectrum(f) -> (3, n)``, averaged over octave bands:
    (3, bands) ratios and their (bands,) tolerances.

    A band of n Welch bins, each averaged over K half-overlapping segments, has a relative
    standard error of about 1/√(n·K/2) (adjacent bins of a Hann window are correlated). The
    tolerance is 4 of those plus 5 %: the sampled process folds a little power back below
    Nyquist (about 3 % at 2 Hz here)."""
    f, p = welch(samples.T, fs=1 / TS, nperseg=4096)
    segments = 2 * len(samples) // 4096 - 1
    edges = 0.02 * 2.0 ** np.arange(0, 8)
    ratio, tolerance = [], []
    for low, high in zip(edges[:-1], edges[1:]):
        band = (f >= low) & (f < high)
        ratio.append(p[:, band].mean(axis=1) / spectrum(f[band]).mean(axis=1))
        tolerance.append(4 / math.sqrt(band.sum() * segments / 2) + 0.05)
    return np.array(ratio).T, np.array(tolerance)


def test_same_seed_same_gusts_in_any_order():
    a = dryden_turbulence("moderate", 3.0, airspeed=4.0, seed=3)
    b = dryden_turbulence("moderate", 3.0, airspeed=4.0, seed=3)
    late = a(95.0)  # generated in one go, where b grows its record step by step
    times = [0.0, 0.01, 12.34, 95.0, 41.0]
    assert np.array_equal(late, b(95.0))
    assert all(np.array_equal(a(t), b(t)) for t in times)
    c = dryden_turbulence("moderate", 3.0, airspeed=4.0, seed=4)
    assert not np.allclose(c(12.34), a(12.34))


def test_turbulence_is_held_over_a_sampling_interval_and_starts_stationary():
    turbulence = dryden_turbulence("light", 2.0, airspeed=5.0, ts=0.01, seed=1)
    assert np.array_equal(turbulence(0.30), turbulence(0.30 + 0.004))
    assert np.array_equal(turbulence(0.1 + 0.2), turbulence.samples(31)[30])  # 0.30000000000000004
    # Stationary from t = 0: the first samples of many seeds have σ, not a start-up transient.
    first = np.array([dryden_turbulence("light", 2.0, 5.0, seed=s)(0.0) for s in range(400)])
    se = turbulence.sigma / math.sqrt(2 * 400)
    assert (np.abs(first.std(axis=0) - turbulence.sigma) < 4 * se).all()


def test_heading_turns_u_and_v_in_the_horizontal_plane():
    east = dryden_turbulence("light", 2.0, airspeed=5.0, seed=2).samples(500)
    north = dryden_turbulence("light", 2.0, airspeed=5.0, seed=2, heading=np.pi / 2).samples(500)
    assert np.allclose(north[:, 0], -east[:, 1]) and np.allclose(north[:, 1], east[:, 0])
    assert np.array_equal(north[:, 2], east[:, 2])


def test_low_altitude_parameters_of_mil_f_8785c():
    sigma, length = low_altitude_dryden(2.0, TURBULENCE_LEVELS["light"])
    assert sigma[0] == pytest.approx(1.5, abs=0.05) and length[0] == pytest.approx(15, abs=0.5)
    assert sigma[0] == sigma[1] and length[0] == length[1]
    assert sigma[2] == pytest.approx(0.1 * 15 * KNOT) and length[2] == 2.0
    # At 1000 ft the low-altitude form meets the isotropic one: σ_u = σ_w, L_u = L_w = h.
    sigma, length = low_altitude_dryden(LOW_ALTITUDE_CEILING, 10.0)
    assert sigma == pytest.approx(np.full(3, 1.0))
    assert length == pytest.approx(np.full(3, 1000 * FOOT))


def test_one_cosine_gust_peak_and_duration_are_exact():
    amplitude = np.array([3.0, 0.0, 0.0])
    gust = OneCosineGust(amplitude, duration=0.8, start=2.0)
    assert np.array_equal(gust(2.4), amplitude)               # the peak, at start + duration/2
    assert gust(2.2) == pytest.approx(amplitude / 2)          # half way up
    t = np.linspace(0.0, 5.0, 50_001)
    g = np.array([gust(s)[0] for s in t])
    assert g.max() == 3.0 and g.min() == 0.0
    nonzero = t[g > 0]
    assert nonzero[0] - 2.0 <= 1.01e-4 and 2.8 - nonzero[-1] <= 1.01e-4  # one grid step
    held = OneCosineGust(amplitude, duration=0.5, start=1.0, hold=True)
    assert np.array_equal(held(1.5), amplitude) and np.array_equal(held(30.0), amplitude)
    assert held(1.25) == pytest.approx(amplitude / 2) and not held(1.0).any()


def test_wind_sums_mean_turbulence_and_gusts():
    turbulence = dryden_turbulence("light", 2.0, airspeed=3.0, seed=5)
    gust = OneCosineGust((0.0, 2.0, 0.0), duration=0.5, start=1.0)
    wind = Wind(mean=(3.0, 0.0, 0.0), turbulence=turbulence, gusts=[gust])
    for t in (0.0, 1.25, 7.3):
        assert wind(t) == pytest.approx(np.array([3.0, 0, 0]) + turbulence(t) + gust(t))
    assert np.array_equal(Wind(mean=(1.0, 2.0, 0.0))(4.0), [1.0, 2.0, 0.0])


@pytest.mark.parametrize("make, match", [
    (lambda: DrydenTurbulence((1, np.nan, 1), (10, 10, 2), 5.0), "sigma"),
    (lambda: DrydenTurbulence((1, -1, 1), (10, 10, 2), 5.0), "sigma must be 3 finite numbers >= 0"),
    (lambda: DrydenTurbulence((1, 1, 1), (10, 0, 2), 5.0), "length must be 3 finite numbers > 0"),
    (lambda: DrydenTurbulence((1, 1, 1), (10, 10, 2), 0.0), r"airspeed \(m/s\) must be"),
    (lambda: DrydenTurbulence((1, 1, 1), (10, 10, 2), 5.0, ts=np.inf), r"ts \(s\) must be"),
    (lambda: DrydenTurbulence((1, 1, 1), (10, 10, 2), 5.0, seed=-1), "seed must be an integer"),
    (lambda: dryden_turbulence("strong", 2.0, 5.0), "level must be one of"),
    (lambda: low_altitude_dryden(0.0, 7.7), "altitude must be > 0"),
    (lambda: low_altitude_dryden(400.0, 7.7), r"altitude \(m\) must be .* \[0.0, 304.8"),
    (lambda: low_altitude_dryden(2.0, np.nan), r"wind_6m \(m/s\) must be"),
    (lambda: OneCosineGust((3, 0), 0.5, 1.0), "amplitude must be 3 finite numbers"),
    (lambda: OneCosineGust((3, 0, 0), 0.0, 1.0), r"duration \(s\) must be .* > 0"),
    (lambda: OneCosineGust((3, 0, 0), 0.5, -1.0), r"start \(s\) must be"),
    (lambda: Wind(mean=(0, 0, np.inf)), "mean must be 3 finite numbers"),
    (lambda: Wind(turbulence=3.0), "turbulence must be a callable"),
    (lambda: dryden_turbulence("light", 2.0, 5.0)(-0.1), "t must be >= 0"),
    (lambda: Wind()(np.nan), "time t must be a finite number"),
])
def test_bad_input_is_named(make, match):
    with pytest.raises(ValueError, match=match):
        make()

"""Wind fields for a plant: a mean wind, Dryden turbulence and discrete 1-cosine gusts.

Each field is a callable of time: ``wind(t) -> (3,) array``, m/s, in the world frame
(x, y horizontal, z up), for t >= 0 in s. A plant reads it once per sampling interval, for
example :class:`~paper_repro.sim.rotorpy_plant.RotorpyPlant`. The fields are seeded: the same
arguments give the same wind, whatever the order in which times are asked.

* :class:`Wind`: a mean wind vector plus, optionally, turbulence and gusts.
* :class:`DrydenTurbulence`: the Dryden form of continuous turbulence. Its spectra and its
  low-altitude intensities and scale lengths (:func:`low_altitude_dryden`) are those of
  MIL-F-8785C, §3.7 (U.S. Military Specification, *Flying Qualities of Piloted Airplanes*,
  5 Nov. 1980), repeated in MIL-HDBK-1797 (19 Dec. 1997), Appendix A.
* :class:`OneCosineGust`: a discrete gust with the 1-cosine shape of MIL-F-8785C §3.7.5.

Frozen turbulence (Taylor's hypothesis) is assumed, as in MIL-F-8785C. The turbulent field is
fixed in the air mass, and the vehicle moves through it at a constant airspeed V. A spatial
frequency Ω (rad/m) is then felt at the time frequency ω = V·Ω (rad/s). V is a parameter.
The field is a function of time only: the vehicle's position and its changes of airspeed are
ignored. For a vehicle hovering in a mean wind, V is the speed of that wind.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm, solve_continuous_lyapunov

from paper_repro.validation import is_number, require_positive, require_range, require_time

KNOT = 0.514444
"""One knot in m/s."""

FOOT = 0.3048
"""One foot in m."""

TURBULENCE_LEVELS = {"light": 15 * KNOT, "moderate": 30 * KNOT, "severe": 45 * KNOT}
"""W₂₀, the wind speed at 20 ft (6 m) of each turbulence level of MIL-F-8785C, m/s."""

LOW_ALTITUDE_CEILING = 1000 * FOOT
"""304.8 m: the low-altitude form of MIL-F-8785C holds below 1000 ft."""

_CHUNK = 256  # fewest samples generated at a time (the sequence does not depend on it)


class Wind:
    """The wind a plant flies in: ``mean + turbulence(t) + Σ gusts(t)``.

    Parameters
    ----------
    mean : (3,) array, m/s, the mean wind in the world frame. Zero by default.
    turbulence : a :class:`DrydenTurbulence` (or any callable of t giving (3,) m/s), or None.
    gusts : a sequence of :class:`OneCosineGust` (or any callables of t giving (3,) m/s).

    ``wind(t)`` returns the (3,) wind in m/s at time t >= 0 (s).
    """

    def __init__(self, mean=(0.0, 0.0, 0.0), turbulence=None, gusts=()):
        self.mean = _vector("mean", mean)
        if turbulence is not None and not callable(turbulence):
            raise ValueError(f"turbulence must be a callable of t or None, got {turbulence!r}")
        if not all(callable(g) for g in gusts):
            raise ValueError(f"gusts must be callables of t, got {gusts!r}")
        self.turbulence = turbulence
        self.gusts = tuple(gusts)

    def __call__(self, t) -> np.ndarray:
        """The wind at time t (s): a new (3,) array, m/s."""
        require_time(t)
        out = self.mean.copy()
        if self.turbulence is not None:
            out += self.turbulence(t)
        for gust in self.gusts:
            out += gust(t)
        return out


class DrydenTurbulence:
    """Dryden turbulence: three independent Gaussian components with the spectra of
    MIL-F-8785C, seen by a vehicle at airspeed V through a frozen field.

    The one-sided spectra, in rad/s, are::

        Φ_u(ω) = σ_u² (2 L_u / π V) / (1 + (L_u ω / V)²)
        Φ_v(ω) = σ_v² (L_v / π V) (1 + 3 (L_v ω / V)²) / (1 + (L_v ω / V)²)²

    and Φ_w as Φ_v with L_w, σ_w. Each integrates to σ² over ω in [0, ∞).

    The components come out of shaping filters: a first-order one for u, a second-order one
    for v and w. Each filter is driven by continuous white noise of unit intensity and is
    discretised exactly over T_s: the state advances by e^{A T_s} plus a Gaussian increment
    whose covariance is the integral of the noise over the interval (Van Loan's method). For
    T_s small, that increment has the standard deviation √T_s of a Wiener increment: the
    discrete form of white noise whose samples scale as 1/√T_s. The filter starts in its
    stationary distribution, so the samples have exactly the continuous process's statistics
    at the sampling instants, from t = 0. Between samples the wind is held.

    Parameters
    ----------
    sigma : (σ_u, σ_v, σ_w), m/s, the standard deviations, each >= 0.
    length : (L_u, L_v, L_w), m, the scale lengths, each > 0.
    airspeed : V, m/s, > 0. The speed of the vehicle relative to the frozen field.
    ts : T_s, s, > 0. The sampling interval of the turbulence.
    seed : int >= 0, the seed of the white noise.
    heading : rad, the direction of u (the mean wind's) in the horizontal plane, from +x.
        v is horizontal, 90° to the left of u; w is vertical (+z, up).

    ``turbulence(t)`` returns the (3,) turbulent wind in the world frame at time t >= 0, m/s.
    """

    def __init__(self, sigma, length, airspeed: float, ts: float = 0.01, seed: int = 0,
                 heading: float = 0.0):
        self.sigma = _vector("sigma", sigma)
        self.length = _vector("length", length)
        if (self.sigma < 0).any():
            raise ValueError(f"sigma must be 3 finite numbers >= 0 (m/s), got {sigma!r}")
        if (self.length <= 0).any():
            raise ValueError(f"length must be 3 finite numbers > 0 (m), got {length!r}")
        require_positive("airspeed (m/s)", airspeed)
        require_positive("ts (s)", ts)
        if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        if not (is_number(heading) and math.isfinite(heading)):
            raise ValueError(f"heading must be a finite number (rad), got {heading!r}")
        self.airspeed, self.ts, self.seed = float(airspeed), float(ts), int(seed)
        self.heading = float(heading)
        self._ad, self._noise, self._c, p = _shaping_filters(self.sigma, self.length,
                                                             self.airspeed, self.ts)
        c, s = math.cos(self.heading), math.sin(self.heading)
        self._axes = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # (u, v, w) -> world
        self._rng = np.random.default_rng(self.seed)
        self._state = np.linalg.cholesky(p) @ self._rng.standard_normal(len(p))
        self._samples = np.zeros((0, 3))

    def __call__(self, t) -> np.ndarray:
        """The turbulent wind at time t (s), held over each sampling interval: (3,) m/s."""
        require_time(t)
        if t < 0:
            raise ValueError(f"time t must be >= 0 (s), got {t!r}")
        k = math.floor(t / self.ts + 1e-6)  # t = k·T_s computed in floating point is sample k
        return self.samples(k + 1)[k].copy()

    def samples(self, n: int) -> np.ndarray:
        """The first ``n`` samples, at t = 0, T_s, ..., (n−1)·T_s: (n, 3) array, m/s, world
        frame (a view: do not write to it)."""
        have = len(self._samples)
        if have < n:  # the record at least doubles: generating a long flight costs O(n)
            more = self._generate(max(n - have, have, _CHUNK))
            self._samples = np.vstack([self._samples, more])
        return self._samples[:n]

    def spectrum(self, frequency) -> np.ndarray:
        """The one-sided Dryden spectra of (u, v, w) at ``frequency`` (n,) Hz: (3, n) array,
        (m/s)²/Hz. It integrates to σ² over [0, ∞) Hz (for comparison with Welch's estimate)."""
        omega = 2 * np.pi * np.asarray(frequency, float)
        out = []
        for i, (sig, ell) in enumerate(zip(self.sigma, self.length)):
            x = (ell * omega / self.airspeed) ** 2
            if i == 0:
                phi = sig**2 * 2 * ell / (np.pi * self.airspeed) / (1 + x)
            else:
                phi = sig**2 * ell / (np.pi * self.airspeed) * (1 + 3 * x) / (1 + x) ** 2
            out.append(2 * np.pi * phi)  # per rad/s -> per Hz
        return np.array(out)

    def _generate(self, n: int) -> np.ndarray:
        """The next ``n`` samples of (u, v, w) rotated to the world frame: (n, 3)."""
        increments = self._rng.standard_normal((n, len(self._state))) @ self._noise.T
        out = np.empty((n, 3))
        x = self._state
        for k in range(n):
            out[k] = self._c @ x
            x = self._ad @ x + increments[k]
        self._state = x
        return out @ self._axes.T


class OneCosineGust:
    """A discrete gust of 1-cosine shape, m/s, in the world frame.

    ``hold=False`` (the default): a pulse that rises and falls over ``duration``::

        g(t) = amplitude · ½ (1 − cos(2π (t − start) / duration))

    for start <= t <= start + duration, and 0 outside. It peaks at ``amplitude`` at
    start + duration/2.

    ``hold=True``: the discrete gust of MIL-F-8785C §3.7.5. It rises over ``duration`` as
    amplitude · ½ (1 − cos(π (t − start) / duration)) and then stays at ``amplitude``.

    Parameters
    ----------
    amplitude : (3,) array, m/s, the peak gust vector (e.g. 2–4 m/s along a horizontal axis).
    duration : s, > 0, the length of the pulse (or of the rise, when ``hold``).
    start : s, >= 0, when the gust begins.
    hold : bool, whether the gust stays at its peak after it has risen.
    """

    def __init__(self, amplitude, duration: float, start: float, hold: bool = False):
        self.amplitude = _vector("amplitude", amplitude)
        require_positive("duration (s)", duration)
        require_range("start (s)", start, 0.0, math.inf)
        if not isinstance(hold, bool):
            raise ValueError(f"hold must be a bool, got {hold!r}")
        self.duration, self.start, self.hold = float(duration), float(start), hold

    def __call__(self, t) -> np.ndarray:
        """The gust at time t (s): a new (3,) array, m/s."""
        require_time(t)
        s = (t - self.start) / self.duration
        if s <= 0 or (s >= 1 and not self.hold):
            return np.zeros(3)
        if s >= 1:
            return self.amplitude.copy()
        phase = np.pi * s if self.hold else 2 * np.pi * s
        return self.amplitude * 0.5 * (1 - math.cos(phase))


def low_altitude_dryden(altitude: float, wind_6m: float) -> tuple[np.ndarray, np.ndarray]:
    """The intensities and scale lengths of MIL-F-8785C's low-altitude turbulence.

    With h the altitude in ft and W₂₀ the wind speed at 20 ft (6 m)::

        L_w = h,   L_u = L_v = h / (0.177 + 0.000823 h)^1.2
        σ_w = 0.1 W₂₀,   σ_u = σ_v = σ_w / (0.177 + 0.000823 h)^0.4

    At 2 m in light turbulence (W₂₀ = 15 kt) this gives σ_u ≈ 1.5 m/s and L_u ≈ 15 m.
    The form holds below 1000 ft (304.8 m); near the ground L_w = h becomes small.

    Parameters
    ----------
    altitude : h, m, in (0, 304.8].
    wind_6m : W₂₀, m/s, >= 0: the wind speed at 6 m, or a level of
        :data:`TURBULENCE_LEVELS` (light 7.7, moderate 15.4, severe 23.2 m/s).

    Returns
    -------
    sigma : (3,) array, (σ_u, σ_v, σ_w), m/s.
    length : (3,) array, (L_u, L_v, L_w), m.
    """
    require_range("altitude (m)", altitude, 0.0, LOW_ALTITUDE_CEILING, closed_upper=True)
    if altitude == 0:
        raise ValueError(f"altitude must be > 0 (m), got {altitude!r}")
    require_range("wind_6m (m/s)", wind_6m, 0.0, math.inf)
    h = altitude / FOOT
    base = 0.177 + 0.000823 * h
    sigma_w = 0.1 * wind_6m
    sigma_u = sigma_w / base**0.4
    length_u = h / base**1.2 * FOOT
    return np.array([sigma_u, sigma_u, sigma_w]), np.array([length_u, length_u, altitude])


def dryden_turbulence(level: str | float, altitude: float, airspeed: float, ts: float = 0.01,
                      seed: int = 0, heading: float = 0.0) -> DrydenTurbulence:
    """Low-altitude Dryden turbulence of a level (``"light"``, ``"moderate"``, ``"severe"``,
    or W₂₀ in m/s) at ``altitude`` (m), seen at ``airspeed`` V (m/s); see
    :func:`low_altitude_dryden` and :class:`DrydenTurbulence` for the other arguments."""
    if isinstance(level, str):
        if level not in TURBULENCE_LEVELS:
            raise ValueError(f"level must be one of {tuple(TURBULENCE_LEVELS)} or W20 in m/s, "
                             f"got {level!r}")
        level = TURBULENCE_LEVELS[level]
    sigma, length = low_altitude_dryden(altitude, level)
    return DrydenTurbulence(sigma, length, airspeed, ts, seed, heading)


def _shaping_filters(sigma, length, airspeed, ts):
    """The exact discrete form of the three shaping filters, stacked (5 states).

    Returns Ad (5, 5), a square root of the increments' covariance (5, 5), the output map
    C (3, 5) scaled so that each output has variance σ², and the stationary covariance P (5, 5).
    """
    blocks = []
    for i, ell in enumerate(length):
        tau = ell / airspeed
        if i == 0:  # 1 / (1 + τ s)
            a, b, c = np.array([[-1 / tau]]), np.array([[1.0]]), np.array([1.0])
        else:  # (1 + √3 τ s) / (1 + τ s)², controllable canonical form
            a = np.array([[0.0, 1.0], [-1 / tau**2, -2 / tau]])
            b = np.array([[0.0], [1.0]])
            c = np.array([1 / tau**2, math.sqrt(3) / tau])
        p = solve_continuous_lyapunov(a, -b @ b.T)
        blocks.append((a, b, c * sigma[i] / math.sqrt(c @ p @ c), p))
    n = sum(len(a) for a, *_ in blocks)
    a_all, bb, c_all, p_all = np.zeros((n, n)), np.zeros((n, n)), np.zeros((3, n)), np.zeros((n, n))
    j = 0
    for i, (a, b, c, p) in enumerate(blocks):
        m = len(a)
        a_all[j:j + m, j:j + m], bb[j:j + m, j:j + m] = a, b @ b.T
        c_all[i, j:j + m], p_all[j:j + m, j:j + m] = c, p
        j += m
    # Van Loan: expm([[-A, BBᵀ], [0, Aᵀ]]·T_s) = [[·, F12], [0, F22]], Ad = F22ᵀ, Q = F22ᵀ·F12.
    f = expm(np.block([[-a_all, bb], [np.zeros((n, n)), a_all.T]]) * ts)
    ad = f[n:, n:].T
    q = ad @ f[:n, n:]
    q = 0.5 * (q + q.T)
    w, v = np.linalg.eigh(q)
    return ad, v * np.sqrt(np.clip(w, 0, None)), c_all, p_all


def _vector(name: str, value) -> np.ndarray:
    """A (3,) finite float array, m/s, or a ValueError naming ``name``."""
    arr = np.asarray(value, dtype=float) if not isinstance(value, (str, bytes)) else None
    if arr is None or arr.shape != (3,) or not np.isfinite(arr).all():
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return arr

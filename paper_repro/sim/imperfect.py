"""What stands between a real controller and its vehicle: an estimated state and a delay.

Both wrap any :class:`~paper_repro.sim.plant.Plant` and are plants themselves, so the closed
loop does not change:

* :class:`EstimatedState`: the controller is given the state of ``latency`` steps ago, with
  Gaussian noise on each component (``measure``). The vehicle flies its true state.
* :class:`DelayedInput`: the input computed at step k is applied from step k + ``delay``
  (the time a solve and its transport take); the rest input before that. The result logs
  the input the controller computed, not the one applied.

Four remedies are plant wrappers too:

* :class:`EstimateFilter`: the noisy estimate is filtered with the nominal model: each step
  predicts the state through the input applied, then moves the prediction a fixed share of
  the way to the new measurement.
* :class:`LatencyCompensation`: the controller is given the state its next input will meet,
  predicted with the nominal model over the known latency through the inputs already sent.
* :class:`HoverThrustEstimate`: the thrusts sent are scaled by an estimate of how much
  thrust the vehicle lacks, learnt from its vertical acceleration (as PX4's hover-thrust
  estimator does); a heavier vehicle or weaker rotors no longer sag below the plan.
* :class:`MotorLagCompensation`: each thrust is sent with a lead, u + τ̂·u̇, so that rotors
  with a first-order lag of time constant τ̂ make the thrust the plan asked for.

:func:`~paper_repro.sim.plant.plant_for` builds them from ``config.plant``
(``estimation``, ``delay_steps``, ``estimate_filter_time``, ``compensate_latency``,
``hover_thrust_time``, ``motor_lag_compensation``).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from paper_repro.validation import as_vector


class EstimatedState:
    """``plant``, measured through a noisy, late estimate.

    Parameters
    ----------
    plant : the plant flown.
    sigma : (n_x,) standard deviations of the noise on each state component, >= 0.
    latency : steps of T_s between a state and the estimate of it, an integer >= 0.
    seed : seed of the noise.
    """

    def __init__(self, plant, sigma, latency: int, seed: int = 0):
        self.plant = plant
        self.sigma = np.asarray(sigma, float)
        if self.sigma.ndim != 1 or not (np.isfinite(self.sigma).all()
                                        and (self.sigma >= 0).all()):
            raise ValueError(f"sigma must be a vector of finite numbers >= 0, got {sigma!r}")
        if not (isinstance(latency, int) and not isinstance(latency, bool) and latency >= 0):
            raise ValueError(f"latency must be an integer >= 0 (steps), got {latency!r}")
        self.latency, self.seed = latency, seed
        self._history: deque = deque(maxlen=latency + 1)
        self._rng = np.random.default_rng(seed)

    def reset(self, x0) -> None:
        """Start a flight at x0: the estimate starts as x0 (the vehicle at rest before it)."""
        x0 = as_vector("x0", x0, len(self.sigma))
        self._history.clear()
        self._history.extend([x0.copy()] * (self.latency + 1))
        self._rng = np.random.default_rng(self.seed)
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        x_next = self.plant.step(x, u)
        self._history.append(np.array(x_next, float))
        return x_next

    def measure(self, x) -> np.ndarray:
        """The estimate the controller is given while the vehicle is in ``x``: the state
        ``latency`` steps ago (``x`` itself with no latency), plus noise; a new array."""
        if not self._history:
            self.reset(x)
        late = np.array(x if self.latency == 0 else self._history[0], float)
        return late + self.sigma * self._rng.standard_normal(len(self.sigma))


class DelayedInput:
    """``plant``, whose inputs arrive ``delay`` steps late.

    Parameters
    ----------
    plant : the plant flown.
    delay : steps of T_s, an integer >= 1.
    rest_input : (n_u,) the input applied before the first computed one arrives (the
        quadrotor's hover thrusts).
    """

    def __init__(self, plant, delay: int, rest_input):
        if not (isinstance(delay, int) and not isinstance(delay, bool) and delay >= 1):
            raise ValueError(f"delay must be an integer >= 1 (steps), got {delay!r}")
        self.plant, self.delay = plant, delay
        self.rest_input = np.asarray(rest_input, float)
        self._queue: deque = deque()

    def reset(self, x0) -> None:
        self._queue = deque([self.rest_input.copy()] * self.delay)
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        """Apply the input of ``delay`` steps ago and queue ``u``."""
        if not self._queue:
            self._queue = deque([self.rest_input.copy()] * self.delay)
        self._queue.append(np.array(u, float))
        return self.plant.step(x, self._queue.popleft())

    def measure(self, x) -> np.ndarray:
        measure = getattr(self.plant, "measure", None)
        return measure(x) if callable(measure) else x


class EstimateFilter:
    """``plant``, measured through a filter of its noisy estimate with the nominal model: a
    remedy for the estimate's noise.

    The estimate at step k is of the state L steps ago, and the input sent at step j acts from
    step j + d. Between two estimates the filter predicts its state x̂ with the nominal model
    through the input that acted; then it moves the prediction a share K of the way to the new
    estimate, x̂ ← x̂⁻ + K·(y − x̂⁻), with K = 1 − exp(−T_s/τ) (a first-order filter of time
    constant τ, whose prediction is the model's rather than a constant). With the nominal
    model as the plant and no noise, x̂ is the state the estimate is of; white noise of σ
    leaves about σ·√(K/(2 − K)). The filtered state is as late as the estimate: give it
    to :class:`LatencyCompensation` to predict over the latency.

    Parameters
    ----------
    plant : the plant flown (with its estimate and its delay).
    nominal : a plant of the nominal model (``step(x, u)`` over T_s), used to predict.
    ts : s, the sampling period T_s, > 0.
    time_constant : τ, s, > 0.
    steps : L + d, the estimate's latency and the delay in steps of T_s, an integer >= 0.
    rest_input : (n_u,) the input sent before the flight (the hover thrusts).
    """

    def __init__(self, plant, nominal, ts: float, time_constant: float, steps: int,
                 rest_input):
        if not (ts > 0 and time_constant > 0 and np.isfinite(time_constant)):
            raise ValueError(f"ts and time_constant must be finite numbers of seconds > 0, got "
                             f"{ts!r} and {time_constant!r}")
        if not (isinstance(steps, int) and not isinstance(steps, bool) and steps >= 0):
            raise ValueError(f"steps must be an integer >= 0 (L + d), got {steps!r}")
        self.plant, self.nominal, self.steps = plant, nominal, steps
        self.gain = 1.0 - float(np.exp(-ts / time_constant))
        self.rest_input = np.asarray(rest_input, float)
        self._sent: deque = deque(maxlen=steps + 1)
        self._estimate = self._prediction = None

    def reset(self, x0) -> None:
        """Start a flight at x0, known: the filter starts there, the rotors at rest."""
        self._sent.clear()
        self._sent.extend([self.rest_input.copy()] * (self.steps + 1))
        self._estimate = np.array(x0, float)
        self._prediction = None
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        """Send ``u``, step the plant, and predict the filter's state one step on, through
        the input that acted over the step its next estimate is of (sent L + d steps ago)."""
        if self._estimate is None:
            self.reset(x)
        self._sent.append(np.array(u, float))
        if self._prediction is None:  # the estimate of this step was never read
            self._prediction = self._estimate
        self._prediction = np.asarray(self.nominal.step(self._prediction, self._sent[0]),
                                      float)
        return self.plant.step(x, u)

    def measure(self, x) -> np.ndarray:
        """The filtered estimate while the vehicle is in ``x`` (read as often as needed within
        a step: the correction is made once); a non-finite estimate is handed on as it is."""
        if self._estimate is None:
            self.reset(x)
        if self._prediction is not None:
            measure = getattr(self.plant, "measure", None)
            y = np.array(measure(x) if callable(measure) else x, float)
            if not np.isfinite(y).all():
                return y
            self._estimate = self._prediction + self.gain * (y - self._prediction)
            self._prediction = None
        return self._estimate.copy()


class LatencyCompensation:
    """``plant``, measured through a prediction over its known latency: a remedy.

    The state measured at step k is that of step k − L (an estimate ``L`` steps late), and
    the input computed now acts from step k + d (a delay of ``d`` steps). The inputs applied
    in between are known: they are the last L + d inputs sent. So the measured state is rolled
    forward through them with the nominal model, and the controller is given its prediction of
    the state at k + d. With the nominal model as the plant and no noise, it is that state.

    Parameters
    ----------
    plant : the plant flown (with its estimate and its delay).
    nominal : a plant of the nominal model (``step(x, u)`` over T_s), used to predict.
    steps : L + d, an integer >= 1.
    rest_input : (n_u,) the input sent before the flight (the hover thrusts).
    """

    def __init__(self, plant, nominal, steps: int, rest_input):
        if not (isinstance(steps, int) and not isinstance(steps, bool) and steps >= 1):
            raise ValueError(f"steps must be an integer >= 1 (L + d), got {steps!r}")
        self.plant, self.nominal, self.steps = plant, nominal, steps
        self.rest_input = np.asarray(rest_input, float)
        self._sent: deque = deque(maxlen=steps)

    def reset(self, x0) -> None:
        self._sent.clear()
        self._sent.extend([self.rest_input.copy()] * self.steps)
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        """Send ``u`` and step the plant."""
        if not self._sent:
            self._sent.extend([self.rest_input.copy()] * self.steps)
        self._sent.append(np.array(u, float))
        return self.plant.step(x, u)

    def measure(self, x) -> np.ndarray:
        """The plant's measurement rolled forward through the last L + d inputs sent; a
        non-finite measurement is handed on as it is (the loop treats it as a fault)."""
        measure = getattr(self.plant, "measure", None)
        m = np.array(measure(x) if callable(measure) else x, float)
        if not np.isfinite(m).all():
            return m
        if not self._sent:
            self._sent.extend([self.rest_input.copy()] * self.steps)
        for u in self._sent:
            m = np.asarray(self.nominal.step(m, u), float)
        return m


class HoverThrustEstimate:
    """``plant``, whose thrusts are scaled by a learnt correction: a remedy.

    The NMPC plans with the nominal mass and thrust coefficient. If the vehicle makes k times
    the thrust the nominal model predicts for its weight (k = thrust_scale / mass_scale, say),
    it sags or climbs off the plan, and the NMPC, which has no integral action, settles off
    its target. This wrapper estimates k from the measured vertical acceleration and sends
    the thrusts divided by the estimate k̂, so the vehicle makes the thrust the plan asked for.

    Each step, from two successive measurements m₀ (k − 1) and m₁ (k), and the thrusts f
    applied in between (sent ``latency`` steps before, the estimate's and the input's delay):

    * measured: a = (v_z(m₁) − v_z(m₀))/T_s + g;
    * nominal: a₀ = R₃₃(m₀)·Σf / m, with R₃₃ = cos φ cos θ the body z-axis' vertical part;
    * k̂ ← k̂ + (T_s/τ)·(a/a₀ − k̂), a first-order filter of time constant τ, read only while
      a₀ > g/2 (the thrust carries most of the weight, so the ratio is well posed).

    Anything else that pushes the vehicle vertically (drag of a climb, a vertical gust) moves
    k̂ too, as on PX4; τ sets how fast it follows. The scaled thrusts are clipped to the
    rotors' bounds.

    Parameters
    ----------
    plant : the plant flown (with its estimate and its delay).
    ts : T_s, s.  mass : the nominal mass, kg.  gravity : g, m/s².
    time_constant : τ, s, > 0.
    input_bounds : ((n_u,), (n_u,)) the thrusts' bounds, N.
    latency : L + d, steps of T_s between an input sent and the measurement that shows it,
        an integer >= 0.
    rest_input : (n_u,) the thrusts sent before the flight (hover).
    """

    def __init__(self, plant, ts: float, mass: float, gravity: float, time_constant: float,
                 input_bounds, latency: int, rest_input):
        if not (time_constant > 0 and np.isfinite(time_constant)):
            raise ValueError(f"time_constant must be a finite number of seconds > 0, "
                             f"got {time_constant!r}")
        if not (isinstance(latency, int) and not isinstance(latency, bool) and latency >= 0):
            raise ValueError(f"latency must be an integer >= 0 (steps), got {latency!r}")
        self.plant, self.ts, self.mass, self.gravity = plant, ts, mass, gravity
        self.gain = min(1.0, ts / time_constant)
        self.lower, self.upper = (np.asarray(b, float) for b in input_bounds)
        self.latency = latency
        self.rest_input = np.asarray(rest_input, float)
        self.estimate = 1.0  # k̂
        self._applied: deque = deque(maxlen=latency + 1)
        self._last: np.ndarray | None = None

    def reset(self, x0) -> None:
        self.estimate, self._last = 1.0, None
        self._applied.clear()
        self._applied.extend([self.rest_input.copy()] * (self.latency + 1))
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        """Send ``u`` / k̂, clipped to the bounds, and step the plant."""
        if not self._applied:
            self.reset(x)
        f = np.clip(np.asarray(u, float) / self.estimate, self.lower, self.upper)
        self._applied.append(f)
        return self.plant.step(x, f)

    def measure(self, x) -> np.ndarray:
        """The plant's measurement, handed on unchanged; k̂ learns from it."""
        measure = getattr(self.plant, "measure", None)
        m = np.asarray(measure(x) if callable(measure) else x, float)
        if not self._applied:
            self.reset(x)
        if self._last is not None and np.isfinite(m).all():
            self._learn(self._last, m, self._applied[0])
        self._last = m.copy() if np.isfinite(m).all() else None
        return m

    def _learn(self, m0, m1, f) -> None:
        """One update of k̂ from the measurements m0 → m1 under the thrusts f."""
        phi, theta = m0[3], m0[4]
        nominal = np.cos(phi) * np.cos(theta) * float(np.sum(f)) / self.mass
        if nominal <= self.gravity / 2:
            return
        measured = (m1[8] - m0[8]) / self.ts + self.gravity
        self.estimate += self.gain * (measured / nominal - self.estimate)
        self.estimate = float(np.clip(self.estimate, 0.5, 2.0))


class MotorLagCompensation:
    """``plant``, whose rotors lag, driven through the inverse of the lag: a remedy.

    A rotor with a first-order lag of time constant τ turns a command c into a thrust f with
    τ·ḟ + f = c. Sending c = u + τ̂·u̇ for the planned thrust u makes f = u when τ̂ = τ (exactly
    for a ramp, after the transient). Each step sends

        c_k = u_k + (τ̂ / T_s)·(u_k − u_{k−1}),

    clipped to the rotors' bounds (the first step sends u_0). A constant thrust is sent as it
    is. τ̂ is the rotors' time constant as identified (a bench test of a motor's step).

    Parameters
    ----------
    plant : the plant flown.
    ts : T_s, s.  time_constant : τ̂, s, > 0.
    input_bounds : ((n_u,), (n_u,)) the thrusts' bounds, N.
    """

    def __init__(self, plant, ts: float, time_constant: float, input_bounds):
        if not (time_constant > 0 and np.isfinite(time_constant)):
            raise ValueError(f"time_constant must be a finite number of seconds > 0, "
                             f"got {time_constant!r}")
        self.plant, self.gain = plant, time_constant / ts
        self.lower, self.upper = (np.asarray(b, float) for b in input_bounds)
        self._last: np.ndarray | None = None

    def reset(self, x0) -> None:
        self._last = None
        if callable(getattr(self.plant, "reset", None)):
            self.plant.reset(x0)

    def step(self, x, u) -> np.ndarray:
        """Send ``u`` with its lead and step the plant."""
        u = np.array(u, float)
        c = u if self._last is None else u + self.gain * (u - self._last)
        self._last = u
        return self.plant.step(x, np.clip(c, self.lower, self.upper))

    def measure(self, x) -> np.ndarray:
        measure = getattr(self.plant, "measure", None)
        return measure(x) if callable(measure) else x

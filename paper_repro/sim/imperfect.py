"""What stands between a real controller and its vehicle: an estimated state and a delay.

Both wrap any :class:`~paper_repro.sim.plant.Plant` and are plants themselves, so the closed
loop does not change:

* :class:`EstimatedState`: the controller is given the state of ``latency`` steps ago, with
  Gaussian noise on each component (``measure``). The vehicle flies its true state.
* :class:`DelayedInput`: the input computed at step k is applied from step k + ``delay``
  (the time a solve and its transport take); the rest input before that. The result logs
  the input the controller computed, not the one applied.

One remedy is a plant wrapper too:

* :class:`LatencyCompensation`: the controller is given the state its next input will meet,
  predicted with the nominal model over the known latency through the inputs already sent.

:func:`~paper_repro.sim.plant.plant_for` builds them from ``config.plant``
(``estimation``, ``delay_steps``, ``compensate_latency``).
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

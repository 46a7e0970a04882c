"""The mission's clock: the tracking NMPC linearised at hover (paper_repro.analysis.clock)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from paper_repro.analysis import clock as timeline
from paper_repro.config import Config, NMPCParams
from paper_repro.studies.catalogue import (
    CANDIDATES,
    TIMELINE_QUICK_STEPS,
    candidate_config,
    timeline_study,
)
from paper_repro.vehicles.quadrotor import equilibrium
from paper_repro.world.scene import Scene

# One region slot of one point: the barrier terms are inactive far from the clouds anyway, and
# the small slot keeps building the solvers quick.
SMALL = Config(nmpc=NMPCParams(region_slots=1, points_per_region=1))


def _variant(config: Config = SMALL, **nmpc) -> Config:
    return dataclasses.replace(config, nmpc=dataclasses.replace(config.nmpc, **nmpc))


def _scaled(name: str, factor: float, indices=None, config: Config = SMALL) -> Config:
    values = list(getattr(config.nmpc, name))
    for i in indices if indices is not None else range(len(values)):
        values[i] *= factor
    return _variant(config, **{name: tuple(values)})


@pytest.fixture(scope="module")
def printed() -> timeline.ClockAnalysis:
    return timeline.clock(Config())


# --- prediction_ts ---------------------------------------------------------------------------

def test_prediction_step_defaults_to_the_sampling_period():
    assert NMPCParams().prediction_step == NMPCParams().ts
    assert NMPCParams(prediction_ts=0.02).prediction_step == 0.02
    cfg = _variant(Config(), prediction_ts=0.02)
    assert Config.from_dict(cfg.to_dict()).nmpc.prediction_step == 0.02


@pytest.mark.parametrize("bad", [0.0, -0.01, float("nan"), float("inf")])
def test_prediction_ts_must_be_positive(bad):
    with pytest.raises(ValueError, match="prediction_ts"):
        NMPCParams(prediction_ts=bad)


def test_prediction_model_uses_the_prediction_step():
    a_10, b_10 = timeline.prediction_linearisation(SMALL)
    a_20, b_20 = timeline.prediction_linearisation(_variant(prediction_ts=0.02))
    # Position integrates velocity over one prediction step h.
    assert a_10[0, 6] == pytest.approx(0.01)
    assert a_20[0, 6] == pytest.approx(0.02)
    # At hover the linearised quadrotor is a chain of at most four integrators (A_c⁵ = 0),
    # which RK4 integrates exactly: the prediction model's Jacobians are the plant's exact
    # zero-order-hold discretisation over the same step, to rounding.
    a_p, b_p = timeline.plant_linearisation(SMALL)
    np.testing.assert_allclose(a_10, a_p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b_10, b_p, rtol=0, atol=1e-12)


# --- the LQ problem is the OCP linearised ------------------------------------------------------

def test_lq_feedback_is_the_first_input_of_the_nmpc_near_hover():
    """IPOPT on the full OCP (21), far from any cloud: u_0 − u_lin shrinks as the square of the
    deviation from hover, so the LQ feedback is its exact linearisation."""
    from paper_repro.solvers.ipopt import TrackingNMPC

    ctl = TrackingNMPC(SMALL, tol=1e-12)
    gain_x, gain_t = timeline.lq_feedback(SMALL)
    rest, hover = equilibrium([1.0, -0.5, 10.0])
    step = np.zeros(12)
    step[[0, 1, 2, 3, 6, 11]] = [0.3, 0.3, 0.1, 1e-3, 0.02, 0.01]
    errors = []
    for scale in (0.1, 0.01):
        x0 = rest + scale * step
        sol = ctl.solve(x0, rest[:3])
        assert sol.success
        u_lin = hover + gain_x @ x0 + gain_t @ rest[:3]
        assert np.max(np.abs(sol.u[0] - hover)) > 1e-3 * scale  # the input does move
        errors.append(np.max(np.abs(sol.u[0] - u_lin)))
    assert errors[1] < 0.02 * errors[0]  # quadratic, not linear, in the deviation
    assert errors[1] < 1e-6


def test_any_equilibrium_at_the_target_is_a_fixed_point(printed):
    """Translation invariance: hovering at y_t (any yaw) is an equilibrium of the closed loop,
    which is what lets predicted_mission_time iterate the error alone."""
    target = np.array([-12.0, 18.0, 11.0])
    for yaw in (0.0, 0.7):
        rest, _ = equilibrium(target, yaw)
        np.testing.assert_allclose(printed.closed_loop @ rest + printed.target_input @ target,
                                   rest, atol=1e-9)


# --- the clock -------------------------------------------------------------------------------

def test_printed_parameters_give_the_measured_time_constants(printed):
    assert 140.0 <= printed.tau_lateral_s <= 165.0  # ≈ 154.7 s
    assert printed.tau_vertical_s < 30.0  # ≈ 6.3 s: z converges within tens of seconds
    assert printed.tau_yaw_s == np.inf  # no set-point on ψ: a neutral mode
    assert np.all(np.abs(printed.eigenvalues) <= 1.0 + 1e-9)
    assert printed.axes.count("lateral") == 8
    assert printed.axes.count("vertical") == 2


@pytest.mark.parametrize("factor", [3.0, 10.0])
def test_lateral_tau_scales_as_one_over_T(factor):
    """τ·T is constant to 0.1 % (0.9998 at ×3, 0.9990 at ×10): not exactly, because τ is
    affine in 1/T, τ = α/T + β with β ≈ −0.017 s ≈ −1e-4·τ, which the next test checks."""
    tau = timeline.clock(SMALL).tau_lateral_s
    scaled = timeline.clock(_scaled("t", factor)).tau_lateral_s
    assert factor * scaled / tau == pytest.approx(1.0, abs=2e-3)


def test_lateral_tau_is_affine_in_one_over_T():
    taus = {k: timeline.clock(_scaled("t", k)).tau_lateral_s for k in (1.0, 3.0, 10.0)}
    alpha, beta = np.linalg.solve([[1.0, 1.0], [1 / 3, 1.0]], [taus[1.0], taus[3.0]])
    assert abs(beta) < 1e-3 * alpha  # β is a small correction ...
    assert alpha / 10 + beta == pytest.approx(taus[10.0], rel=1e-4)  # ... and it is real
    assert alpha / 10 != pytest.approx(taus[10.0], rel=1e-4)


def test_only_the_ratio_of_stage_weights_to_T_matters():
    """Halving Q and R is halving the whole cost after doubling T: the same minimiser."""
    half_stage = _scaled("r", 0.5, config=_scaled("q", 0.5))
    double_t = _scaled("t", 2.0)
    a, b = timeline.clock(half_stage), timeline.clock(double_t)
    assert a.tau_lateral_s == pytest.approx(b.tau_lateral_s, rel=1e-9)
    assert a.tau_vertical_s == pytest.approx(b.tau_vertical_s, rel=1e-9)


@pytest.mark.parametrize("indices", [(0, 1), (6, 7), (0, 1, 2, 6, 7, 8)],
                         ids=["position_xy", "velocity_xy", "position_and_velocity"])
@pytest.mark.parametrize("factor", [0.1, 10.0])
def test_lateral_tau_hardly_depends_on_position_and_velocity_weights(indices, factor):
    """Within 0.5 % over a factor 10 either way (the velocity weight ×10 moves τ by +0.43 %;
    ×100 would move it by 4.7 %): the lateral clock is set by R, the rate weights and T."""
    tau = timeline.clock(SMALL).tau_lateral_s
    assert timeline.clock(_scaled("q", factor, indices)).tau_lateral_s == pytest.approx(
        tau, rel=5e-3)


def test_lateral_and_vertical_axes_are_decoupled():
    base = timeline.clock(SMALL)
    vertical_weights = timeline.clock(_scaled("q", 10.0, (2, 8)))
    lateral_weights = timeline.clock(_scaled("q", 10.0, (0, 1, 3, 4, 6, 7, 9, 10)))
    assert vertical_weights.tau_lateral_s == pytest.approx(base.tau_lateral_s, rel=1e-8)
    assert lateral_weights.tau_vertical_s == pytest.approx(base.tau_vertical_s, rel=1e-8)
    assert vertical_weights.tau_vertical_s != pytest.approx(base.tau_vertical_s, rel=1e-2)


def test_a_longer_terminal_horizon_speeds_the_clock_up():
    taus = [timeline.clock(_variant(**kw)).tau_lateral_s
            for kw in ({}, {"horizon": 44}, {"prediction_ts": 0.012}, {"prediction_ts": 0.02})]
    assert taus[0] > 2.5 * taus[1] and taus[0] > 2.5 * taus[2] and taus[2] > 10 * taus[3]


# --- mission time ----------------------------------------------------------------------------

def test_mission_time_is_the_first_crossing_of_the_linear_loop():
    """The blockwise search agrees step for step with a plain iteration of the loop."""
    cfg = _variant(prediction_ts=0.02)  # a fast clock: a few thousand steps
    an = timeline.clock(cfg)
    start, targets = np.array([3.0, -4.0, 2.0]), np.array([[0.0, 0.0, 3.0], [1.0, 1.0, 1.0]])
    times, total = timeline.predicted_mission_time(cfg, start, targets, tolerance=0.3,
                                                   analysis=an)
    x, _ = equilibrium(start)
    expected, k = [], 0
    for target in targets:
        while np.linalg.norm(x[:3] - target) >= 0.3:
            x = an.closed_loop @ x + an.target_input @ target
            k += 1
        expected.append(k * cfg.nmpc.ts)
    np.testing.assert_allclose(times, expected, rtol=0, atol=1e-9)
    assert total == times[-1]


def test_printed_mission_time_of_the_linear_loop(printed):
    times, total = timeline.predicted_mission_time(Config(), analysis=printed)
    # About 1329 s: the flown 1389 s of Fig. 4 less the detours around the clouds.
    assert 1200.0 < total < 1400.0
    assert 0.0 < times[0] < total
    fast, _ = timeline.predicted_mission_time(_scaled("t", 10.0, config=Config()))
    assert fast[-1] < total / 5


def test_unreached_targets_take_forever():
    times, total = timeline.predicted_mission_time(SMALL, max_time=10.0)
    assert np.all(np.isinf(times)) and total == np.inf


@pytest.mark.parametrize("kwargs, name", [({"tolerance": 0.0}, "tolerance"),
                                          ({"max_time": -1.0}, "max_time"),
                                          ({"start": (0.0, 1.0)}, "start")])
def test_bad_mission_arguments_are_named(kwargs, name):
    with pytest.raises(ValueError, match=name):
        timeline.predicted_mission_time(SMALL, **kwargs)


# --- flights ---------------------------------------------------------------------------------

FLIGHTS = {  # config, lateral distance to the target (m), flight (s), fit from (s)
    "printed": (SMALL, 8.0, 10.0, 2.0),
    "T_x10": (_scaled("t", 10.0), 8.0, 10.0, 2.0),
    "prediction_ts_0.02": (_variant(prediction_ts=0.02), 3.0, 4.0, 1.0),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(FLIGHTS))
def test_flown_lateral_decay_matches_the_predicted_time_constant(name):
    """Fly the rti solver in an empty workspace, lateral step at constant height; the slope of
    ln(distance) after the fast modes have died (τ ≤ 0.3 s) gives the flown τ. Measured:
    0.996, 1.039 and 0.977 of the prediction."""
    from paper_repro.sim.loop import simulate

    cfg, distance, duration, fit_from = FLIGHTS[name]
    target = np.array([0.0, 0.0, 5.0])
    start = target + distance * np.array([0.6, -0.8, 0.0])
    scene = Scene("open", regions=(), start=tuple(start), targets=(tuple(target),))
    result = simulate(cfg, max_steps=int(round(duration / cfg.nmpc.ts)), progress=False,
                      scene=scene)
    t = np.append(result.t, result.t[-1] + cfg.nmpc.ts)  # x has one row more than t
    lateral = np.linalg.norm(result.x[:, :2] - target[:2], axis=1)
    late = t >= fit_from
    slope = np.polyfit(t[late], np.log(lateral[late]), 1)[0]
    assert -1.0 / slope == pytest.approx(timeline.clock(cfg).tau_lateral_s, rel=0.10)


# --- the clock of a flight ---------------------------------------------------------------------

def _flight(visible, reached=(-1, -1), ts=0.01):
    """The parts of a SimulationResult the clock helpers read."""
    from types import SimpleNamespace

    visible = np.asarray(visible, int)
    return SimpleNamespace(t=np.arange(len(visible)) * ts, visible_points=visible,
                           reached=np.asarray(reached), config=Config())


def test_avoidance_windows_are_the_runs_of_steps_with_a_point_in_view():
    seen = np.zeros(10_000, int)
    seen[1000:1500] = 3   # 10-15 s
    seen[1700:1800] = 1   # 17-18 s: 2 s after the first, one phase with a 5 s merge gap
    seen[6000:6001] = 9   # 60 s, one step
    windows = timeline.avoidance_windows(_flight(seen))
    assert windows == pytest.approx(np.array([[10.0, 18.0], [60.0, 60.01]]))
    apart = timeline.avoidance_windows(_flight(seen), merge_gap_s=0.0)
    assert apart == pytest.approx(np.array([[10.0, 15.0], [17.0, 18.0], [60.0, 60.01]]))


def test_avoidance_windows_at_the_ends_and_when_nothing_is_seen():
    assert timeline.avoidance_windows(_flight(np.zeros(50))).shape == (0, 2)
    windows = timeline.avoidance_windows(_flight(np.ones(50)))
    assert windows == pytest.approx(np.array([[0.0, 0.5]]))
    assert timeline.format_windows(np.zeros((0, 2))) == "–"
    assert timeline.format_windows(np.array([[41.2, 58.0], [112.0, 131.4]])) == \
        "41–58, 112–131 s"


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_merge_gap_must_be_finite_and_non_negative(bad):
    with pytest.raises(ValueError, match="merge_gap_s"):
        timeline.avoidance_windows(_flight(np.ones(5)), merge_gap_s=bad)


def test_flight_clock_against_the_paper():
    seen = np.zeros(52_000, int)
    seen[5000:12_000] = 5
    clock_ = timeline.flight_clock(_flight(seen, reached=(20_000, 51_000)))
    assert clock_["first_target_s"] == pytest.approx(200.0)
    assert clock_["mission_time_s"] == pytest.approx(510.0)
    assert clock_["avoidance_span_s"] == pytest.approx((50.0, 120.0))
    assert clock_["mission_ratio"] == pytest.approx(1.02) and clock_["within_10_percent"]
    late = timeline.flight_clock(_flight(seen, reached=(20_000, -1)))
    assert np.isnan(late["mission_time_s"]) and not late["within_10_percent"]


def test_timeline_study_flies_each_candidate_on_the_paper_mission():
    study = timeline_study(quick=True)
    assert [dict(s.labels)["candidate"] for s in study.specs] == list(CANDIDATES)
    for spec in study.specs:
        sim = spec.config.simulation
        assert (sim.scenario, sim.kind, spec.max_steps) == ("paper", "mission",
                                                           TIMELINE_QUICK_STEPS)
        assert spec.config.distance.metric == "smooth"
    by_label = {dict(s.labels)["candidate"]: s.config.nmpc for s in study.specs}
    assert by_label["printed"] == Config().nmpc
    assert by_label["N = 43"].horizon == 43
    assert by_label["h = 0.0118 s"].prediction_step == pytest.approx(0.0118)
    # The printed run shares its cache folder with `reproduce`'s smooth run.
    from paper_repro.studies.reproduce import run_specs

    full = timeline_study(labels=["printed"]).specs[0]
    assert full.directory() == run_specs()[0].directory()


def test_unknown_candidate_is_named():
    with pytest.raises(ValueError, match="label"):
        candidate_config("N = 99")

"""Chattering and summary metrics: properties a reader can check by hand."""

from types import SimpleNamespace

import numpy as np
import pytest

from paper_repro import Config, make_scene
from paper_repro.analysis.metrics import (
    body_rates,
    cbf_condition_share,
    chattering_metrics,
    input_spectrum,
    region_distances,
    scan_change_steps,
    sign_changes,
    summary_row,
    summary_table,
    tracking_error,
)
from paper_repro.sim.result import SimulationResult
from paper_repro.world.motion import Motion
from paper_repro.world.scene import Region, Scene

TS = 0.01
T = np.arange(0.0, 20.0, TS)


def _sine(freq=0.5, amplitude=1.0, offset=5.0):
    return offset + amplitude * np.sin(2 * np.pi * freq * T)


def _square(freq=40.0, amplitude=0.1):
    return amplitude * np.sign(np.sin(2 * np.pi * freq * T + 0.1))


def test_smooth_sine_has_few_sign_changes_and_no_high_frequency_energy():
    m = chattering_metrics(_sine(), TS)
    # 0.5 Hz for 20 s: 10 periods, two direction reversals per period.
    assert m["du_sign_changes"] == 20
    assert m["hf_energy_fraction"] < 1e-5
    assert m["hf_rms"] < 2e-3
    # TV of a sine: 4·amplitude per period.
    assert m["total_variation"] == pytest.approx(40.0, rel=1e-3)
    assert m["max_abs_du"] == pytest.approx(2 * np.pi * 0.5 * TS, rel=1e-3)


def test_adding_a_40_hz_square_wave_raises_every_chattering_measure():
    smooth = chattering_metrics(_sine(), TS)
    chatter = chattering_metrics(_sine() + _square(), TS)
    # A 40 Hz square wave flips direction 80 times a second.
    assert chatter["du_sign_changes"] > 70 * 20
    assert chatter["hf_energy_fraction"] > 100 * smooth["hf_energy_fraction"]
    # Its RMS is its amplitude, 0.1, and nearly all of it lies above 5 Hz.
    assert chatter["hf_rms"] == pytest.approx(0.1, rel=0.05)
    # Each of the 1,600 edges is a jump of 2·0.1 (the slow sine moves far less in a step).
    assert chatter["total_variation"] > 0.95 * 1600 * 0.2 > 5 * smooth["total_variation"]
    assert chatter["max_abs_du"] >= 0.2


def test_total_variation_of_a_monotone_ramp_is_its_range():
    ramp = np.linspace(2.0, 7.0, 500)
    m = chattering_metrics(ramp, TS)
    assert m["total_variation"] == pytest.approx(5.0)
    assert m["du_sign_changes"] == 0
    # A trend is not chattering: the end line is removed before the FFT.
    assert m["hf_energy_fraction"] == 0.0
    assert m["hf_rms"] < 1e-12


def test_constant_and_single_sample_signals_have_zero_chattering():
    for u in (np.full(300, 5.49), np.array([5.49])):
        m = chattering_metrics(u, TS)
        assert m["total_variation"] == 0 and m["max_abs_du"] == 0
        assert m["hf_energy_fraction"] == 0 and m["du_sign_changes"] == 0


def test_channels_add_up():
    u = np.column_stack([_sine(), _sine() + _square(), np.linspace(0, 1, len(T))])
    total = chattering_metrics(u, TS)
    parts = [chattering_metrics(u[:, i], TS) for i in range(3)]
    assert total["total_variation"] == pytest.approx(sum(p["total_variation"] for p in parts))
    assert total["du_sign_changes"] == sum(p["du_sign_changes"] for p in parts)
    assert total["max_abs_du"] == max(p["max_abs_du"] for p in parts)


def test_high_frequency_power_is_the_power_above_the_cutoff():
    low = np.sin(2 * np.pi * 1.0 * T)
    high = 0.3 * np.sin(2 * np.pi * 20.0 * T)
    m = chattering_metrics(low + high, TS, cutoff_hz=5.0)
    assert m["hf_rms"] == pytest.approx(0.3 / np.sqrt(2), rel=0.02)
    assert m["hf_energy_fraction"] == pytest.approx(0.09 / 1.09, rel=0.02)


def test_spectrum_integrates_to_the_power_of_the_signal():
    u = np.column_stack([_sine(), 0.5 * _sine(freq=7.0)])
    freqs, psd = input_spectrum(u, TS)
    power = np.sum(psd[1:]) * (freqs[1] - freqs[0])
    assert power == pytest.approx(0.5 + 0.125, rel=0.02)


def test_cutoff_sets_the_boundary_of_high_frequency_energy():
    u = _sine(freq=3.0)
    assert chattering_metrics(u, TS, cutoff_hz=5.0)["hf_energy_fraction"] < 1e-6
    assert chattering_metrics(u, TS, cutoff_hz=2.0)["hf_energy_fraction"] > 0.99


def test_sign_changes_ignore_the_dead_band():
    noise = 1e-6 * np.random.default_rng(0).standard_normal(1000)
    assert sign_changes(np.diff(5.49 + noise)) == 0
    assert sign_changes(np.diff(5.49 + noise), deadband=0.0) > 100
    # A pause between two increases is not a reversal.
    assert sign_changes([0.1, 0.0, 0.0, 0.1, -0.1]) == 1


@pytest.mark.parametrize("kwargs, match", [
    ({"ts": 0.0}, "ts"),
    ({"ts": TS, "cutoff_hz": 50.0}, "Nyquist"),
    ({"ts": TS, "cutoff_hz": -1.0}, "cutoff_hz"),
    ({"ts": TS, "deadband": -1.0}, "deadband"),
])
def test_invalid_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        chattering_metrics(_sine(), **kwargs)


def test_invalid_signal_raises():
    with pytest.raises(ValueError, match="u must"):
        chattering_metrics(np.zeros((0, 4)), TS)
    with pytest.raises(ValueError, match="finite"):
        chattering_metrics([1.0, np.nan], TS)


def _result(steps=400, reached=(150, -1), metric="smooth", outcome=None, clearance_min=1.5):
    """A hand-made run of the paper scene: two targets, the first reached at step 150."""
    cfg = Config()
    targets = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    k = np.arange(steps)
    index = np.where(k < 150, 0, 1)
    x = np.zeros((steps + 1, 12))
    x[:, 0] = np.linspace(0.0, 2.0, steps + 1)
    u = 5.49 + 0.1 * np.sin(2 * np.pi * 0.5 * k * 0.01)[:, None] * np.ones(4)
    return SimulationResult(
        t=k * 0.01, x=x, u=u, x_a=x[:-1], u_a=np.full((steps, 4), 5.49),
        solve_time=np.linspace(0.01, 0.1, steps), iterations=np.full(steps, 7),
        success=np.arange(steps) % 100 != 0, status=np.full(steps, "Solve_Succeeded"),
        clearance=np.linspace(5.0, clearance_min, steps), target_index=index,
        visible_points=np.zeros(steps, int), dropped_points=np.zeros(steps, int),
        targets=targets, reached=np.array(reached), scene=make_scene("paper"), config=cfg,
        outcome=outcome or ("completed" if min(reached) >= 0 else "step_limit"),
        meta={"wall_time_s": 12.0})


def test_tracking_error_uses_the_active_target():
    r = _result()
    e = tracking_error(r)
    assert e.shape == (400, 3)
    assert np.allclose(e[10], r.x[10, :3] - r.targets[0])
    assert np.allclose(e[200], r.x[200, :3] - r.targets[1])


def test_summary_row_reports_solve_times_failures_clearance_and_mission_time():
    row = summary_row(_result())
    assert row["run"] == "paper/smooth"
    assert row["steps"] == 400 and row["failed_solves"] == 4
    assert row["solve_max_ms"] == pytest.approx(100.0)
    assert row["solve_median_ms"] == pytest.approx(55.0)
    assert row["min_clearance_m"] == pytest.approx(1.5)
    assert row["targets_reached"] == "1/2" and not row["completed"]
    assert np.isnan(row["mission_time_s"]) and row["simulated_time_s"] == pytest.approx(4.0)
    assert not row["collision"] and not row["stalled"] and np.isnan(row["time_to_complete_s"])
    done = summary_row(_result(reached=(150, 390)))
    assert done["completed"] and done["mission_time_s"] == pytest.approx(3.9)
    assert done["time_to_complete_s"] == pytest.approx(4.0)
    assert done["steps_per_s"] == pytest.approx(400 / 12.0)


def test_summary_row_flags_collision_below_the_rotor_arm_and_stalls():
    """Collision is clearance < 0.35 m (about the 0.332 m arm), strictly; a stall is the
    run's outcome, never a completion."""
    assert summary_row(_result(clearance_min=0.349))["collision"]
    assert not summary_row(_result(clearance_min=0.351))["collision"]
    stalled = summary_row(_result(outcome="stalled"))
    assert stalled["stalled"] and not stalled["completed"] and stalled["outcome"] == "stalled"


def test_steps_outside_the_state_box_count_each_step_once_and_not_the_start():
    r = _result()
    assert summary_row(r)["steps_outside_state_box"] == 0
    r.x[0, 9] = 3.0                     # the start does not count
    r.x[5, 9] = r.x[5, 3] = 3.0         # roll rate and roll out at one step: one step
    r.x[7, 2] = -0.1                    # below the ground
    r.x[8, 9] = np.pi / 2               # on the bound is inside
    assert summary_row(r)["steps_outside_state_box"] == 2


def test_summary_table_has_one_row_per_run():
    table = summary_table([_result(), _result()])
    assert len(table) == 2 and table.index.name == "run"
    for col in ("solve_mean_ms", "solve_median_ms", "solve_p95_ms", "solve_max_ms",
                "iterations_mean", "failed_solves", "tv_u_N", "max_abs_du_N",
                "hf_energy_fraction", "du_sign_changes", "min_clearance_m", "mission_time_s"):
        assert col in table.columns
    with pytest.raises(ValueError):
        summary_table([])


def test_scan_change_steps_pick_the_steps_that_see_a_new_set_and_their_neighbours():
    """A thrust jump placed at the first solve that sees a new scan is found there; the
    comparison steps are the non-change steps within the neighbourhood only."""
    import dataclasses

    r = _result()
    visible = np.zeros(400, int)
    visible[100:] = 5   # scan 100 sees 5 points
    visible[300:] = 7   # scan 300 sees 7
    u = np.full((400, 4), 5.49)
    u[100:] += 0.2      # the solve of scan 100 jumps by 0.2 N
    u[300:, 2] -= 0.05  # and that of scan 300 by 0.05 N on one rotor
    r = dataclasses.replace(r, u=u, visible_points=visible)
    at, around = scan_change_steps(r, neighbourhood=3)
    np.testing.assert_allclose(at, [0.2, 0.05])
    assert len(around) == 2 * 6 and np.all(around == 0.0)
    assert len(scan_change_steps(r, neighbourhood=None)[1]) == 399 - 2
    row = summary_row(r)
    assert row["scan_changes"] == 2 and row["scan_change_jump_share"] == 1.0
    assert row["du_scan_change_median_N"] == pytest.approx(0.125)


def _dot_run(path, motion=None):
    """A run whose output follows ``path`` (K + 1, 3) m past one cloud point at the origin (moved
    by ``motion``): what :func:`cbf_condition_share` reads of a result."""
    scene = Scene("dot", (Region("dot", None),), tuple(path[0]), (tuple(path[-1]),),
                  clouds=(np.zeros((1, 3)),), motions=None if motion is None else (motion,))
    x = np.zeros((len(path), 12))
    x[:, :3] = path
    return SimpleNamespace(scene=scene, x=x, t=np.arange(len(path) - 1) * TS, config=Config())


def test_region_distances_are_the_true_distances_to_each_region_where_it_is():
    path = np.column_stack([np.linspace(4.0, 0.5, 351), np.zeros(351), np.full(351, 1.0)])
    d = region_distances(_dot_run(path))
    np.testing.assert_allclose(d[:, 0], np.hypot(path[:-1, 0], 1.0), rtol=1e-12)
    # The point moving at the UAV's own velocity stays where it was relative to it.
    motion = Motion.constant((-1.0, 0.0, 0.0))
    d = region_distances(_dot_run(path, motion))
    np.testing.assert_allclose(d[:, 0], np.hypot(4.0, 1.0), rtol=1e-12)


@pytest.mark.parametrize("gap, share", [(2.0, 0.0), (1.0, 1.0), (3.5, np.nan)])
def test_a_constant_distance_keeps_the_cbf_condition_only_outside_the_margin(gap, share):
    """β(y_{k+1}) = β(y_k) ≥ δ·β(y_k) holds exactly where β ≥ 0 (d ≥ √(2·d_min) = 1.41 m)
    and fails at every step inside it; out of the 3 m range nothing is in view (NaN)."""
    t = np.arange(201) * TS
    path = np.column_stack([t, np.full_like(t, gap), np.zeros_like(t)])
    run = _dot_run(path, Motion.constant((1.0, 0.0, 0.0)))
    np.testing.assert_equal(cbf_condition_share(run), share)


def test_a_straight_approach_breaks_the_cbf_condition_below_its_analytic_distance():
    """Head-on at h = 1 cm per step: ½(d − h)² − d_min < δ(½d² − d_min) ⇔
    (1 − δ)d² − 2hd + h² − 2(1 − δ)d_min < 0, so (15) fails exactly below the root d*
    ≈ 1.63 m, and the share is that of the in-view steps nearer than d*."""
    h, delta, d_min = 0.01, Config().barrier.delta, Config().barrier.d_min
    d = np.arange(350, 60, -1) * h + h / 2  # no sample on the range or the root
    path = np.column_stack([d, np.zeros_like(d), np.zeros_like(d)])
    a, b, c = 1 - delta, -2 * h, h**2 - 2 * (1 - delta) * d_min
    root = (-b + np.sqrt(b * b - 4 * a * c)) / (2 * a)
    recorded = d[:-1]  # the state after the last step is not a recorded step
    in_view = recorded[:-1] <= 3.0
    expected = np.sum(in_view & (recorded[:-1] < root)) / np.sum(in_view)
    assert 1.6 < root < 1.65
    assert cbf_condition_share(_dot_run(path)) == pytest.approx(expected, abs=1e-12)


def test_encounters_count_the_runs_that_came_within_the_sensor_range():
    """Strictly within r_s: a run at exactly the range, or without a clearance, met nothing."""
    from paper_repro.analysis.metrics import encounters

    assert encounters([0.1, 2.99, 3.0, 7.5, np.nan], 3.0) == 2
    assert encounters([], 3.0) == 0


def _rotation(phi, theta, psi):
    """R = Rz(ψ)Ry(θ)Rx(φ)."""
    c, s = np.cos, np.sin
    rz = np.array([[c(psi), -s(psi), 0], [s(psi), c(psi), 0], [0, 0, 1]])
    ry = np.array([[c(theta), 0, s(theta)], [0, 1, 0], [-s(theta), 0, c(theta)]])
    rx = np.array([[1, 0, 0], [0, c(phi), -s(phi)], [0, s(phi), c(phi)]])
    return rz @ ry @ rx


def test_body_rates_are_the_rotation_s_angular_velocity_by_finite_differences():
    """ω̂ = Rᵀ Ṙ, with Ṙ by central differences along the Euler angles' rates."""
    rng = np.random.default_rng(3)
    x = np.zeros((5, 12))
    x[:, 3:6] = rng.uniform(-0.5, 0.5, (5, 3))
    x[:, 9:12] = rng.normal(size=(5, 3))
    h = 1e-6
    for row, omega in zip(x, body_rates(x), strict=True):
        r = _rotation(*row[3:6])
        dr = (_rotation(*(row[3:6] + h * row[9:12]))
              - _rotation(*(row[3:6] - h * row[9:12]))) / (2 * h)
        skew = r.T @ dr
        np.testing.assert_allclose([skew[2, 1], skew[0, 2], skew[1, 0]], omega, atol=1e-8)
    level = np.zeros((1, 12))
    level[0, 9:12] = (0.1, -0.2, 0.3)  # level flight: the body rates are the Euler rates
    np.testing.assert_allclose(body_rates(level)[0], level[0, 9:12])


def test_plant_columns_count_saturation_margin_and_slow_calls():
    from paper_repro.analysis.metrics import plant_columns

    cfg = Config()
    k = 10
    u = np.full((k, 4), 5.0)
    u[2, 0], u[3, 1] = 0.0, 12.0  # two steps with a rotor at a bound of 𝒰
    clearance = np.full(k + 1, 3.0)
    clearance[4:7] = 1.0  # three samples inside the margin √(2·1 m²) = 1.41 m
    result = SimpleNamespace(config=cfg, u=u, x=np.zeros((k + 1, 12)), clearance=clearance,
                             solve_time=np.r_[np.full(k - 1, 1e-3), 0.02])
    cols = plant_columns(result)
    assert cols["saturation_time_s"] == pytest.approx(2 * cfg.nmpc.ts)
    assert cols["margin_time_s"] == pytest.approx(3 * cfg.nmpc.ts)
    assert cols["calls_over_ts"] == 1 and cols["body_rate_rms_rad_s"] == 0.0

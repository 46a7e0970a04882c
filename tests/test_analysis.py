"""Statistics over study tables: rates and their intervals, paired comparisons, sweeps."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from paper_repro.analysis import statistics as A


def _table(n=30, seed=0):
    """Paired runs on n scenes: the Euclidean variant chatters 10× more (per scene, with
    noise), clears by 0.1 m more, and collides on two scenes; one smooth run failed."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(1.0, 2.0, n)
    rows = []
    for s in range(n):
        for metric, factor in (("smooth", 1.0), ("euclidean", 10.0)):
            failed = metric == "smooth" and s == 0
            rows.append({
                "scene_seed": s, "metric": metric, "eta": 0.3 if metric == "smooth" else 0.0,
                "sigma": 0.8 if metric == "smooth" else np.nan,
                "status": "failed" if failed else "ok",
                "outcome": None if failed else ("completed" if s % 5 else "stalled"),
                "completed": False if failed else bool(s % 5), "stalled": not failed and s % 5 == 0,
                "collision": metric == "euclidean" and s in (3, 7),
                "tv_u_rate_N_per_s": np.nan if failed else base[s] * factor * rng.uniform(0.9, 1.1),
                "hf_energy_fraction": 0.05 * factor / 10, "max_abs_du_N": factor * 0.1,
                "min_clearance_m": 1.3 + (0.1 if metric == "euclidean" else 0.0),
                "time_to_complete_s": 50.0, "solve_median_ms": 0.6, "solve_p99_ms": 1.2})
    return pd.DataFrame(rows)


def test_rates_count_every_run_and_match_the_exact_binomial_interval():
    r = A.rates(_table()).set_index(["metric", "event"])
    e = r.loc[("euclidean", "collision")]
    assert (e["n"], e["k"]) == (30, 2)
    ci = stats.binomtest(2, 30).proportion_ci(0.95, method="exact")
    assert e["low"] == pytest.approx(ci.low) and e["high"] == pytest.approx(ci.high)
    smooth = r.loc["smooth"]
    assert smooth.loc["failed", "k"] == 1 and smooth.loc["stalled", "k"] == 5
    # Every run is in exactly one outcome class.
    assert smooth.loc[["completed", "stalled", "step_limit", "failed"], "k"].sum() == 30


def test_paired_comparison_recovers_the_ratio_and_uses_only_scenes_where_both_flew():
    p = A.paired(_table()).set_index("measure")
    tv = p.loc["tv_u_rate_N_per_s"]
    assert tv["scenes"] == 29  # scene 0's smooth run failed
    assert tv["low"] <= tv["median_effect"] <= tv["high"]
    assert 9.0 < tv["low"] and tv["high"] < 11.0 and tv["wilcoxon_p"] < 1e-6
    clear = p.loc["min_clearance_m"]
    assert clear["effect"] == "difference b − a"
    assert clear["median_effect"] == pytest.approx(0.1)


def test_paired_comparison_is_reproducible():
    a, b = A.paired(_table(), seed=3), A.paired(_table(), seed=3)
    pd.testing.assert_frame_equal(a, b)


def test_by_setting_has_one_row_per_setting_with_intervals():
    s = A.by_setting(_table())
    assert len(s) == 2 and set(s["metric"]) == {"smooth", "euclidean"}
    row = s[s["metric"] == "euclidean"].iloc[0]
    assert row["collision_rate"] == pytest.approx(2 / 30)
    assert row["tv_u_rate_N_per_s_low"] <= row["tv_u_rate_N_per_s"] <= row[
        "tv_u_rate_N_per_s_high"]


def test_ecdf_is_monotone_and_ends_at_one():
    x, f = A.ecdf([3.0, 1.0, np.nan, 2.0])
    assert list(x) == [1.0, 2.0, 3.0] and f[-1] == 1.0 and np.all(np.diff(f) > 0)


def _cell_rows(effect, level, metric, collisions, n=4, remedy="none"):
    return [{"effect": effect, "level": level, "metric": metric, "remedy": remedy,
             "status": "ok", "outcome": "completed", "completed": True, "stalled": False,
             "collision": i < collisions} for i in range(n)]


def test_the_margin_is_the_largest_level_below_the_first_with_a_collision():
    rows = (_cell_rows("none", 0.0, "smooth", 3)  # ignored: the baseline
            + _cell_rows("delay", 2.0, "smooth", 4, remedy="compensated")  # ignored: a remedy
            + [r for level, k in ((1.0, 0), (2.0, 0), (3.0, 1)) for r in
               _cell_rows("delay", level, "smooth", k)]
            + [r for level, k in ((1.0, 0), (2.0, 2), (3.0, 0)) for r in
               _cell_rows("delay", level, "euclidean", k)]
            + [r for level, k in ((1.0, 1), (2.0, 0))
               for r in _cell_rows("lag", level, "smooth", k)]
            + [r for level in (1.0, 2.0) for r in _cell_rows("wind", level, "smooth", 0)])
    m = A.margins(pd.DataFrame(rows)).set_index(["effect", "metric"])
    assert (m.loc[("delay", "smooth"), ["margin", "first_failure"]] == [2.0, 3.0]).all()
    # the first failure counts, even if a higher level happened to stay clear
    assert (m.loc[("delay", "euclidean"), ["margin", "first_failure"]] == [1.0, 2.0]).all()
    assert m.loc[("delay", "euclidean"), "worst_k"] == 2
    assert np.isnan(m.loc[("lag", "smooth"), "margin"])
    wind = m.loc[("wind", "smooth")]
    assert wind["margin"] == 2.0 and np.isnan(wind["first_failure"]) and wind["worst_k"] == 0
    # Clopper-Pearson: 0 of 4 bounds the rate below 1 - 0.025^(1/4) = 0.60
    assert wind["worst_high"] == pytest.approx(1 - 0.025 ** 0.25)
    assert set(m.index.get_level_values("effect")) == {"delay", "lag", "wind"}


def test_a_flight_into_the_ground_breaks_the_margin_as_a_collision_does():
    rows = [r for level in (1.0, 2.0) for r in _cell_rows("lag", level, "smooth", 0)]
    rows[-1].update(outcome="left_workspace", completed=False)  # level 2: one into the ground
    m = A.margins(pd.DataFrame(rows)).set_index(["effect", "metric"])
    assert (m.loc[("lag", "smooth"), ["margin", "first_failure"]] == [1.0, 2.0]).all()
    by_collision = A.margins(pd.DataFrame(rows), event="collision")
    assert by_collision["margin"].iloc[0] == 2.0 and np.isnan(by_collision["first_failure"].iloc[0])

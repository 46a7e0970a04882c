"""The book's sentences and tables of the flights against RotorPy, on a small run table whose
answers are known: which effect breaks, where, and what its remedy buys."""

import numpy as np
import pandas as pd
import pytest

from paper_repro.evidence import hardware as H


def _cell(effect, level, name, metric, unsafe=0, remedy="none", n=6, clearance=1.2,
          hf=(0.02, 0.9)):
    """``n`` passages of one cell; the first ``unsafe`` leave the workspace."""
    share = hf[0] if metric == "smooth" else hf[1]
    return [{"name": f"{effect}-{level}-{remedy}-{metric}-{i}", "effect": effect,
             "level": level, "level_name": name, "remedy": remedy, "metric": metric,
             "scene_seed": i, "status": "ok",
             "outcome": "left_workspace" if i < unsafe else "completed",
             "completed": i >= unsafe, "stalled": False, "collision": False,
             "min_clearance_m": clearance, "hf_energy_fraction": share * (1 + 0.01 * i)}
            for i in range(n)]


@pytest.fixture
def table():
    rows = []
    for metric in H.METRICS:
        rows += _cell("none", 0.0, "off", metric)
        rows += _cell("motor_lag", 0.025, "25 ms", metric)
        rows += _cell("motor_lag", 0.05, "50 ms", metric, unsafe=2 if metric == "smooth" else 5)
        rows += _cell("motor_lag", 0.05, "50 ms", metric, remedy="lag compensated",
                      unsafe=0 if metric == "smooth" else 1)
        rows += _cell("motor_lag", 0.07, "70 ms", metric, unsafe=6, clearance=3.8,
                      hf=(0.15, 0.15))
        rows += _cell("rotor_drag", 8e-5, "8e-05", metric)
    t = pd.DataFrame(rows)
    t["unsafe"] = t["outcome"] == "left_workspace"
    return t


def test_what_breaks_first_names_the_effect_its_levels_and_its_remedy(table):
    text = H.breaks(table, lidar_range=3.0)
    smooth, euclid = text.split("- With the Euclidean")
    assert "Collisions, each effect alone: smoothed D 0 in 36 (the rate is below" in text
    assert "motor lag: unsafe from 50 ms (2/6 at 50 ms, 6/6 at 70 ms)" in smooth
    assert "(5/6 at 50 ms, 6/6 at 70 ms)" in euclid
    assert "With its remedy (lag compensated): 0/6 at 50 ms." in smooth
    assert "With its remedy (lag compensated): 1/6 at 50 ms." in euclid
    # at 70 ms every run stayed beyond the LiDAR's range: it never saw a region
    assert "At 70 ms every run left the workspace before a region came within" in smooth
    assert "no unsafe run with rotor drag, at any level flown" in smooth
    # a run that came within range is not called blind
    assert "At 70 ms every run" not in H.breaks(table.assign(min_clearance_m=1.0), 3.0)
    # a collision is unsafe, and said so
    crash = table["name"] == "motor_lag-0.05-none-euclidean-0"
    table.loc[crash, ["collision", "outcome", "min_clearance_m"]] = [True, "collision", 0.2]
    assert "(5/6 at 50 ms, 1 collided, 6/6 at 70 ms)" in H.breaks(table, 3.0)
    assert "Euclidean ½d² 1 in 36" in H.breaks(table, 3.0)


def test_the_euclidean_chatters_more_where_the_whole_interval_is_above_one(table):
    text = H.claim(table, n_resamples=200)
    rows = {line.split(" | ")[0].lstrip("| "): line for line in text.splitlines()[2:]
            if line.startswith("|")}
    assert rows["every effect off"].endswith("| yes |")
    assert rows["motor lag 70 ms"].endswith("| not shown |")  # the same share for both
    assert text.endswith("above 5 Hz (median) in every cell.")
    reverse = table.assign(hf_energy_fraction=np.where(
        table["metric"] == "smooth", 0.9, 0.02) * (1 + 0.01 * table["scene_seed"]))
    text = H.claim(reverse, n_resamples=200)
    assert text.splitlines()[2].endswith("| no, less |")
    # the smoothed thrusts chatter in every cell: the claim fails there, and it says so
    assert "The smoothed thrusts chatter too" in text and "every effect off (92 %)" in text


def test_margins_and_the_readme_row_count_the_unsafe_runs(table):
    margins = H.margins(table)
    lag = next(line for line in margins.splitlines() if line.startswith("| motor lag"))
    assert "| 25 ms / 25 ms | 50 ms / 50 ms | 6/6 / 6/6 |" in lag
    row = H.overview(table)
    assert "(72 passages)" in row[0]
    assert row[1].startswith("collisions: smoothed 0/36, Euclidean 0/36.")
    assert "smoothed: motor lag (worst cell 6/6; with lag compensated 0/6)" in row[1]
    assert "Euclidean: motor lag (worst cell 6/6; with lag compensated 1/6)" in row[1]
    assert row[1].endswith("chatter too (most of their power above 5 Hz) with: no effect")


def test_every_effect_at_once_counts_collisions_apart_from_the_unsafe_runs(table):
    rows = []
    for remedy, unsafe, n in (("none", 6, 6), ("all", 1, 9), ("all + filtered", 0, 6)):
        for metric in H.METRICS:  # the headline, every remedy, on the most passages
            rows += _cell("combined", 1.0, "light", metric, unsafe=unsafe, remedy=remedy, n=n)
    t = pd.DataFrame(rows)
    crash = t["name"] == "combined-1.0-all-euclidean-0"
    t.loc[crash, ["collision", "outcome"]] = [True, "collision"]
    t["unsafe"] = t["collision"] | (t["outcome"] == "left_workspace")
    lines = H.combined(pd.concat([table, t])).splitlines()
    assert len(lines) == 2 + 3  # the other effects are not its rows
    assert lines[2].startswith("| every effect at once, light | 0/6 [0, 46] % / 0/6 [0, 46] % "
                               "| 6/6 [54, 100] % / 6/6 [54, 100] % |")
    assert lines[3].startswith("| every effect at once, light, every remedy | 0/9 [0, 34] % / "
                               "1/9 [0, 48] % | 1/9 [0, 48] % / 1/9 [0, 48] % |")
    assert lines[4].startswith("| every effect at once, light, every remedy and the estimate "
                               "filter | 0/6")
    row = H.overview(table, t)
    assert row[1].endswith("Every effect at once (light, every remedy): smoothed 0 collided "
                           "and 1 unsafe in 9, Euclidean 1 collided and 1 unsafe in 9")

"""The studies towards hardware: the controller against RotorPy, one effect at a time and all
at once, paired on the same passages; each cell is what it says, and the controller is the
same whatever the plant."""

import dataclasses

import numpy as np
import pytest

from paper_repro import studies as S
from paper_repro.config import PlantParams
from paper_repro.studies.catalogue import (
    COMBINED,
    COMBINED_REMEDIES,
    EFFECTS,
    ESTIMATE_FILTER_TIME,
    EVERY_REMEDY,
    HARDWARE_GROUPS,
    HARDWARE_STEPS,
    HEADLINE,
    REMEDIED,
    REMEDIES,
    hardware,
    hardware_combined,
    make_study,
    with_remedy,
)


def _cells(study):
    """{(effect, level, remedy): {metric: [seeds]}}, and the plants of each cell by seed."""
    cells, plants = {}, {}
    for spec in study.specs:
        lab = dict(spec.labels)
        cell = (lab["effect"], lab.get("level"), lab["remedy"])
        cells.setdefault(cell, {}).setdefault(lab["metric"], []).append(lab["scene_seed"])
        plants.setdefault(cell, {})[lab["scene_seed"]] = spec.config.plant
    return cells, plants


def test_the_studies_share_the_effects_out_and_each_flies_the_baseline():
    groups = [set(effects) for effects in HARDWARE_GROUPS.values()]
    assert set().union(*groups) == set(EFFECTS) and sum(map(len, groups)) == len(EFFECTS)
    for name in HARDWARE_GROUPS:
        assert make_study(name, scenes=2).name == name
        assert make_study(name, quick=True).name == f"{name}-quick"


@pytest.mark.parametrize("group", sorted(HARDWARE_GROUPS))
def test_each_effect_alone_at_each_level_on_the_same_passages_for_both_metrics(group):
    study = hardware(group, scenes=3)
    cells, plants = _cells(study)
    expected = {("none", 0.0, "none")} | {
        (effect, level, remedy) for effect in HARDWARE_GROUPS[group]
        for level, _, _ in EFFECTS[effect]
        for remedy in ("none", *REMEDIED.get(effect, ()))}
    assert set(cells) == expected
    for by_metric in cells.values():  # paired: the same three passages with both metrics
        assert by_metric == {"smooth": [0, 1, 2], "euclidean": [0, 1, 2]}
    for spec in study.specs:
        assert spec.max_steps == HARDWARE_STEPS
    for (effect, level, remedy), by_seed in plants.items():
        for seed, plant in by_seed.items():
            # RotorPy with every effect off, but the cell's: the turbulence and the estimate's
            # noise drawn from the passage's seed
            baseline = PlantParams(simulator="rotorpy", seed=seed)
            changed = {f.name for f in dataclasses.fields(plant)
                       if getattr(plant, f.name) != getattr(baseline, f.name)}
            settings = dict(next(c for v, _, c in EFFECTS.get(effect, ()) if v == level)
                            ) if effect != "none" else {}
            assert changed == set(settings) | (set(REMEDIES[remedy](settings))
                                               if remedy != "none" else set())
            if remedy == "lag compensated":  # the lag inverted for its own time constant
                assert plant.motor_lag_compensation == plant.motor_lag
            if remedy == "filtered":
                assert plant.estimate_filter_time == ESTIMATE_FILTER_TIME
    for levels in EFFECTS.values():  # the levels rise with the severity
        values = [v for v, _, _ in levels]
        assert values == sorted(values) and len(set(values)) == len(values)


def test_every_effect_at_once_with_every_remedy_on_300_passages_and_each_other_cell_on_50():
    cells, plants = _cells(hardware_combined())
    assert set(cells) == {("combined", float(i + 1), r) for i in range(len(COMBINED))
                          for r in COMBINED_REMEDIES}
    for (_, level, remedy), by_metric in cells.items():
        name = list(COMBINED)[int(level) - 1]
        n = 300 if (name, remedy) == HEADLINE else 50
        assert by_metric == {"smooth": list(range(n)), "euclidean": list(range(n))}
        plant = plants[("combined", level, remedy)][7]
        remedied = remedy != "none"
        assert plant.compensate_latency == remedied
        assert (plant.hover_thrust_time is not None) == remedied
        assert plant.motor_lag_compensation == (plant.motor_lag if remedied else None)
        assert plant.estimate_filter_time == (ESTIMATE_FILTER_TIME if "filtered" in remedy
                                              else None)
        for setting, value in COMBINED[name].items():
            assert getattr(plant, setting) == value


def test_a_remedy_is_named_or_refused_by_name():
    effect = {"estimation": "mocap", "delay_steps": 1}
    every = with_remedy(effect, "all")  # no motor lag here: nothing to compensate
    assert set(every) - set(effect) == {k for n in EVERY_REMEDY if n != "lag compensated"
                                        for k in REMEDIES[n](effect)}
    assert with_remedy(effect, "all + filtered") == {
        **every, "estimate_filter_time": ESTIMATE_FILTER_TIME}
    assert with_remedy(effect, "none") == effect
    with pytest.raises(ValueError, match="remedy: 'filter'"):
        with_remedy(effect, "all + filter")


def test_one_controller_per_metric_whatever_the_plant():
    """The NMPC predicts with its nominal model: a plant's effects never rebuild it."""
    specs = [s for g in HARDWARE_GROUPS for s in hardware(g, quick=True).specs]
    specs += hardware_combined(quick=True).specs
    keys = {dict(s.labels)["metric"]: set() for s in specs}
    for s in specs:
        keys[dict(s.labels)["metric"]].add(S.controller_key(s.config))
    assert all(len(k) == 1 for k in keys.values()) and len(keys) == 2


def test_a_quick_cell_flies_against_rotorpy_and_reports_the_plant_columns(tmp_path):
    pytest.importorskip("rotorpy.vehicles.multirotor")
    specs = [s for s in hardware_combined(quick=True).specs
             if dict(s.labels)["metric"] == "smooth" and dict(s.labels)["remedy"] == "none"]
    study = S.Study("hardware-test", tuple(dataclasses.replace(s, max_steps=150)
                                           for s in specs))
    result = S.run_study(study, out=tmp_path / "study", workers=0, runs_dir=tmp_path / "runs",
                         progress=False, log=lambda line: None)
    table = result.table
    assert (table["status"] == "ok").all(), table["error"].tolist()
    assert {"saturation_time_s", "body_rate_rms_rad_s", "margin_time_s",
            "calls_over_ts"} <= set(table.columns)
    # (a run may end early: every effect at once can bring the vehicle to the ground)
    assert (table["steps"] <= 150).all() and np.isfinite(table["body_rate_rms_rad_s"]).all()

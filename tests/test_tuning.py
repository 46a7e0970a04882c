"""Tuning with Optuna: bad input named before anything flies, the objectives and constraints of
a trial from its table, an infeasible trial never on the front, a resumed study that continues.

The closed-loop tests tune σ alone (it is not compiled into the solver's C, so no new build) on
one tiny passage of 40 steps, one LiDAR slot of 64 points.
"""

import dataclasses
import json
import math

import numpy as np
import optuna
import pandas as pd
import pytest

from paper_repro import Config, NMPCParams
from paper_repro.studies import tuning as T
from paper_repro.studies import tuning_scenes
from paper_repro.studies.catalogue import passage_spec
from paper_repro.studies.tuning_results import (
    best_setups,
    evaluate_heldout,
    load_study,
    preset_config,
    presets_from_setups,
    printed_position,
    trials_frame,
    verdicts,
)
from paper_repro.studies.tuning_space import (
    DEFAULT_OBJECTIVES,
    MIN_CLEARANCE,
    finished_trials,
    printed_params,
    search_space,
)

TINY = Config(nmpc=NMPCParams(region_slots=1, points_per_region=64))
SIGMA_ONLY = {"sigma": (0.4, 1.6, 0.05)}


# --- bad input ------------------------------------------------------------------------------

@pytest.mark.parametrize("space, message", [
    ({"eta": (0.3, 0.3)}, r"eta: the range \[0.3, 0.3\] is empty"),
    ({"d_min": (2.0, 0.5)}, r"d_min: lower bound 2 is above the upper bound 0.5"),
    ({"delta": (0.5, 1.2)}, r"delta: the range \[0.5, 1.2\] lies outside what the "
                            r"configuration accepts \(delta must lie in \(0, 1\)"),
    ({"kappa": (-1.0, 10.0)}, r"kappa: the range .* lies outside .*\(kappa must be"),
    ({"mu": (1e4, 2.5e4, 1e4)}, r"mu: high - low = 15000 must be a whole number of steps"),
    ({"lam": (0.9, 0.99)}, r"parameter must be one of .* got 'lam'"),
    ({}, r"at least one parameter"),
])
def test_a_bad_range_names_its_parameter_before_any_trial(space, message, monkeypatch, tmp_path):
    def never(*a, **k):
        raise AssertionError("a run was started")

    monkeypatch.setattr(T, "run_study", never)
    with pytest.raises(ValueError, match=message):
        T.tune(T.TuningSettings(2, space=space, seeds=(0,), out=tmp_path,
                                runs_dir=tmp_path / "r"), workers=0)
    assert not (tmp_path / "tuning.db").exists()


@pytest.mark.parametrize("kwargs, message", [
    ({"objectives": ("chattering", "time_to_complete_s")}, "objective must be one of"),
    ({"objectives": ()}, "objectives must name at least one"),
    ({"objectives": ("hf_energy_fraction",) * 2}, "objectives must not repeat"),
    ({"trials": 0}, "trials must be an integer >= 1"),
    ({"storage": "tuning.db"}, "storage must be an RDB URL"),
    ({"sampler": "cmaes"}, "sampler must be one of"),
    ({"seeds": (61,)}, r"training scenes must not be held-out scenes .* \[61\]"),
])
def test_other_bad_input_is_named(kwargs, message, monkeypatch, tmp_path):
    monkeypatch.setattr(T, "run_study", lambda *a, **k: pytest.fail("a run was started"))
    args = {"trials": 2, "seeds": (0,), "out": tmp_path, "runs_dir": tmp_path / "r"} | kwargs
    workers = args.pop("workers", 0)
    with pytest.raises(ValueError, match=message):
        T.tune(T.TuningSettings(**args), workers=workers)


def test_every_default_range_holds_the_printed_value_on_its_grid():
    printed = printed_params()
    for name, r in search_space().items():
        assert r.values() is not None and np.any(np.isclose(r.values(), printed[name])), name
        assert r.why


# --- objectives and constraints from a table ------------------------------------------------

def _table(**cols):
    n = len(next(iter(cols.values())))
    base = {"status": ["ok"] * n, "completed": [True] * n, "stalled": [False] * n,
            "collision": [False] * n, "min_clearance_m": [1.2] * n,
            "time_to_complete_s": [40.0] * n, "hf_energy_fraction": [0.1] * n,
            "tv_u_rate_N_per_s": [1.0] * n}
    return pd.DataFrame(base | cols)


def test_objectives_are_scene_means_and_a_safe_trial_is_feasible():
    t = _table(hf_energy_fraction=[0.1, 0.3], time_to_complete_s=[40.0, 60.0],
               min_clearance_m=[1.4, 1.2])
    values, con = tuning_scenes.evaluate_table(t, ("hf_energy_fraction", "time_to_complete_s"))
    assert values == pytest.approx((0.2, 50.0))
    assert con == pytest.approx((MIN_CLEARANCE - 1.2, 0.0, 0.0)) and max(con) <= 0


def test_a_stall_a_collision_or_a_raised_run_makes_the_trial_infeasible():
    t = _table(completed=[True, False, True], stalled=[False, True, False],
               time_to_complete_s=[40.0, math.nan, 50.0],
               min_clearance_m=[1.0, 1.0, 0.3], collision=[False, False, True])
    values, con = tuning_scenes.evaluate_table(t, ("time_to_complete_s",), time_limit_s=150.0)
    assert values[0] == pytest.approx((40 + 150 + 50) / 3)  # the stall counts the limit
    assert con == pytest.approx((MIN_CLEARANCE - 0.3, 1.0, 1.0))
    failed = _table(status=["ok", "failed"], hf_energy_fraction=[0.2, math.nan],
                    completed=[True, False])
    values, con = tuning_scenes.evaluate_table(failed, ("hf_energy_fraction",))
    assert values[0] == pytest.approx(0.2) and con[2] == 1  # finite, and infeasible


def test_a_scene_the_printed_set_up_stalls_on_costs_time_not_feasibility():
    t = _table(scene_seed=[0, 4, 5], completed=[True, False, True],
               stalled=[False, True, False], time_to_complete_s=[40.0, math.nan, 50.0])
    values, con = tuning_scenes.evaluate_table(t, ("time_to_complete_s",), time_limit_s=150.0,
                                   must_complete=(0, 5))
    assert con[2] == 0 and values[0] == pytest.approx((40 + 150 + 50) / 3)
    assert tuning_scenes.evaluate_table(t, ("time_to_complete_s",), must_complete=(0, 4))[1][2] == 1
    assert tuning_scenes.evaluate_table(t, ("time_to_complete_s",))[1][2] == 1  # None: every scene


def _printed_flights(outcomes):
    """A stand-in for ``run_study`` that returns the printed flights ``{seed: (completed,
    stalled, hf, clearance)}`` of the seeds asked."""
    class Done:
        def __init__(self, table):
            self.table = table

    def run_study(study, **kw):
        seeds = [dict(s.labels)["scene_seed"] for s in study.specs]
        rows = [dict(zip(("completed", "stalled", "hf_energy_fraction", "min_clearance_m"),
                         outcomes[seed])) | {"scene_seed": seed} for seed in seeds]
        t = pd.DataFrame(rows)
        return Done(_table(**{c: list(t[c]) for c in t.columns}))
    return run_study


def test_training_scenes_mix_clean_stalling_and_chattering_ones(monkeypatch):
    clean, stall, chat, close = (True, False, 0.02, 1.3), (False, True, 0.02, 1.3), \
        (True, False, 0.9, 1.3), (True, False, 0.02, 0.8)
    outcomes = {0: stall, 1: clean, 2: close, 3: chat, 4: clean, 5: stall, 6: clean, 7: chat,
                8: clean, 9: clean}
    monkeypatch.setattr(tuning_scenes, "run_study", _printed_flights(outcomes))
    seeds, must = tuning_scenes.training_scenes(5, 3, candidates=range(10), log=lambda line: None)
    # 2 clean (1, 4), 2 stalling (0, 5), 1 chattering (3); 2 is too close to count.
    assert seeds == (0, 1, 3, 4, 5) and must == (1, 3, 4)
    with pytest.raises(ValueError, match=r"too few .* 'chattering': '1 of 2'"):
        tuning_scenes.training_scenes(5, 4, candidates=range(4), log=lambda line: None)
    with pytest.raises(ValueError, match=r"hard must be an integer in \[0, scenes = 5\]"):
        tuning_scenes.training_scenes(5, 6, candidates=range(10), log=lambda line: None)


def test_without_required_completion_only_stalls_count():
    t = _table(completed=[False, False], stalled=[False, True])
    assert tuning_scenes.evaluate_table(t, require_completion=False)[1][2] == 1
    assert tuning_scenes.evaluate_table(t, require_completion=True)[1][2] == 2


# --- the front ------------------------------------------------------------------------------

def _study_by_hand(points):
    """An in-memory study of finished trials ``(sigma, chattering, time, constraints)``."""
    study = optuna.create_study(directions=["minimize", "minimize"])
    study.set_user_attr("objectives", list(DEFAULT_OBJECTIVES))
    study.set_user_attr("space", {"sigma": [0.4, 1.6, 0.05]})
    dist = {"sigma": optuna.distributions.FloatDistribution(0.4, 1.6, step=0.05)}
    for sigma, chat, tm, con in points:
        study.add_trial(optuna.trial.create_trial(
            params={"sigma": sigma}, distributions=dist, values=[chat, tm],
            user_attrs={"constraints": list(con)},
            system_attrs={"constraints": tuple(con)}))  # what constraints_func stores
    return study


def test_an_infeasible_trial_is_never_reported_as_best():
    ok = (-0.1, 0.0, 0.0)
    study = _study_by_hand([
        (0.8, 0.10, 50.0, ok),               # printed
        (0.5, 0.001, 1.0, (0.4, 1.0, 2.0)),  # dominates everything, but stalls and collides
        (1.0, 0.05, 60.0, ok),
        (1.2, 0.20, 45.0, ok),
        (1.4, 0.30, 70.0, ok),               # dominated
    ])
    frame = trials_frame(study)
    infeasible = frame[frame["number"] == 1].iloc[0]
    assert not infeasible["feasible"] and not infeasible["pareto"]
    assert set(frame.loc[frame["pareto"], "number"]) == {0, 2, 3}
    # Optuna's own front (constraints from the system attribute) agrees.
    assert {t.number for t in study.best_trials} == {0, 2, 3}
    best = best_setups(frame)
    assert best["best_chattering"]["trial"] == 2 and best["safest"]["trial"] == 2
    pos = printed_position(frame)
    assert pos["on_front"] and pos["dominated_by"] == 0
    # The sampler sees the same constraints.
    assert T.trial_constraints(study.trials[1]) == [0.4, 1.0, 2.0]


def test_the_safest_set_up_is_the_clearest_front_point_that_chatters_less_than_printed():
    study = _study_by_hand([
        (0.8, 0.10, 50.0, (-0.2, 0.0, 0.0)),   # printed
        (1.0, 0.01, 60.0, (-0.05, 0.0, 0.0)),  # best on chattering, close to the margin
        (1.2, 0.05, 55.0, (-0.4, 0.0, 0.0)),   # clearer, still calmer than printed
        (1.4, 0.20, 40.0, (-0.9, 0.0, 0.0)),   # clearest, but chatters more than printed
    ])
    best = best_setups(trials_frame(study))
    assert best["best_chattering"]["trial"] == 1 and best["safest"]["trial"] == 2
    assert best["safest"]["sigma"] == 1.2


def test_a_tuned_set_up_is_offered_only_without_held_out_collisions_and_lost_completions(
        tmp_path):
    t = pd.concat([
        _table(completed=[True, True, False]).assign(setup="printed"),
        _table(collision=[False, True, False]).assign(setup="best_chattering"),
        _table(completed=[True, False, False]).assign(setup="safest"),
        _table(completed=[True] * 3).assign(setup="calm"),
    ], ignore_index=True)
    v = verdicts(t)
    assert v["printed"]["offered"] and v["calm"]["offered"]
    assert not v["best_chattering"]["offered"] and "1/3 held-out collisions" in \
        v["best_chattering"]["why"]
    assert not v["safest"]["offered"] and "fewer than the printed set-up's 2/3" in \
        v["safest"]["why"]
    setups = {s: printed_params() for s in v}
    (tmp_path / "presets.json").write_text(json.dumps(presets_from_setups(setups, None, v)))
    assert preset_config("calm", tmp_path) == Config()
    with pytest.raises(ValueError, match=r"'safest' is not offered .*fewer than"):
        preset_config("safest", tmp_path)


def test_no_feasible_trial_means_no_front_to_pick_from():
    study = _study_by_hand([(0.8, 0.1, 50.0, (0.1, 0.0, 1.0))])
    with pytest.raises(ValueError, match="no feasible trial"):
        best_setups(trials_frame(study))


# --- closed loop: resume --------------------------------------------------------------------

def _tune(tmp_path, trials, **kw):
    settings = T.TuningSettings(trials, quick=True, space=SIGMA_ONLY, seeds=(0,), max_steps=40,
                                base=TINY, out=tmp_path / "tuning", runs_dir=tmp_path / "runs")
    return T.tune(settings, workers=0, log=lambda line: None, **kw)


def test_a_resumed_study_continues_the_trial_count(tmp_path):
    class DriverKilled(Exception):
        pass

    def stop_after_two(study, trial):
        if trial.number == 1:
            raise DriverKilled

    with pytest.raises(DriverKilled):
        _tune(tmp_path, 4, callbacks=[stop_after_two])
    first = load_study(tmp_path / "tuning")
    done = {t.number: t.values for t in finished_trials(first)}
    assert sorted(done) == [0, 1]
    assert first.trials[0].params == {"sigma": 0.8}  # trial 0 is the printed set-up
    first.ask()  # a trial left running by a driver that was killed

    again = _tune(tmp_path, 4)
    finished = finished_trials(again.study)
    assert len(finished) == 4 and again.flown_trials == 2  # not 4: nothing started over
    assert {t.number: t.values for t in finished if t.number in done} == done
    assert min(t.number for t in finished if t.number not in done) > max(done)
    assert again.study.trials[2].state == optuna.trial.TrialState.FAIL  # the stale one
    # A third call with everything done flies nothing.
    assert _tune(tmp_path, 4).flown_trials == 0


def test_a_resumed_study_must_be_the_same_study(tmp_path):
    _tune(tmp_path, 1)
    with pytest.raises(ValueError, match="max_steps: the stored study"):
        T.tune(T.TuningSettings(2, quick=True, space=SIGMA_ONLY, seeds=(0,), max_steps=30,
                                base=TINY, out=tmp_path / "tuning",
                                runs_dir=tmp_path / "runs"), workers=0, log=lambda line: None)


def test_a_study_stored_before_the_solver_options_moved_resumes_as_the_same_study(tmp_path):
    """A stored base of the former layout (``nmpc.line_search``, ``simulation.lidar_range``) is
    the same base: the study resumes and flies nothing; a different base is still refused."""
    _tune(tmp_path, 1)
    storage = f"sqlite:///{tmp_path / 'tuning' / 'tuning.db'}"
    study = optuna.load_study(study_name=T.STUDY_NAME, storage=storage)
    old = study.user_attrs["base"]
    old["nmpc"]["line_search"] = old["solver"].pop("line_search")
    old["simulation"]["lidar_range"] = old["sensor"].pop("range")
    study.set_user_attr("base", old)
    assert _tune(tmp_path, 1).flown_trials == 0
    assert "line_search" in optuna.load_study(study_name=T.STUDY_NAME,
                                              storage=storage).user_attrs["base"]["solver"]
    other = dataclasses.replace(TINY, sensor=dataclasses.replace(TINY.sensor, range=4.0))
    with pytest.raises(ValueError, match="base: the stored study"):
        T.tune(T.TuningSettings(1, quick=True, space=SIGMA_ONLY, seeds=(0,), max_steps=40,
                                base=other, out=tmp_path / "tuning",
                                runs_dir=tmp_path / "runs"), workers=0, log=lambda line: None)


def test_heldout_scenes_are_never_training_scenes_and_shared_setups_fly_once(tmp_path):
    setups = {"printed": printed_params(TINY), "safest": printed_params(TINY)}
    with pytest.raises(ValueError, match=r"held-out scenes must never be training .* \[3\]"):
        evaluate_heldout(setups, seeds=(3,), train_seeds=(3,), workers=0)
    table = evaluate_heldout(setups, seeds=(60,), max_steps=30, base=TINY, workers=0,
                               out=tmp_path / "h", runs_dir=tmp_path / "runs",
                               log=lambda line: None)
    assert list(table["setup"]) == ["printed", "safest"]
    assert table["result_dir"].nunique() == 1  # one flight serves both set-ups
    spec = tuning_scenes.tuning_spec(printed_params(TINY), 60, 30, TINY)
    assert spec.name == passage_spec(60, max_steps=30, base=TINY).name  # Monte Carlo's cache

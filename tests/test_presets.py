"""Named set-ups (paper_repro.presets) and how the commands take them."""

from __future__ import annotations

import dataclasses

import pytest

from paper_repro import cli, paths, presets
from paper_repro.config import Config
from paper_repro.studies import reproduce as reproduce


def test_the_default_preset_is_the_printed_configuration():
    assert presets.DEFAULT == "paper"
    assert presets.preset() == Config()
    assert presets.preset("paper") == Config()


def test_paper_timeline_changes_only_the_horizon():
    printed, timed = Config(), presets.preset("paper-timeline")
    assert timed.nmpc.horizon == 43 != printed.nmpc.horizon
    assert dataclasses.replace(timed, nmpc=dataclasses.replace(
        timed.nmpc, horizon=printed.nmpc.horizon)) == printed


def test_a_preset_keeps_the_other_options_of_its_base():
    base = dataclasses.replace(Config(), distance=dataclasses.replace(
        Config().distance, metric="euclidean"))
    cfg = presets.preset("paper-timeline", base=base)
    assert cfg.distance.metric == "euclidean" and cfg.nmpc.horizon == 43


@pytest.mark.parametrize("bad", ["nope", "", None, "Paper"])
def test_unknown_preset_names_the_accepted_ones(bad):
    with pytest.raises(ValueError, match="preset must be one of .*paper-timeline"):
        presets.preset(bad)


@pytest.mark.parametrize("command", [["run", "--out", "{tmp}"], ["reproduce"],
                                     ["study", "monte_carlo", "--quick"]])
def test_commands_reject_an_unknown_preset_before_flying(command, tmp_path, capsys):
    argv = [a.format(tmp=tmp_path) for a in command] + ["--preset", "nope"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "preset must be one of" in err and "paper-timeline" in err


def test_reproduce_writes_a_preset_into_its_own_folder(tmp_path, monkeypatch):
    seen = {}

    def fake_execute(notebook, output, parameters=None):
        seen.setdefault("figures", parameters["figures_dir"])
        seen.setdefault("executed", str(output))
        raise _Stop

    monkeypatch.setattr(reproduce, "execute_notebook", fake_execute)
    with pytest.raises(_Stop):
        reproduce.reproduce(notebooks=["07_distance_tutorial"], preset="paper-timeline",
                            log=lambda line: None)
    expected = paths.figures_dir() / "presets" / "paper-timeline"
    assert seen["figures"] == str(expected)
    assert "presets/paper-timeline" in seen["executed"]


def test_the_preset_enters_the_runs_of_reproduce():
    cfg = presets.preset("paper-timeline")
    specs = reproduce.run_specs(config=cfg)
    assert all(s.config.nmpc.horizon == 43 for s in specs)
    assert {s.directory() for s in specs}.isdisjoint(
        {s.directory() for s in reproduce.run_specs()})


@pytest.mark.parametrize("name", ["monte_carlo", "eta_sweep", "sensor_noise"])
def test_a_study_starts_from_the_preset(name):
    from paper_repro.studies.catalogue import make_study

    printed = make_study(name, quick=True)
    timed = make_study(name, quick=True, base=presets.preset("paper-timeline"))
    assert all(s.config.nmpc.horizon == 43 for s in timed.specs)
    assert [s.name for s in timed.specs] == [s.name for s in printed.specs]
    assert {s.key for s in timed.specs}.isdisjoint({s.key for s in printed.specs})


class _Stop(Exception):
    """Ends a reproduce call once its folders are known (nothing is flown or drawn)."""


def test_moving_design_is_the_moving_studys_design():
    """One description: the preset applied to each paper-barrier run of the moving study gives
    the study's design run of the same crossing, prediction and metric; and ``run`` builds the
    same configuration from the shell."""
    import argparse

    from paper_repro.cli.parser import COMMANDS
    from paper_repro.cli.run import run_config
    from paper_repro.studies.catalogue import make_study

    specs = make_study("moving_obstacles", quick=True).specs
    keys = ("metric", "scene_seed", "prediction", "barrier")
    labels = [{k: v for k, v in s.labels if k in keys} for s in specs]
    design = [(s, lab) for s, lab in zip(specs, labels, strict=True) if lab["barrier"] == "design"]
    assert design
    parser = argparse.ArgumentParser()
    COMMANDS["run"].add_arguments(parser)
    for spec, lab in design:
        paper = next(s for s, other in zip(specs, labels, strict=True)
                     if other == {**lab, "barrier": "paper"})
        assert presets.preset("moving-design", base=paper.config) == spec.config
        sim = spec.config.simulation
        args = parser.parse_args([
            "--out", "unused", "--preset", "moving-design", "--scenario", sim.scenario,
            "--kind", sim.kind, "--seed", str(sim.seed), "--metric", lab["metric"],
            "--prediction", lab["prediction"], "--line-search",
            "--set", f"simulation.max_steps={sim.max_steps}"])
        assert run_config(args) == spec.config


def test_moving_design_on_another_scene_is_the_designs_controller():
    from paper_repro.studies.catalogue import moving_design_controller

    printed = Config()
    kalman = dataclasses.replace(printed, nmpc=dataclasses.replace(printed.nmpc,
                                                                   prediction="kalman"))
    for metric in ("smooth", "euclidean"):
        base = dataclasses.replace(kalman, distance=dataclasses.replace(kalman.distance,
                                                                        metric=metric))
        assert presets.preset("moving-design", base=base) == moving_design_controller(
            base, metric)
    # a static prediction hands the design no velocity: the preset predicts with the tracker
    assert presets.preset("moving-design").nmpc.prediction == "kalman"
    with pytest.raises(ValueError, match="needs nmpc.prediction 'oracle' or 'kalman'"):
        dataclasses.replace(presets.preset("moving-design"), nmpc=dataclasses.replace(
            printed.nmpc, prediction="static", prediction_ts=0.015))

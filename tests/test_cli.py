"""The command line flies what the library flies: every scenario of make_scene, the
prediction of moving regions and the sensing window, and every command is listed."""

import subprocess
import sys

import numpy as np
import pytest

from paper_repro import cli
from paper_repro.cli.parser import COMMANDS
from paper_repro.sim.result import SimulationResult
from paper_repro.world.scenarios import SCENARIOS


def test_run_flies_the_crossing_with_a_kalman_prediction(tmp_path, capsys):
    """A moving scene from the command line, with the tracker's velocities handed to the
    controller (and logged in the result)."""
    out = tmp_path / "crossing"
    assert cli.main(["run", "--scenario", "crossing", "--prediction", "kalman",
                     "--max-steps", "150", "--window", "0.5", "--no-progress",
                     "--out", str(out)]) == 0
    assert "crossing/smooth" in capsys.readouterr().out
    result = SimulationResult.load(out)
    assert result.scene.is_moving and result.steps == 150
    assert result.config.nmpc.prediction == "kalman"
    assert result.config.distance.window == 0.5
    assert result.region_velocities.shape == (150, len(result.scene.clouds), 3)
    assert np.isfinite(result.region_velocities).all()


@pytest.mark.parametrize("option, value, name", [
    ("--prediction", "psychic", "--prediction"), ("--window", "3.5", "window"),
    ("--window", "-1", "window"), ("--scenario", "moon", "--scenario")])
def test_bad_run_options_are_refused_before_flying(option, value, name, tmp_path, capsys):
    assert cli.main(["run", option, value, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and name in err and len(err.strip().splitlines()) == 1


def test_run_offers_exactly_the_scenes_make_scene_builds():
    """Every choice of ``run --scenario`` builds, and a name outside them is refused by the
    library too, naming the parameter: the command line cannot lag the library."""
    from paper_repro.world.scenarios import make_scene

    choices = {a.dest: a.choices for a in _subparser("run")._actions}["scenario"]
    assert set(choices) >= {"paper", "encounter", "random", "crossing", "oncoming",
                            "random-crossing"}
    for name in choices:
        assert make_scene(name, 1).regions
    with pytest.raises(ValueError, match="scenario must be one of"):
        make_scene("moon")
    assert tuple(choices) == SCENARIOS


def test_seed_lists_read_ranges_and_single_seeds_and_name_what_they_accept():
    import argparse

    from paper_repro.cli.args import seed_list

    assert seed_list("0-3") == [0, 1, 2, 3]
    assert seed_list("5,2,3-4,2") == [2, 3, 4, 5]
    for bad in ("x", "3-1", "-2", "1,,2", "0-"):
        with pytest.raises(argparse.ArgumentTypeError, match="must be seeds like 0-29"):
            seed_list(bad)


def test_the_help_lists_every_command():
    text = subprocess.run([sys.executable, "-m", "paper_repro", "--help"],
                          capture_output=True, text=True, check=True).stdout
    for name in COMMANDS:
        assert name in text
    assert set(COMMANDS) == {"run", "scene", "reproduce", "study", "tune", "golden",
                             "regenerate", "cache", "readme", "book"}


def test_cache_rekey_reports_each_folder_and_refuses_what_it_cannot_do(tmp_path, capsys):
    assert cli.main(["cache", "--rekey", str(tmp_path)]) == 0
    assert capsys.readouterr().out.strip() == (f"{tmp_path}: 0 moved, 0 current, 0 unproven, "
                                                "0 duplicate, 0 damaged")
    assert cli.main(["cache", str(tmp_path)]) == 2
    assert "--rekey" in capsys.readouterr().err
    assert cli.main(["cache", "--rekey", str(tmp_path / "nowhere")]) == 2
    assert "DIR must be a folder" in capsys.readouterr().err


def _subparser(name):
    import argparse

    parser = argparse.ArgumentParser()
    COMMANDS[name].add_arguments(parser)
    return parser


def test_run_tells_of_a_collision_and_of_the_design_for_moving_regions():
    """A flight below the collision clearance is named as one; on moving regions flown with
    the static prediction, the design for them is offered."""
    import dataclasses as dc

    import numpy as np

    from paper_repro import Config
    from paper_repro.analysis.metrics import COLLISION_CLEARANCE
    from paper_repro.cli.run import collision_notes
    from paper_repro.world.scenarios import make_scene

    class Flight:
        def __init__(self, clearance, scene, config=None):
            self.clearance, self.scene = np.asarray(clearance), scene
            self.config = config or Config()

    crossing, encounter = make_scene("crossing"), make_scene("encounter")
    assert collision_notes(Flight([2.0, COLLISION_CLEARANCE], crossing)) == []
    notes = collision_notes(Flight([2.0, 0.25, 1.0], crossing))
    assert "0.250 m" in notes[0] and "--preset moving-design" in notes[1]
    assert len(collision_notes(Flight([0.25], encounter))) == 1  # static regions: no design
    oracle = dc.replace(Config(), nmpc=dc.replace(Config().nmpc, prediction="oracle"))
    assert len(collision_notes(Flight([0.25], crossing, oracle))) == 1

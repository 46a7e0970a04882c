"""The linearisation with a shared barrier (β and ∂β/∂y evaluated once for all stages and read
by each) computes the QP of the one that writes β out in every stage, to rounding: static and
moving regions, both metrics, the swept path and the look-ahead of the moving design."""

import dataclasses

import numpy as np
import pytest

from paper_repro import Config, DistanceParams, NMPCParams, SimulationParams, SolverParams
from paper_repro.presets import moving_design_controller
from paper_repro.problem.ocp import OCP
from paper_repro.sim.loop import simulate
from paper_repro.solvers.linearisation import LinearisationLadder, linearisation
from paper_repro.solvers.rti import RealTimeNMPC
from paper_repro.world.lidar import Lidar
from paper_repro.world.scenarios import make_scene
from paper_repro.world.truth import scene_velocities

SMALL = NMPCParams(region_slots=2, points_per_region=24)


def _config(metric, moving):
    cfg = Config(distance=DistanceParams(metric=metric), nmpc=SMALL,
                 simulation=SimulationParams(scenario="crossing" if moving else "encounter"))
    if moving:
        cfg = dataclasses.replace(cfg, nmpc=dataclasses.replace(cfg.nmpc, prediction="oracle"))
        cfg = moving_design_controller(cfg, metric)
    return cfg


@pytest.mark.parametrize("metric", ["smooth", "euclidean"])
@pytest.mark.parametrize("moving", [False, True], ids=["static", "moving-design"])
def test_the_shared_barrier_gives_the_same_qp(metric, moving, rng):
    cfg = _config(metric, moving)
    ocp = OCP(cfg)
    scene = make_scene(cfg.simulation.scenario)
    # a state beside the first region, its points in view
    near = scene.clouds[0][0] + np.array([0.0, -2.0, 0.0])
    x0 = np.zeros(12)
    x0[:3], x0[6] = near, 0.3
    visible = Lidar(scene.clouds).scan(x0[:3])
    assert sum(map(len, visible)) > 0
    velocities = scene_velocities(scene, 0.0) if moving else None
    p = np.concatenate([scene.targets[0], ocp.scan.pack(visible, ocp.output(x0), velocities),
                        ocp.runtime_values])
    guess = ocp.rest(x0)
    X = np.array(guess.x[1:]) + 0.01 * rng.standard_normal((ocp.horizon, 12))
    U, a = np.array(guess.u), ocp.parameters_of(guess.x_a, guess.u_a)
    for values_only in (False, True):
        inlined = linearisation(ocp, values_only=values_only)
        shared = linearisation(ocp, values_only=values_only, shared_barrier=True)
        for one, two in zip(LinearisationLadder.evaluate(inlined, x0, X, U, a, p),
                            LinearisationLadder.evaluate(shared, x0, X, U, a, p), strict=True):
            one, two = np.asarray(one), np.asarray(two)
            assert np.isfinite(two).all()
            assert np.abs(one - two).max() <= 1e-12 * max(1.0, np.abs(one).max())


def test_a_closed_loop_with_the_shared_barrier_flies_the_same_path():
    """The encounter's first 4 s, the region in view from step 316: the two linearisations'
    flights agree to far below a millimetre (the rounding of the QP's data)."""
    cfg = _config("smooth", moving=False)
    runs = [simulate(cfg, RealTimeNMPC(cfg, capacities=(), shared_barrier=shared),
                     max_steps=400, progress=False) for shared in (False, True)]
    assert runs[0].visible_points.max() > 0
    assert np.abs(runs[0].x[:, :3] - runs[1].x[:, :3]).max() < 1e-8


def test_the_option_reaches_the_controller_and_enters_the_key_when_on():
    """Off is how the flights before the option were flown: such a run keeps its key; on
    (the default) enters it."""
    off = dataclasses.replace(Config(), solver=SolverParams(shared_barrier=False))
    assert "shared_barrier" not in off.key_dict()["solver"]
    assert Config().key_dict()["solver"]["shared_barrier"] is True
    fn = RealTimeNMPC(Config(), compile=False, capacities=()).ladder.rungs[0][1]
    assert fn.name().endswith("_shared")
    with pytest.raises(ValueError, match="shared_barrier"):
        SolverParams(shared_barrier="yes")

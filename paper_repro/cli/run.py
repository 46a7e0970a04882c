"""``python -m paper_repro run``: fly one closed-loop mission and save its result.

The scene is a named one (``--scenario``) or your own, from scan files (``--cloud``, see
:mod:`paper_repro.world.scan_regions`). The configuration is built in this order: the scene
and the options below, then the preset (``--preset``), then every ``--set``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from paper_repro.cli.args import (
    non_negative_int,
    output_directory,
    point,
    positive_float,
    positive_int,
    setting,
    with_settings,
)
from paper_repro.config import (
    ESTIMATES,
    GUIDES,
    PLANT_SIMULATORS,
    PREDICTIONS,
    QP_SOLVERS,
    TURBULENCE,
    Config,
)
from paper_repro.world.scan_regions import REGION_VOXEL, SCAN_SCENARIO
from paper_repro.world.scenarios import SCENARIOS

HELP = "fly one closed-loop mission and save its result"

DESCRIPTION = """Fly one closed-loop mission and save its result (result.npz, config.json).

Your own scene: --cloud FILE (repeatable; .npy .npz .csv .xyz .txt .ply .pcd) with --start and
--target; the flight is a passage that ends 2 m past the clouds. Any setting of the
configuration: --set section.field=value (repeatable), e.g. --set distance.eta=0.2.
Against another simulator: --plant rotorpy --motor-lag 0.03 --rotor-drag 1e-4 --wind 3."""


def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro run``."""
    parser.add_argument("--scenario", choices=SCENARIOS, default="paper",
                        help="the scene (paper_repro.world.make_scene); crossing, oncoming and "
                             "random-crossing have moving regions")
    parser.add_argument("--seed", type=non_negative_int, default=None,
                        help="scene seed (Halton clouds; the layout of a random scene); default "
                             "the config's")
    parser.add_argument("--kind", choices=("mission", "passage"), default=None,
                        help="mission: reach every target; passage: end 2 m past the "
                             "obstacles (a random scene's, or the clouds'); default mission, "
                             "passage with --cloud")
    add_cloud_arguments(parser)
    parser.add_argument("--start", type=point, default=None, metavar="X,Y,Z",
                        help="with --cloud: the start, m (in the workspace, outside the clouds)")
    parser.add_argument("--target", type=point, default=None, metavar="X,Y,Z",
                        help="with --cloud: the target, m, more than 2 m past the clouds")
    parser.add_argument("--metric", choices=("smooth", "euclidean"), default="smooth")
    parser.add_argument("--solver", choices=("rti", "reference"), default="rti",
                        help="rti: Gauss-Newton real-time iteration (default); reference: "
                             "IPOPT, exact Hessian, as in the paper")
    parser.add_argument("--qp-solver", choices=QP_SOLVERS, default="riccati-ipm",
                        help="QP solver of rti: riccati-ipm (warm-started active set, then "
                             "an interior point on its kernels where the active set changes "
                             "a lot; default), riccati (the active set, HPIPM where it runs "
                             "out) or hpipm (interior point)")
    parser.add_argument("--line-search", action="store_true",
                        help="rti: the damped real-time iteration (merit line search and "
                             "Levenberg-Marquardt damping; smoother than the paper's "
                             "controller with the Euclidean metric)")
    parser.add_argument("--prediction", choices=PREDICTIONS, default=None,
                        help="how the controller predicts moving regions: static (the paper), "
                             "oracle (their true velocities) or kalman (tracked); default the "
                             "preset's")
    parser.add_argument("--window", type=float, default=None, metavar="W",
                        help="smooth sensing window w, m, in [0, LiDAR range) (0: the paper's "
                             "hard cut-off); default the preset's")
    parser.add_argument("--map-voxel", type=float, default=None, metavar="M",
                        help="voxel side of the local map, m, in (0, LiDAR range); 0: no map, "
                             "the raw scan (sensor.map_voxel); default the preset's")
    parser.add_argument("--guide", choices=GUIDES, default=None, metavar="PLANNER",
                        help=f"what hands the NMPC its set-point, one of {', '.join(GUIDES)} "
                             "(guide.planner; grid needs --map-voxel); default the preset's")
    add_plant_arguments(parser)
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="limit on closed-loop steps (default: the config's max_steps)")
    parser.add_argument("--out", required=True, help="directory for result.npz and config.json")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--preset", default="paper", metavar="NAME",
                        help="named set-up (paper_repro.presets): 'paper' (default, the "
                             "printed parameters), 'paper-timeline' (the paper's clock) or "
                             "'moving-design' (the moving study's barrier)")
    parser.add_argument("--set", type=setting, action="append", default=[], dest="settings",
                        metavar="SECTION.FIELD=VALUE",
                        help="any field of the configuration (paper_repro.config.Config), "
                             "applied last, checked as the dataclasses check it; repeatable")


def add_plant_arguments(parser) -> None:
    """What the vehicle flies in (``config.plant``, :class:`~paper_repro.config.PlantParams`):
    the simulator and its best-known effects by name; the others by ``--set plant.NAME=``."""
    parser.add_argument("--plant", choices=PLANT_SIMULATORS, default=None, metavar="SIMULATOR",
                        help="ours (default: the NMPC's own model, integrated by RK45) or "
                             "rotorpy (RotorPy's multirotor; pip install -e \".[hardware]\")")
    parser.add_argument("--motor-lag", type=float, default=None, metavar="S",
                        help="rotorpy: the rotor speeds' time constant, s (e.g. 0.03)")
    parser.add_argument("--rotor-drag", type=float, default=None, metavar="K_D",
                        help="rotorpy: rotor drag k_d, N/(rad/s · m/s) (e.g. 1e-4)")
    parser.add_argument("--wind", type=float, default=None, metavar="M/S",
                        help="rotorpy: a mean wind along +y (across the paper's flights), m/s; "
                             "needs a drag (--rotor-drag)")
    parser.add_argument("--turbulence", choices=TURBULENCE, default=None, metavar="LEVEL",
                        help=f"rotorpy: Dryden turbulence, one of {', '.join(TURBULENCE)}")
    parser.add_argument("--estimation", choices=tuple(ESTIMATES), default=None,
                        metavar="LEVEL", help="the state the controller is given: perfect "
                                              "(default), mocap or vio (noise and latency)")
    parser.add_argument("--delay", type=non_negative_int, default=None, metavar="STEPS",
                        help="computation delay, in steps of T_s (default 0)")
    parser.add_argument("--estimate-filter", type=float, default=None, metavar="TAU",
                        help="filter the estimate with the nominal model and time constant "
                             "TAU s (a remedy for its noise; e.g. 0.05)")
    parser.add_argument("--compensate-latency", action="store_true", default=None,
                        help="the controller predicts the state over the estimate's latency "
                             "and the delay with its nominal model (a remedy)")
    parser.add_argument("--hover-thrust", type=float, default=None, metavar="TAU",
                        help="scale the thrusts by the thrust the vehicle is learnt to lack, "
                             "with time constant TAU s (a remedy; e.g. 2)")
    parser.add_argument("--motor-lag-compensation", type=float, default=None, metavar="S",
                        help="send each thrust with the lead that inverts a rotor lag of this "
                             "time constant, s (a remedy; e.g. the --motor-lag)")


def add_cloud_arguments(parser) -> None:
    """``--cloud`` and its placement, shared by ``run`` and ``scene``."""
    parser.add_argument("--cloud", action="append", default=[], metavar="FILE",
                        help="a scan file (repeatable): its points become the scene's regions")
    parser.add_argument("--cloud-scale", type=positive_float, default=1.0, metavar="S",
                        help="scale s of the placement y = s·p + offset (e.g. 0.001 for mm)")
    parser.add_argument("--cloud-offset", type=point, default=(0.0, 0.0, 0.0),
                        metavar="X,Y,Z", help="offset of the placement, m (default 0,0,0)")
    parser.add_argument("--region-voxel", type=positive_float, default=REGION_VOXEL,
                        metavar="H", help="voxel side h, m, of the rule that splits the scans "
                                          f"into regions (default {REGION_VOXEL:g})")


def main(args) -> int:
    """Fly the mission the options describe; every option, the config it makes and the scene
    are checked before anything is built."""
    from paper_repro.sim.loop import simulate

    cfg = run_config(args)
    scene = cloud_mission(args, cfg) if args.cloud else None
    out = output_directory("--out", args.out)
    result = simulate(cfg, max_steps=args.max_steps, scene=scene,
                      progress=False if args.no_progress else None)
    print(f"{result.summary()} -> {result.save(out)}")
    for line in collision_notes(result):
        print(line)
    return 0


def collision_notes(result) -> list[str]:
    """What the user is told when the flight came closer to a cloud than the studies' collision
    clearance, and, for moving regions flown with the paper's static prediction, what to fly
    instead."""
    from paper_repro.analysis.metrics import COLLISION_CLEARANCE

    closest = float(np.nanmin(result.clearance)) if len(result.clearance) else np.inf
    if not closest < COLLISION_CLEARANCE:
        return []
    notes = [f"collision: the vehicle came {closest:.3f} m from a cloud point, below the "
             f"collision clearance of {COLLISION_CLEARANCE:g} m (the rotor radius)"]
    if result.scene.is_moving and result.config.nmpc.prediction == "static":
        notes.append("the regions move and the prediction is static (the paper's): "
                     "--preset moving-design flies the design for moving regions")
    return notes


def run_config(args) -> Config:
    """The configuration of ``run``'s options: the scene and the options, then the preset,
    then ``--set``."""
    from paper_repro.presets import preset

    if not args.cloud:
        for option, value in (("--start", args.start), ("--target", args.target)):
            if value is not None:
                raise ValueError(f"{option} needs --cloud (a named scene has its own)")
    base = Config()
    sim = base.simulation
    kind = args.kind or ("passage" if args.cloud else "mission")
    scenario = SCAN_SCENARIO if args.cloud else args.scenario
    base = dataclasses.replace(
        base,
        distance=dataclasses.replace(base.distance, metric=args.metric),
        solver=dataclasses.replace(base.solver, nlp_solver=args.solver,
                                   qp_solver=args.qp_solver, line_search=args.line_search),
        simulation=dataclasses.replace(sim, scenario=scenario, kind=kind,
                                       seed=sim.seed if args.seed is None else args.seed))
    cfg = preset(args.preset, base)
    options = [(section, field, value, f"{option} {value}")
               for option, section, field, value in (
                   ("--window", "distance", "window", args.window),
                   ("--prediction", "nmpc", "prediction", args.prediction),
                   ("--map-voxel", "sensor", "map_voxel", args.map_voxel),
                   ("--guide", "guide", "planner", args.guide),
                   ("--plant", "plant", "simulator", args.plant),
                   ("--motor-lag", "plant", "motor_lag", args.motor_lag),
                   ("--rotor-drag", "plant", "rotor_drag", args.rotor_drag),
                   ("--wind", "plant", "wind", None if args.wind is None
                    else (0.0, float(args.wind), 0.0)),
                   ("--turbulence", "plant", "turbulence", args.turbulence),
                   ("--estimation", "plant", "estimation", args.estimation),
                   ("--delay", "plant", "delay_steps", args.delay),
                   ("--estimate-filter", "plant", "estimate_filter_time",
                    args.estimate_filter),
                   ("--compensate-latency", "plant", "compensate_latency",
                    args.compensate_latency),
                   ("--hover-thrust", "plant", "hover_thrust_time", args.hover_thrust),
                   ("--motor-lag-compensation", "plant", "motor_lag_compensation",
                    args.motor_lag_compensation))
               if value is not None]
    return with_settings(cfg, options + list(args.settings))  # checked together: --set wins


def cloud_mission(args, config: Config):
    """The scene of ``--cloud`` files from ``--start`` to ``--target``, checked: both in the
    workspace (:func:`~paper_repro.sim.checks.check_setup`) and farther than the rotor radius
    from every cloud point (:func:`~paper_repro.sim.checks.setup_hazards`)."""
    from paper_repro.sim.checks import check_setup, setup_hazards
    from paper_repro.world.scan_regions import scan_scene

    for option, value in (("--start", args.start), ("--target", args.target)):
        if value is None:
            raise ValueError(f"--cloud needs {option} X,Y,Z (m, in the workspace)")
    scene = scan_scene(args.cloud, args.start, args.target, config, args.cloud_scale,
                       args.cloud_offset, args.region_voxel)
    check_setup(config, scene)
    hazards = setup_hazards(config, scene)
    arm = config.quadrotor.arm
    for option, clearance in (("--start", hazards["start_clearance_m"]),
                              ("--target", hazards["target_clearance_m"][0])):
        if clearance < arm:
            raise ValueError(f"{option} lies {clearance:.3g} m from a cloud point, within the "
                             f"rotor radius {arm:g} m (quadrotor.arm): it must lie outside "
                             "the clouds")
    return scene

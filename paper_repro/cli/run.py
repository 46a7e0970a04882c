"""``python -m paper_repro run``: fly one closed-loop mission and save its result."""

from __future__ import annotations

import dataclasses

from paper_repro.cli.args import non_negative_int, output_directory, positive_int
from paper_repro.config import PREDICTIONS, QP_SOLVERS
from paper_repro.world.scenarios import SCENARIOS

HELP = "fly one closed-loop mission and save its result"


def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro run``."""
    parser.add_argument("--scenario", choices=SCENARIOS, default="paper",
                        help="the scene (paper_repro.world.make_scene); crossing, oncoming and "
                             "random-crossing have moving regions")
    parser.add_argument("--seed", type=non_negative_int, default=None,
                        help="scene seed (Halton clouds; the layout of a random scene); default "
                             "the config's")
    parser.add_argument("--kind", choices=("mission", "passage"), default="mission",
                        help="mission: reach every target; passage: end 2 m past a random "
                             "scene's obstacle field")
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
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="limit on closed-loop steps (default: the config's max_steps)")
    parser.add_argument("--out", required=True, help="directory for result.npz and config.json")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--preset", default="paper", metavar="NAME",
                        help="named set-up (paper_repro.presets): 'paper' (default, the "
                             "printed parameters) or 'paper-timeline' (the paper's clock)")


def main(args) -> int:
    """Fly the mission the options describe; every option (and the config it makes) is
    checked before anything is built."""
    from paper_repro.presets import preset
    from paper_repro.sim.loop import simulate

    cfg = preset(args.preset)
    sim = cfg.simulation
    cfg = dataclasses.replace(
        cfg,
        distance=dataclasses.replace(
            cfg.distance, metric=args.metric,
            window=cfg.distance.window if args.window is None else args.window),
        nmpc=dataclasses.replace(
            cfg.nmpc,
            prediction=cfg.nmpc.prediction if args.prediction is None else args.prediction),
        solver=dataclasses.replace(cfg.solver, nlp_solver=args.solver,
                                   qp_solver=args.qp_solver, line_search=args.line_search),
        simulation=dataclasses.replace(
            sim, scenario=args.scenario, kind=args.kind,
            seed=sim.seed if args.seed is None else args.seed),
    )
    out = output_directory("--out", args.out)
    result = simulate(cfg, max_steps=args.max_steps,
                      progress=False if args.no_progress else None)
    print(f"{result.summary()} -> {result.save(out)}")
    return 0

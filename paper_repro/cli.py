"""Command line: ``python -m paper_repro {run,scene,reproduce} ...``.

    python -m paper_repro run --scenario encounter --metric smooth --max-steps 500 --out results/x
    python -m paper_repro run --scenario random --seed 3 --kind passage --out results/passage
    python -m paper_repro scene --scenario paper
    python -m paper_repro reproduce [--quick]
    python -m paper_repro study monte_carlo [--quick] [--workers N] [--scheduler ADDRESS]
    python -m paper_repro tune [--trials N] [--quick] [--workers N] [--storage URL]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

from . import reproduce as _reproduce
from .config import Config


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the command. A bad option or an inconsistent mission
    (``ValueError``) prints one line ``error: <message>`` on stderr and returns 2, before
    anything is built or flown."""
    try:
        return _main(argv)
    except (_UsageError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


class _UsageError(Exception):
    """An argparse error, raised instead of printing the usage and exiting."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors become one line, via main
        raise _UsageError(f"{self.prog}: {message}")


def _main(argv: list[str] | None) -> int:
    parser = _Parser(prog="python -m paper_repro", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="fly one closed-loop mission and save its result")
    run.add_argument("--scenario", choices=("paper", "encounter", "random"), default="paper")
    run.add_argument("--seed", type=_reproduce.non_negative_int, default=None,
                     help="scene seed (Halton clouds; the layout of a random scene); default "
                          "the config's")
    run.add_argument("--kind", choices=("mission", "passage"), default="mission",
                     help="mission: reach every target; passage: end 2 m past a random "
                          "scene's obstacle field")
    run.add_argument("--metric", choices=("smooth", "euclidean"), default="smooth")
    run.add_argument("--solver", choices=("rti", "reference"), default="rti",
                     help="rti: Gauss-Newton real-time iteration (default); reference: IPOPT, "
                          "exact Hessian, as in the paper")
    run.add_argument("--qp-solver", choices=("riccati", "hpipm"), default="riccati",
                     help="QP solver of rti: riccati (warm-started active set, default) or "
                          "hpipm (interior point)")
    run.add_argument("--line-search", action="store_true",
                     help="rti: the damped real-time iteration (merit line search and "
                          "Levenberg-Marquardt damping; smoother than the paper's controller "
                          "with the Euclidean metric)")
    run.add_argument("--max-steps", type=_reproduce.positive_int, default=None,
                     help="limit on closed-loop steps (default: the config's max_steps)")
    run.add_argument("--out", required=True, help="directory for result.npz and config.json")
    run.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    run.add_argument("--preset", default="paper", metavar="NAME",
                     help="named set-up (paper_repro.presets): 'paper' (default, the printed "
                          "parameters) or 'paper-timeline' (the paper's clock)")

    scene = sub.add_parser("scene", help="print a scene and a distance table")
    scene.add_argument("--scenario", choices=("paper", "encounter", "random"), default="paper")
    scene.add_argument("--seed", type=_reproduce.non_negative_int, default=None,
                       help="scene seed (default: the config's)")

    reproduce = sub.add_parser(
        "reproduce", help="simulate what is missing, run every notebook, write figures/",
        description=_reproduce.DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    _reproduce.add_arguments(reproduce)

    from . import study as _study

    study = sub.add_parser(
        "study", help="fly a study (random scenes, parameter sweeps) on Dask; table + figures",
        description=_study.__doc__.split("\n\n")[0])
    _study.add_arguments(study)

    from . import tuning as _tuning

    tune = sub.add_parser(
        "tune", help="tune eta, sigma, d_min, kappa, mu, delta with Optuna on random passages; "
                     "held-out comparison + figures", description=_tuning.__doc__.split("\n\n")[0])
    _tuning.add_arguments(tune)

    from . import evidence as _evidence

    golden = sub.add_parser(
        "golden", help="fly the golden flights and compare them with figures/golden/ "
                       "(--write: commit the flights that moved)",
        description=_evidence.__doc__.split("\n\n")[0])
    _evidence.add_arguments(golden)

    from . import report as _report

    readme = sub.add_parser("readme", help="write the README's tables from the committed "
                                           "tables in figures/ (--check: only compare)")
    _report.add_arguments(readme)

    args = parser.parse_args(argv)
    # Every option is checked here, before a scene, a controller or a flight is built.
    if getattr(args, "preset", None) is not None:
        from .presets import check_name

        check_name(args.preset)
    if args.command == "run":
        args.out = _output_directory("--out", args.out)
    if args.command == "reproduce" and args.figures_dir is not None:
        args.figures_dir = _output_directory("--figures-dir", args.figures_dir)
    if args.command == "reproduce":
        return _reproduce.main(args)
    if args.command == "study":
        return _study.main(args)
    if args.command == "tune":
        return _tuning.main(args)
    if args.command == "golden":
        return _evidence.main(args)
    if args.command == "readme":
        return _report.main(args)
    if args.command == "run":
        return _run(args)
    return _scene(args)


def _run(args) -> int:
    from .presets import preset
    from .simulation import simulate

    cfg = preset(args.preset)
    cfg = dataclasses.replace(
        cfg,
        distance=dataclasses.replace(cfg.distance, metric=args.metric),
        nmpc=dataclasses.replace(cfg.nmpc, solver=args.solver, qp_solver=args.qp_solver,
                                 line_search=args.line_search),
        simulation=dataclasses.replace(
            cfg.simulation, scenario=args.scenario, kind=args.kind,
            seed=cfg.simulation.seed if args.seed is None else args.seed),
    )
    result = simulate(cfg, max_steps=args.max_steps,
                      progress=False if args.no_progress else None)
    out = result.save(args.out)
    print(f"{result.summary()} -> {out}")
    return 0


def _output_directory(option: str, text: str) -> Path:
    """Create the directory ``text`` (if new) and check that a file can be written into it,
    so that a run never flies and then fails to save; ``ValueError`` naming ``option``."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} must be a directory (existing or new), got the existing "
                         f"file {text!r}")
    try:  # permissions alone do not tell (root, read-only mounts): create and probe
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise ValueError(f"{option} must be a writable directory, got {text!r} "
                         f"({exc.strerror or exc})") from None
    return path


def _scene(args) -> int:
    from .distance import clearance, euclidean_distance, smooth_distance
    from .scene import make_scene

    cfg = Config()
    scene = make_scene(args.scenario,
                       cfg.simulation.seed if args.seed is None else args.seed)
    eta, sigma = cfg.distance.eta, cfg.distance.sigma
    print(f"scene {scene.name!r}: start {list(scene.start)}, targets "
          f"{[list(t) for t in scene.targets]}")
    print(f"{'region':<12}{'points':>8}   {'centroid':<24}")
    for region, cloud in zip(scene.regions, scene.clouds, strict=True):
        c = [round(float(v), 2) for v in cloud.mean(axis=0)]
        print(f"{region.name:<12}{len(cloud):>8}   {str(c):<24}")
    print(f"\nD_η,σ (η = {eta} m, σ = {sigma} m) against ½d² from the start to the first "
          "region (m²; clearance d in m):")
    print(f"{'d':>8}{'½d²':>10}{'D':>10}")
    cloud = scene.clouds[0]
    start = np.asarray(scene.start, float)
    proj = cloud[np.argmin(np.sum((cloud - start) ** 2, axis=1))]
    for s in np.linspace(0.0, 1.0, 8):
        y = proj + s * (start - proj)
        print(f"{clearance(y, cloud):8.3f}{euclidean_distance(y, cloud):10.3f}"
              f"{smooth_distance(y, cloud, eta, sigma):10.3f}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

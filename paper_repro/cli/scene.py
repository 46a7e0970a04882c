"""``python -m paper_repro scene``: print a scene and a table of D_{η,σ} against ½d²."""

from __future__ import annotations

import numpy as np

from paper_repro.cli.args import non_negative_int
from paper_repro.config import Config
from paper_repro.world.scenarios import SCENARIOS

HELP = "print a scene and a table of the smoothed distance against ½d²"


def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro scene``."""
    parser.add_argument("--scenario", choices=SCENARIOS, default="paper")
    parser.add_argument("--seed", type=non_negative_int, default=None,
                        help="scene seed (default: the config's)")


def main(args) -> int:
    """Print the scene's regions, then D_{η,σ} and ½d² along a line from the start to the
    first region."""
    from paper_repro.problem.distance import clearance, euclidean_distance, smooth_distance
    from paper_repro.world.scenarios import make_scene

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

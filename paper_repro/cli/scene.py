"""``python -m paper_repro scene``: print a scene and a table of D_{η,σ} against ½d²; with
``--cloud``, the regions a scan splits into, and a figure of them with ``--figure``."""

from __future__ import annotations

import numpy as np

from paper_repro.cli.args import non_negative_int, point
from paper_repro.cli.run import add_cloud_arguments
from paper_repro.config import Config
from paper_repro.world.scenarios import SCENARIOS

HELP = "print a scene (or the regions of scan files) and D_{η,σ} against ½d²"


def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro scene``."""
    parser.add_argument("--scenario", choices=SCENARIOS, default="paper")
    parser.add_argument("--seed", type=non_negative_int, default=None,
                        help="scene seed (default: the config's)")
    add_cloud_arguments(parser)
    parser.add_argument("--start", type=point, default=None, metavar="X,Y,Z",
                        help="with --cloud and --target: the mission's start, m, checked")
    parser.add_argument("--target", type=point, default=None, metavar="X,Y,Z",
                        help="with --cloud and --start: the mission's target, m, checked")
    parser.add_argument("--figure", default=None, metavar="PATH",
                        help="draw the regions into this image (.png or .pdf)")


def main(args) -> int:
    """Print the scene's regions, then D_{η,σ} and ½d² along a line from the start to the
    nearest region; draw the regions with ``--figure``."""
    cfg = Config()
    if args.figure is not None and not args.figure.lower().endswith((".png", ".pdf")):
        raise ValueError(f"--figure must end in .png or .pdf, got {args.figure!r}")
    if args.cloud:
        scene = _cloud_scene(args, cfg)
        if scene is None:
            return 0
        _print_scene_line(scene)
    else:
        from paper_repro.world.scenarios import make_scene

        scene = make_scene(args.scenario,
                           cfg.simulation.seed if args.seed is None else args.seed)
        _print_scene_line(scene)
        _print_regions(scene.clouds, [r.name for r in scene.regions])
        if args.figure:
            _draw(args.figure, scene.clouds, [r.name for r in scene.regions], scene)
    _print_distance_table(scene, cfg)
    return 0


def _cloud_scene(args, cfg: Config):
    """The regions of ``--cloud`` printed (and drawn); the scene when ``--start`` and
    ``--target`` are given (checked as ``run`` checks them), else ``None``."""
    from paper_repro.cli.run import cloud_mission
    from paper_repro.world.scan_regions import scan_regions

    regions = scan_regions(args.cloud, cfg, args.cloud_scale, args.cloud_offset,
                           args.region_voxel)
    names = [f"scan-{k}" for k in range(len(regions))]
    print(f"{len(regions)} region(s) from {len(args.cloud)} file(s): 26-connected voxels of "
          f"{args.region_voxel:g} m; thinned to at most {cfg.nmpc.points_per_region} points "
          f"within r_s = {cfg.sensor.range:g} m")
    print(f"{'region':<12}{'points':>8}{'in files':>10}{'voxel [m]':>11}   "
          f"{'centroid [m]':<24}{'extent [m]':<24}")
    for name, r in zip(names, regions, strict=True):
        c = [round(float(v), 2) for v in r.points.mean(axis=0)]
        e = [round(float(v), 2) for v in np.ptp(r.points, axis=0)]
        side = f"{r.side:.3g}" if r.side else "-"
        print(f"{name:<12}{len(r.points):>8}{r.raw:>10}{side:>11}   {str(c):<24}{str(e):<24}")
    scene = None
    if args.start is not None or args.target is not None:
        scene = cloud_mission(args, cfg)
    if args.figure:
        _draw(args.figure, [r.points for r in regions], names, scene)
    return scene


def _print_scene_line(scene) -> None:
    print(f"scene {scene.name!r}: start {list(scene.start)}, targets "
          f"{[list(t) for t in scene.targets]}")


def _print_regions(clouds, names) -> None:
    print(f"{'region':<12}{'points':>8}   {'centroid':<24}")
    for name, cloud in zip(names, clouds, strict=True):
        c = [round(float(v), 2) for v in cloud.mean(axis=0)]
        print(f"{name:<12}{len(cloud):>8}   {str(c):<24}")


def _print_distance_table(scene, cfg: Config) -> None:
    from paper_repro.problem.distance import clearance, euclidean_distance, smooth_distance

    eta, sigma = cfg.distance.eta, cfg.distance.sigma
    start = np.asarray(scene.start, float)
    nearest = int(np.argmin([clearance(start, c) for c in scene.clouds]))
    cloud = scene.clouds[nearest]
    print(f"\nD_η,σ (η = {eta} m, σ = {sigma} m) against ½d² from the start to region "
          f"{scene.regions[nearest].name!r} (m²; clearance d in m):")
    print(f"{'d':>8}{'½d²':>10}{'D':>10}")
    proj = cloud[np.argmin(np.sum((cloud - start) ** 2, axis=1))]
    for s in np.linspace(0.0, 1.0, 8):
        y = proj + s * (start - proj)
        print(f"{clearance(y, cloud):8.3f}{euclidean_distance(y, cloud):10.3f}"
              f"{smooth_distance(y, cloud, eta, sigma):10.3f}")


def _draw(path: str, clouds, names, scene) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from paper_repro.plots.flight import plot_regions

    fig = plot_regions(clouds, names, None if scene is None else scene.start,
                       None if scene is None else scene.targets)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    print(f"regions drawn -> {path}")

"""``python -m paper_repro reproduce``: fly what is missing, run every notebook, write figures/."""

from __future__ import annotations

import argparse
import dataclasses

from paper_repro.cli.args import non_negative_int, output_directory, positive_int
from paper_repro.config import Config
from paper_repro.studies.reproduce import NOTEBOOKS, QUICK_STEPS, reproduce

HELP = 'simulate what is missing, run every notebook, write figures/'



def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``python -m paper_repro reproduce``."""
    parser.add_argument("--workers", type=non_negative_int, default=None,
                        help="processes that fly the missions (default: one per mission, at "
                             "most one per core; 0: one after the other in this process)")
    parser.add_argument("--quick", action="store_true",
                        help=f"short mission ({QUICK_STEPS} steps per metric) into "
                             "figures/quick/ for a fast look")
    parser.add_argument("--max-steps", type=positive_int, default=None,
                        help="step limit per run (default: the whole mission, or "
                             f"{QUICK_STEPS} with --quick)")
    parser.add_argument("--force", action="store_true",
                        help="re-simulate even when a cached result exists (the cache is keyed "
                             "by the configuration, not by the code)")
    parser.add_argument("--solver", choices=("rti", "reference"), default=None,
                        help="NMPC solver of the runs (default: the config's, "
                             f"{Config().solver.nlp_solver!r}; 'reference' is IPOPT as in the "
                             "paper, about 100x slower)")
    parser.add_argument("--notebooks", nargs="+", metavar="NAME", default=None,
                        choices=[nb.name for nb in NOTEBOOKS],
                        help="execute only these notebooks (default: all)")
    parser.add_argument("--figures-dir", default=None,
                        help="where figures and summary.csv go (default: figures/, or "
                             "figures/quick/ with --quick)")
    parser.add_argument("--no-progress", action="store_true",
                        help="hide the closed-loop progress bar")
    parser.add_argument("--preset", default="paper", metavar="NAME",
                        help="named set-up (paper_repro.presets): 'paper' (default, the printed "
                             "parameters) or 'paper-timeline' (the paper's clock, N = 43); "
                             "figures of a preset other than 'paper' go to "
                             "figures/presets/NAME/")


def main(args: argparse.Namespace) -> int:
    """Run :func:`reproduce` from parsed command-line arguments."""
    if args.figures_dir is not None:
        args.figures_dir = output_directory("--figures-dir", args.figures_dir)
    config = Config()
    if args.solver is not None:
        config = dataclasses.replace(
            config, solver=dataclasses.replace(config.solver, nlp_solver=args.solver))
    reproduce(quick=args.quick, max_steps=args.max_steps, force=args.force,
              notebooks=args.notebooks, config=config, figures_dir=args.figures_dir,
              progress=False if args.no_progress else None,
              log=lambda line: print(line, flush=True), preset=args.preset,
              workers=args.workers)
    return 0

"""``python -m paper_repro study NAME``: fly a study of the catalogue and write its table."""

from __future__ import annotations

import time
from pathlib import Path

from paper_repro import paths
from paper_repro.paths import study_dir
from paper_repro.progress import duration
from paper_repro.studies.catalogue import STUDIES, STUDY_NOTEBOOK_QUICK, STUDY_NOTEBOOKS, make_study
from paper_repro.studies.engine import run_study

HELP = 'fly a study (random scenes, parameter sweeps) on Dask; table + figures'


# --- the command ----------------------------------------------------------------------------

def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro study NAME``."""
    parser.add_argument("name", choices=sorted(STUDIES), help="which study")
    parser.add_argument("--quick", action="store_true",
                        help="a few short runs (what CI executes); output under figures/quick/")
    from paper_repro.cli.args import non_negative_int, positive_int

    parser.add_argument("--workers", type=non_negative_int, default=None,
                        help="worker processes of the embedded Dask cluster (default: one per "
                             "core; 0: no Dask, in this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="send the runs to an existing Dask scheduler (tcp://host:8786) "
                             "instead; its workers must see the output folders")
    parser.add_argument("--out", default=None,
                        help="where the table, study.json and the figures go (default: "
                             "figures/studies/NAME, or figures/quick/studies/NAME)")
    parser.add_argument("--scenes", type=positive_int, default=None,
                        help="random passages (scene seeds 0..N-1; default: the study's own, "
                             "100 for monte_carlo, 20 for eta_sweep, 8 for sensor_noise)")
    parser.add_argument("--force", action="store_true", help="fly every run again")
    parser.add_argument("--no-figures", action="store_true",
                        help="only the table: do not execute the study's notebook")
    parser.add_argument("--no-progress", action="store_true", help="plain progress lines")
    parser.add_argument("--preset", default="paper", metavar="NAME",
                        help="named set-up the runs start from (paper_repro.presets; default "
                             "'paper', the printed parameters); another preset's output goes "
                             "to figures/presets/NAME/studies/")


def main(args) -> int:
    """Run ``python -m paper_repro study``: the study (cached runs are only loaded), its table,
    then its notebook, which draws the figures from the saved table."""
    from paper_repro.evidence.golden import command_line, layer_of, stamp
    from paper_repro.presets import DEFAULT, preset

    study = make_study(args.name, quick=args.quick, base=preset(args.preset),
                       scenes=args.scenes)
    out = Path(args.out) if args.out else study_dir(args.name, args.quick)
    if args.out is None and args.preset != DEFAULT:
        out = paths.figures_dir(args.quick) / "presets" / args.preset / "studies" / args.name
    result = run_study(study, out=out, workers=args.workers, scheduler=args.scheduler,
                       force=args.force, runs_dir=paths.results_dir() / "runs",
                       progress=False if args.no_progress else None,
                       log=lambda line: print(line, flush=True))
    notebook = STUDY_NOTEBOOKS.get(args.name)  # a study without one: its table is its set
    if not args.no_figures and notebook is not None:
        from paper_repro.studies.reproduce import execute_notebook, notebook_path

        t0 = time.perf_counter()
        params = {"study_dir": str(result.directory),
                  **(STUDY_NOTEBOOK_QUICK.get(args.name, {}) if args.quick else {})}
        execute_notebook(notebook_path(notebook),
                         paths.executed_dir(args.quick) / f"{notebook}.ipynb", params)
        print(f"notebook {notebook}: figures in {result.directory} "
              f"({duration(time.perf_counter() - t0)})", flush=True)
    if not args.no_figures:
        # Last, once the table and every figure are in place: the set is this code's.
        stamp(result.directory, command_line(), layer_of(*(s.config for s in study.specs)))
    return 0

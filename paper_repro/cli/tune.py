"""``python -m paper_repro tune``: tune the avoidance parameters with Optuna."""

from __future__ import annotations

import time
from pathlib import Path

from paper_repro import paths
from paper_repro.config import Config
from paper_repro.paths import tuning_dir
from paper_repro.studies.tuning import (
    DEFAULT_HARD,
    DEFAULT_SCENES,
    DEFAULT_TRIALS,
    QUICK,
    TuningSettings,
    check_tune_args,
    tune,
    tuning_client,
)
from paper_repro.studies.tuning_results import run_heldout
from paper_repro.studies.tuning_scenes import HELDOUT_SEEDS
from paper_repro.studies.tuning_space import DEFAULT_OBJECTIVES, OBJECTIVES, finished_trials

HELP = ("tune eta, sigma, d_min, kappa, mu, delta with Optuna on random passages; "
        "held-out comparison + figures")


# --- the command ----------------------------------------------------------------------------

def add_arguments(parser) -> None:
    """Options of ``python -m paper_repro tune``."""
    from paper_repro.cli.args import positive_int

    parser.add_argument("--trials", type=positive_int, default=None,
                        help=f"finished trials the study should hold (default {DEFAULT_TRIALS}; "
                             f"{QUICK['trials']} with --quick); a resumed study runs the rest")
    parser.add_argument("--quick", action="store_true",
                        help="a few 400-step trials (what CI executes); output under "
                             "figures/quick/tuning/")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes of the embedded Dask cluster (default: one per "
                             "core; 0: no Dask, one trial at a time in this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="send the runs to an existing Dask scheduler (tcp://host:8786)")
    parser.add_argument("--storage", default=None, metavar="URL",
                        help="Optuna RDB storage (default sqlite:///figures/tuning/tuning.db)")
    parser.add_argument("--objectives", nargs="+", default=list(DEFAULT_OBJECTIVES),
                        metavar="NAME", help=f"objectives to minimise, of {sorted(OBJECTIVES)}")
    parser.add_argument("--scenes", type=positive_int, default=None,
                        help=f"training scenes (default {DEFAULT_SCENES}; "
                             f"{QUICK['scenes']} with --quick)")
    parser.add_argument("--hard", type=int, default=None,
                        help=f"how many training scenes are ones where the printed set-up "
                             f"stalls or chatters (default {DEFAULT_HARD}; "
                             f"{QUICK['hard']} with --quick)")
    parser.add_argument("--heldout", type=int, default=None,
                        help=f"held-out scenes (default {len(HELDOUT_SEEDS)}; "
                             f"{QUICK['heldout']} with --quick; 0 skips the evaluation)")
    parser.add_argument("--sampler", choices=("tpe", "nsga2"), default="tpe")
    parser.add_argument("--seed", type=int, default=0, help="sampler seed")
    parser.add_argument("--out", default=None,
                        help="where the storage, tables and figures go (default "
                             "figures/tuning, or figures/quick/tuning)")
    parser.add_argument("--no-figures", action="store_true",
                        help="do not execute the notebook 12_tuning")


def main(args) -> int:
    """``python -m paper_repro tune``: the study (resumed if stored), the held-out evaluation,
    then notebook ``12_tuning``, which draws everything from the saved study and table."""
    from paper_repro.progress import duration

    quick = args.quick
    trials = args.trials or (QUICK["trials"] if quick else DEFAULT_TRIALS)
    out = Path(args.out) if args.out else tuning_dir(quick)
    heldout = args.heldout if args.heldout is not None else (
        QUICK["heldout"] if quick else len(HELDOUT_SEEDS))
    if heldout > len(HELDOUT_SEEDS):
        raise ValueError(f"--heldout must be at most {len(HELDOUT_SEEDS)} (the held-out seeds "
                         f"{HELDOUT_SEEDS[0]}-{HELDOUT_SEEDS[-1]}), got {heldout}")
    log = lambda line: print(line, flush=True)  # noqa: E731
    # Everything is checked before a cluster is started or a scene flown.
    check_tune_args(trials, quick, args.workers, args.scheduler, args.storage, None,
                     args.objectives, args.scenes, None, args.sampler, None, Config(),
                     args.hard)
    for name in ("heldout", "seed"):
        if getattr(args, name) is not None and getattr(args, name) < 0:
            raise ValueError(f"--{name} must be an integer >= 0, got {getattr(args, name)}")
    t0 = time.perf_counter()
    with tuning_client(args.workers, args.scheduler, None, log) as client:
        settings = TuningSettings(trials, quick=quick, storage=args.storage,
                                  objectives=args.objectives, scenes=args.scenes,
                                  hard=args.hard,
                                  sampler=args.sampler, seed=args.seed, out=out)
        res = tune(settings, client=client, log=log)
        if heldout:
            run_heldout(res, heldout, client=client, log=log)
    print(f"tune: {len(finished_trials(res.study))} trials, {res.flown_trials} run now, in "
          f"{duration(time.perf_counter() - t0)} -> {out}", flush=True)
    if not args.no_figures:
        from paper_repro.studies.reproduce import execute_notebook, notebook_path

        execute_notebook(notebook_path("12_tuning"),
                         paths.executed_dir(quick) / "12_tuning.ipynb",
                         {"tuning_dir": str(out)})
        print(f"notebook 12_tuning: figures in {out}", flush=True)
        from paper_repro.evidence.golden import command_line, stamp

        stamp(out, command_line())  # last: the set is this code's
    return 0

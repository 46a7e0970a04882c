"""``python -m paper_repro regenerate``: make the stale evidence sets again, one job per core,
the speed tables last and alone (:mod:`paper_repro.evidence.regenerate`)."""

from __future__ import annotations

import os

from paper_repro import paths
from paper_repro.cli.args import positive_int
from paper_repro.evidence.regenerate import plan, run
from paper_repro.evidence.sets import SETS, last_wall_time_s, resumed

HELP = ("make the stale evidence sets again (and those that read them), one job per core, "
        "the speed tables last and alone, then the README's tables")


def main(args) -> int:
    """``python -m paper_repro regenerate [SET ...] [--all] [--jobs N] [--dry-run]``."""
    names = [s.folder for s in SETS] if args.all else (
        ["" if n in ("figures", "figures/") else n.removeprefix("figures/")
         for n in args.sets] or None)
    items = plan(names)
    if not items:
        print("every evidence set is current: nothing to make")
        return 0
    if args.dry_run:
        print(f"{len(items)} evidence set(s) to make, {args.jobs} at a time (the last run's "
              "wall time, where the set records it):")
        known = 0.0
        for item in sorted(items, key=lambda s: s.timed):
            when = "last, alone" if item.timed else (
                f"after {', '.join(item.after)}" if item.after else "at once")
            seconds = last_wall_time_s(paths.figures_dir() / item.folder)
            part = resumed(paths.figures_dir() / item.folder) if seconds else None
            if part:  # the last call found runs cached: count their flights too
                seconds += part[2]
            known += seconds or 0.0
            last = (f"{'about ' if part else ''}{seconds / 60:.1f} min" if seconds
                    else "not recorded")
            print(f"  {item.label} ({when}; last run {last})\n"
                  f"      {item.command} {item.one_core}".rstrip())
        print(f"the recorded wall times add up to {known / 3600:.1f} h, one command at a "
              "time (a set whose runs are cached takes less)")
        return 0
    jobs = run(items, jobs=args.jobs, readme=not args.no_readme)
    print("\n".join(f"{j.status:8s} {j.label:42s} {j.wall_s / 60:6.1f} min  {j.note}".rstrip()
                    for j in jobs))
    return 0 if all(j.status == "made" for j in jobs) else 1


def add_arguments(parser) -> None:
    parser.add_argument("sets", nargs="*", metavar="SET",
                        help="evidence sets to make, as folders under figures/ (default: the "
                             "stale ones), e.g. studies/monte_carlo")
    parser.add_argument("--all", action="store_true", help="every evidence set")
    parser.add_argument("--jobs", type=positive_int, default=os.cpu_count() or 1,
                        help="commands at once, one core each (default: the machine's cores)")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the plan and run nothing")
    parser.add_argument("--no-readme", action="store_true",
                        help="do not format the README's and the book's tables at the end")

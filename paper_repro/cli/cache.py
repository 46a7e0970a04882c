"""``python -m paper_repro cache --rekey``: keep the run cache through a change of the
configuration's layout that moves no flight."""

from __future__ import annotations

from pathlib import Path

from paper_repro import paths
from paper_repro.studies.runs import rekey

HELP = ("re-key the run cache after a change of the configuration's layout that moves no "
        "flight (each old key is checked first)")
DESCRIPTION = HELP + (
    ". A run's cache key hashes its configuration, so a setting added with a default, or "
    "moved to another part, gives every run a new key although no flight changed. --rekey "
    "moves each result whose old key is proven (its stored configuration and today's golden "
    "hash give that key) to its new folder; the others are left to be flown again.")


def main(args) -> int:
    """``python -m paper_repro cache --rekey [DIR ...]``."""
    if not args.rekey:
        raise ValueError("cache: say what to do (--rekey)")
    folders = [Path(d) for d in args.dirs] or [paths.results_dir(), paths.results_dir() / "runs"]
    for folder in folders:
        if not folder.is_dir():
            raise ValueError(f"DIR must be a folder of cached runs, got {str(folder)!r}")
    for folder in folders:
        counts = rekey(folder)
        print(f"{folder}: " + ", ".join(f"{n} {k}" for k, n in counts.items()))
    return 0


def add_arguments(parser) -> None:
    parser.add_argument("dirs", nargs="*", metavar="DIR",
                        help="folders of cached runs (default: results/ and results/runs/)")
    parser.add_argument("--rekey", action="store_true",
                        help="move every result whose old key is proven to its new key")

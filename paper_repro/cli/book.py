"""``python -m paper_repro book``: the HTML book from ``docs/`` and the executed notebooks."""

from __future__ import annotations

import sys
from pathlib import Path

from paper_repro.book.site import build

HELP = ("build the HTML book from docs/ and the executed notebooks (build/book/html); a study "
        "notebook not executed here is drawn from the committed tables, in seconds, flying "
        "nothing")


def main(args) -> int:
    """``python -m paper_repro book [--quick] [--strict] [--executed DIR] [--out DIR]``."""
    try:
        build(quick=args.quick, executed=args.executed, out=args.out, strict=args.strict)
    except RuntimeError as exc:  # Sphinx's own report: printed whole, no traceback
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


def add_arguments(parser) -> None:
    parser.add_argument("--quick", action="store_true",
                        help="from the --quick runs' notebooks (notebooks/executed/quick/)")
    parser.add_argument("--strict", action="store_true",
                        help="refuse to build unless every notebook has been executed by its "
                             "command (default: a study notebook not executed is drawn from "
                             "the committed tables into build/book/drawn/, any other is shown "
                             "without outputs)")
    parser.add_argument("--executed", type=Path, default=None,
                        help="folder of the executed notebooks (default notebooks/executed/)")
    parser.add_argument("--out", type=Path, default=None,
                        help="the book's folder (default build/book/)")

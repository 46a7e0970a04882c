"""``python -m paper_repro readme``: write (or check) the tables of the README and the book's
pages from figures/."""

from __future__ import annotations

from paper_repro.evidence.readme import blocks, page_paths, render

HELP = ("write the tables of the README and of docs/ from the committed tables in figures/ "
        "(--check: only compare)")


def main(args) -> int:
    """``python -m paper_repro readme [--check]``."""
    stale, written = [], 0
    for path in page_paths():
        text = path.read_text()
        new = render(text)
        if args.check:
            stale += [f"{path.name}:{n}" for n, body in blocks(text).items()
                      if blocks(new)[n] != body]
        elif new != text:
            path.write_text(new)
        written += len(blocks(new))
    if args.check:
        print("blocks out of date: " + ", ".join(stale) if stale else "every block is current")
        return 1 if stale else 0
    print(f"{written} block(s) written from figures/ into the README and docs/")
    return 0


def add_arguments(parser) -> None:
    parser.add_argument("--check", action="store_true",
                        help="only say which blocks differ from the committed tables")

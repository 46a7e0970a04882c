"""``python -m paper_repro readme``: write (or check) the README's tables from figures/."""

from __future__ import annotations

from paper_repro.evidence.readme import blocks, readme_path, render

HELP = "write the README's tables from the committed tables in figures/ (--check: only compare)"



def main(args) -> int:
    """``python -m paper_repro readme [--check]``."""
    path = readme_path()
    text = path.read_text()
    new = render(text)
    if args.check:
        stale = [n for n, body in blocks(text).items() if blocks(new)[n] != body]
        print("README blocks out of date: " + ", ".join(stale) if stale else
              "README blocks are current")
        return 1 if stale else 0
    path.write_text(new)
    print(f"README: {len(blocks(new))} block(s) written from figures/")
    return 0


def add_arguments(parser) -> None:
    parser.add_argument("--check", action="store_true",
                        help="only say which blocks differ from the committed tables")

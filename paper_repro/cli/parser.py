"""Command line: ``python -m paper_repro COMMAND ...``.

    python -m paper_repro run --scenario encounter --metric smooth --max-steps 500 --out results/x
    python -m paper_repro run --scenario random --seed 3 --kind passage --out results/passage
    python -m paper_repro run --scenario crossing --prediction kalman --out results/crossing
    python -m paper_repro scene --scenario paper
    python -m paper_repro reproduce [--quick]
    python -m paper_repro study monte_carlo [--quick] [--workers N] [--scheduler ADDRESS]
    python -m paper_repro tune [--trials N] [--quick] [--workers N] [--storage URL]
    python -m paper_repro golden [--write]
    python -m paper_repro regenerate [SET ...] [--jobs N] [--dry-run]
    python -m paper_repro cache --rekey
    python -m paper_repro readme [--check]
    python -m paper_repro book [--quick]
"""

from __future__ import annotations

import argparse
import sys

from paper_repro.cli import (
    book,
    cache,
    golden,
    readme,
    regenerate,
    reproduce,
    run,
    scene,
    study,
    tune,
)

COMMANDS = {"run": run, "scene": scene, "reproduce": reproduce,
            "study": study, "tune": tune, "golden": golden, "regenerate": regenerate,
            "cache": cache, "readme": readme, "book": book}
"""Every command: a module with ``HELP``, ``add_arguments(parser)`` and
``main(args)``; ``main`` checks every option before anything is built or flown."""


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the command. A bad option or an inconsistent mission
    (``ValueError``) prints one line ``error: <message>`` on stderr and returns 2, before
    anything is built or flown."""
    try:
        parser = _Parser(prog="python -m paper_repro", description=__doc__,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
        sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                    help=", ".join(COMMANDS))
        for name, command in COMMANDS.items():
            command.add_arguments(sub.add_parser(
                name, help=command.HELP, description=getattr(command, "DESCRIPTION", command.HELP),
                formatter_class=argparse.RawDescriptionHelpFormatter))
        args = parser.parse_args(argv)
        return COMMANDS[args.command].main(args)
    except (_UsageError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


class _UsageError(Exception):
    """An argparse error, raised instead of printing the usage and exiting."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors become one line, via main
        raise _UsageError(f"{self.prog}: {message}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

"""The benchmarks' output: a fixed-width table for the eye, then the same rows as JSON."""

from __future__ import annotations

import json


def print_table(rows: list[dict], columns: list[tuple[str, str, str]], width: int = 12) -> None:
    """Print ``rows`` under ``columns`` = [(key, header, format spec)], then the rows as one
    JSON line (what a script reading the benchmark should parse)."""
    print("".join(f"{header:>{width}}" for _, header, _ in columns))
    for row in rows:
        print("".join(f"{row[key]:>{width}{spec}}" if spec != "s" else f"{row[key]!s:>{width}}"
                      for key, _, spec in columns))
    print(json.dumps(rows))

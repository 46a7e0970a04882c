"""Fly a committed study's first scenes again and compare the rows with its committed table.

    python benchmarks/recheck_study.py NAME [--scenes 2] [--workers 2]

``--scenes 0`` flies the whole study, as committed (the only choice for a study that does not
fly random scenes, as ``timeline``).

A study's table is what its flights determine, byte for byte, on the machine that flew it.
The golden flights (``python -m paper_repro golden``) pin the code's behaviour on a few short
flights; a study's long flights can still come out otherwise on another machine, in the last
digits, where the Euclidean metric chatters (a chattering flight is chaotic: see
``environment.md``, "The same flights on another machine"). This flies the runs of the first
``--scenes`` scenes of study ``NAME`` (``python -m paper_repro study --help`` lists them) with
the study engine into a temporary folder, with a run cache of its own (nothing cached is
trusted), and compares each row with the committed row of the same name, column by column:
``identical``, or the columns that differ with the largest relative difference among them.

The last line is the JSON of the counts (``rows``, ``identical``, ``differ``, ``missing``).
The exit status is 1 when a row differs: the committed table is not what this machine flies,
and the study is to be flown again here (or where it was flown) before its numbers are quoted
as this commit's.
"""

from __future__ import annotations

import paper_repro._blas  # noqa: F401  (before NumPy: one OpenBLAS kernel)

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from paper_repro import paths
from paper_repro.studies.catalogue import make_study
from paper_repro.studies.engine import load_table, run_study


def compare(committed: pd.DataFrame, flown: pd.DataFrame) -> pd.DataFrame:
    """One row per flown run: ``name``, ``status`` (``identical``, ``differ`` or ``missing``:
    no committed row of that name), the differing ``columns`` and the largest relative
    difference among their numbers (``max_rel``; inf where a value is not a number)."""
    committed = committed.set_index("name")
    rows = []
    for name, row in flown.set_index("name").iterrows():
        if name not in committed.index:
            rows.append({"name": name, "status": "missing", "columns": "", "max_rel": np.nan})
            continue
        old = committed.loc[name]
        differing, worst = [], 0.0
        for column in flown.columns.drop("name"):
            a, b = old.get(column), row[column]
            if pd.isna(a) and pd.isna(b) or a == b:
                continue
            differing.append(column)
            try:
                worst = max(worst, abs(float(b) - float(a)) / max(abs(float(a)), 1e-300))
            except (TypeError, ValueError):
                worst = np.inf
        rows.append({"name": name, "status": "differ" if differing else "identical",
                     "columns": ", ".join(differing), "max_rel": worst if differing else 0.0})
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("name", help="a committed study (figures/studies/NAME)")
    parser.add_argument("--scenes", type=int, default=2,
                        help="first scenes to fly (>= 1; 0: the whole study)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0: none)")
    args = parser.parse_args(argv)
    folder = paths.figures_dir() / "studies" / args.name
    if not (folder / "table.parquet").is_file():
        parser.error(f"NAME must be a committed study under {folder.parent}, got {args.name!r}")
    if args.scenes < 0 or args.workers < 0:
        parser.error("--scenes must be >= 0 (0: the whole study) and --workers >= 0")
    try:
        study = make_study(args.name, scenes=args.scenes or None)
    except ValueError as exc:
        parser.error(f"{exc}; --scenes 0 flies the whole study")
    committed = load_table(folder, timings=False)
    with tempfile.TemporaryDirectory() as tmp:
        run_study(study, out=Path(tmp) / "study",
                  runs_dir=Path(tmp) / "runs", workers=args.workers, progress=False,
                  log=lambda line: None)
        flown = load_table(Path(tmp) / "study", timings=False)
    table = compare(committed, flown)
    with pd.option_context("display.width", 200, "display.max_colwidth", 80):
        print(table.to_string(index=False))
    counts = {"study": args.name, "rows": len(table),
              **{s: int((table["status"] == s).sum()) for s in ("identical", "differ",
                                                                 "missing")}}
    print(json.dumps(counts))
    return 1 if counts["differ"] else 0


if __name__ == "__main__":
    sys.exit(main())

"""``python -m paper_repro golden``: fly the golden flights and compare (or write) them."""

from __future__ import annotations

from paper_repro.evidence.golden import (
    GOLDEN_FLIGHTS,
    LAYERS,
    check_golden,
    golden_hash,
    machine_signature,
    stale_evidence,
    write_golden,
    write_machine_copies,
)

HELP = ("fly the golden flights and compare them with figures/golden/ (--write: commit "
        "the flights that moved)")


def main(args) -> int:
    """``python -m paper_repro golden [--write] [--force] [NAME ...]``."""
    if args.machine_copy and (args.write or not args.names):
        raise SystemExit("golden: --machine-copy takes the names of the flights to copy, and "
                         "not --write")
    if args.machine_copy:
        rows = write_machine_copies(args.names)
    elif args.write:
        rows = write_golden(args.names or None, args.force)
    else:
        rows = check_golden(args.names or None)
    for row in rows:
        state = ("identical" if row["identical"] else "within tolerance" if row["ok"]
                 else "MOVED")
        extra = " (written)" if row.get("written") else ""
        if "machines" in row["reference"].parts:
            extra += f" (against this machine's copy, {machine_signature()})"
        print(f"{row['name']:28s} {row['steps']:>10s}  position {row['position_error']:.3g} m"
              f"  input {row['input_error']:.3g}  {state}{extra}")
    print(f"golden hash {golden_hash()}" + "".join(
        f", layer {layer!r} {golden_hash(layer)}" for layer in LAYERS if layer))
    stale = stale_evidence()
    if stale:
        print("evidence sets made with another golden set (regenerate them): "
              + ", ".join(stale))
    return 0 if args.write or all(r["ok"] for r in rows) else 1


def add_arguments(parser) -> None:
    parser.add_argument("names", nargs="*", metavar="NAME",
                        help="golden flights to fly (default: all): "
                             + ", ".join(f.name for f in GOLDEN_FLIGHTS))
    parser.add_argument("--write", action="store_true",
                        help="write the flights that moved, and golden.json")
    parser.add_argument("--force", action="store_true", help="with --write: rewrite every file")
    parser.add_argument("--machine-copy", action="store_true",
                        help="keep the named flights, flown here, as this machine's copies: "
                             "for flights that only this machine's arithmetic moves")


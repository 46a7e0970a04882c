"""How the README's blocks format a committed table: markdown tables, shares, rates with their
intervals, ratios, lengths and times."""

from __future__ import annotations

import pandas as pd


def markdown_table(header: list[str], rows: list[list]) -> str:
    def cell(c) -> str:
        return str(c).replace("|", "\\|")  # a bar inside a cell (|Δu|) must not split it

    lines = ["| " + " | ".join(map(cell, header)) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(map(cell, row)) + " |" for row in rows]
    return "\n".join(lines)


def share(x: float) -> str:
    return f"{100 * x:.1f} %" if 0 < x < 0.01 else f"{100 * x:.0f} %"


def rate(r) -> str:
    return rate_of(r["rate"], r["low"], r["high"], int(r["k"]), int(r["n"]))


def rate_of(rate, low, high, k: int | None = None, n: int | None = None) -> str:
    count = f"{k}/{n}, " if k is not None else ""
    return f"{count}{100 * rate:.0f} % [{100 * low:.0f}, {100 * high:.0f}]"


def ratio(x: float) -> str:
    return "—" if pd.isna(x) else f"×{x:.3g}"


def metres(x: float) -> str:
    if pd.isna(x) or x == 0:
        return "—"
    if x < 0.01:
        return f"{1e3 * x:.2g} mm"
    return f"{100 * x:.2g} cm" if x < 1 else f"{x:.2g} m"


def ms(x: float) -> str:
    """A time in ms: two significant digits, whole milliseconds from 10 ms."""
    return f"{x:,.0f}" if x >= 10 else f"{x:.2g}"


def num(x: float) -> str:
    return f"{x:,.0f}" if abs(x) >= 1000 else f"{x:.3g}"


def paired_table(table: pd.DataFrame, a: str, b: str) -> str:
    """Paired effects (``analysis.paired``; its columns ``median_smooth`` and
    ``median_euclidean`` hold the medians of ``a`` and ``b``)."""
    rows = []
    for r in table.itertuples():
        effect = (f"×{num(r.median_effect)} [{num(r.low)}, {num(r.high)}]"
                  if r.effect.startswith("ratio")
                  else f"{r.median_effect:+.3g} [{r.low:+.3g}, {r.high:+.3g}]")
        rows.append([r.label, num(r.median_smooth), num(r.median_euclidean), effect,
                     f"{r.wilcoxon_p:.2g}", f"{int(r.scenes)}"])
    return markdown_table(["measure (median over scenes)", a, b, f"{b} vs {a}, per scene",
                      "Wilcoxon p", "scenes"], rows)

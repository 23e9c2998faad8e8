"""Result tables as Markdown and CSV, from rows (dicts) and columns ``(key, header in the
.md, format in the .md)``: the writer of Table 1's and the studies' tables."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence

__all__ = ["csv_text", "format_cell", "markdown_table"]


def format_cell(value, spec: str) -> str:
    """``value`` as a Markdown cell: ``—`` for None, ``nan`` for a non-finite float, else
    ``format(value, spec)`` (``spec = "s"``: ``str``)."""
    if value is None:
        return "—"
    if isinstance(value, float) and not math.isfinite(value):
        return "nan"
    if spec == "s":
        return str(value)
    return format(value, spec)


def markdown_table(rows: Sequence[dict], columns: Sequence[tuple[str, str, str]]) -> str:
    """``rows`` as a Markdown table of ``columns``."""
    lines = [
        "| " + " | ".join(header for _, header, _ in columns) + " |",
        "|" + "|".join("---" for _ in columns) + "|",
    ]
    for r in rows:
        lines.append("| " + " | ".join(format_cell(r[k], f) for k, _, f in columns) + " |")
    return "\n".join(lines)


def csv_text(rows: Sequence[dict], columns: Sequence[tuple[str, str, str]]) -> str:
    """``rows`` as CSV: one header line of the keys, floats at full precision (``repr``)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow([k for k, _, _ in columns])
    for r in rows:
        cells = []
        for k, _, _ in columns:
            v = r[k]
            cells.append("" if v is None else (repr(v) if isinstance(v, float) else str(v)))
        writer.writerow(cells)
    return buf.getvalue()

"""Compare two result CSVs (``table1.csv`` or ``faults.csv``) row by row.

Used to check that a change of the controllers' code leaves their figures unchanged: run the
same command with the old and the new code and compare the two CSV files::

    python benchmarks/compare_results.py OLD.csv NEW.csv [--rtol 1e-6] [--atol 1e-12]

Rows are matched by their key columns (picked from the header: ``traj, T_tot_s, controller``
for Table 1; ``fault, trajectory, controller`` (+ ``simulator``) for the fault campaign; or
``--keys``). Every other column is compared, except the timing columns (CPU or wall-clock
time of the computation, e.g. ``step_time_median_ms``, ``wall_time_s``; the simulated times
such as ``exec_time_s`` are compared), which are listed as excluded:

- numbers: equal when ``|old - new| <= max(atol, rtol * max(|old|, |new|))``; the relative
  difference reported is ``|old - new| / max(|old|, |new|)`` (0 when ``|old - new| <=
  atol``); NaN equals NaN and an empty cell equals an empty cell;
- anything else (``yes``/``NO``, ``True``/``False``, names, messages): the same text.

Printed precision. A file whose numbers are rounded when written (``faults.csv`` writes
floats with 6 significant digits) cannot show a relative change below ~1e-6: two values
that differ by less than ``rtol`` can round to neighbouring printed values. The digits of
each file are detected (the most significant digits of any of its numbers); when that is
at most 12, a pair that differs by no more than one unit in the last printed digit is
reported as ``~print`` (indistinguishable at the printed precision) and is not a failure
unless ``--strict-precision``. Files written with ``repr`` (``table1.csv``, 15-17 digits)
are compared at ``rtol`` as they are.

Rows present in only one file are listed: a row missing from NEW is a failure, a row only
in NEW (e.g. a new controller) is not, unless ``--strict-rows``. Likewise a column missing
from NEW is a failure, a new column is listed (a failure with ``--strict-columns``).

Exit status: 0 the same within tolerance, 1 a difference (or missing row/column), 2 bad
usage or unreadable input.
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Comparison", "compare_files", "is_timing_column", "main"]

#: Key columns of the known files, tried in order (all of a set must be in both headers).
KNOWN_KEYS: tuple[tuple[str, ...], ...] = (
    ("traj", "T_tot_s", "controller"),  # table1.csv
    ("fault", "trajectory", "controller", "simulator"),  # faults.csv
    ("fault", "trajectory", "controller"),
    ("trajectory", "T_tot_s", "controller"),
    ("controller", "trajectory", "fault"),
)
#: A column measuring the computation's CPU / wall-clock time: "time" with step, wall, solve,
#: cpu, compute or elapsed (e.g. step_time_median_ms, wall_time_s, solve_time_s).
_TIMING = re.compile(r"(step|wall|solve|solver|cpu|compute|elapsed|runtime)", re.IGNORECASE)
#: Printed digits above which a file counts as written at full precision.
_FULL_PRECISION_DIGITS = 12
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def is_timing_column(name: str) -> bool:
    """Whether ``name`` is a timing column of the computation (excluded from the check)."""
    low = name.lower()
    return ("time" in low and bool(_TIMING.search(low))) or low in ("wall_s", "elapsed_s")


def _number(text: str) -> float | None:
    """The value of a numeric cell (``nan``/``inf`` included), else ``None``."""
    t = text.strip()
    if _NUMBER.match(t):
        return float(t)
    if t.lower() in ("nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity", "-infinity"):
        return float(t)
    return None


def _significant_digits(text: str) -> int:
    """Significant digits written in a numeric cell (``0.00123457`` -> 6, ``8.0`` -> 2)."""
    mantissa = re.split(r"[eE]", text.strip().lstrip("+-"))[0]
    digits = mantissa.replace(".", "").lstrip("0")
    return max(len(digits), 1)


def _quantum(value: float, digits: int) -> float:
    """One unit in the last of ``digits`` significant digits of ``value`` (0 for 0/inf)."""
    if value == 0.0 or not math.isfinite(value) or digits > _FULL_PRECISION_DIGITS:
        return 0.0
    return 10.0 ** (math.floor(math.log10(abs(value))) - (digits - 1))


@dataclass
class Table:
    path: Path
    header: list[str]
    rows: dict[tuple[str, ...], dict[str, str]]
    order: list[tuple[str, ...]]
    digits: int  # most significant digits of any numeric cell
    duplicates: int


def _read(path: Path, keys: list[str]) -> Table:
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        header = list(reader.fieldnames or [])
        records = list(reader)
    missing = [k for k in keys if k not in header]
    if missing:
        raise ValueError(f"{path}: no key column(s) {', '.join(missing)} in the header")
    rows: dict[tuple[str, ...], dict[str, str]] = {}
    order: list[tuple[str, ...]] = []
    digits, duplicates, seen = 1, 0, {}
    for rec in records:
        base = tuple((rec.get(k) or "").strip() for k in keys)
        n = seen.get(base, 0)
        seen[base] = n + 1
        key = base if n == 0 else base + (f"#{n + 1}",)  # repeated key: match by occurrence
        duplicates += n > 0
        rows[key] = {c: (rec.get(c) or "") for c in header}
        order.append(key)
        for c in header:
            cell = rows[key][c]
            if c not in keys and _NUMBER.match(cell.strip()):
                digits = max(digits, _significant_digits(cell))
    return Table(path, header, rows, order, digits, duplicates)


def _canonical_key(key: str) -> str:
    """A key cell as a number if it is one (``8`` and ``8.0`` match), else as it is."""
    v = _number(key)
    return repr(v) if v is not None else key


def pick_keys(header_old: list[str], header_new: list[str]) -> list[str]:
    """The key columns of the first :data:`KNOWN_KEYS` set present in both headers."""
    for keys in KNOWN_KEYS:
        if all(k in header_old and k in header_new for k in keys):
            return list(keys)
    raise ValueError(
        "cannot tell the key columns from the headers; give them with --keys a,b,c "
        f"(header: {', '.join(header_old)})"
    )


@dataclass
class Cell:
    key: tuple[str, ...]
    column: str
    old: str
    new: str
    rel: float  # relative difference (inf for text or NaN against a number)
    status: str  # "differs" or "~print"


@dataclass
class Comparison:
    """The outcome of :func:`compare_files`."""

    keys: list[str]
    compared: list[str]
    excluded: list[str]
    only_old_columns: list[str]
    only_new_columns: list[str]
    only_old_rows: list[tuple[str, ...]]
    only_new_rows: list[tuple[str, ...]]
    rows_compared: int
    cells_compared: int
    differing: list[Cell]  # beyond tolerance (status "differs") or at print precision
    max_rel: float
    max_rel_at: tuple[tuple[str, ...], str] | None
    digits_old: int
    digits_new: int
    duplicates: int

    def failures(
        self,
        strict_rows: bool = False,
        strict_columns: bool = False,
        strict_precision: bool = False,
    ) -> list[str]:
        """Why the comparison fails (empty: it passes)."""
        out = []
        bad = [c for c in self.differing if c.status == "differs" or strict_precision]
        if bad:
            out.append(f"{len(bad)} value(s) differ beyond tolerance")
        if self.only_old_rows:
            out.append(f"{len(self.only_old_rows)} row(s) missing from NEW")
        if strict_rows and self.only_new_rows:
            out.append(f"{len(self.only_new_rows)} row(s) only in NEW (--strict-rows)")
        if self.only_old_columns:
            out.append(f"column(s) missing from NEW: {', '.join(self.only_old_columns)}")
        if strict_columns and self.only_new_columns:
            out.append(f"column(s) only in NEW (--strict-columns): {self.only_new_columns}")
        return out


def _compare_cell(a: str, b: str, rtol: float, atol: float, quantum: float) -> tuple[float, str]:
    """``(relative difference, status)``; status ``""`` (equal), ``differs`` or ``~print``."""
    sa, sb = a.strip(), b.strip()
    if sa == sb:
        return 0.0, ""
    x, y = _number(sa), _number(sb)
    if x is None or y is None:
        return math.inf, "differs"
    if math.isnan(x) or math.isnan(y):
        return (0.0, "") if math.isnan(x) and math.isnan(y) else (math.inf, "differs")
    if math.isinf(x) or math.isinf(y):
        return (0.0, "") if x == y else (math.inf, "differs")
    diff = abs(x - y)
    if diff <= atol:  # under the absolute floor: equal, and no relative difference to report
        return 0.0, ""
    scale = max(abs(x), abs(y))
    rel = diff / scale
    if diff <= rtol * scale:
        return rel, ""
    if quantum > 0 and diff <= quantum * (1 + 1e-9):
        return rel, "~print"
    return rel, "differs"


def _columns(
    header_old: list[str],
    h_old: list[str],
    header_new: list[str],
    h_new: list[str],
    keys: list[str],
    skip: set[str],
    include: set[str],
) -> tuple[list[str], list[str], list[str], list[str]]:
    """``(excluded, compared, only_old, only_new)`` columns: timing columns and ``skip``
    are excluded unless in ``include``; the key columns are neither."""
    excluded = [c for c in header_old if c not in keys and (c in skip or is_timing_column(c))]
    excluded = [c for c in excluded if c not in include]
    compared = [c for c in header_old if c not in keys and c not in excluded and c in h_new]
    only_old = [c for c in header_old if c not in h_new and c not in excluded]
    only_new = [
        c for c in header_new if c not in h_old and c not in skip and not is_timing_column(c)
    ]
    return excluded, compared, only_old, only_new


def _matched_rows(order_old: list, order_new: list) -> tuple[list, list, list]:
    """``(matched, only_old, only_new)``: the old rows paired with the new ones of the same
    canonical key, in the old order, and the rows of either without a partner."""
    canon_new = {tuple(_canonical_key(k) for k in key): key for key in order_new}
    matched: list[tuple[tuple[str, ...], tuple[str, ...]]] = []
    only_old = []
    for key in order_old:
        other = canon_new.pop(tuple(_canonical_key(k) for k in key), None)
        if other is None:
            only_old.append(key)
        else:
            matched.append((key, other))
    only_new = [k for k in order_new if k in canon_new.values()]
    return matched, only_old, only_new


def _compared_cells(t_old, t_new, matched, compared, rtol: float, atol: float) -> tuple:
    """``(differing cells, largest relative difference, where, cells compared)`` over the
    matched rows' ``compared`` columns."""
    differing: list[Cell] = []
    max_rel, max_at, cells = 0.0, None, 0
    for key_old, key_new in matched:
        ro, rn = t_old.rows[key_old], t_new.rows[key_new]
        for c in compared:
            a, b = ro[c], rn[c]
            xa, xb = _number(a), _number(b)
            quantum = 0.0
            if xa is not None and xb is not None:
                quantum = max(_quantum(xa, t_old.digits), _quantum(xb, t_new.digits))
            rel, status = _compare_cell(a, b, rtol, atol, quantum)
            cells += 1
            if rel > max_rel or (max_at is None and rel > 0):
                max_rel, max_at = rel, (key_old, c)
            if status:
                differing.append(Cell(key_old, c, a, b, rel, status))
    return differing, max_rel, max_at, cells


def compare_files(
    old: str | Path,
    new: str | Path,
    *,
    rtol: float = 1e-6,
    atol: float = 1e-12,
    keys: list[str] | None = None,
    exclude: list[str] | None = None,
    include: list[str] | None = None,
) -> Comparison:
    """Compare ``new`` with ``old`` (the reference); see the module's documentation.

    ``exclude`` adds columns to skip; ``include`` compares columns that would be skipped as
    timing columns.
    """
    old, new = Path(old), Path(new)
    with open(old, newline="", encoding="utf-8") as fh:
        h_old = next(csv.reader(fh), [])
    with open(new, newline="", encoding="utf-8") as fh:
        h_new = next(csv.reader(fh), [])
    keys = list(keys) if keys else pick_keys(h_old, h_new)
    t_old, t_new = _read(old, keys), _read(new, keys)
    excluded, compared, only_old_columns, only_new_columns = _columns(
        t_old.header, h_old, t_new.header, h_new, keys, set(exclude or []), set(include or [])
    )
    matched, only_old_rows, only_new_rows = _matched_rows(t_old.order, t_new.order)
    differing, max_rel, max_at, cells = _compared_cells(t_old, t_new, matched, compared, rtol, atol)
    return Comparison(
        keys=keys,
        compared=compared,
        excluded=excluded,
        only_old_columns=only_old_columns,
        only_new_columns=only_new_columns,
        only_old_rows=only_old_rows,
        only_new_rows=only_new_rows,
        rows_compared=len(matched),
        cells_compared=cells,
        differing=differing,
        max_rel=max_rel,
        max_rel_at=max_at,
        digits_old=t_old.digits,
        digits_new=t_new.digits,
        duplicates=t_old.duplicates + t_new.duplicates,
    )


def _fmt_key(keys: list[str], key: tuple[str, ...]) -> str:
    return "/".join(key)


def _fmt_rel(rel: float) -> str:
    return "inf" if math.isinf(rel) else f"{rel:.3e}"


def _differing_lines(cmp: Comparison, max_lines: int) -> list[str]:
    """The table of the values that differ, largest first (at most ``max_lines``)."""
    if not cmp.differing:
        return []
    shown = sorted(cmp.differing, key=lambda c: -c.rel)[:max_lines]
    wk = max(len(_fmt_key(cmp.keys, c.key)) for c in shown)
    wk = max(wk, len("row"))
    wc = max(max(len(c.column) for c in shown), len("column"))
    wv = max(max(len(c.old) for c in shown), max(len(c.new) for c in shown), 3)
    wv = min(wv, 24)
    n_diff = sum(c.status == "differs" for c in cmp.differing)
    n_print = len(cmp.differing) - n_diff
    lines = [""]
    lines.append(
        f"values that differ: {n_diff} beyond tolerance, {n_print} at printed precision "
        f"(~print){'' if len(shown) == len(cmp.differing) else f'; largest {len(shown)}'}"
    )
    lines.append(
        f"  {'row':{wk}s}  {'column':{wc}s}  {'old':>{wv}s}  {'new':>{wv}s}  "
        f"{'rel. diff':>9s}  status"
    )
    for c in shown:
        lines.append(
            f"  {_fmt_key(cmp.keys, c.key):{wk}s}  {c.column:{wc}s}  {c.old[:wv]:>{wv}s}  "
            f"{c.new[:wv]:>{wv}s}  {_fmt_rel(c.rel):>9s}  {c.status}"
        )
    return lines


def format_report(
    cmp: Comparison,
    old: str,
    new: str,
    rtol: float,
    atol: float,
    max_lines: int = 60,
    strict_rows: bool = False,
    strict_columns: bool = False,
    strict_precision: bool = False,
) -> str:
    """The printed report."""
    lines = [
        f"OLD {old}",
        f"NEW {new}",
        f"rows matched by {', '.join(cmp.keys)}: {cmp.rows_compared} rows, "
        f"{len(cmp.compared)} columns, {cmp.cells_compared} values compared "
        f"(rtol {rtol:g}, atol {atol:g})",
        f"excluded (timing) columns: {', '.join(cmp.excluded) if cmp.excluded else 'none'}",
    ]
    for name, digits in (("OLD", cmp.digits_old), ("NEW", cmp.digits_new)):
        if digits <= _FULL_PRECISION_DIGITS:
            lines.append(
                f"note: {name} prints numbers with at most {digits} significant digits: "
                "differences of one unit in the last digit are shown as ~print"
            )
    if cmp.duplicates:
        lines.append(f"note: {cmp.duplicates} repeated key(s), matched by occurrence")
    if cmp.only_new_columns:
        lines.append(f"columns only in NEW: {', '.join(cmp.only_new_columns)}")
    if cmp.only_old_columns:
        lines.append(f"columns missing from NEW: {', '.join(cmp.only_old_columns)}")
    if cmp.only_old_rows:
        lines.append(f"rows missing from NEW ({len(cmp.only_old_rows)}):")
        lines += [f"  - {_fmt_key(cmp.keys, k)}" for k in cmp.only_old_rows]
    if cmp.only_new_rows:
        tag = "" if strict_rows else ", not a failure"
        lines.append(f"rows only in NEW ({len(cmp.only_new_rows)}{tag}):")
        lines += [f"  + {_fmt_key(cmp.keys, k)}" for k in cmp.only_new_rows]
    lines += _differing_lines(cmp, max_lines)
    lines.append("")
    if cmp.max_rel_at is None:
        lines.append("largest relative difference: 0 (every compared value equal within atol)")
    else:
        key, col = cmp.max_rel_at
        lines.append(
            f"largest relative difference: {_fmt_rel(cmp.max_rel)} "
            f"({_fmt_key(cmp.keys, key)}, {col})"
        )
    fails = cmp.failures(strict_rows, strict_columns, strict_precision)
    lines.append("RESULT: DIFFERENT: " + "; ".join(fails) if fails else "RESULT: SAME")
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    doc = (__doc__ or "").split("\n\n", 1)
    parser = argparse.ArgumentParser(
        prog="compare_results.py",
        description=doc[0],
        epilog=doc[1] if len(doc) > 1 else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("old", help="reference CSV (the old code's table1.csv or faults.csv)")
    parser.add_argument("new", help="CSV to check (the new code's)")
    parser.add_argument(
        "--rtol", type=float, default=1e-6, help="relative tolerance (default 1e-6)"
    )
    parser.add_argument(
        "--atol",
        type=float,
        default=1e-12,
        help="absolute floor for values near 0 (default 1e-12)",
    )
    parser.add_argument(
        "--keys", help="comma-separated key columns (default: picked from the header)"
    )
    parser.add_argument(
        "--exclude", action="append", default=[], metavar="COL", help="also skip column COL"
    )
    parser.add_argument(
        "--include",
        action="append",
        default=[],
        metavar="COL",
        help="compare COL although it is a timing column",
    )
    parser.add_argument(
        "--strict-rows", action="store_true", help="rows only in NEW are a failure too"
    )
    parser.add_argument(
        "--strict-columns", action="store_true", help="columns only in NEW are a failure too"
    )
    parser.add_argument(
        "--strict-precision",
        action="store_true",
        help="differences within one unit of the last printed digit are a failure too",
    )
    parser.add_argument(
        "--max-lines", type=int, default=60, help="rows of the difference table (default 60)"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.rtol < 0 or args.atol < 0:
        parser.error("--rtol and --atol must be ≥ 0")
    keys = [k.strip() for k in args.keys.split(",")] if args.keys else None
    exclude = [c for item in args.exclude for c in item.split(",") if c]
    include = [c for item in args.include for c in item.split(",") if c]
    try:
        cmp = compare_files(
            args.old,
            args.new,
            rtol=args.rtol,
            atol=args.atol,
            keys=keys,
            exclude=exclude,
            include=include,
        )
    except (OSError, ValueError, csv.Error) as exc:
        print(f"compare_results: error: {exc}", file=sys.stderr)
        return 2
    print(
        format_report(
            cmp,
            args.old,
            args.new,
            args.rtol,
            args.atol,
            args.max_lines,
            args.strict_rows,
            args.strict_columns,
            args.strict_precision,
        )
    )
    return 1 if cmp.failures(args.strict_rows, args.strict_columns, args.strict_precision) else 0


if __name__ == "__main__":
    sys.exit(main())

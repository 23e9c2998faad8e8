"""Reading a study file's tables with the key, the expected type and the offending value in
every error.

A :class:`TableReader` wraps one TOML table: :meth:`~TableReader.take` reads a key (checked
against its kind), and :meth:`~TableReader.finish` refuses the keys nobody took, listing
those that are known. The reader knows where it is (``[grid]``, ``[[trajectories]] #2``),
so every message names the file, the table and the key.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, cast

from dqcontrol.errors import ParameterError

__all__ = ["KINDS", "REQUIRED", "TOP_LEVEL", "StudyFileError", "TableReader"]

#: How messages name the file's top level.
TOP_LEVEL = "at the top level"


class StudyFileError(ParameterError):
    """A study file is missing, is not TOML, or holds an unknown key or a wrong value; the
    message names the file, the table, the key, what was found and what would be right."""


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


#: Marker of a key without a default.
REQUIRED: Any = _Required()


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _number_list(value: object) -> bool:
    return isinstance(value, list) and all(_is_number(v) for v in value)


def _nested_number_list(value: object) -> bool:
    return isinstance(value, list) and all(_number_list(v) for v in value)


#: Kinds of values: name → (check, what the message says is expected).
KINDS: dict[str, tuple[Callable[[object], bool], str]] = {
    "str": (lambda v: isinstance(v, str) and bool(v.strip()), "a non-empty string"),
    "bool": (lambda v: isinstance(v, bool), "true or false"),
    "int": (lambda v: isinstance(v, int) and not isinstance(v, bool), "an integer"),
    "number": (_is_number, "a finite number"),
    "positive": (lambda v: _is_number(v) and cast(float, v) > 0, "a finite number > 0"),
    "numbers": (_number_list, "a list of numbers"),
    "positives": (
        lambda v: _number_list(v) and bool(v) and all(x > 0 for x in cast(list, v)),
        "a non-empty list of numbers > 0",
    ),
    "strs": (
        lambda v: isinstance(v, list) and bool(v) and all(isinstance(x, str) for x in v),
        "a non-empty list of strings",
    ),
    "matrix": (_nested_number_list, "a list of lists of numbers"),
    "table": (lambda v: isinstance(v, dict), "a table"),
    "tables": (
        lambda v: isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v),
        "an array of tables ([[...]])",
    ),
    "any": (lambda v: True, "a value"),
}


def _shown(value: object) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{text} ({type(value).__name__})"


class TableReader:
    """One table of a study file being read.

    Args:
        data: the table's items.
        where: how messages name it (``"[grid]"``, :data:`TOP_LEVEL`).
        source: the file's name, first in every message.
    """

    def __init__(self, data: Mapping[str, object], where: str, source: str) -> None:
        self.data = dict(data)
        self.where = where
        self.source = source
        self.known: list[str] = []

    def error(self, key: str | None, problem: str) -> StudyFileError:
        """A :class:`StudyFileError` about ``key`` of this table (or the table itself)."""
        if self.where == TOP_LEVEL:
            at = f"[{key}]" if key else TOP_LEVEL
        else:
            at = f"{self.where} {key}" if key else self.where
        return StudyFileError(f"{self.source}: {at}: {problem}")

    def has(self, key: str) -> bool:
        """Whether the table gives ``key``."""
        return key in self.data

    def take(self, key: str, kind: str, default: object = REQUIRED, *, unit: str = "") -> Any:
        """The value of ``key``, checked to be of ``kind`` (a key of :data:`KINDS`), or
        ``default`` if absent.

        Raises:
            StudyFileError: the key is required and absent, or its value has the wrong kind.
        """
        self.known.append(key)
        check, expected = KINDS[kind]
        expected += f" [{unit}]" if unit else ""
        if key not in self.data:
            if default is REQUIRED:
                raise self.error(key, f"missing; expected {expected}")
            return default
        value = self.data[key]
        if not check(value):
            raise self.error(key, f"expected {expected}, got {_shown(value)}")
        return value

    def child(self, key: str, default_empty: bool = True) -> TableReader:
        """The sub-table ``key`` as a reader (an empty one if absent and ``default_empty``)."""
        value = self.take(key, "table", {} if default_empty else REQUIRED)
        where = f"[{key}]" if self.where == TOP_LEVEL else f"{self.where[:-1]}.{key}]"
        return TableReader(value, where, self.source)

    def rest(self) -> dict[str, object]:
        """The keys not taken so far (for tables whose keys are checked elsewhere)."""
        taken = set(self.known)
        return {k: v for k, v in self.data.items() if k not in taken}

    def finish(self, known: Sequence[str] | None = None) -> None:
        """Refuse the keys that were not taken (or, if given, that are not in ``known``).

        Raises:
            StudyFileError: naming the unknown keys and listing the known ones.
        """
        known = self.known if known is None else list(known)
        unknown = sorted(set(self.data) - set(known))
        if unknown:
            names = ", ".join(repr(k) for k in unknown)
            where = TOP_LEVEL if self.where == TOP_LEVEL else f"in {self.where}"
            raise StudyFileError(
                f"{self.source}: unknown key {names} {where}; known keys there: "
                f"{', '.join(known) or 'none'}"
            )

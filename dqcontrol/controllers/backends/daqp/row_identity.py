"""A level's last active set carried to a step whose general rows came and went
(docs/theory.md §7.5).

A backend keeps each level's last active set as indices of rows. Where a limit's rows
change between steps (a collision pair entering or leaving the influence distance), every
row after them moves, and the indices of the last set name other rows. Each general row is
therefore named by its limit (the inequality's name and its place among the inequalities of
that name) and by its key within the limit (:attr:`Inequality.keys
<dqcontrol.controllers.core.problem.Inequality>`, or its order where the limit gives none): the
last set is moved to the rows of the same names, and the rows that left are dropped.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.problem import Inequality

__all__ = ["carried_set"]

#: Keys within one limit are below this; a limit's number times it names its rows apart.
_SPAN = 1 << 40
#: The number of each limit ever seen (its name and its place among those of that name):
#: the same in every set of rows, so that a set's names can be kept with it.
_LIMITS: dict[tuple[str, int], int] = {}
#: The names of the last sets of rows asked for, by identity (a step asks for the same two
#: for each of its levels).
_RECENT: list[tuple[tuple[Inequality, ...], np.ndarray]] = []


def _names(inequalities: tuple[Inequality, ...]) -> np.ndarray:
    """Every general row's name as an integer (the same rows' names while the tuple is the
    same object)."""
    for rows, names in _RECENT:
        if rows is inequalities:
            return names
    parts = []
    seen: dict[str, int] = {}
    for g in inequalities:
        place = seen.get(g.name, 0)
        seen[g.name] = place + 1
        number = _LIMITS.setdefault((g.name, place), len(_LIMITS))
        keys = np.arange(g.lower.size) if g.keys is None else np.asarray(g.keys, dtype=np.int64)
        parts.append(number * _SPAN + keys)
    names = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
    _RECENT[:] = [(inequalities, names), *_RECENT[:3]]
    return names


def carried_set(
    active: np.ndarray,
    at_upper: np.ndarray,
    first_general: int,
    before: tuple[Inequality, ...],
    now: tuple[Inequality, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """The active set ``active`` (row indices, with ``at_upper``: held at the upper bound) of
    rows whose general rows, from index ``first_general`` on, were ``before``'s, moved to
    ``now``'s: a row before ``first_general`` keeps its index, a general row takes the index
    of the row of the same name now and is dropped where there is none. The order is
    kept."""
    names_before, names_now = _names(before), _names(now)
    general = active >= first_general
    moved = np.full(active.size, -1, dtype=np.int64)
    moved[~general] = active[~general]
    old = active[general] - first_general
    valid = old < names_before.size
    if names_now.size and valid.any():
        order = np.argsort(names_now, kind="stable")
        wanted = names_before[old[valid]]
        at = np.minimum(np.searchsorted(names_now, wanted, sorter=order), names_now.size - 1)
        found = names_now[order[at]] == wanted
        index = np.where(found, order[at] + first_general, -1)
        slots = np.flatnonzero(general)[valid]
        moved[slots] = index
    keep = moved >= 0
    return moved[keep], at_upper[keep]

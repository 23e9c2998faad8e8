"""An active set carried to rows that came and went, against a reference by names."""

import numpy as np
import pytest

from dqcontrol.controllers.backends.daqp.row_identity import carried_set
from dqcontrol.controllers.core.problem import Inequality


def _rows(name: str, count: int, keys=None) -> Inequality:
    return Inequality(
        name, np.zeros((count, 3)), np.zeros(count), np.ones(count),
        None if keys is None else np.asarray(keys, dtype=np.int64),
    )  # fmt: skip


def _names(inequalities) -> list[tuple]:
    """Each general row's name, the plain way: (limit name, place among those of that
    name, key or order)."""
    out, seen = [], {}
    for g in inequalities:
        place = seen.get(g.name, 0)
        seen[g.name] = place + 1
        keys = range(g.lower.size) if g.keys is None else g.keys.tolist()
        out += [(g.name, place, k) for k in keys]
    return out


def _reference(active, at_upper, first, before, now):
    old, new = _names(before), _names(now)
    where = {name: i for i, name in enumerate(new)}
    kept = []
    for a, u in zip(active.tolist(), at_upper.tolist(), strict=True):
        if a < first:
            kept.append((a, u))
        elif a - first < len(old) and old[a - first] in where:
            kept.append((where[old[a - first]] + first, u))
    return [k[0] for k in kept], [k[1] for k in kept]


@pytest.mark.parametrize("seed", range(20))
def test_a_set_follows_its_rows_by_name(seed):
    rng = np.random.default_rng(seed)

    def limits(keys):
        return (
            _rows("acceleration", 6),
            _rows("collision", keys.size, keys),
            _rows("trust_region", 2),
            _rows("trust_region", 3),
        )

    before_keys = np.sort(rng.choice(200, size=rng.integers(0, 12), replace=False))
    now_keys = np.sort(rng.choice(200, size=rng.integers(0, 12), replace=False))
    now_keys[: before_keys.size // 2] = before_keys[: min(before_keys.size // 2, now_keys.size)]
    before, now = limits(before_keys), limits(np.unique(now_keys))
    first = 5  # five variables' rows before the general ones
    total = first + sum(g.lower.size for g in before)
    active = rng.permutation(total)[: rng.integers(0, total + 1)]
    at_upper = rng.random(active.size) < 0.5
    got = carried_set(active, at_upper, first, before, now)
    want = _reference(active, at_upper, first, before, now)
    assert got[0].tolist() == want[0]
    assert got[1].tolist() == want[1]


def test_rows_that_keep_their_places_keep_their_indices():
    rows = (_rows("a", 4), _rows("b", 3, [7, 9, 11]))
    active = np.array([0, 3, 6, 8])  # two variables' rows, then a's four and b's three
    at_upper = np.array([True, False, True, False])
    got = carried_set(active, at_upper, 2, rows, rows)
    assert got[0].tolist() == [0, 3, 6, 8]
    assert got[1].tolist() == [True, False, True, False]


def test_a_row_that_left_is_dropped_and_the_rows_after_it_move_back():
    before = (_rows("collision", 3, [4, 5, 8]), _rows("phase_end", 1))
    now = (_rows("collision", 2, [5, 8]), _rows("phase_end", 1))
    # rows: 2 variables, then collision 4, 5, 8, then phase_end
    got = carried_set(np.array([1, 2, 3, 5]), np.ones(4, dtype=bool), 2, before, now)
    assert got[0].tolist() == [1, 2, 4]  # key 4 gone; key 5 → 2; phase_end 5 → 4

"""The compiled pass of the predicted position rows (:mod:`.predicted_position`): which
rows a state can reach and their bounds, in one loop.

Each value is the numpy expression's, operation for operation (no sums are reordered):
``reach = reach_i + extra_k``, the row is kept where ``q̄ + reach ≥ q_max`` or
``q̄ - reach ≤ q_min``, and its bounds are ``q_min - q_base`` and ``q_max - q_base``.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["reachable_rows_into"]


@compiled
def reachable_rows_into(
    q_lin: np.ndarray,
    q_base: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    reach: np.ndarray,
    extra: np.ndarray,
    keep: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> int:
    """Mark in ``keep`` ``(s, n)`` the rows (state ``i``, joint ``k``) of the states
    ``q_lin`` ``(s, n)`` within ``reach[i] + extra[k]`` of a bound, write their bounds
    ``q_min - q_base``, ``q_max - q_base`` to the start of ``lower``/``upper`` in row
    order, and return how many there are."""
    count = 0
    for i in range(q_lin.shape[0]):
        for k in range(q_lin.shape[1]):
            r = reach[i] + extra[k]
            near = q_lin[i, k] + r >= q_max[k] or q_lin[i, k] - r <= q_min[k]
            keep[i, k] = near
            if near:
                lower[count] = q_min[k] - q_base[i, k]
                upper[count] = q_max[k] - q_base[i, k]
                count += 1
    return count


@compiled
def states_and_terminal_into(
    q_lin: np.ndarray,
    q_base: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    reach: np.ndarray,
    no_extra: np.ndarray,
    terminal_extra: np.ndarray,
    terminal: bool,
    keep: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> tuple[int, int]:
    """:func:`reachable_rows_into` of the ``p`` states (reach ``reach[i] + no_extra[k]``)
    into ``keep[:p]`` and the start of ``lower``/``upper``, then, with ``terminal``, of the
    last state again (reach ``reach[-1] + terminal_extra[k]``) into ``keep[p]`` and
    ``lower``/``upper`` from ``p n`` on. Returns both counts (the second 0 without
    ``terminal``)."""
    p, n = q_lin.shape
    count = reachable_rows_into(
        q_lin, q_base, q_min, q_max, reach, no_extra, keep[:p], lower[: p * n], upper[: p * n]
    )
    if not terminal:
        return count, 0
    last = reachable_rows_into(
        q_lin[p - 1 :], q_base[p - 1 :], q_min, q_max, reach[p - 1 :], terminal_extra,
        keep[p:], lower[p * n :], upper[p * n :],
    )  # fmt: skip
    return count, last

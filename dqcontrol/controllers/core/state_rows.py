"""Dense rows formed from the rows of each predicted state
(:class:`~dqcontrol.controllers.core.problem.StateRows`, docs/theory.md §7.4)."""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["state_rows_into"]


@compiled
def state_rows_into(
    states: np.ndarray, weights: np.ndarray, phase_weights: np.ndarray, rows: np.ndarray
) -> None:
    """The dense rows ``(p, r, q, n + 1)`` of rows given by state (``states`` ``(p, r, n +
    1)``, ``weights`` and ``phase_weights`` ``(p, q)``: the first ``p`` states of ``q``
    blocks): block ``(i, j)`` holds ``weights[i, j]`` times ``states[i]``'s first ``n``
    columns and ``phase_weights[i, j]`` times its last."""
    p, r, m = states.shape
    n = m - 1
    for i in range(p):
        for a in range(r):
            for j in range(weights.shape[1]):
                w = weights[i, j]
                for c in range(n):
                    rows[i, a, j, c] = w * states[i, a, c]
                rows[i, a, j, n] = phase_weights[i, j] * states[i, a, n]

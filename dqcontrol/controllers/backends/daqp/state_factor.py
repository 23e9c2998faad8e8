"""The first level's Hessian factorised in the predicted states (docs/theory.md §7.5).

The path level's Hessian is ``P = Tᵀ G T + Λ``: ``T`` maps the decision to the predicted
states (``u_i = Σ_{j ≤ i} S_j z_j``, block ``j`` entering every state from its own on with
the one diagonal scale ``S_j``), ``G`` holds each state's Gram matrix and ``Λ`` each
block's own (the damping). Then ``P = Tᵀ M T`` with ``M = G + T⁻ᵀ Λ T⁻¹``, and since
``T⁻¹ u`` is ``S_j⁻¹ (u_j - u_{j-1})`` block by block, ``M`` is block tridiagonal: block
``(j, j)`` is ``G_j + Λ'_j + Λ'_{j+1}``, blocks ``(j + 1, j)`` and ``(j, j + 1)`` are
``-Λ'_{j+1}``, with ``Λ'_j = S_j⁻¹ Λ_j S_j⁻¹``. Its Cholesky factor ``M = L_M L_Mᵀ`` is
block bidiagonal (``p`` blocks of ``m × m``), and ``F = Tᵀ L_M`` has ``F Fᵀ = P``: the
active-set kernels need only solves with ``F`` and ``Fᵀ``
(:mod:`~dqcontrol.controllers.backends.daqp.active_set`), each a pass over the blocks instead
of a dense triangular solve.

The factor's blocks are the tuple ``(diagonal, below, inverse_scales)``: ``diagonal[j]``
the lower triangular ``L_M`` block ``(j, j)``, ``below[j]`` its block ``(j, j - 1)``
(``below[0]`` zero), ``inverse_scales[j]`` the diagonal of ``S_j⁻¹``;
:func:`state_factor` gives them in the factor tuple of the active-set kernels, after an
empty dense factor.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.core.objective import held_from_own_block
from dqcontrol.controllers.linalg.cholesky import cholesky_above

__all__ = [
    "state_backward",
    "state_factor",
    "state_forward",
    "state_forward_rows",
]


@compiled
def _inverse_scales(weights: np.ndarray, phase_weights: np.ndarray, m: int) -> np.ndarray:
    """``S_j⁻¹`` of every block: ``1 / weights[j, j]`` for the commands, ``1 /
    phase_weights[j, j]`` for the scaling ``(p, m)``."""
    p = weights.shape[0]
    inverse = np.empty((p, m))
    for j in range(p):
        inverse[j, : m - 1] = 1.0 / weights[j, j]
        inverse[j, m - 1] = 1.0 / phase_weights[j, j]
    return inverse


@compiled
def state_factor(
    grams: np.ndarray,
    weights: np.ndarray,
    phase_weights: np.ndarray,
    damping: np.ndarray,
    share: float,
) -> tuple[bool, tuple]:
    """``(ok, factor)`` for ``P = Tᵀ blockdiag(grams) T + blockdiag(damping)`` (``grams``,
    ``damping`` ``(p, m, m)``; ``T`` from ``weights`` for the commands and
    ``phase_weights`` for the scaling, ``(p, p)``). Not ``ok`` where a block does not enter
    the later states alike (``T⁻¹`` is then not bidiagonal) or a squared pivot of ``L_M``
    is not above ``share`` times the largest diagonal entry of ``M``."""
    p, m, _ = grams.shape
    diagonal = np.zeros((p, m, m))
    below = np.zeros((p, m, m))
    none = np.zeros((0, 0))
    if not (held_from_own_block(weights) and held_from_own_block(phase_weights)):
        return False, (none, diagonal, below, np.ones((p, m)))
    inverse = _inverse_scales(weights, phase_weights, m)
    scaled = np.empty((p, m, m))  # Λ'_j = S_j⁻¹ Λ_j S_j⁻¹
    largest = 0.0
    for j in range(p):
        for x in range(m):
            for y in range(m):
                scaled[j, x, y] = inverse[j, x] * damping[j, x, y] * inverse[j, y]
    for j in range(p):
        for x in range(m):
            entry = grams[j, x, x] + scaled[j, x, x]
            largest = max(largest, entry + scaled[j + 1, x, x] if j + 1 < p else entry)
    work = np.empty((m, m))
    for j in range(p):
        for x in range(m):  # M_jj minus (block below) (block below)ᵀ, lower triangle
            for y in range(x + 1):
                s = grams[j, x, y] + scaled[j, x, y]
                if j + 1 < p:
                    s += scaled[j + 1, x, y]
                for t in range(m):
                    s -= below[j, x, t] * below[j, y, t]
                work[x, y] = s
        if not cholesky_above(work, diagonal[j], share * largest, 0.0):
            return False, (none, diagonal, below, inverse)
        if j + 1 < p:  # below[j + 1] = -Λ'_{j+1} L_jj⁻ᵀ, row by row
            for r in range(m):
                for c in range(m):
                    s = -scaled[j + 1, r, c]
                    for t in range(c):
                        s -= below[j + 1, r, t] * diagonal[j, c, t]
                    below[j + 1, r, c] = s / diagonal[j, c, c]
    return True, (none, diagonal, below, inverse)


@compiled
def state_forward(factor: tuple, b: np.ndarray, out: np.ndarray) -> None:
    """``out = F⁻¹ b = L_M⁻¹ T⁻ᵀ b``."""
    diagonal, below, inverse = factor
    p, m, _ = diagonal.shape
    for j in range(p):
        for x in range(m):
            k = j * m + x
            s = inverse[j, x] * b[k]
            if j + 1 < p:
                s -= inverse[j + 1, x] * b[k + m]
            if j > 0:  # minus (block below) (the last block's values)
                for t in range(m):
                    s -= below[j, x, t] * out[(j - 1) * m + t]
            for t in range(x):
                s -= diagonal[j, x, t] * out[j * m + t]
            out[k] = s / diagonal[j, x, x]


@compiled
def state_backward(factor: tuple, b: np.ndarray, out: np.ndarray) -> None:
    """``out = F⁻ᵀ b = T⁻¹ L_M⁻ᵀ b``."""
    diagonal, below, inverse = factor
    p, m, _ = diagonal.shape
    x_blocks = np.empty(p * m)
    for j in range(p - 1, -1, -1):
        for x in range(m - 1, -1, -1):
            k = j * m + x
            s = b[k]
            if j + 1 < p:  # minus (block below the next)ᵀ (the next block's values)
                for t in range(m):
                    s -= below[j + 1, t, x] * x_blocks[(j + 1) * m + t]
            for t in range(x + 1, m):
                s -= diagonal[j, t, x] * x_blocks[j * m + t]
            x_blocks[k] = s / diagonal[j, x, x]
    for j in range(p):
        for x in range(m):
            k = j * m + x
            previous = x_blocks[k - m] if j > 0 else 0.0
            out[k] = inverse[j, x] * (x_blocks[k] - previous)


@compiled
def state_forward_rows(factor: tuple, held: np.ndarray, yt: np.ndarray) -> None:
    """``yt[:, j] = F⁻¹ held[j]`` for every row of ``held`` ``(k, n)``, side by side."""
    diagonal, below, inverse = factor
    p, m, _ = diagonal.shape
    k = held.shape[0]
    s = np.empty(k)
    for j in range(p):
        for x in range(m):
            row = j * m + x
            for r in range(k):
                s[r] = inverse[j, x] * held[r, row]
            if j + 1 < p:
                scale = inverse[j + 1, x]
                for r in range(k):
                    s[r] -= scale * held[r, row + m]
            if j > 0:
                for t in range(m):
                    coefficient = below[j, x, t]
                    line = yt[(j - 1) * m + t]
                    for r in range(k):
                        s[r] -= coefficient * line[r]
            for t in range(x):
                coefficient = diagonal[j, x, t]
                line = yt[j * m + t]
                for r in range(k):
                    s[r] -= coefficient * line[r]
            pivot = diagonal[j, x, x]
            out = yt[row]
            for r in range(k):
                out[r] = s[r] / pivot

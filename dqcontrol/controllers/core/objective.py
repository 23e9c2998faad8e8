"""The first level's dense objective with each changing dense residual in one compiled call
(docs/theory.md §7.4).

:func:`~dqcontrol.controllers.core.problem.objective` adds a residual with changing dense rows
(a path level's error rows, row-weighted) through several numpy operations: the weighted
rows, their product, its scaled sum into the Hessian, the linear term. Here one compiled
call does the same sums in the same order (:func:`level_objective`); block-diagonal
residuals go through the same kernels as there. Rows given through the predicted states
they read (:class:`~dqcontrol.controllers.core.problem.StateRows`) are summed from each state's
small Gram matrix instead: the same products up to rounding, for a fraction of the work. A
level whose live rows are all read-only (``P`` is then kept), or that has other forms, is
left to :func:`~dqcontrol.controllers.core.problem.objective`. A level whose dense part is such
rows, and whose other terms are block-diagonal, is also given without forming ``P``
(:func:`state_objective`): ``c`` and the parts a backend factorises in the predicted states
(docs/theory.md §7.5).
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.core.problem import DecisionLayout, Residual, StateHessian, objective
from dqcontrol.controllers.linalg.gram import (
    add_diagonal_blocks,
    block_gram,
    frozen,
    kept,
    subtract_block_lin,
)

__all__ = ["dense_hessian", "held_from_own_block", "level_objective", "state_objective"]

_NO_WEIGHTS = frozen(np.zeros(0))  # read-only as row weights are: one compiled form


@compiled
def _add_changing_rows(
    p_mat: np.ndarray,
    c: np.ndarray,
    a: np.ndarray,
    row_weights: np.ndarray,
    b: np.ndarray,
    w2: float,
) -> None:
    """``p_mat += w2 (W A)ᵀ A`` and ``c -= w2 (W A)ᵀ b`` in place (``row_weights`` empty:
    ``W = I``), each product rounded before its sum as numpy's ``+= w2 * …``."""
    weighted = np.empty_like(a)
    for i in range(a.shape[0]):
        scale = row_weights[i] if row_weights.size else 1.0
        for j in range(a.shape[1]):
            weighted[i, j] = a[i, j] * scale
    gram = weighted.T @ a
    for i in range(gram.shape[0]):
        for j in range(gram.shape[1]):
            p_mat[i, j] += w2 * gram[i, j]
    lin = weighted.T @ b
    for i in range(c.size):
        c[i] -= w2 * lin[i]


@compiled
def held_from_own_block(weights: np.ndarray) -> bool:
    """Whether every column ``j`` of ``weights`` ``(p, p)`` is zero above the diagonal and
    the same, and not zero, from the diagonal down."""
    p = weights.shape[0]
    for j in range(p):
        if weights[j, j] == 0.0:
            return False
        for i in range(p):
            if weights[i, j] != (weights[j, j] if i >= j else 0.0):
                return False
    return True


@compiled
def _state_grams(
    rows: np.ndarray, row_weights: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``Σ_a ρ_a rowsᵢ[a]ᵀ rowsᵢ[a]`` ``(p, m, m)`` and ``Σ_a ρ_a rowsᵢ[a] b_a`` ``(p, m)`` of
    each state's rows ``(p, r, m)`` (``ρ``: ``row_weights``, empty for ones)."""
    p, r, m = rows.shape
    grams, lin = np.zeros((p, m, m)), np.zeros((p, m))
    for i in range(p):
        for a in range(r):
            row = i * r + a
            rho = row_weights[row] if row_weights.size else 1.0
            for x in range(m):
                v = rows[i, a, x] * rho
                lin[i, x] += v * b[row]
                for y in range(m):
                    grams[i, x, y] += v * rows[i, a, y]
    return grams, lin


@compiled
def _column_scales(weights: np.ndarray, phase_weights: np.ndarray, i: int, m: int) -> np.ndarray:
    """How each block's variables enter state ``i``: ``(p, m)``, the commands' weight
    ``n`` times, then the phase's."""
    p = weights.shape[0]
    scale = np.empty((p, m))
    for j in range(p):
        scale[j, : m - 1] = weights[i, j]
        scale[j, m - 1] = phase_weights[i, j]
    return scale


@compiled
def _add_suffix_blocks(p_mat, c, grams, lin, weights, phase_weights, w2) -> None:
    """Block ``(j, k)``, ``j ≤ k``, is ``D_j S_k D_k`` with ``S_k`` the sum of the Gram
    matrices of the states from ``k`` on, where every block enters the states from its own
    on with one weight ``D_j`` (:func:`held_from_own_block`)."""
    p, m = lin.shape
    for i in range(p - 2, -1, -1):
        for x in range(m):
            lin[i, x] += lin[i + 1, x]
            for y in range(m):
                grams[i, x, y] += grams[i + 1, x, y]
    scale = _column_scales(weights, phase_weights, p - 1, m)
    for j in range(p):
        for k in range(j, p):
            _add_scaled(p_mat, grams[k], scale[j], scale[k], j * m, k * m, w2)
        for x in range(m):
            c[j * m + x] -= w2 * scale[j, x] * lin[j, x]


@compiled
def _add_each_state(p_mat, c, grams, lin, weights, phase_weights, w2) -> None:
    """Block ``(j, k)`` summed state by state, for any weights."""
    p, m = lin.shape
    for i in range(p):
        scale = _column_scales(weights, phase_weights, i, m)
        for j in range(p):
            if not (weights[i, j] != 0.0 or phase_weights[i, j] != 0.0):
                continue
            for k in range(j, p):
                if weights[i, k] != 0.0 or phase_weights[i, k] != 0.0:
                    _add_scaled(p_mat, grams[i], scale[j], scale[k], j * m, k * m, w2)
            for x in range(m):
                c[j * m + x] -= w2 * scale[j, x] * lin[i, x]


@compiled
def _add_scaled(p_mat, gram, left, right, row: int, col: int, w2: float) -> None:
    """``p_mat[row:, col:] += w2 diag(left) gram diag(right)``, and the same numbers at
    ``[col:, row:]`` transposed (once on the diagonal)."""
    m = gram.shape[0]
    for x in range(m):
        sx = w2 * left[x]
        for y in range(m):
            value = sx * right[y] * gram[x, y]
            p_mat[row + x, col + y] += value
            if row != col:
                p_mat[col + y, row + x] += value


@compiled
def _add_state_rows(
    p_mat: np.ndarray,
    c: np.ndarray,
    grams: np.ndarray,
    lin: np.ndarray,
    weights: np.ndarray,
    phase_weights: np.ndarray,
    w2: float,
) -> None:
    """``p_mat += w2 (W A)ᵀ A`` and ``c -= w2 (W A)ᵀ b`` in place for ``A`` given by its
    :class:`~dqcontrol.controllers.core.problem.StateRows`, from each state's ``grams`` and
    ``lin`` (:func:`_state_grams`, overwritten): block ``(j, k)`` of ``AᵀA`` is the sum over
    the states of each one's small Gram matrix, scaled by how blocks ``j`` and ``k`` enter
    it."""
    if held_from_own_block(weights) and held_from_own_block(phase_weights):
        _add_suffix_blocks(p_mat, c, grams, lin, weights, phase_weights, w2)
    else:
        _add_each_state(p_mat, c, grams, lin, weights, phase_weights, w2)


@compiled
def _subtract_state_lin(
    c: np.ndarray, lin: np.ndarray, weights: np.ndarray, phase_weights: np.ndarray, w2: float
) -> None:
    """``c -= w2 (W A)ᵀ b`` in place from each state's ``lin`` (:func:`_state_grams`)."""
    p, m = lin.shape
    for j in range(p):
        for i in range(p):
            if weights[i, j] != 0.0 or phase_weights[i, j] != 0.0:
                scale = w2 * weights[i, j]
                for x in range(m - 1):
                    c[j * m + x] -= scale * lin[i, x]
                c[j * m + m - 1] -= w2 * phase_weights[i, j] * lin[i, m - 1]


def _changing_dense(r: Residual, nv: int) -> bool:
    """Whether ``r`` has dense rows that change (writable), or gives them by state."""
    return (r.A is not None and r.A.flags.writeable) or _full_states(r, nv)


def level_objective(layout: DecisionLayout, residuals: tuple[Residual, ...]) -> tuple:
    """``(P, c)`` of :func:`~dqcontrol.controllers.core.problem.objective`: the same sums in the
    same order, each changing dense residual in one compiled call."""
    live = tuple(r for r in residuals if 2.0 * r.weight != 0.0)
    nv = layout.num_vars
    if not any(_changing_dense(r, nv) for r in live) or not all(
        r.blocks is not None or _changing_dense(r, nv) for r in live
    ):
        return objective(layout, residuals)
    p_mat = np.zeros((nv, nv))
    c = np.zeros(nv)
    for r in live:
        w2 = 2.0 * r.weight
        if r.blocks is not None and r.row_weights is None:
            add_diagonal_blocks(p_mat, block_gram(r.blocks), w2)
            subtract_block_lin(c, r.blocks, r.b, w2)
        elif r.states is not None and _full_states(r, nv):
            st = r.states
            grams, lin = _state_grams(st.rows, _row_weights(r), r.b)
            _add_state_rows(p_mat, c, grams, lin, st.weights, st.phase_weights, w2)
        else:
            rows = np.ascontiguousarray(r.dense(layout))
            _add_changing_rows(p_mat, c, rows, _row_weights(r), r.b, w2)
    return p_mat, c


def state_objective(
    layout: DecisionLayout, residuals: tuple[Residual, ...]
) -> tuple[np.ndarray, StateHessian] | None:
    """``(c, states)``: the linear term of :func:`level_objective` and its ``P`` as a
    :class:`~dqcontrol.controllers.core.problem.StateHessian`, without forming ``P``
    (:func:`dense_hessian` forms it), for a level with one residual with state rows whose
    blocks each enter the states from their own on alike (:func:`held_from_own_block`)
    and every other one block-diagonal over every variable; ``None`` for any other
    level."""
    nv = layout.num_vars
    found, blocks = None, []
    for r in residuals:
        if 2.0 * r.weight == 0.0:
            continue
        if r.states is not None and found is None and _full_states(r, nv):
            found = r
        elif r.blocks is not None and _full_blocks(r, nv):
            blocks.append((r.blocks, r.b, 2.0 * r.weight))
        else:
            return None
    if found is None or found.states is None:
        return None
    st = found.states
    if not (held_from_own_block(st.weights) and held_from_own_block(st.phase_weights)):
        return None
    c = np.zeros(nv)
    grams = _state_parts(
        st.rows, _row_weights(found), found.b, st.weights, st.phase_weights,
        2.0 * found.weight, c,
    )  # fmt: skip
    for rows, b, w2 in blocks:
        if b.flags.writeable or kept((b,), _any_nonzero):  # else ``c -= 0``: c as it is
            subtract_block_lin(c, rows, b, w2)
    operands = tuple(rows for rows, _, _ in blocks)
    damping = kept(operands, _scaled_grams, (tuple(w2 for *_, w2 in blocks), grams.shape))
    return c, StateHessian(grams, st.weights, st.phase_weights, damping)


def _any_nonzero(values: np.ndarray) -> np.ndarray:
    """Whether some entry of ``values`` is not zero, as a 0-d array (for :func:`kept`)."""
    return np.array(values.any())


def _scaled_grams(*args) -> np.ndarray:
    """``Σ_k w2_k A_kᵀ A_k`` block by block from the blocks ``A_k`` followed by ``(w2s,
    shape)`` (zeros of ``shape`` for none)."""
    *operands, w2s, shape = args
    own = [w2 * block_gram(blocks) for blocks, w2 in zip(operands, w2s, strict=True)]
    return own[0] if len(own) == 1 else sum(own, np.zeros(shape))


@compiled
def _state_parts(
    rows: np.ndarray,
    row_weights: np.ndarray,
    b: np.ndarray,
    weights: np.ndarray,
    phase_weights: np.ndarray,
    w2: float,
    c: np.ndarray,
) -> np.ndarray:
    """Each state's Gram matrix times ``w2`` ``(p, m, m)``, with ``c -= w2 (W A)ᵀ b`` in
    place (:func:`_state_grams`, :func:`_subtract_state_lin`)."""
    grams, lin = _state_grams(rows, row_weights, b)
    _subtract_state_lin(c, lin, weights, phase_weights, w2)
    for i in range(grams.shape[0]):
        for x in range(grams.shape[1]):
            for y in range(grams.shape[2]):
                grams[i, x, y] *= w2
    return grams


def _row_weights(r: Residual) -> np.ndarray:
    return _NO_WEIGHTS if r.row_weights is None else r.row_weights


def _full_states(r: Residual, nv: int) -> bool:
    """Whether ``r`` gives its rows through states that cover every variable."""
    return r.states is not None and r.states.rows.shape[0] * r.states.rows.shape[2] == nv


def _full_blocks(r: Residual, nv: int) -> bool:
    """Whether ``r`` gives its rows as blocks that cover every variable, unweighted."""
    return (
        r.blocks is not None
        and r.blocks.shape[0] * r.blocks.shape[2] == nv
        and r.row_weights is None
    )


def dense_hessian(states: StateHessian) -> np.ndarray:
    """``P`` of a :class:`~dqcontrol.controllers.core.problem.StateHessian`, dense."""
    p, m, _ = states.grams.shape
    p_mat = np.zeros((p * m, p * m))
    grams, lin = states.grams.copy(), np.zeros((p, m))
    _add_state_rows(p_mat, np.zeros(p * m), grams, lin, states.weights, states.phase_weights, 1.0)
    add_diagonal_blocks(p_mat, states.damping, 1.0)
    return p_mat

"""The tracking cost's Hessian blocks in compiled calls (docs/theory.md §4.2, §7.3).

For one block ``i`` the tracking term of docs/theory.md §4.2 is ``λ1 ‖J_i qd_i - s_i w_i‖²``
in ``z_i = [qd_i, s_i]``, i.e. ``λ1 ‖G_i z_i‖²`` with ``G_i = [J_i, -w_i]`` and
``-w_i = K (x_i - x_d,i) - dx_d/dσ,i``; its Hessian block is ``2 λ1 G_iᵀ G_i``.
:func:`add_task_grams` adds it to a block-diagonal Hessian in one compiled call per step
instead of a dozen numpy calls on 8×8 arrays; :func:`task_matrices` gives the ``G_i``
themselves (the term's residual rows), with the same floating-point operations;
:func:`align_signs` flips poses (and Jacobians) to ``x · x_d ≥ 0`` (docs/theory.md §1);
:func:`scatter_symmetric` writes stored upper-triangle values into a dense matrix.
Numba compiles them without fast-math: the IEEE operations in the order written.
"""

from __future__ import annotations

import numpy as np

from dqcontrol._compiled import compiled

__all__ = [
    "add_task_grams",
    "align_signs",
    "measured_state",
    "gram",
    "scatter_blocks",
    "scatter_symmetric",
    "task_matrices",
]


@compiled
def gram(g: np.ndarray) -> np.ndarray:
    """``Gᵀ G`` (m, m) of ``G`` (r, m), new, symmetric: each entry the plain sum over the
    rows in order."""
    m = g.shape[1]
    h = np.empty((m, m))
    for i in range(m):
        for j in range(i, m):
            acc = 0.0
            for k in range(g.shape[0]):
                acc += g[k, i] * g[k, j]
            h[i, j] = acc
            h[j, i] = acc
    return h


@compiled
def align_signs(xs: np.ndarray, jacs: np.ndarray, xd: np.ndarray) -> None:
    """Negate ``xs[i]`` and ``jacs[i]`` in place where ``xs[i] · xd[i] < 0``: the error is
    then formed between the nearer of ``±x`` and ``x_d``."""
    for i in range(xs.shape[0]):
        align = 0.0
        for k in range(8):
            align += xs[i, k] * xd[i, k]
        if align < 0.0:
            for k in range(8):
                xs[i, k] = -xs[i, k]
                for j in range(jacs.shape[2]):
                    jacs[i, k, j] = -jacs[i, k, j]


@compiled
def measured_state(
    x: np.ndarray, jac: np.ndarray, pair: np.ndarray, q: np.ndarray, sigma: float, out: np.ndarray
) -> None:
    """One block at the measured state: ``x`` and ``jac`` negated in place where
    ``x · x_d < 0`` (as :func:`align_signs`), then copied into ``out`` with the target pair
    ``[x_d; dx_d/dσ]``, ``q`` and ``σ``: ``out = [x (8), jac (8 n, row-major), x_d (8),
    dx_d/dσ (8), q (n), σ]`` (the buffer behind a one-block context's arrays)."""
    n = jac.shape[1]
    align = 0.0
    for k in range(8):
        align += x[k] * pair[0, k]
    if align < 0.0:
        for k in range(8):
            x[k] = -x[k]
            for j in range(n):
                jac[k, j] = -jac[k, j]
    o = 8 + 8 * n
    for k in range(8):
        out[k] = x[k]
        out[o + k] = pair[0, k]
        out[o + 8 + k] = pair[1, k]
        for j in range(n):
            out[8 + k * n + j] = jac[k, j]
    o += 16
    for j in range(n):
        out[o + j] = q[j]
    out[o + n] = sigma


@compiled
def _task_matrix(
    x: np.ndarray, jac: np.ndarray, xd: np.ndarray, dxd: np.ndarray, gain: float, g: np.ndarray
) -> None:
    """``g = G = [J, K (x - x_d) - dx_d/dσ]`` (8, n+1) of one block."""
    n = jac.shape[1]
    for k in range(8):
        for j in range(n):
            g[k, j] = jac[k, j]
        g[k, n] = gain * (x[k] - xd[k]) - dxd[k]


@compiled
def task_matrices(
    xs: np.ndarray, jacs: np.ndarray, xd: np.ndarray, dxd: np.ndarray, gain_per_s: float
) -> np.ndarray:
    """``G_i = [J_i, K (x_i - x_d,i) - dx_d,i]`` for every block, ``(p, 8, n+1)``, new."""
    p, n = jacs.shape[0], jacs.shape[2]
    out = np.empty((p, 8, n + 1))
    for i in range(p):
        _task_matrix(xs[i], jacs[i], xd[i], dxd[i], gain_per_s, out[i])
    return out


@compiled
def add_task_grams(
    xs: np.ndarray,
    jacs: np.ndarray,
    xd: np.ndarray,
    dxd: np.ndarray,
    gain_per_s: float,
    two_weight: float,
    hessian: np.ndarray,
) -> None:
    """``hessian[i] += 2 λ1 G_iᵀ G_i`` in place for every block.

    ``xs`` (p, 8), ``jacs`` (p, 8, n): poses and Jacobians (sign-aligned to the targets);
    ``xd``, ``dxd`` (p, 8): targets and their σ-derivatives; ``two_weight`` is ``2 λ1``;
    ``hessian`` ``(p, n+1, n+1)``. Each entry is ``h + (Gᵀ G)_ab · 2 λ1`` with ``(Gᵀ G)_ab``
    the plain sum over the 8 rows in order, and the block stays exactly symmetric.
    """
    p, n = jacs.shape[0], jacs.shape[2]
    m = n + 1
    g = np.empty((8, m))
    for i in range(p):
        _task_matrix(xs[i], jacs[i], xd[i], dxd[i], gain_per_s, g)
        for a in range(m):
            for b in range(a, m):
                acc = 0.0
                for k in range(8):
                    acc += g[k, a] * g[k, b]
                v = acc * two_weight
                hessian[i, a, b] = hessian[i, a, b] + v
                if b != a:
                    hessian[i, b, a] = hessian[i, b, a] + v


@compiled
def scatter_symmetric(
    h: np.ndarray, rows: np.ndarray, cols: np.ndarray, values: np.ndarray
) -> None:
    """``h[rows, cols] = h[cols, rows] = values`` (the upper triangle's entries, mirrored)."""
    for e in range(values.shape[0]):
        h[rows[e], cols[e]] = values[e]
        h[cols[e], rows[e]] = values[e]


@compiled
def scatter_blocks(h: np.ndarray, blocks: np.ndarray) -> None:
    """Write the ``(p, m, m)`` blocks on the diagonal of the dense ``h`` ``(p m, p m)``."""
    m = blocks.shape[1]
    for i in range(blocks.shape[0]):
        o = i * m
        for a in range(m):
            for b in range(m):
                h[o + a, o + b] = blocks[i, a, b]

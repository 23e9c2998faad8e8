"""The path level solved in the predicted states: what it would cost against the solve of
``dqcontrol bench``'s step today (docs/performance.md).

The path level of the path-following controller (LBR4p, 2 s circle, ``T = 1 ms``,
``p = 10``, after 300 steps) is taken with its last active set, and solved twice on that
set, each time with the check of the KKT conditions the backend runs:

- **today**: LAPACK's Cholesky factor of the 80 × 80 Hessian ``P``, the check with dense
  triangular solves (``backends/active_set.py``), and the null space of the 60 held path
  rows by the compiled profile QR (``null_space.py``);
- **in the states** ``x = S z`` (``S⁻¹`` a difference without a servo model): the rows
  ``A S⁻¹`` and ``M = S⁻ᵀ P S⁻¹`` by differences, a banded Cholesky factor of ``M`` (block
  tridiagonal: lower bandwidth ``2(n + 1) - 1``), the same check with solves that follow
  the band, and the null space of the path rows a state at a time (each state's rows read
  that state only: ``R S⁻¹`` is block diagonal, its null space a block per state, already
  orthonormal).

Both give the same point (printed: the largest difference of ``z``) and null spaces of the
same rows (printed: ``|R Z|`` with ``Z = S⁻¹ Z_x``). The times are medians of 2000 calls,
three interleaved rounds. Forming ``P`` is left out of both: in the states its blocks would
come from the path rows a state at a time instead.

    python benchmarks/bench_stagewise_level.py
"""

from __future__ import annotations

import numpy as np
from bench_stagewise_factor import bench_step_controller, median_us
from numba import njit

from dqcontrol.controllers.backends.active_set import (
    SOLVED,
    _worst_multiplier,
    solve_on_active_set,
)
from dqcontrol.controllers.backends.daqp_dense import (
    ACTIVE_SET_CHANGES,
    ACTIVE_SET_DUAL_SHARE,
    _factor,
)
from dqcontrol.controllers.entries import nonzero_entries
from dqcontrol.controllers.householder import applied_q, profile_qr
from dqcontrol.controllers.level_objective import level_objective
from dqcontrol.controllers.null_space import compiled_null_space

PRIMAL_TOL = 1e-9


def path_level() -> dict:
    """The path level of the bench's step after 300 steps, its last active set and the
    prediction's interval lengths."""
    ctrl = bench_step_controller()
    problem = ctrl.last_problem()
    p_mat, c = level_objective(problem.layout, problem.levels[0].residuals)
    held = problem.levels[0].residuals[0].dense(problem.layout)
    entry = ctrl.backend._active[0]
    durations = problem.layout.durations_s
    weights = ctrl.prediction_model.weights
    assert np.allclose(weights, np.tril(np.broadcast_to(durations, weights.shape)), 0, 0)
    return {
        "P": p_mat, "c": c, "A": np.array(problem.A), "lower": problem.lower,
        "upper": problem.upper, "held": np.ascontiguousarray(held), "active": entry[1],
        "at_upper": entry[2], "durations": durations, "m": problem.layout.block_size,
    }  # fmt: skip


@njit(cache=True)
def columns_in_states(mat: np.ndarray, durations: np.ndarray, m: int) -> np.ndarray:
    """``mat S⁻¹``: block ``j`` of a row becomes ``a_j / Δ_j - a_{j+1} / Δ_{j+1}``."""
    rows, nv = mat.shape
    p = nv // m
    inverse = 1.0 / durations
    out = np.empty((rows, nv))
    for i in range(rows):
        line, source = out[i], mat[i]
        for j in range(p - 1):
            a, b = inverse[j], inverse[j + 1]
            for c in range(m):
                line[j * m + c] = source[j * m + c] * a - source[(j + 1) * m + c] * b
        a = inverse[p - 1]
        for c in range(m):
            line[(p - 1) * m + c] = source[(p - 1) * m + c] * a
    return out


@njit(cache=True)
def banded_cholesky(a: np.ndarray, band: int, out: np.ndarray) -> bool:
    """Lower Cholesky factor of the symmetric ``a`` whose entries below the diagonal are
    zero beyond ``band``; the factor keeps that band."""
    n = a.shape[0]
    out[:] = 0.0
    for j in range(n):
        s = a[j, j]
        for k in range(max(0, j - band), j):
            s -= out[j, k] * out[j, k]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        out[j, j] = d
        for i in range(j + 1, min(n, j + band + 1)):
            t = a[i, j]
            for k in range(max(0, i - band), j):
                t -= out[i, k] * out[j, k]
            out[i, j] = t / d
    return True


@njit(cache=True)
def _forward_band(factor, band, b, out, first):
    n = b.shape[0]
    out[:first] = 0.0
    for i in range(first, n):
        s = b[i]
        for k in range(max(first, i - band), i):
            s -= factor[i, k] * out[k]
        out[i] = s / factor[i, i]


@njit(cache=True)
def _backward_band(factor, band, b, out):
    n = b.shape[0]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, min(n, i + band + 1)):
            s -= factor[k, i] * out[k]
        out[i] = s / factor[i, i]


@njit(cache=True)
def _worst_general_row(a, lower, upper, x, primal_tol) -> int:
    """``_worst_row`` of ``backends/active_set.py`` with every row general (in the states
    no row is a unit row)."""
    worst, row = primal_tol, -1
    for r in range(a.shape[0]):
        value = a[r] @ x
        if lower[r] - worst <= value <= upper[r] + worst:
            continue
        norm = max(np.sqrt(a[r] @ a[r]), 1.0)
        if value - upper[r] > worst * norm:
            worst, row = (value - upper[r]) / norm, r
        elif lower[r] - value > worst * norm:
            worst, row = (lower[r] - value) / norm, r
    return row


@njit(cache=True)
def check_banded(factor, band, c, a, lower, upper, active, at_upper, z, lam) -> int:
    """The equality optimum of the set ``active`` with the banded factor and the KKT
    check of ``solve_on_active_set`` (one pass: the set is right)."""
    n, k = c.shape[0], active.shape[0]
    g = np.empty(n)
    _forward_band(factor, band, c, g, 0)
    y = np.empty((k, n))
    for j in range(k):
        row = a[active[j]]
        first = 0
        while first < n and row[first] == 0.0:
            first += 1
        _forward_band(factor, band, row, y[j], first)
    schur = y @ y.T
    rhs = np.empty(k)
    for i in range(k):
        bound = upper[active[i]] if at_upper[i] else lower[active[i]]
        rhs[i] = -(bound + y[i] @ g)
    if k:
        lam[:] = np.linalg.solve(schur, rhs)
    v = g + y.T @ lam
    _backward_band(factor, band, v, z)
    z[:] = -z
    if _worst_general_row(a, lower, upper, z, PRIMAL_TOL) >= 0:
        return 2
    if _worst_multiplier(lower, upper, active, at_upper, lam, ACTIVE_SET_DUAL_SHARE) >= 0:
        return 3
    return 0


@njit(cache=True)
def null_space_per_state(rows: np.ndarray, per_state: int, m: int) -> np.ndarray:
    """The null space of rows that each read one state (``per_state`` rows a state, in
    order), a block per state."""
    p = rows.shape[0] // per_state
    dim = m - per_state
    basis = np.zeros((p * m, p * dim))
    reach = np.full(per_state, m - 1)
    for k in range(p):
        cols = np.empty((m, per_state))
        for t in range(per_state):
            for c in range(m):
                cols[c, t] = rows[k * per_state + t, k * m + c]
        tau, _pivots = profile_qr(cols, reach)
        basis[k * m : (k + 1) * m, k * dim : (k + 1) * dim] = applied_q(cols, reach, tau, per_state)
    return basis


def _solvers(lev: dict) -> tuple:
    """``(today, in_states)``: the path level on its last set, each returning the status
    of the check, the point (``z``; ``x`` in the states) and the path rows' null space."""
    m, dur, n = lev["m"], lev["durations"], lev["c"].size
    active, at_upper, lower, upper = lev["active"], lev["at_upper"], lev["lower"], lev["upper"]
    general = np.ascontiguousarray(lev["A"][n:])  # the rows after the identity: C
    entries = nonzero_entries(general)

    def today():
        factor = _factor(lev["P"])
        z, duals = np.empty(n), np.empty(lev["A"].shape[0])
        status = solve_on_active_set(
            factor, lev["c"], general, entries, True, lower, upper, active, at_upper, PRIMAL_TOL,
            ACTIVE_SET_DUAL_SHARE, ACTIVE_SET_CHANGES, z, duals,
        )[0]  # fmt: skip
        return status, z, compiled_null_space(lev["held"])[1]

    def in_states():
        rows_x = columns_in_states(lev["A"], dur, m)
        half = columns_in_states(lev["P"], dur, m)
        m_mat = columns_in_states(np.ascontiguousarray(half.T), dur, m)
        c_x = columns_in_states(lev["c"][None, :], dur, m)[0]
        factor = np.empty_like(m_mat)
        assert banded_cholesky(m_mat, 2 * m - 1, factor)
        x, lam = np.empty(n), np.empty(active.size)
        status = check_banded(
            factor, 2 * m - 1, c_x, rows_x, lower, upper, active, at_upper, x, lam
        )
        held_x = columns_in_states(lev["held"], dur, m)
        return status, x, null_space_per_state(held_x, 6, m)

    return today, in_states


def _decisions(states: np.ndarray, dur: np.ndarray, m: int) -> np.ndarray:
    """``S⁻¹`` of each column of ``states`` (blocks ``x_k`` → ``(x_k - x_{k-1}) / Δ_k``)."""
    blocks = states.reshape(dur.size, m, -1)
    previous = np.concatenate([np.zeros((1, m, blocks.shape[2])), blocks[:-1]])
    return ((blocks - previous) / dur[:, None, None]).reshape(states.shape)


def _agreement(lev: dict, today, in_states) -> None:
    """Print how far the two solves agree."""
    m, dur = lev["m"], lev["durations"]
    status, z, basis = today()
    status_x, x, basis_x = in_states()
    assert status == SOLVED and status_x == SOLVED, (status, status_x)
    z_x = _decisions(x[:, None], dur, m)[:, 0]
    held_x = columns_in_states(lev["held"], dur, m).reshape(-1, 6, dur.size, m)
    off = max(float(np.abs(np.delete(held_x[k], k, axis=1)).max()) for k in range(dur.size))
    residual_x = np.abs(lev["held"] @ _decisions(basis_x, dur, m)).max()
    residual = np.abs(lev["held"] @ basis).max()
    print(f"the same point: |z - z_states| = {np.abs(z - z_x).max():.1e} "
          f"(|z| = {np.abs(z).max():.2f}); path rows off their state in R S^-1: {off:.1e}; "
          f"|R Z| = {residual_x:.1e} (today's {residual:.1e}), "
          f"dimensions {basis.shape[1]} and {basis_x.shape[1]}")  # fmt: skip


def _parts(lev: dict) -> dict:
    """Each part of both solves, as a call to time."""
    m, dur, n = lev["m"], lev["durations"], lev["c"].size
    active, at_upper, lower, upper = lev["active"], lev["at_upper"], lev["lower"], lev["upper"]
    general = np.ascontiguousarray(lev["A"][n:])  # the rows after the identity: C
    entries = nonzero_entries(general)
    rows_x = columns_in_states(lev["A"], dur, m)
    m_mat = columns_in_states(np.ascontiguousarray(columns_in_states(lev["P"], dur, m).T), dur, m)
    c_x = columns_in_states(lev["c"][None, :], dur, m)[0]
    factor, held_rows = np.empty_like(m_mat), columns_in_states(lev["held"], dur, m)
    banded_cholesky(m_mat, 2 * m - 1, factor)
    factor_today = _factor(lev["P"])
    z, duals, lam = np.empty(n), np.empty(lev["A"].shape[0]), np.empty(active.size)

    def transforms():
        columns_in_states(lev["A"], dur, m)
        columns_in_states(np.ascontiguousarray(columns_in_states(lev["P"], dur, m).T), dur, m)
        columns_in_states(lev["c"][None, :], dur, m)
        columns_in_states(lev["held"], dur, m)

    return {
        "today: factor": lambda: _factor(lev["P"]),
        "today: check": lambda: solve_on_active_set(
            factor_today,
            lev["c"],
            general,
            entries,
            True,
            lower,
            upper,
            active,
            at_upper,
            PRIMAL_TOL,
            ACTIVE_SET_DUAL_SHARE,
            ACTIVE_SET_CHANGES,
            z,
            duals,
        ),  # fmt: skip
        "today: null space": lambda: compiled_null_space(lev["held"]),
        "states: the rows carried into them": transforms,
        "states: banded factor": lambda: banded_cholesky(m_mat, 2 * m - 1, factor),
        "states: check": lambda: check_banded(
            factor, 2 * m - 1, c_x, rows_x, lower, upper, active, at_upper, z, lam
        ),
        "states: null space": lambda: null_space_per_state(held_rows, 6, m),
    }


def main() -> None:
    lev = path_level()
    today, in_states = _solvers(lev)
    _agreement(lev, today, in_states)
    parts = _parts(lev)
    for rnd in range(3):
        now = median_us(today, 2000)
        states = median_us(in_states, 2000)
        times = {name: median_us(call, 2000) for name, call in parts.items()}
        print(f"round {rnd + 1}: today {now:.1f} µs, in the states {states:.1f} µs, of which "
              f"{times['states: the rows carried into them']:.1f} µs carry the rows there; "
              + ", ".join(f"{k} {v:.1f}" for k, v in times.items()))  # fmt: skip


if __name__ == "__main__":
    main()

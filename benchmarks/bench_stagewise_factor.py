"""The path level's Hessian in the predicted states: block tridiagonal, and how much a
factorisation that keeps that structure would save (docs/performance.md).

The path-following controller's decision is ``z = (qd_0, s_0, …, qd_{p-1}, s_{p-1})``; its
predicted states ``x_i = (q_{i+1} - q, σ_{i+1} - σ)`` are ``x = S z`` with ``S`` lower
block triangular (the prediction's weights). The path rows of state ``i`` reach ``x_i``
only, and the damping rows ``z = S⁻¹ x`` reach two neighbouring states (without a servo
model ``S⁻¹`` takes differences), so ``M = S⁻ᵀ P S⁻¹`` is block tridiagonal with blocks of
``n + 1``. This script runs the controller of ``dqcontrol bench`` (LBR4p, 2 s circle,
``T = 1 ms``, ``p = 10``) for 300 steps, takes the path level's Hessian ``P`` of the last
step, prints the largest entry of ``M`` outside the band against the largest overall,
checks a block-tridiagonal Cholesky factor against ``M``, and times that factorisation
against LAPACK's dense one of ``P`` (medians of 3000 calls, three interleaved rounds).

    python benchmarks/bench_stagewise_factor.py
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit
from scipy.linalg import lapack

from dqcontrol import load_lbr4p
from dqcontrol.controllers import PathFollowingController
from dqcontrol.controllers.level_objective import level_objective
from dqcontrol.experiments.thesis import (
    LBR4P_Q0,
    THESIS_ACCELERATION_LIMIT,
    THESIS_VELOCITY_LIMITS,
)
from dqcontrol.trajectories import Circle

PERIOD_S = 0.001


def bench_step_controller(steps: int = 300) -> PathFollowingController:
    """The path-following controller of ``dqcontrol bench`` (LBR4p, 2 s circle,
    ``T = 1 ms``, ``p = 10``) after ``steps`` steps of the kinematic loop."""
    ctrl = PathFollowingController(
        load_lbr4p(), Circle(2.0), PERIOD_S, velocity_limits=THESIS_VELOCITY_LIMITS,
        acceleration_limit=THESIS_ACCELERATION_LIMIT,
    )  # fmt: skip
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    for _ in range(steps):
        q = q + PERIOD_S * ctrl.step(q).qd_command
    return ctrl


def path_level_hessian() -> tuple[np.ndarray, np.ndarray, int]:
    """``(P, S, n + 1)``: the path level's Hessian after 300 steps, the map from the
    decision to the predicted states and the size of a state's block."""
    ctrl = bench_step_controller()
    problem = ctrl.last_problem()
    p_mat, _ = level_objective(problem.layout, problem.levels[0].residuals)
    model = ctrl.prediction_model
    n, p = problem.layout.num_joints, problem.layout.num_blocks
    m = n + 1
    states = np.zeros((p * m, p * m))
    for i in range(p):
        for j in range(p):
            states[i * m : i * m + n, j * m : j * m + n] = model.weights[i, j] * np.eye(n)
            states[i * m + n, j * m + n] = model.sigma_weights[i, j]
    return p_mat, states, m


@njit(cache=True)
def block_tridiagonal_cholesky(
    diag: np.ndarray, sub: np.ndarray, l_diag: np.ndarray, l_sub: np.ndarray
) -> bool:
    """Lower Cholesky factor of the symmetric block-tridiagonal matrix with diagonal
    blocks ``diag`` ``(p, m, m)`` and sub-diagonal blocks ``sub`` ``(p-1, m, m)``: its
    diagonal blocks into ``l_diag``, its sub-diagonal ones into ``l_sub``. ``False`` where
    a pivot is not positive."""
    p, m, _ = diag.shape
    for i in range(p):
        a = diag[i].copy()
        if i > 0:
            for r in range(m):  # l_sub[i-1] = sub[i-1] l_diag[i-1]^-T
                for s in range(m):
                    acc = sub[i - 1, r, s]
                    for t in range(s):
                        acc -= l_sub[i - 1, r, t] * l_diag[i - 1, s, t]
                    l_sub[i - 1, r, s] = acc / l_diag[i - 1, s, s]
            for r in range(m):  # a -= l_sub l_subᵀ (lower triangle)
                for s in range(r + 1):
                    acc = 0.0
                    for t in range(m):
                        acc += l_sub[i - 1, r, t] * l_sub[i - 1, s, t]
                    a[r, s] -= acc
        for j in range(m):
            acc = a[j, j]
            for t in range(j):
                acc -= l_diag[i, j, t] * l_diag[i, j, t]
            if not acc > 0.0:
                return False
            pivot = np.sqrt(acc)
            l_diag[i, j, j] = pivot
            for r in range(j + 1, m):
                acc = a[r, j]
                for t in range(j):
                    acc -= l_diag[i, r, t] * l_diag[i, j, t]
                l_diag[i, r, j] = acc / pivot
            for r in range(j):
                l_diag[i, r, j] = 0.0
    return True


def median_us(call, reps: int = 3000) -> float:
    """The median wall time of ``call()`` over ``reps`` calls [µs]."""
    times = np.empty(reps)
    for k in range(reps):
        start = time.perf_counter()
        call()
        times[k] = time.perf_counter() - start
    return float(np.median(times) * 1e6)


def main() -> None:
    p_mat, states, m = path_level_hessian()
    inverse = np.linalg.inv(states)
    m_mat = inverse.T @ p_mat @ inverse
    p = m_mat.shape[0] // m
    blocks = m_mat.reshape(p, m, p, m).transpose(0, 2, 1, 3)
    band = np.abs(np.subtract.outer(np.arange(p), np.arange(p))) <= 1
    outside = float(np.abs(blocks[~band]).max())
    print(f"M = S^-T P S^-1 ({m_mat.shape[0]}x{m_mat.shape[1]}, blocks of {m}): largest entry "
          f"outside the block-tridiagonal band {outside:.2e}, largest overall "
          f"{np.abs(m_mat).max():.2e}")  # fmt: skip
    diag = np.ascontiguousarray(blocks[np.arange(p), np.arange(p)])
    sub = np.ascontiguousarray(blocks[np.arange(1, p), np.arange(p - 1)])
    l_diag, l_sub = np.zeros((p, m, m)), np.zeros((p - 1, m, m))
    assert block_tridiagonal_cholesky(diag, sub, l_diag, l_sub)
    factor = np.zeros_like(m_mat)
    for i in range(p):
        factor[i * m : (i + 1) * m, i * m : (i + 1) * m] = l_diag[i]
        if i + 1 < p:
            factor[(i + 1) * m : (i + 2) * m, i * m : (i + 1) * m] = l_sub[i]
    banded = np.where(np.repeat(np.repeat(band, m, 0), m, 1), m_mat, 0.0)
    error = np.abs(factor @ factor.T - banded).max() / np.abs(m_mat).max()
    print(f"block-tridiagonal factor: |L Lᵀ - M| / |M| = {error:.1e}")
    for rnd in range(3):
        dense = median_us(lambda: lapack.dpotrf(p_mat.T, lower=0, clean=1))
        stagewise = median_us(lambda: block_tridiagonal_cholesky(diag, sub, l_diag, l_sub))
        print(f"round {rnd + 1}: dense Cholesky of P {dense:.1f} µs, block-tridiagonal "
              f"Cholesky of M {stagewise:.1f} µs ({dense / stagewise:.1f}×)")  # fmt: skip


if __name__ == "__main__":
    main()

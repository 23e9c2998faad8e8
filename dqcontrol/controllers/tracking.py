"""The QP tracking controllers with time scaling: local (p = 1) and predictive (p ≥ 2).

One machinery serves FORMULATION §5.2, §5.3 and §5.4. At every step, for the instants
``τ_1 = 0 < τ_2 < … < τ_p``, with ``z_i = [qd_i; s_i]``:

    minimize   Σ_i λ1 ‖J_i qd_i - s_i w_i‖² + λ2 (1 - s_i)² + μ ‖qd_i‖²
    subject to qd_1 in the command box (velocity, position, acceleration; bounds.py),
               qd_i in the velocity/position box at q̂_i            (i ≥ 2),
               |qd_i - qd_{i-1}| ≤ (τ_i - τ_{i-1}) a_max(q̂_i)       (i ≥ 2),
               0 ≤ s_i ≤ 1   (s_i = 1 without scaling, §5.4)

with ``w_i = dx_d/dσ(σ̂_i) + K (x_d(σ̂_i) - x̂_i)`` (vec8, ``x̂_i`` sign-aligned to the target).
Writing ``G_i = [J_i, -w_i]`` (8×(n+1)), block i of the cost is
``z_iᵀ (λ1 G_iᵀ G_i + diag(μ…μ, λ2)) z_i - 2 λ2 s_i``: ``P`` is block diagonal with dense
blocks, ``c`` is constant, and ``A`` (identity + coupling rows) never changes, so OSQP is set
up once and each step only refills ``P``'s values and the bounds.

Variables are stored block by block (``[qd_1, s_1, qd_2, s_2, …]``); the thesis stacks all
``qd`` then all ``s`` — the same problem with permuted variables.

The local method (p = 1) with DAQP and a constant ``a_max`` — the 1 kHz case of issue 7 —
steps through :meth:`TrackingController._step_local`, the same computation as the general
:meth:`TrackingController._step_general` in fewer numpy calls (``tests/test_local_fast.py``
checks that they agree); every other case, and anything unusual, takes the general step.
"""

from __future__ import annotations

import math
import time
from typing import Literal, NamedTuple

import numpy as np
import scipy.sparse as sp

from dqcontrol.controllers.base import (
    Controller,
    StepDiagnostics,
    StepResult,
    check_position_margin,
    check_positive,
    fast_constructor,
    per_joint,
)
from dqcontrol.controllers.bounds import (
    Box,
    braking_constants,
    intersect_acceleration,
    safe_command,
)
from dqcontrol.controllers.joint_box import joint_boxes, joint_constants, vp_boxes
from dqcontrol.controllers.prediction import integration_matrix
from dqcontrol.controllers.qp_cost import instant_p_values, local_hessian
from dqcontrol.controllers.qp_daqp import DaqpQP
from dqcontrol.controllers.qp_solver import OsqpQP
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = [
    "DEFAULT_SOLVER",
    "AccelerationLimit",
    "QPProblem",
    "TrackingController",
    "default_solver",
]


class QPProblem(NamedTuple):
    """A QP ``minimize ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` as dense arrays."""

    P: np.ndarray
    c: np.ndarray
    A: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


#: ``float`` (constant [rad/s²], or one per joint) or ``"dynamics"`` (FORMULATION §6).
AccelerationLimit = float | np.ndarray | Literal["dynamics"]


def _interpolation_matrix(tau: np.ndarray, shift_s: float) -> np.ndarray:
    """``S`` with ``(S v)_i = g(τ_i + shift)``, ``g`` piecewise linear through ``(τ_j, v_j)``
    and held at its ends: shifts the previous horizon by one period (warm start)."""
    p = tau.size
    out = np.zeros((p, p))
    for i, t in enumerate(tau + shift_s):
        if t >= tau[-1]:
            out[i, -1] = 1.0
            continue
        j = int(np.searchsorted(tau, t, side="right")) - 1
        h = tau[j + 1] - tau[j]
        frac = (t - tau[j]) / h
        out[i, j] = 1.0 - frac
        out[i, j + 1] = frac
    return out


#: The QP backend used when none is named (docs/performance.md has the numbers).
DEFAULT_SOLVER = "daqp"


def default_solver(solver_settings: dict | None = None) -> str:
    """The backend used when ``solver=None``: always :data:`DEFAULT_SOLVER`.

    ``solver_settings`` never choose the backend: settings written for OSQP (``max_iter``,
    ``time_limit`` …) must come with ``solver="osqp"``; given to DAQP they are refused
    with the list of DAQP's settings."""
    del solver_settings
    return DEFAULT_SOLVER


class TrackingController(Controller):
    """Shared implementation of the local and predictive QP controllers.

    Args:
        robot, trajectory, period_s: see :class:`~dqcontrol.controllers.base.Controller`.
        instants_s: prediction instants ``τ_i`` [s], starting at 0 (``[0]`` = local method).
        gain_per_s: task-error gain ``K`` [1/s]; keep ``T s K`` well below 2 (FORMULATION §9).
        task_weight: ``λ1`` (dimensionless, > 0).
        scaling_weight: ``λ2`` (≥ 0); ``λ2 ≪ λ1`` puts the task before the speed.
        regularization: ``μ`` [same unit as λ1], the small damping on ``‖qd‖²``.
        stall_damping: extra damping ``μ_stall`` on ``‖qd‖²`` [same unit as λ1] while the
            task is stalled (default 1e-3; 0 gives FORMULATION §5 exactly). Once the
            applied ``s`` has stayed below ``stall_scaling`` for ``stall_delay_s``, the cost
            gets ``μ_stall (1 - s/stall_scaling) ‖qd‖²`` on every instant (``s``: the last
            applied one): a path point the arm cannot reach drives ``s`` to 0, and without
            it the QP keeps chasing the unreachable target at the acceleration bound (a
            two-period chatter of ``a_max T / 2``); with it the arm comes to rest near the
            path (docs/faults.md). Otherwise the cost is the thesis's.
        stall_scaling: the ``s`` below which the task counts as stalled (default 0.05, in
            ``(0, 1]``).
        stall_delay_s: how long ``s`` must stay below ``stall_scaling`` before the damping
            acts [s] (default 0.5 s, ≥ 0): a task that starts slowly because the arm is
            still accelerating is not a stalled one.
        velocity_limits: ``qd_max`` [rad/s], scalar or per joint; default: the URDF's.
        acceleration_limit: constant ``a_max`` [rad/s²] (scalar or per joint) or
            ``"dynamics"`` for Pinocchio's ``(τ_max - |g|)/M_jj`` clipped to
            ``[acceleration_floor, acceleration_cap]``.
        braking_aware: add the stop-before-the-limit position bound (bounds.py).
        position_margin_rad: the position bounds stop this far inside the URDF's limits
            [rad] (default 5 mrad = 0.29°: a velocity servo lags its command, so a joint
            braked to its limit overshoots — by up to 2.2 mrad in the MuJoCo fault campaign,
            docs/faults.md; with encoder noise use ≥ 3σ).
        measurement_delay_periods: see :class:`~dqcontrol.controllers.base.Controller`.
        scaling: optimise ``s`` (True) or hold ``s ≡ 1`` (FORMULATION §5.4).
        phase_prediction: ``"previous"`` integrates the previous ``s`` profile to predict
            ``σ̂_i``; ``"nominal"`` uses ``σ + τ_i`` (the thesis).
        solver: ``"daqp"`` (the default: dual active-set, ``qp_daqp.py``) or ``"osqp"``
            (ADMM refined to the exact optimum, ``qp_solver.py``). Both give the same
            commands (to ~1e-10 rad/s over a run); DAQP is 4–15× faster on these QPs
            (docs/performance.md). ``None`` picks DAQP; settings written for OSQP need
            ``solver="osqp"`` (DAQP refuses them, naming the settings it knows).
        solver_settings: settings overriding the solver's defaults.
    """

    name = "tracking"

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        *,
        instants_s: np.ndarray,
        gain_per_s: float = 10.0,
        task_weight: float = 1.0,
        scaling_weight: float = 1e-3,
        regularization: float = 1e-6,
        stall_damping: float = 1e-3,
        stall_scaling: float = 0.05,
        stall_delay_s: float = 0.5,
        velocity_limits: float | np.ndarray | None = None,
        acceleration_limit: AccelerationLimit = 10.0,
        acceleration_floor: float = 0.5,
        acceleration_cap: float = 50.0,
        braking_aware: bool = True,
        position_margin_rad: float = 5e-3,
        measurement_delay_periods: int = 0,
        scaling: bool = True,
        phase_prediction: Literal["previous", "nominal"] = "previous",
        solver: Literal["osqp", "daqp"] | None = None,
        solver_settings: dict | None = None,
    ) -> None:
        super().__init__(robot, trajectory, period_s, measurement_delay_periods)
        if solver is None:
            solver = default_solver(solver_settings)
        if solver not in ("osqp", "daqp"):
            raise ParameterError(f"solver must be 'osqp' or 'daqp', got {solver!r}")
        self.solver = solver
        n = self.n
        self.gain_per_s = check_positive("gain_per_s (K)", gain_per_s, "1/s")
        self.task_weight = check_positive("task_weight (lambda1)", task_weight, "-")
        self.scaling_weight = check_positive(
            "scaling_weight (lambda2)", scaling_weight, "-", allow_zero=True
        )
        self.regularization = check_positive(
            "regularization (mu)", regularization, "-", allow_zero=True
        )
        self.stall_damping = check_positive(
            "stall_damping", stall_damping, "- (same unit as lambda1)", allow_zero=True
        )
        self.stall_scaling = check_positive("stall_scaling", stall_scaling, "-")
        if self.stall_scaling > 1.0:
            raise ParameterError(f"stall_scaling must be in (0, 1], got {stall_scaling!r}")
        self.stall_delay_s = check_positive("stall_delay_s", stall_delay_s, "s", allow_zero=True)
        self._stall_steps = math.ceil(self.stall_delay_s / self.period_s - 1e-9)
        if phase_prediction not in ("previous", "nominal"):
            raise ParameterError(
                f"phase_prediction must be 'previous' or 'nominal', got {phase_prediction!r}"
            )
        self.phase_prediction = phase_prediction
        self.scaling = bool(scaling)
        self.braking_aware = bool(braking_aware)
        tau = np.asarray(instants_s, dtype=float)
        if tau.ndim != 1 or tau.size < 1 or tau[0] != 0.0 or np.any(np.diff(tau) <= 0.0):
            raise ParameterError(
                f"instants_s must start at 0 and increase strictly [s], got {instants_s!r}"
            )
        self.instants_s = tau
        self.p = tau.size

        lim = robot.limits
        margin = check_position_margin(position_margin_rad, lim.q_min, lim.q_max)
        self.position_margin_rad = margin
        self.q_min, self.q_max = lim.q_min + margin, lim.q_max - margin
        if velocity_limits is None:
            qd_max = lim.qd_max.copy()
            if np.any(qd_max <= 0.0) or not np.all(np.isfinite(qd_max)):
                raise ParameterError(
                    "the URDF gives no positive velocity limit for some joints "
                    f"({lim.qd_max}); pass velocity_limits [rad/s]"
                )
        else:
            qd_max = per_joint("velocity_limits", velocity_limits, n, "rad/s")
        self.qd_max = qd_max

        self.dynamic_acceleration = isinstance(acceleration_limit, str)
        if self.dynamic_acceleration:
            if acceleration_limit != "dynamics":
                raise ParameterError(
                    "acceleration_limit must be a positive number [rad/s²], one per joint, or "
                    f"'dynamics', got {acceleration_limit!r}"
                )
            self.acceleration_floor = check_positive(
                "acceleration_floor", acceleration_floor, "rad/s^2"
            )
            self.acceleration_cap = check_positive("acceleration_cap", acceleration_cap, "rad/s^2")
            if self.acceleration_floor > self.acceleration_cap:
                raise ParameterError(
                    f"acceleration_floor ({acceleration_floor}) must be ≤ acceleration_cap "
                    f"({acceleration_cap}) [rad/s²]"
                )
            self.a_const = None
        else:
            self.a_const = per_joint(
                "acceleration_limit", acceleration_limit, n, "rad/s² (or 'dynamics')"
            )

        # ---- QP structure, built once
        p, m = self.p, n + 1
        self._m = m
        block = sp.csc_matrix(np.triu(np.ones((m, m))))
        p_pattern = sp.block_diag([block] * p, format="csc")
        # gather index: CSC order of each block's upper triangle into H (p, m, m) row-major
        cols, rows = [], []
        for c in range(m):
            for r in range(c + 1):
                rows.append(r)
                cols.append(c)
        within = np.array(rows) * m + np.array(cols)
        self._p_gather = (np.arange(p)[:, None] * m * m + within[None, :]).ravel()
        num_vars = p * m
        coupling = []
        for i in range(1, p):
            for j in range(n):
                row = np.zeros(num_vars)
                row[i * m + j] = 1.0
                row[(i - 1) * m + j] = -1.0
                coupling.append(row)
        a_rows = [sp.identity(num_vars, format="csc")]
        if coupling:
            a_rows.append(sp.csc_matrix(np.array(coupling)))
        a_matrix = sp.vstack(a_rows, format="csc")
        if solver == "daqp":
            # without time scaling, s ≡ 1 is an equality by design (the only one)
            fixed = None if self.scaling else np.arange(p) * m + n
            # p instants: P is block diagonal, solved as a least-distance problem
            # (qp_ldp.py); one instant keeps DAQP's own path, as the local fast path
            self.qp = DaqpQP(
                p_pattern, a_matrix, solver_settings, equality_rows=fixed,
                block_size=m if p > 1 else None,
            )  # fmt: skip
        else:
            self.qp = OsqpQP(p_pattern, a_matrix, solver_settings)
        self._c = np.zeros(num_vars)
        self._c[n::m] = -2.0 * self.scaling_weight
        self._diag = np.zeros((p, m, m))
        idx = np.arange(n)
        self._diag[:, idx, idx] = self.regularization
        self._diag[:, n, n] = self.scaling_weight
        self._lower = np.zeros(a_matrix.shape[0])
        self._upper = np.zeros(a_matrix.shape[0])
        s_lo = 0.0 if self.scaling else 1.0
        for i in range(p):
            self._lower[i * m + n] = s_lo
            self._upper[i * m + n] = 1.0
        self._dtau = np.diff(tau)
        if p > 1:
            self._w_int = integration_matrix(tau, self.period_s)
            self._shift = _interpolation_matrix(tau, self.period_s)
        # the diagonal D of the cost at the stored (upper-triangle) positions of P
        self._diag_values = self._diag.ravel()[self._p_gather]
        # where the qd diagonal entries sit among the stored values (stall damping)
        qd_diag = np.zeros((p, m, m), dtype=bool)
        qd_diag[:, idx, idx] = True
        self._qd_diag_pos = np.flatnonzero(qd_diag.ravel()[self._p_gather])
        self._s_applied = 1.0
        self._stalled_steps = 0  # steps for which s has been below stall_scaling
        # views of the bound vectors: the qd part of each instant's block, the coupling rows
        self._lower_qd = self._lower[: p * m].reshape(p, m)[:, :n]
        self._upper_qd = self._upper[: p * m].reshape(p, m)[:, :n]
        self._lower_cpl = self._lower[p * m :]
        self._upper_cpl = self._upper[p * m :]
        if self.a_const is not None:  # constant a_max: the coupling bounds never change
            self._a_const_batch = np.tile(self.a_const, (p, 1))
            self._accel_step = self.period_s * self.a_const
            self._brake_const = braking_constants(self._a_const_batch, self.period_s)
            self._brake_const_1 = braking_constants(self.a_const, self.period_s)
            dv = (self._dtau[:, None] * self._a_const_batch[1:]).ravel()
            np.negative(dv, out=self._lower_cpl)
            self._upper_cpl[:] = dv
        self._no_brake = (np.zeros((p, n)),) * 3  # braking constants when braking is off
        self._uses_warm = isinstance(self.qp, OsqpQP)
        # the single-instant fast path (_step_local): DAQP, constant a_max
        self._local_qp = (
            self.qp if (p == 1 and solver == "daqp" and self.a_const is not None) else None
        )
        if self._local_qp is not None:
            self._diag2 = 2.0 * self._diag[0]  # 2 D, dense (m, m)
            self._bounds_init = np.zeros((2, m))  # [lower; upper]: the joints', then s's
            self._bounds_init[:, n] = self._lower.item(n), self._upper.item(n)
            self._conflict = np.zeros(n, dtype=np.int8)  # written by joint_boxes
            self._local_key: tuple = (None, None, None)  # (qd_max, T, braking_aware)
            self._local_consts: np.ndarray | None = None
            # the result objects' __dict__ filled at once (base.fast_constructor)
            self._new_diag = fast_constructor(StepDiagnostics, status="solved")
            self._new_result = fast_constructor(
                StepResult, qd_command=np.zeros(n), s=1.0, sigma=0.0, sigma_next=0.0,
                pose=np.zeros(8), target=np.zeros(8), diagnostics=StepDiagnostics("solved"),
            )  # fmt: skip
        self._horizon_qd = np.zeros((p, n))
        self._horizon_s = np.ones(p)
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    # ------------------------------------------------------------------ memory
    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        self._horizon_qd = np.tile(qd0, (self.p, 1))
        self._horizon_s = np.ones(self.p)
        self._s_applied = 1.0
        self._stalled_steps = 0  # steps for which s has been below stall_scaling
        self.qp.reset()

    # ------------------------------------------------------------------ pieces of a step
    def _predict(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted configurations ``q̂_i`` (p, n) and phases ``σ̂_i`` (p,)."""
        if self.p == 1:
            return q[None, :], np.array([self.sigma])
        q_hat = q + self._w_int @ self._horizon_qd
        if self.scaling and self.phase_prediction == "previous":
            sigma_hat = self.sigma + self._w_int @ self._horizon_s
        else:
            sigma_hat = self.sigma + self.instants_s
        return q_hat, sigma_hat

    def _acceleration(self, q_hat: np.ndarray) -> np.ndarray:
        """``a_max`` at each predicted configuration (p, n) [rad/s²]."""
        if self.a_const is not None:
            return self._a_const_batch
        return np.array(
            [
                self.robot._acceleration_limits(
                    qi, 1.0, self.acceleration_floor, self.acceleration_cap
                )
                for qi in q_hat
            ]
        )

    def _stall_extra(self) -> float:
        """The stall damping's extra weight on ``‖qd‖²`` this step (0 unless stalled)."""
        if self._stalled_steps >= self._stall_steps and self.scaling and self.stall_damping:
            return self.stall_damping * (1.0 - self._s_applied / self.stall_scaling)
        return 0.0

    def _record_applied_s(self, s_now: float) -> None:
        """Remember the applied ``s`` and for how many steps it has been below
        ``stall_scaling`` (what :meth:`_stall_extra` reads)."""
        self._s_applied = s_now
        if s_now < self.stall_scaling:
            self._stalled_steps += 1
        else:
            self._stalled_steps = 0

    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """The fast single-instant step where it applies, else the general one."""
        if self._local_qp is not None and self.qp is self._local_qp:
            res = self._step_local(q)
            if res is not None:
                return res
        return self._step_general(q, qd)

    def _local_constants(self, qd_max: list[float]) -> np.ndarray | None:
        """Per joint ``(qd_max, far, a T, 2 a, (a T)², T a)`` for the fast path's box (see
        ``joint_box.joint_constants``) at ``qd_max``, ``T`` and the braking switch (and
        ``a_max``, which is set at construction), as an ``(n, 6)`` array; ``None`` where
        they are not usable there (not finite, not > 0)."""
        self._local_key = (qd_max, self.period_s, self.braking_aware)
        at, two_a, at2 = self._brake_const_1
        limits = list(
            zip(at.tolist(), two_a.tolist(), at2.tolist(), self._accel_step.tolist(), strict=True)
        )
        values = qd_max + [self.period_s] + [v for row in limits for v in row]
        if all(math.isfinite(v) and v > 0.0 for v in values):
            consts = np.array(joint_constants(limits, qd_max, self.period_s, self.braking_aware))
        else:
            consts = None
        self._local_consts = consts
        return consts

    def _step_local(self, q: np.ndarray) -> StepResult | None:
        """The single-instant step (p = 1) with DAQP and a constant ``a_max``: the step of
        :meth:`_step_general` in three compiled calls and a few numpy ones (issue 7;
        ``tests/test_local_fast.py`` compares the two over closed loops).

        The box (velocity, position, braking, then acceleration with its conflict rule) by
        ``joint_box.joint_boxes``, bit for bit ``bounds._vp_box`` + ``intersect_acceleration``;
        ``H = 2 (λ1 Gᵀ G + D)`` by ``qp_cost.local_hessian``; DAQP without the general
        wrapper's checks (made by the box kernel); the result objects filled at once.
        Returns ``None``, having changed nothing, where the box is not usable here (a NaN
        limit or previous command, a bound beyond ±1e30, a non-finite ``qd_max``, ``T`` or
        ``a_max``): :meth:`_step_general` and the solver wrapper's checks handle those.
        """
        start = time.perf_counter()
        qd_max = self.qd_max.tolist()
        period_s = self.period_s
        braking = self.braking_aware
        key = self._local_key
        if qd_max == key[0] and period_s == key[1] and braking is key[2]:
            consts = self._local_consts
        else:  # the first step, or T, qd_max or braking_aware changed
            consts = self._local_constants(qd_max)
        if consts is None:
            return None
        n = self.n
        bounds = self._bounds_init.copy()  # [lower; upper], s's bounds set; DAQP keeps it
        conflicts = joint_boxes(
            q, self.qd_prev, self.q_min, self.q_max, consts, period_s, braking, bounds,
            self._conflict,
        )  # fmt: skip
        if conflicts < 0:
            return None
        conflict = tuple(np.flatnonzero(self._conflict).tolist()) if conflicts else ()

        # cost: H = 2 (λ1 Gᵀ G + D (+ stall damping)), G = [J, -w]
        sigma = self.sigma
        x, jac = self.robot._pose_and_jacobian(q)  # fresh arrays (flipped in place if needed)
        pair = self.trajectory.target_pair(sigma)  # [x_d; dx_d/dσ]
        h = local_hessian(
            x, jac, pair, self.gain_per_s, 2.0 * self.task_weight, self._diag2,
            2.0 * self._stall_extra(),
        )  # fmt: skip
        lower, upper = bounds[0], bounds[1]
        self._last = (h, lower, upper)
        sol, ok, status, iterations, solve_time = self._local_qp.solve_dense(
            h, self._c, lower, upper
        )
        if ok:
            s_now = min(max(sol.item(n), 0.0), 1.0) if self.scaling else 1.0
            # Box.project, in place on DAQP's fresh solution (s is clipped too, unused)
            np.maximum(sol, lower, out=sol)
            np.minimum(sol, upper, out=sol)
            qd_cmd = sol[:n]
            fallback, message = False, ""
        else:
            qd_cmd = safe_command(Box(lower[:n], upper[:n], self._conflict.astype(bool)))
            s_now = 0.0
            fallback = True
            message = f"QP failed ({status}); safe fallback: brake within a_max, s = 0"
        self._record_applied_s(s_now)
        step_time = time.perf_counter() - start
        diag = self._new_diag(
            status=status,
            iterations=iterations,
            solve_time_s=solve_time,
            step_time_s=step_time,
            fallback=fallback,
            conflict_joints=conflict,
            message=message,
        )
        return self._new_result(
            qd_command=qd_cmd,
            s=s_now,
            sigma=sigma,
            sigma_next=sigma + period_s * s_now,
            pose=x,
            target=pair[0],
            diagnostics=diag,
        )

    def _step_general(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """Every case: p instants, either backend, constant or dynamics-aware ``a_max``."""
        # The hot path of every QP controller: each numpy call costs about a microsecond
        # here, so the work is done in few, batched calls on preallocated arrays
        # (docs/performance.md).
        start = time.perf_counter()
        n, m, p = self.n, self._m, self.p
        if p == 1:
            q_hat = q[None, :]
            x, jac = self.robot._pose_and_jacobian(q)
            pair = self.trajectory.target_pair(self.sigma)  # [x_d; dx_d/dσ]
            xs, jacs, xd, dxd = x[None], jac[None], pair[:1], pair[1:]
        else:
            q_hat, sigma_hat = self._predict(q)
            xs, jacs = self.robot._poses_and_jacobians(q_hat)
            xd, dxd = self.trajectory.targets(sigma_hat)
        # cost: P = 2 (λ1 Gᵀ G + D), G_i = [J_i, -w_i]; only the stored upper triangles
        # (compiled: qp_cost.instant_p_values; the poses are flipped to x_i · x_d,i ≥ 0 in
        # place, and for one instant these are local_hessian's numbers, bit for bit)
        p_values = instant_p_values(
            xs, jacs, xd, dxd, self.gain_per_s, self.task_weight, self._p_gather,
            self._diag_values, self._stall_extra(), self._qd_diag_pos,
        )  # fmt: skip
        x0, xd0 = xs[0], xd[0]

        # bounds: velocity/position boxes of every instant at once (predicted ones clipped
        # to the limits), then the acceleration bound on the applied command
        a_max = self._acceleration(q_hat)
        if not self.braking_aware:
            brake = self._no_brake
        elif self.a_const is not None:
            brake = self._brake_const
        else:
            brake = braking_constants(a_max, self.period_s)
        # compiled (joint_box.vp_boxes): bounds._vp_box of q (instant 0) and of the
        # predicted q̂_i clipped to the limits, straight into the bound vectors
        vp_boxes(
            q, q_hat, self.q_min, self.q_max, self.qd_max, self.period_s, self.braking_aware,
            *brake, self._lower_qd, self._upper_qd,
        )  # fmt: skip
        if p > 1 and self.a_const is None:
            dv = (self._dtau[:, None] * a_max[1:]).ravel()
            np.negative(dv, out=self._lower_cpl)
            self._upper_cpl[:] = dv
        step = self._accel_step if self.a_const is not None else self.period_s * a_max[0]
        box = intersect_acceleration(self._lower_qd[0], self._upper_qd[0], self.qd_prev, step)
        lower, upper = self._lower, self._upper
        self._lower_qd[0] = box.lower
        self._upper_qd[0] = box.upper
        warm = None
        if p > 1 and self._uses_warm:
            warm = np.empty(p * m)
            warm_view = warm.reshape(p, m)
            warm_view[:, :n] = self._shift @ self._horizon_qd
            warm_view[:, n] = self._shift @ self._horizon_s

        self._last = (p_values, lower.copy(), upper.copy())
        sol = self.qp.solve(p_values, self._c, lower, upper, warm)
        relaxed = False
        if not sol.ok and p > 1:
            # regain feasibility: drop the predicted instants' boxes, keep the coupling
            self._lower_qd[1:] = -np.inf
            self._upper_qd[1:] = np.inf
            sol = self.qp.solve(p_values, self._c, lower, upper, None)
            relaxed = sol.ok

        conflict = tuple(np.flatnonzero(box.conflict).tolist()) if box.conflict.any() else ()
        horizon_qd = horizon_s = None
        if sol.ok:
            z = sol.x.reshape(p, m)
            qd_cmd = box.project(z[0, :n])
            s_now = min(max(float(z[0, n]), 0.0), 1.0) if self.scaling else 1.0
            if p > 1:
                self._horizon_qd = z[:, :n].copy()
                self._horizon_qd[0] = qd_cmd
                if self.scaling:
                    self._horizon_s = np.minimum(np.maximum(z[:, n], 0.0), 1.0)
                else:
                    self._horizon_s = np.ones(p)
            fallback, message = False, ""
            if relaxed:
                message = "predicted position bounds dropped to regain feasibility"
        else:
            qd_cmd = safe_command(box)
            s_now = 0.0
            if p > 1:
                self._horizon_qd = np.tile(qd_cmd, (p, 1))
                self._horizon_s = np.zeros(p)
            # the solver keeps its warm start: a cold restart after every failure locked a
            # flaky solver in the fallback for good (docs/faults.md); the backends rebuild
            # themselves after an exception
            fallback = True
            message = f"QP failed ({sol.status}); safe fallback: brake within a_max, s = 0"
        if p > 1:
            horizon_qd, horizon_s = self._horizon_qd.copy(), self._horizon_s.copy()
        self._record_applied_s(s_now)
        diag = StepDiagnostics(
            status=sol.status,
            iterations=sol.iterations,
            solve_time_s=sol.solve_time_s,
            step_time_s=time.perf_counter() - start,
            fallback=fallback,
            relaxed=relaxed,
            conflict_joints=conflict,
            message=message,
        )
        return StepResult(
            qd_command=qd_cmd,
            s=s_now,
            sigma=self.sigma,
            sigma_next=self.sigma + self.period_s * s_now,
            pose=x0,  # fresh arrays of this step (views of the kinematics' output)
            target=xd0,
            diagnostics=diag,
            horizon_qd=horizon_qd,
            horizon_s=horizon_s,
        )

    def last_problem(self) -> QPProblem:
        """The QP of the last step as dense arrays, for inspection and tests.

        ``minimize ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` with
        ``z = [qd_1, s_1, …, qd_p, s_p]``, as first posed (before any relaxation).
        """
        if self._last is None:
            raise ParameterError("no QP has been built yet: call step() first")
        p_values, lower, upper = self._last
        if p_values.ndim == 2:  # the single-instant fast path keeps the whole H
            return QPProblem(p_values.copy(), self._c.copy(), np.eye(self._m), lower, upper)
        pat = self.qp.p_pattern
        upper_tri = sp.csc_matrix((p_values, pat.indices, pat.indptr), shape=pat.shape).toarray()
        full = upper_tri + np.triu(upper_tri, 1).T
        return QPProblem(full, self._c.copy(), self.qp.a_matrix.toarray(), lower, upper)

"""A controller composed on the QP core: prediction, priority levels, limits, backend
(docs/theory.md §7).

At every step :class:`QPController`

1. predicts the horizon's states (its :class:`~dqcontrol.controllers.prediction.base.
   PredictionModel`) and evaluates the kinematics there (poses sign-aligned to the
   targets), the acceleration bound and the rest of the
   :class:`~dqcontrol.controllers.core.context.StepContext`;
2. builds and solves the QP: with one level whose terms are block diagonal, the
   :class:`~dqcontrol.controllers.core.problem.BlockQP` of
   :class:`~dqcontrol.controllers.core.block_assembly.BlockAssembly` goes to the backend's
   block path (:meth:`~dqcontrol.controllers.backends.base.Backend.solve_blocks`); otherwise
   the levels are solved lexicographically
   (:func:`~dqcontrol.controllers.core.levels.solve_levels`) on the same backend
   (:attr:`QPController.backend`);
3. if that fails and some limit is relaxable, solves again without the relaxable limits;
   if it still fails, applies the safe fallback (the point of the applied block's bounds
   closest to zero: braking within ``a_max``, ``s = 0``) and says so;
4. applies the first block's command clipped to its bounds and remembers the plan.

It never raises from inside a step because a QP failed (docs/theory.md §5).
"""

from __future__ import annotations

from time import perf_counter

import numpy as np

from dqcontrol.controllers.backends.base import Backend, make_backend
from dqcontrol.controllers.base import (
    Controller,
    StepDiagnostics,
    StepResult,
    fast_constructor,
    per_joint,
)
from dqcontrol.controllers.core.block_assembly import BlockAssembly, overrides
from dqcontrol.controllers.core.box_rules import clip_solution
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.levels import build_problem, solve_levels
from dqcontrol.controllers.core.problem import Level, Problem
from dqcontrol.controllers.core.task_kernels import align_signs, measured_state
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.prediction.base import Prediction, PredictionModel
from dqcontrol.controllers.terms.term import Term
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["QPController"]

_RELAXED = "predicted position bounds dropped to regain feasibility"


class QPController(Controller):
    """A controller composed of a prediction model, priority levels and limits.

    Args:
        robot, trajectory, period_s, measurement_delay_periods: see
            :class:`~dqcontrol.controllers.base.Controller`.
        prediction: the prediction model (its ``layout`` is the decision layout).
        levels: the priority levels, highest first.
        limits: every limit (any order: hard bounds are merged last).
        solver: a registered backend's name (``"daqp"``, the default, or ``"osqp"``:
            :func:`~dqcontrol.controllers.backends.base.backend_names`);
            ``solver_settings`` for it.
        s_max: the largest time scaling the applied ``s`` is clipped to.
        acceleration_limit: ``a_max`` [rad/s²] of every block (scalar or per joint), in the
            step context (subclasses may compute it per state instead).

    Attributes:
        backend: the :class:`~dqcontrol.controllers.backends.base.Backend` every QP of a
            step goes to (one level: its block path; several: the levels). It may be
            replaced by a wrapper (a :class:`~dqcontrol.controllers.backends.base.
            ForwardingBackend`: fault injection, logging): every solve goes through it.
    """

    name = "qp"
    backend: Backend

    def __init__(
        self,
        robot: RobotModel,
        trajectory: Trajectory,
        period_s: float,
        *,
        prediction: PredictionModel | None = None,
        levels: tuple[Level, ...] = (),
        limits: tuple[Limit, ...] = (),
        solver: str | None = None,
        solver_settings: dict | None = None,
        s_max: float = 1.0,
        acceleration_limit: float | np.ndarray = 10.0,
        measurement_delay_periods: int = 0,
    ) -> None:
        super().__init__(robot, trajectory, period_s, measurement_delay_periods)
        if prediction is not None:
            a_max = per_joint("acceleration_limit", acceleration_limit, self.n, "rad/s²")
            self._a_batch = np.tile(a_max, (prediction.layout.num_blocks, 1))
            self.compose(prediction, levels, limits, solver, solver_settings, s_max)

    def compose(
        self,
        prediction: PredictionModel,
        levels: tuple[Level, ...],
        limits: tuple[Limit, ...],
        solver: str | None = None,
        solver_settings: dict | None = None,
        s_max: float = 1.0,
    ) -> None:
        """Set the composition (a subclass calls it once its own settings are checked)."""
        if not levels:
            raise ParameterError("a QP controller needs at least one priority level")
        self.prediction_model = prediction
        self.layout = prediction.layout
        self.levels = tuple(levels)
        self.limits = tuple(limits)
        self.s_max = float(s_max)
        self.solver = "daqp" if solver is None else solver
        self._solver_settings = solver_settings
        terms = [t for lev in self.levels for t in lev.terms]
        self._prepare = tuple(t.prepare for t in terms if overrides(t, Term, "prepare"))
        self._observe = tuple(t.observe for t in terms if overrides(t, Term, "observe"))
        self._resets = tuple(t for t in terms if overrides(t, Term, "reset"))
        single = len(self.levels) == 1
        self._assembly = BlockAssembly(self.levels[0].terms, self.limits) if single else None
        self.backend = make_backend(solver, solver_settings)
        self._warm_starts = single and self.backend.uses_warm_start
        prediction.warm = self._warm_starts
        self._one_block = self.layout.num_blocks == 1
        self._constant_acceleration = self._acceleration_is_constant()
        self._s_at = self.n if self._scaled() else -1  # where the applied s is, if solved
        self._fast = self.robot.fast
        self._conflict = np.zeros(self.layout.num_vars, dtype=bool)
        self._level_note = ""
        self._ctx: StepContext | None = None
        self._cache: dict = {}
        self._new_diag = fast_constructor(StepDiagnostics, status="solved")
        self._new_result = fast_constructor(
            StepResult, qd_command=np.zeros(self.n), s=1.0, sigma=0.0, sigma_next=0.0,
            pose=np.zeros(8), target=np.zeros(8), diagnostics=StepDiagnostics("solved"),
        )  # fmt: skip

    # ------------------------------------------------------------------ memory
    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        self.prediction_model.reset(q0, qd0)
        for term in self._resets:
            term.reset()
        self.backend.reset()
        self._ctx = None

    @property
    def qp(self) -> Backend:
        """The backend (:attr:`backend`), under the name the fault wrappers use."""
        return self.backend

    @qp.setter
    def qp(self, backend: Backend) -> None:
        self.backend = backend

    def _acceleration(self, q_lin: np.ndarray) -> np.ndarray:
        """``a_max`` [rad/s²] at each block's state ``(p, n)``: the constant
        ``acceleration_limit`` here (the same array at every step); subclasses may make it
        depend on the state."""
        return self._a_batch

    def _acceleration_is_constant(self) -> bool:
        """Whether :meth:`_acceleration` gives the same array at every step."""
        return type(self)._acceleration is QPController._acceleration

    # ------------------------------------------------------------------ one step
    def _context(self, q: np.ndarray) -> StepContext:
        """The step context: prediction, aligned kinematics, ``a_max`` (one object, reused)."""
        sigma = self.sigma
        pred = self.prediction_model.predict(q, sigma)
        xs, jacs = self._fast.poses_and_jacobians(pred.q_lin)
        xd, dxd = self.trajectory.targets(pred.sigma_lin)
        align_signs(xs, jacs, xd)
        a_max = self._acceleration(pred.q_lin)
        ctx = self._ctx
        if ctx is None:
            ctx = self._ctx = StepContext(
                self.robot, self.trajectory, self.layout, self.period_s, q, self.qd_prev,
                sigma, pred, xs, jacs, xd, dxd, a_max,
            )  # fmt: skip
            return ctx
        ctx.period_s = self.period_s
        ctx.q = q
        ctx.qd_prev = self.qd_prev
        ctx.sigma = sigma
        ctx.prediction = pred
        ctx.poses = xs
        ctx.jacobians = jacs
        ctx.targets = xd
        ctx.target_derivatives = dxd
        ctx.a_max = a_max
        return ctx

    def _measured_context(self, q: np.ndarray) -> StepContext:
        """One block: no prediction, the state is the measured one. The context's arrays
        stay the same objects from step to step (views of one buffer), refilled by one
        compiled call; the fresh pose and target pair are kept for the result."""
        sigma = self.sigma
        x, jac = self._fast.pose_and_jacobian(q)
        pair = self.trajectory.target_pair(sigma)
        ctx = self._ctx
        if ctx is None:
            ctx = self._ctx = self._one_block_context(q, sigma)
        measured_state(x, jac, pair, q, sigma, self._state)
        ctx.period_s = self.period_s
        ctx.q = q
        ctx.qd_prev = self.qd_prev
        ctx.sigma = sigma
        if not self._constant_acceleration:
            ctx.a_max = self._acceleration(ctx.prediction.q_lin)
        self._pose_target = (x, pair[0])
        return ctx

    def _one_block_context(self, q: np.ndarray, sigma: float) -> StepContext:
        n = self.n
        state = self._state = np.zeros(8 + 8 * n + 16 + n + 1)
        o = 8 + 8 * n
        poses, jacs = state[:8].reshape(1, 8), state[8:o].reshape(1, 8, n)
        xd, dxd = state[o : o + 8].reshape(1, 8), state[o + 8 : o + 16].reshape(1, 8)
        q_lin, sigma_lin = state[o + 16 : o + 16 + n].reshape(1, n), state[o + 16 + n :]
        pred = Prediction(q_lin, sigma_lin, q_lin, sigma_lin, np.zeros((1, 1)), None, None)
        return StepContext(
            self.robot, self.trajectory, self.layout, self.period_s, q, self.qd_prev, sigma,
            pred, poses, jacs, xd, dxd, self._acceleration(q_lin),
        )  # fmt: skip

    def _warm(self, ctx: StepContext) -> np.ndarray | None:
        """The previous plan shifted, as a decision vector (for a backend that takes one)."""
        pred = ctx.prediction
        if pred.warm_qd is None:
            return None
        n, layout = self.n, self.layout
        warm = np.empty((layout.num_blocks, layout.block_size))
        warm[:, :n] = pred.warm_qd
        if layout.with_scaling:
            warm[:, n] = pred.warm_s
        return warm.ravel()

    def _solve_levels(self, ctx: StepContext) -> tuple:
        """``(solution, lower, upper, conflict, relaxed)`` by the lexicographic levels."""
        problem = build_problem(ctx, self.levels, self.limits, self._cache)
        result = solve_levels(problem, self.backend)
        relaxed = False
        if result.failed_level == 0 and any(lim.relaxable for lim in self.limits):
            kept = tuple(lim for lim in self.limits if not lim.relaxable)
            again = solve_levels(build_problem(ctx, self.levels, kept, self._cache), self.backend)
            if again.failed_level != 0:
                result, relaxed = again, True
        sol = result.solution
        if result.failed_level is not None and result.failed_level > 0:
            failed = result.per_level[result.failed_level]
            self._level_note = (
                f"level {result.failed_level + 1} failed ({failed.status}); the higher "
                "levels' optimum kept"
            )
        self._conflict = problem.conflict
        return sol, problem.lower, problem.upper, bool(problem.conflict[: self.n].any()), relaxed

    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        start = perf_counter()
        ctx = self._measured_context(q) if self._one_block else self._context(q)
        for prepare in self._prepare:
            prepare(ctx)
        assembly = self._assembly
        if assembly is not None:  # one level: its BlockQP, solved by the block backend
            qp = assembly.build(ctx, False, self._warm(ctx) if self._warm_starts else None)
            if qp is not None:
                backend = self.backend
                sol = backend.solve_blocks(qp)
                relaxed = False
                if not sol.ok and assembly.relaxable:  # again without the relaxable limits
                    relaxed_qp = assembly.build(ctx, relaxed=True)
                    if relaxed_qp is not None:
                        sol = backend.solve_blocks(relaxed_qp)
                        relaxed = sol.ok
                out = (sol, qp.lower, qp.upper, assembly.has_conflict, relaxed)
                return self._finish(ctx, out, start)
            self._assembly = None  # not block diagonal: the levels' dense path from now on
        return self._finish(ctx, self._solve_levels(ctx), start)

    def _finish(self, ctx: StepContext, out: tuple, start: float) -> StepResult:
        """Apply the solution (clipped to the applied block's bounds) or the fallback;
        ``out`` is ``(solution, lower, upper, conflict, relaxed)``."""
        sol, lower, upper, clash, relaxed = out
        n = self.n
        if sol.ok:
            z = sol.x
            # the applied command clipped to its bounds in place; s as solved, within [0, s_max]
            s_now = clip_solution(z, lower, upper, n, self._s_at, self.s_max)
            qd_cmd = z[:n]
            message = _RELAXED if relaxed else self._level_note
            self._level_note = ""
        else:
            z = None
            qd_cmd = np.minimum(np.maximum(np.zeros(n), lower[:n]), upper[:n])  # fallback
            s_now = 0.0
            message = f"QP failed ({sol.status}); safe fallback: brake within a_max, s = 0"
        horizon_qd = horizon_s = None
        if not self._one_block:
            horizon_qd, horizon_s = self._commit(z, qd_cmd, s_now)
        for observe in self._observe:
            observe(z, s_now)
        conflict = self._conflict_joints() if clash else ()
        diag = self._new_diag(
            status=sol.status, iterations=sol.iterations, solve_time_s=sol.solve_time_s,
            step_time_s=perf_counter() - start, fallback=z is None, relaxed=relaxed,
            conflict_joints=conflict, message=message,
        )  # fmt: skip
        sigma = self.sigma
        if self._one_block:  # no horizon to report
            pose, target = self._pose_target
            return self._new_result(
                qd_command=qd_cmd, s=s_now, sigma=sigma,
                sigma_next=sigma + self.period_s * s_now, pose=pose, target=target,
                diagnostics=diag,
            )  # fmt: skip
        return self._new_result(
            qd_command=qd_cmd, s=s_now, sigma=sigma, sigma_next=sigma + self.period_s * s_now,
            pose=ctx.poses[0], target=ctx.targets[0], diagnostics=diag,
            horizon_qd=horizon_qd, horizon_s=horizon_s,
        )  # fmt: skip

    def _conflict_joints(self) -> tuple[int, ...]:
        """The joints whose hard bound won a conflict at this step."""
        mask = self._assembly.conflict if self._assembly is not None else self._conflict
        return tuple(np.flatnonzero(mask[: self.n]).tolist())

    def _scaled(self) -> bool:
        """Whether the applied ``s`` is the solution's (else it is 1)."""
        return self.layout.with_scaling

    def _commit(self, z, qd_cmd: np.ndarray, s_now: float) -> tuple:
        """Remember the plan (the fallback's: hold the command, ``s = 0``); the horizon
        reported in the result."""
        layout = self.layout
        p = layout.num_blocks
        if z is None:
            plan_qd, plan_s = np.tile(qd_cmd, (p, 1)), np.zeros(p)
        else:
            qd_plan, s_plan = layout.split(z)
            plan_qd = qd_plan.copy()
            plan_qd[0] = qd_cmd
            if self._scaled() and s_plan is not None:
                plan_s = np.minimum(np.maximum(s_plan, 0.0), self.s_max)
            else:
                plan_s = np.ones(p)
        self.prediction_model.commit(plan_qd, plan_s)
        return plan_qd.copy(), plan_s.copy()

    # ------------------------------------------------------------------ inspection
    def last_problem(self) -> Problem:
        """The problem of the last step, as first posed (before any relaxation): every
        level's terms and every limit's rows, by name
        (:class:`~dqcontrol.controllers.core.problem.Problem`; it also reads as the first
        level's dense QP ``P, c, A, lower, upper``)."""
        if self._ctx is None:
            raise ParameterError("no QP has been built yet: call step() first")
        return build_problem(self._ctx, self.levels, self.limits)

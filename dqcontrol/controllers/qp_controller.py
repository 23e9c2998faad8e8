"""A controller composed on the QP core: prediction, priority levels, limits, backend
(docs/theory.md §7).

Every QP controller steps through one pipeline (:meth:`QPController._step`):

1. the step context: the horizon's predicted states (its :class:`~dqcontrol.controllers.
   prediction.base.PredictionModel`), the kinematics there (poses sign-aligned to the
   targets), the acceleration bound (:meth:`QPController._step_context`);
2. the problem: the levels of terms and the limits at that context, a
   :class:`~dqcontrol.controllers.core.step_problem.StepProblem`, handed whole to the
   backend (:meth:`~dqcontrol.controllers.backends.base.Backend.solve_problem`), which
   solves it in the form its structure allows (one block-diagonal level, or the levels
   lexicographically);
3. the remedies: where the first level is infeasible, the problem again with the
   controller's remedies in turn (:meth:`QPController._remedies`: without the relaxable
   limits by default), the first that regains feasibility kept;
4. the result: the first block's command clipped to its bounds and the plan remembered,
   or, where nothing was feasible, the safe fallback (the point of the applied block's
   bounds closest to zero: braking within ``a_max``, ``s = 0``), and the diagnostics
   saying which (:meth:`QPController._finish`).

A controller is a composition — prediction, levels, limits, backend, remedies — and the
hooks a controller may give: its context, its remedies, more rounds of the solve
(:meth:`QPController._solve`), what it keeps after a step. It never raises from inside a
step because a QP failed (docs/theory.md §5).
"""

from __future__ import annotations

from time import perf_counter
from typing import NamedTuple

import numpy as np

from dqcontrol.controllers.backends.base import Backend, check_backend_name, make_backend
from dqcontrol.controllers.base import (
    Controller,
    StepDiagnostics,
    StepResult,
    fast_constructor,
    per_joint,
    robot_acceleration_limit,
)
from dqcontrol.controllers.core.block_assembly import BlockAssembly, overrides
from dqcontrol.controllers.core.box_rules import clip_solution
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.levels import LevelsResult
from dqcontrol.controllers.core.problem import Level, Problem
from dqcontrol.controllers.core.step_problem import StepProblem
from dqcontrol.controllers.core.task_kernels import align_signs, measured_state
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.prediction.base import Prediction, PredictionModel
from dqcontrol.controllers.terms.term import Term
from dqcontrol.errors import ParameterError
from dqcontrol.model.robot import RobotModel
from dqcontrol.trajectories import Trajectory

__all__ = ["QPController", "Remedy", "Solved"]

_RELAXED = "predicted position bounds dropped to regain feasibility"
_NO_REMEDY = ""
_new_solved = tuple.__new__  # a NamedTuple from all its fields, at a 1 kHz step's cost


class Remedy(NamedTuple):
    """A way to regain feasibility when the first level is infeasible: the problem again
    with other limits (``name`` is what the diagnostics report, ``message`` says it)."""

    name: str
    limits: tuple[Limit, ...]
    message: str


class Solved(NamedTuple):
    """One step's solve: the problem kept (the one solved, its remedy applied), its
    result, the remedy's name (``""``: none), and the solver's work over every attempt
    and round."""

    problem: StepProblem
    result: LevelsResult
    remedy: str
    iterations: int
    solve_time_s: float
    rounds: int = 1
    levels_time_s: float = 0.0


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
            step context (subclasses may compute it per state instead); ``None``: the
            robot's limit profile's, else 10 rad/s².

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
        acceleration_limit: float | np.ndarray | None = None,
        measurement_delay_periods: int = 0,
    ) -> None:
        super().__init__(robot, trajectory, period_s, measurement_delay_periods)
        if prediction is not None:
            a_max = per_joint(
                "acceleration_limit",
                robot_acceleration_limit(robot, acceleration_limit, 10.0),
                self.n,
                "rad/s²",
            )
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
        #: The command applied the period before ``qd_prev`` (the jerk rows read it).
        self.qd_before_prev = self.qd_prev.copy()
        self.levels = tuple(levels)
        self.limits = tuple(limits)
        self.s_max = float(s_max)
        self.solver = check_backend_name(solver)
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
        if not overrides(self, QPController, "_step_context"):  # bound: one call less a step
            self._step_context = self._measured_context if self._one_block else self._context  # type: ignore[method-assign]
        #: The levels of the next step (a controller may change them with its state).
        self._levels_now = self.levels
        #: The pose now and its target, as the step reports them (set with the context).
        self._reported: tuple[np.ndarray, np.ndarray] = (np.zeros(8), np.zeros(8))
        self._remedy_list = self._remedies()
        self._remedy_messages = {r.name: r.message for r in self._remedy_list}
        self._ctx: StepContext | None = None
        self._last: StepProblem | None = None
        self._new_diag = fast_constructor(StepDiagnostics, status="solved")
        self._new_result = fast_constructor(
            StepResult, qd_command=np.zeros(self.n), s=1.0, sigma=0.0, sigma_next=0.0,
            pose=np.zeros(8), target=np.zeros(8), diagnostics=StepDiagnostics("solved"),
        )  # fmt: skip

    # ------------------------------------------------------------------ memory
    def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        self.qd_before_prev = qd0.copy()  # the start without acceleration (at rest: 0)
        self.prediction_model.reset(q0, qd0)
        for term in self._resets:
            term.reset()
        self.backend.reset()
        self._ctx = None
        self._last = None

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
    def _context(self, q: np.ndarray, qd: np.ndarray | None = None) -> StepContext:
        """The step context: prediction, aligned kinematics, ``a_max`` (one object, reused)."""
        sigma = self.sigma
        pred = self.prediction_model.predict(q, sigma)
        xs, jacs = self._fast.poses_and_jacobians(pred.q_lin)
        xd, dxd = self.trajectory.targets(pred.sigma_lin)
        align_signs(xs, jacs, xd)
        a_max = self._acceleration(pred.q_lin)
        self._reported = (xs[0], xd[0])
        ctx = self._ctx
        if ctx is None:
            ctx = self._ctx = StepContext(
                self.robot, self.trajectory, self.layout, self.period_s, q, self.qd_prev,
                sigma, pred, xs, jacs, xd, dxd, a_max, qd_before_prev=self.qd_before_prev,
            )  # fmt: skip
            return ctx
        ctx.period_s = self.period_s
        ctx.q = q
        ctx.qd_prev = self.qd_prev
        ctx.qd_before_prev = self.qd_before_prev
        ctx.sigma = sigma
        ctx.prediction = pred
        ctx.poses = xs
        ctx.jacobians = jacs
        ctx.targets = xd
        ctx.target_derivatives = dxd
        ctx.a_max = a_max
        return ctx

    def _measured_context(self, q: np.ndarray, qd: np.ndarray | None = None) -> StepContext:
        """One block: no prediction, the state is the measured one. The context's arrays
        stay the same objects from step to step (views of one buffer), refilled by one
        compiled call; the fresh pose and target pair are kept for the result."""
        sigma = self.sigma
        ctx = self._ctx
        if ctx is None:
            ctx = self._ctx = self._one_block_context(q, sigma)
        x, jac = np.empty(8), self._jacobian  # the pose is the result's: a new array a step
        self._fast.pose_and_jacobian_into(q, x, jac)
        pair = self.trajectory.target_pair(sigma)
        measured_state(x, jac, pair, q, sigma, self._state)
        ctx.period_s = self.period_s
        ctx.q = q
        ctx.qd_prev = self.qd_prev
        ctx.qd_before_prev = self.qd_before_prev
        ctx.sigma = sigma
        if not self._constant_acceleration:
            ctx.a_max = self._acceleration(ctx.prediction.q_lin)
        self._reported = (x, pair[0])
        return ctx

    def _one_block_context(self, q: np.ndarray, sigma: float) -> StepContext:
        n = self.n
        self._jacobian = np.empty((8, n))  # filled at each step, copied into the state
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

    # ------------------------------------------------------------------ the pipeline
    def _step(self, q: np.ndarray, qd: np.ndarray | None) -> StepResult:
        """The one pipeline: context, problem, backend, remedies, result."""
        start = perf_counter()
        ctx = self._step_context(q, qd)
        for prepare in self._prepare:
            prepare(ctx)
        return self._finish(self._solve(ctx), start)

    def _step_context(self, q: np.ndarray, qd: np.ndarray | None) -> StepContext:
        """The step context at the measured ``q`` (``qd``: the measured velocities, where
        given)."""
        return self._measured_context(q) if self._one_block else self._context(q)

    def _remedies(self) -> tuple[Remedy, ...]:
        """The remedies of an infeasible first level, in order: here, without the
        relaxable limits (the thesis's predicted boxes), where there are any."""
        kept = tuple(lim for lim in self.limits if not lim.relaxable)
        if len(kept) == len(self.limits):
            return ()
        return (Remedy("dropped", kept, _RELAXED),)

    def _solve(self, ctx: StepContext) -> Solved:
        """The step's problem through the backend; where its first level is infeasible,
        again with each remedy in turn, the first that regains feasibility kept (else the
        problem as first posed)."""
        levels = self._levels_now
        assembly = self._assembly
        warm = self._warm(ctx) if self._warm_starts and assembly is not None else None
        first = StepProblem(ctx, levels, self.limits, assembly, False, warm)
        result = self.backend.solve_problem(first)
        kept, outcome, remedy, spent = first, result, _NO_REMEDY, result.time_s
        if result.failed_level == 0:
            for name, limits, _ in self._remedy_list:
                retry = StepProblem(ctx, levels, limits, assembly, True)
                again = self.backend.solve_problem(retry)
                spent += again.time_s
                if again.failed_level != 0:
                    kept, outcome, remedy = retry, again, name
                    break
        if assembly is not None and not first.block_diagonal:
            self._assembly = None  # the levels' form from now on
        fields = (kept, outcome, remedy, outcome.iterations, outcome.solve_time_s, 1, spent)
        return _new_solved(Solved, fields)

    def _finish(self, solved: Solved, start: float) -> StepResult:
        """Apply the solution (the first block clipped to its bounds) or the fallback,
        remember the plan, and give the result."""
        problem, result, remedy, iterations, solve_time, rounds, levels_time = solved
        n = self.n
        lower, upper = problem.lower, problem.upper
        assert lower is not None and upper is not None, "a solved problem was built"
        sol, failed = result.solution, result.failed_level
        if failed != 0:  # the first level solved
            z = sol.x
            assert z is not None, "a solved level has its solution"
            # the applied command clipped to its bounds in place; s within [0, s_max]
            s_now = clip_solution(z, lower, upper, n, self._s_at, self.s_max)
            qd_cmd = z[:n]
            noted = remedy or failed is not None
            message = self._solved_message(solved) if noted else ""
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
        conflict = problem.conflict_joints(n) if problem.has_conflict else ()
        diag = self._new_diag(
            status=sol.status, iterations=iterations, solve_time_s=solve_time,
            step_time_s=perf_counter() - start, fallback=z is None, relaxed=bool(remedy),
            conflict_joints=conflict, message=message, linearisations=rounds,
            levels_time_s=levels_time,
        )  # fmt: skip
        self._last = problem
        self.qd_before_prev = self.qd_prev  # the step then applies qd_cmd: qd_prev moves back
        pose, target = self._reported
        sigma = self.sigma
        return self._new_result(
            qd_command=qd_cmd, s=s_now, sigma=sigma, sigma_next=sigma + self.period_s * s_now,
            pose=pose, target=target, diagnostics=diag, horizon_qd=horizon_qd,
            horizon_s=horizon_s,
        )  # fmt: skip

    def _solved_message(self, solved: Solved) -> str:
        """What the diagnostics say of a step whose first level was solved."""
        if solved.remedy:
            return self._remedy_messages[solved.remedy]
        failed = solved.result.failed_level
        if failed is None:
            return ""
        status = solved.result.per_level[failed].status
        return f"level {failed + 1} failed ({status}); the higher levels' optimum kept"

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
        self.prediction_model.commit(plan_qd, plan_s)  # a copy: the result keeps these
        return plan_qd, plan_s

    # ------------------------------------------------------------------ inspection
    def last_problem(self) -> Problem:
        """The problem solved at the last step (with the remedy that was kept, if any):
        every level's terms and every limit's rows, by name
        (:class:`~dqcontrol.controllers.core.problem.Problem`; it also reads as the first
        level's dense QP ``P, c, A, lower, upper``)."""
        if self._last is None:
            raise ParameterError("no QP has been built yet: call step() first")
        return self._last.problem()

"""QPs made infeasible on purpose: contradictory bounds handed to the real solver.

The least invasive way to make a controller's QP infeasible is to leave the controller's
code alone and corrupt the bounds on their way to the solver: :func:`contradictory` builds
a subclass of any QP controller (the thesis's, with either priority mode, or the
path-following one) whose backend (``backend``, the object every QP of a step goes through,
docs/theory.md §7.5) is wrapped in a :class:`ContradictoryBoundsQP`. The QP is built by the
controller's own terms and limits and solved by its own backend, on the path that
production runs take (every capability of the backend contract: the block path, the
levels, the reduced levels, the warm levels); during a window of control steps the wrapper
rewrites the bounds in between:

- ``"crossed"``: the applied command's box of one joint gets ``lower > upper`` (a QP with
  no feasible point that every solver must refuse). Relaxing the predicted instants
  cannot help, so the controller must use its safe fallback (brake within ``a_max``,
  ``s = 0``, docs/theory.md §5).
- ``"coupled"`` (predictive controllers, ``p ≥ 2``): every box is consistent on its own, but
  the second instant's box of one joint is moved beyond what the acceleration coupling
  ``|qd_2 - qd_1| ≤ (τ_2 - τ_1) a_max`` allows from the first instant's box — a primal
  infeasible QP. The thesis's controllers' first remedy (dropping the predicted instants'
  boxes, ``relaxed``) restores feasibility; the path-following controller keeps a velocity
  box on every interval, so it falls back to braking. The coupling rows are taken to be
  the first general rows (the acceleration limit's, as both controllers compose them).

Outside the window the bounds pass unchanged, so a run shows the transition into the
fault and the recovery out of it.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from dqcontrol.controllers.backends.base import Backend, ForwardingBackend
from dqcontrol.controllers.base import Controller
from dqcontrol.controllers.core.problem import BlockQP, DenseQP, Solution, SplitQP, WarmLevels
from dqcontrol.controllers.core.reduced import LevelRows, ReducedQP
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.controllers.qp_controller import QPController
from dqcontrol.errors import ParameterError

__all__ = ["MODES", "ContradictoryBoundsQP", "contradictory"]

#: The two ways of making the QP infeasible.
MODES = ("crossed", "coupled")


class ContradictoryBoundsQP(ForwardingBackend):
    """A backend wrapper that makes the bounds contradictory while ``active``.

    Args:
        inner: the controller's :class:`~dqcontrol.controllers.backends.base.Backend`.
        num_joints: ``n``; the variables are ``[qd_1, s_1, …, qd_p, s_p]``, then the
            acceleration coupling rows.
        num_instants: ``p``.
        mode: ``"crossed"`` or ``"coupled"`` (module docstring).
        joint: the joint whose bounds are corrupted.
        gap: how far the bounds are pushed apart [rad/s], > 0.

    Every other capability is the inner backend's (:class:`ForwardingBackend`).
    """

    def __init__(
        self,
        inner: Backend,
        num_joints: int,
        num_instants: int,
        mode: str = "crossed",
        joint: int = 0,
        gap: float = 0.5,
    ) -> None:
        if mode not in MODES:
            raise ParameterError(f"mode must be one of {MODES}, got {mode!r}")
        if mode == "coupled" and num_instants < 2:
            raise ParameterError(
                "mode 'coupled' needs a predictive controller (p ≥ 2 instants coupled by the "
                f"acceleration bound), got p = {num_instants}"
            )
        if not 0 <= joint < num_joints:
            raise ParameterError(f"joint must be in [0, {num_joints - 1}], got {joint}")
        if not gap > 0.0:
            raise ParameterError(f"gap must be > 0 [rad/s], got {gap!r}")
        super().__init__(inner)
        self.n = int(num_joints)
        self.p = int(num_instants)
        self.mode = mode
        self.joint = int(joint)
        self.gap = float(gap)
        #: Corrupt the bounds of the next solves (set by the controller each step).
        self.active = False
        #: How many solves received contradictory bounds.
        self.corrupted_solves = 0
        #: How many of those the solver nevertheless reported as solved (a wrong answer:
        #: the corrupted QPs have no feasible point).
        self.false_successes = 0

    def corrupt(self, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """Copies of ``lower``/``upper`` (the variables' bounds, then the general rows') with
        the contradiction of :attr:`mode`, and whether one was made (``"coupled"`` leaves a
        relaxed QP, whose instant 2 is free, alone)."""
        lo, up = lower.copy(), upper.copy()
        j, m = self.joint, self.n + 1
        if self.mode == "crossed":
            lo[j] = up[j] + self.gap
            return lo, up, True
        row = m + j  # qd_2 of joint j
        if not (np.isfinite(lo[row]) and np.isfinite(up[row])):  # relaxed: leave it
            return lo, up, False
        coupling = self.p * m + j  # |qd_2 - qd_1| ≤ dv, row of joint j
        # qd_2 ≥ up(qd_1) + dv + gap cannot be reached from any admissible qd_1
        lo[row] = up[row] = up[j] + up[coupling] + self.gap
        return lo, up, True

    def _count(self, contradicted: bool, sol: Solution) -> Solution:
        if contradicted:
            self.corrupted_solves += 1
            self.false_successes += int(sol.ok)
        return sol

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """A level's dense QP, corrupted while :attr:`active`."""
        if not self.active:
            return self.inner.solve(key, qp)
        lower, upper, bad = self.corrupt(qp.lower, qp.upper)
        return self._count(bad, self.inner.solve(key, qp._replace(lower=lower, upper=upper)))

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """The block QP, corrupted while :attr:`active`."""
        if not self.active:
            return self.inner.solve_blocks(qp)
        lower, upper, bad = self.corrupt(qp.lower, qp.upper)
        return self._count(bad, self.inner.solve_blocks(qp._replace(lower=lower, upper=upper)))

    def solve_reduced(self, key: object, qp: ReducedQP) -> tuple[Solution, np.ndarray]:
        """A reduced level, its rows' bounds corrupted while :attr:`active`."""
        if not self.active:
            return self.inner.solve_reduced(key, qp)
        lower, upper, bad = self.corrupt(qp.lower, qp.upper)
        sol, held = self.inner.solve_reduced(key, qp._replace(lower=lower, upper=upper))
        return self._count(bad, sol), held

    def solve_warm_levels(
        self, first: SplitQP, held: np.ndarray, lower: tuple[LevelRows, ...]
    ) -> WarmLevels | None:
        """The warm levels, the bounds corrupted while :attr:`active` (one solve)."""
        if not self.active:
            return self.inner.solve_warm_levels(first, held, lower)
        lo, up, bad = self.corrupt(first.lower, first.upper)
        out = self.inner.solve_warm_levels(first._replace(lower=lo, upper=up), held, lower)
        if out is not None and out.solutions:
            self._count(bad, out.solutions[0])
        return out


@cache
def contradictory(base: type[Controller]) -> type[Controller]:
    """A subclass of ``base`` whose QP gets contradictory bounds during a window of steps.

    The subclass takes two more keyword arguments:

    - ``contradiction``: ``"crossed"`` or ``"coupled"`` (module docstring);
    - ``window_steps``: ``(first, stop)``, the control steps ``first ≤ k < stop`` (counted
      from :meth:`reset`, 0-based) whose QP is corrupted; default ``(10, 30)``.

    Everything else — the QP's terms and limits, the backend, the fallback, the
    relaxation — is ``base``'s own code; the wrapper sits between the built QP and the
    backend (the controller's public ``backend``).
    """
    if not (isinstance(base, type) and issubclass(base, (QPController, PathFollowingController))):
        raise ParameterError(
            f"base must be a QP controller class (QPController or PathFollowingController), "
            f"got {base!r}"
        )

    class Contradictory(base):  # type: ignore[misc, valid-type]
        backend: ContradictoryBoundsQP  # the backend, wrapped

        def __init__(
            self,
            *args,
            contradiction: str = "crossed",
            window_steps: tuple[int, int] = (10, 30),
            **kwargs,
        ) -> None:
            super().__init__(*args, **kwargs)
            first, stop = (int(v) for v in window_steps)
            if not 0 <= first <= stop:
                raise ParameterError(
                    f"window_steps must be (first, stop) with 0 ≤ first ≤ stop, got "
                    f"{window_steps!r}"
                )
            self.window_steps = (first, stop)
            self.backend = ContradictoryBoundsQP(
                self.backend, self.n, self.layout.num_blocks, contradiction
            )
            self._fault_step = 0

        def _reset_memory(self, q0: np.ndarray, qd0: np.ndarray) -> None:
            super()._reset_memory(q0, qd0)
            self._fault_step = 0
            self.backend.corrupted_solves = 0
            self.backend.false_successes = 0

        def _step(self, q: np.ndarray, qd: np.ndarray | None):
            first, stop = self.window_steps
            self.backend.active = first <= self._fault_step < stop
            self._fault_step += 1
            return super()._step(q, qd)

    Contradictory.__name__ = Contradictory.__qualname__ = f"Contradictory{base.__name__}"
    return Contradictory

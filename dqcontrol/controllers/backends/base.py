"""The backend contract and the registry of backends by name (docs/theory.md §7.5).

A controller hands its backend the whole problem of a step
(:meth:`Backend.solve_problem`, a :class:`~dqcontrol.controllers.core.step_problem.
StepProblem`): one level whose ``P`` is block diagonal goes to :meth:`Backend.solve_blocks`,
several levels are solved lexicographically
(:func:`~dqcontrol.controllers.core.levels.solve_levels`) through the other capabilities.
A backend must implement one method,
:meth:`Backend.solve` (a dense QP ``min ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` with
``A = [I; C]``); every other capability has a dense default here, which a backend may
replace by a path specialised on the problem's structure:

- :meth:`Backend.solve_blocks`: one priority level whose ``P`` is block diagonal
  (:class:`~dqcontrol.controllers.core.problem.BlockQP`);
- :meth:`Backend.solve_reduced`: a lower level in the null space of the levels above,
  given as its parts (:class:`~dqcontrol.controllers.core.reduced.ReducedQP`);
- :meth:`Backend.solve_warm_levels`: the first levels of a problem of several in one call,
  where their last active sets hold (declared by :attr:`Backend.solves_warm_levels`);
- :meth:`Backend.set_general_rows`: the names of the rows of the next problem, so that a
  warm start can follow a row by name.

A new backend is one class that implements :meth:`~Backend.solve` and one call to
:func:`register_backend`; every controller then takes its name as ``solver``. A wrapper
(fault injection, logging) derives from :class:`ForwardingBackend`, which forwards every
capability to the backend it wraps, and overrides what it changes.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.core.levels import LevelsResult, solve_levels
from dqcontrol.controllers.core.problem import (
    BlockQP,
    DenseQP,
    Inequality,
    Solution,
    SplitQP,
    WarmLevels,
)
from dqcontrol.errors import ParameterError

if TYPE_CHECKING:
    from dqcontrol.controllers.core.reduced import LevelRows, ReducedQP
    from dqcontrol.controllers.core.step_problem import StepProblem

__all__ = [
    "DEFAULT_SOLVER",
    "Backend",
    "ForwardingBackend",
    "backend_names",
    "check_backend_name",
    "invalid_bounds",
    "make_backend",
    "refused_bounds",
    "register_backend",
]

_new_result = tuple.__new__  # a NamedTuple from all its fields, at a 1 kHz step's cost

#: The QP backend used when none is named.
DEFAULT_SOLVER = "daqp"


class Backend(ABC):
    """A QP solver behind the controllers' one contract.

    ``key`` names the QP a call belongs to (a priority level, a reduced level ``(k, dim)``):
    a backend may keep one workspace per key, set up on the first solve and updated
    afterwards; a change of shape sets it up again. No method raises for a failed solve:
    the :class:`~dqcontrol.controllers.core.problem.Solution` says so (``ok`` False, ``status``).

    Attributes:
        name: the name the backend is registered under.
        uses_warm_start: :meth:`solve_blocks` reads :attr:`BlockQP.warm` (the previous plan
            shifted), so the controller computes it.
        solves_warm_levels: :meth:`solve_warm_levels` may return the first levels.
    """

    name: str = ""
    uses_warm_start: bool = False
    solves_warm_levels: bool = False

    def solve_problem(self, problem: StepProblem) -> LevelsResult:
        """Solve a step's whole problem in the form its structure allows: one level with a
        block-diagonal ``P`` through :meth:`solve_blocks`, otherwise the levels in order
        (:func:`~dqcontrol.controllers.core.levels.solve_levels`, through :meth:`solve`,
        :meth:`solve_reduced` and :meth:`solve_warm_levels`)."""
        qp = problem.block_form
        if qp is None:
            return solve_levels(problem.problem(), self)
        sol = self.solve_blocks(qp)
        return _new_result(
            LevelsResult,
            (
                sol,
                (sol,),
                None if sol.ok else 0,
                sol.solve_time_s,
                sol.iterations,
                sol.solve_time_s,
            ),
        )

    @abstractmethod
    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve the dense QP of ``key`` (its workspace kept between steps)."""

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """Solve one level whose ``P`` is block diagonal; by default as its dense QP."""
        return self.solve("blocks", qp.dense())

    def solve_reduced(self, key: object, qp: ReducedQP) -> tuple[Solution, np.ndarray]:
        """Solve a level reduced to the null space of the levels above, given as its parts;
        returns the solution of its dense QP (in the basis' coordinates) and the level's
        held rows in the basis. By default through :meth:`solve`."""
        objective = qp.objective()
        return self.solve(key, qp.dense(objective)), objective.held

    def solve_warm_levels(
        self, first: SplitQP, held: np.ndarray, lower: tuple[LevelRows, ...]
    ) -> WarmLevels | None:
        """The first levels of a problem of several, solved in one call on their last active
        sets (``first``: level 0's QP, ``held``: its held rows, ``lower``: the rows of the
        levels below); ``None`` where they do not hold (by default always)."""
        return None

    def set_general_rows(self, num_vars: int, inequalities: tuple[Inequality, ...]) -> None:  # noqa: B027 - optional
        """Name the rows of the next problem: its ``num_vars`` variables and its limits'
        inequalities, in order (a backend may carry warm starts to them by name)."""

    def reset(self) -> None:  # noqa: B027 - optional
        """Forget the workspaces and warm starts."""


class ForwardingBackend(Backend):
    """A backend that forwards every capability to ``inner``: the base of wrappers, which
    override the methods whose QPs they change.

    Args:
        inner: the backend wrapped.
    """

    def __init__(self, inner: Backend) -> None:
        if not isinstance(inner, Backend):
            raise ParameterError(
                f"a backend wrapper needs a Backend to wrap, got {type(inner).__name__}"
            )
        self.inner = inner
        self.name = inner.name
        self.uses_warm_start = inner.uses_warm_start
        self.solves_warm_levels = inner.solves_warm_levels

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """The inner backend's :meth:`Backend.solve`."""
        return self.inner.solve(key, qp)

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """The inner backend's :meth:`Backend.solve_blocks`."""
        return self.inner.solve_blocks(qp)

    def solve_reduced(self, key: object, qp: ReducedQP) -> tuple[Solution, np.ndarray]:
        """The inner backend's :meth:`Backend.solve_reduced`."""
        return self.inner.solve_reduced(key, qp)

    def solve_warm_levels(
        self, first: SplitQP, held: np.ndarray, lower: tuple[LevelRows, ...]
    ) -> WarmLevels | None:
        """The inner backend's :meth:`Backend.solve_warm_levels`."""
        return self.inner.solve_warm_levels(first, held, lower)

    def set_general_rows(self, num_vars: int, inequalities: tuple[Inequality, ...]) -> None:
        """The inner backend's :meth:`Backend.set_general_rows`."""
        self.inner.set_general_rows(num_vars, inequalities)

    def reset(self) -> None:
        """The inner backend's :meth:`Backend.reset`."""
        self.inner.reset()


def invalid_bounds(lower: np.ndarray, upper: np.ndarray, start: float) -> Solution | None:
    """A failed :class:`~dqcontrol.controllers.core.problem.Solution` if some row has
    ``lower > upper`` or a NaN bound (``start``: when the solve began, ``perf_counter``).

    Solvers must never see such bounds: OSQP rejects the update (its Python wrapper ignores
    the return code) and DAQP's ``update`` returns an error code, and both would then solve
    the *previous* problem again and call it solved.
    """
    if (lower <= upper).all():  # False where either side is NaN too
        return None
    return refused_bounds(lower, upper, start)


def refused_bounds(lower: np.ndarray, upper: np.ndarray, start: float) -> Solution:
    """The failed solution of bounds that :func:`invalid_bounds` refuses."""
    rows = np.flatnonzero(~(lower <= upper))
    status = f"invalid_bounds: lower > upper or NaN in rows {rows[:5].tolist()}"
    return Solution(False, status, 0, time.perf_counter() - start)


#: A backend's constructor: its settings (``None``: its defaults) -> the backend.
BackendFactory = Callable[[dict | None], Backend]


def _daqp(settings: dict | None) -> Backend:
    from dqcontrol.controllers.backends.daqp.backend import DaqpBackend

    return DaqpBackend(settings)


def _osqp(settings: dict | None) -> Backend:
    from dqcontrol.controllers.backends.osqp import OsqpBackend

    return OsqpBackend(settings)


_REGISTRY: dict[str, BackendFactory] = {"daqp": _daqp, "osqp": _osqp}


def register_backend(name: str, factory: BackendFactory) -> None:
    """Make ``name`` a ``solver`` of every QP controller, built by ``factory(settings)``
    (a :class:`Backend` subclass taking its settings works as it is). A name already
    registered is refused: :func:`backend_names` lists them."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ParameterError(f"a backend's name must be an identifier, got {name!r}")
    key = name.lower()
    if key in _REGISTRY:
        raise ParameterError(f"a backend named {key!r} is already registered")
    if not callable(factory):
        raise ParameterError(f"the factory of backend {key!r} must be callable")
    _REGISTRY[key] = factory


def backend_names() -> tuple[str, ...]:
    """The registered backends' names, the default first."""
    return (DEFAULT_SOLVER, *sorted(k for k in _REGISTRY if k != DEFAULT_SOLVER))


def check_backend_name(name: str | None) -> str:
    """``name`` (``None``: :data:`DEFAULT_SOLVER`) as registered, or a
    :class:`~dqcontrol.errors.ParameterError` listing the registered names."""
    key = DEFAULT_SOLVER if name is None else name
    if not isinstance(key, str) or key.lower() not in _REGISTRY:
        known = ", ".join(repr(k) for k in backend_names())
        raise ParameterError(f"solver must be one of {known}, got {name!r}")
    return key.lower()


def make_backend(name: str | None, settings: dict | None = None) -> Backend:
    """The backend registered as ``name`` (``None``: :data:`DEFAULT_SOLVER`) with its
    ``settings``; unknown settings are refused by the backend, with the list of its own."""
    backend = _REGISTRY[check_backend_name(name)](settings)
    if not isinstance(backend, Backend):
        raise ParameterError(
            f"the factory of backend {name!r} returned a {type(backend).__name__}, not a Backend"
        )
    return backend

"""The backend protocols (docs/theory.md §7.5): solve a built QP, keep a workspace per
problem structure, never raise for a failed solve."""

from __future__ import annotations

from typing import Protocol

from dqcontrol.controllers.problem import BlockQP, DenseQP, Solution
from dqcontrol.errors import ParameterError

__all__ = ["DEFAULT_SOLVER", "Backend", "BlockBackend", "make_backend", "make_block_backend"]

#: The QP backend used when none is named.
DEFAULT_SOLVER = "daqp"


class Backend(Protocol):
    """Solves ``min ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` with ``A = [I; C]`` dense
    (the priority levels of :func:`~dqcontrol.controllers.levels.solve_levels`).

    ``key`` names the problem (e.g. the priority level): a backend keeps one workspace per
    key, set up on the first solve and updated afterwards (warm start: the previous
    active set); a change of shape sets it up again. ``solve`` never raises for a failed
    solve: the :class:`Solution` says so.

    A backend may also offer ``solve_reduced(key, qp)`` for a level reduced to the null
    space of the levels above, given as its parts
    (:class:`~dqcontrol.controllers.reduced.ReducedQP`), returning the :class:`Solution`
    of its dense QP and the level's held rows in the basis
    (:meth:`~dqcontrol.controllers.backends.daqp_dense.DaqpBackend.solve_reduced`); the
    levels use it where it exists and :meth:`solve` with the dense QP otherwise. It may
    offer ``solve_warm_levels(first, held, lower)`` too: the first levels of a problem of
    several (the first as a :class:`~dqcontrol.controllers.problem.SplitQP`), solved in
    one call where their last active sets hold, as a
    :class:`~dqcontrol.controllers.problem.WarmLevels`
    (:meth:`~dqcontrol.controllers.backends.daqp_dense.DaqpBackend.solve_warm_levels`).
    """

    name: str

    def solve(self, key: object, qp: DenseQP) -> Solution:
        """Solve the dense QP of the level ``key`` (its workspace kept between steps)."""

    def reset(self) -> None:
        """Forget the workspaces and warm starts."""


class BlockBackend(Protocol):
    """Solves a :class:`~dqcontrol.controllers.problem.BlockQP` (one level, ``P`` block
    diagonal): the structured path of the controllers with one priority level.

    The backend specialises on the QP's *structure* (number and size of the blocks, the
    general rows ``C`` and its :attr:`BlockQP.structure` number, the fixed variables): it
    sets a workspace up for a structure once and only updates values while the structure
    stays the same. ``uses_warm_start`` says whether it reads :attr:`BlockQP.warm`.
    Wrappers (fault injection, logging) keep this protocol and forward to the backend.
    """

    name: str
    uses_warm_start: bool

    def solve_blocks(self, qp: BlockQP) -> Solution:
        """Solve a block-diagonal QP."""

    def reset(self) -> None:
        """Forget the workspace and the warm start."""


def _check_name(name: str | None) -> str:
    name = DEFAULT_SOLVER if name is None else name
    if name not in ("daqp", "osqp"):
        raise ParameterError(f"solver must be 'daqp' or 'osqp', got {name!r}")
    return name


def make_backend(name: str | None, settings: dict | None = None) -> Backend:
    """A dense :class:`Backend`: ``"daqp"`` (default) or ``"osqp"``."""
    from dqcontrol.controllers.backends.daqp_dense import DaqpBackend
    from dqcontrol.controllers.backends.osqp_dense import OsqpBackend

    if _check_name(name) == "daqp":
        return DaqpBackend(settings)
    return OsqpBackend(settings)


def make_block_backend(name: str | None, settings: dict | None = None) -> BlockBackend:
    """A :class:`BlockBackend`: ``"daqp"`` (default: :class:`~dqcontrol.controllers.qp_daqp.
    DaqpQP`, DAQP's own settings) or ``"osqp"`` (:class:`~dqcontrol.controllers.qp_solver.
    OsqpQP`, OSQP refined to the exact optimum). Unknown settings are refused here, with the
    list of the solver's own."""
    from dqcontrol.controllers.qp_daqp import DaqpQP
    from dqcontrol.controllers.qp_solver import OsqpQP

    if _check_name(name) == "daqp":
        return DaqpQP(settings=settings)
    return OsqpQP(settings=settings)

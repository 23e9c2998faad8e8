"""The backend protocol: solve a dense QP, keeping a workspace per problem structure."""

from __future__ import annotations

from typing import Protocol

from dqcontrol.controllers.problem import DenseQP, Solution
from dqcontrol.errors import ParameterError

__all__ = ["Backend", "make_backend"]


class Backend(Protocol):
    """Solves ``min ½ zᵀ P z + cᵀ z  s.t.  lower ≤ A z ≤ upper`` with ``A = [I; C]``.

    ``key`` names the problem (e.g. the priority level): a backend keeps one workspace per
    key, set up on the first solve and updated afterwards (warm start: the previous
    active set); a change of shape sets it up again. ``solve`` never raises for a failed
    solve: the :class:`Solution` says so.
    """

    name: str

    def solve(self, key: object, qp: DenseQP) -> Solution: ...

    def reset(self) -> None: ...


def make_backend(name: str | None, settings: dict | None = None) -> Backend:
    """``"daqp"`` (default) or ``"osqp"``."""
    from dqcontrol.controllers.backends.daqp_dense import DaqpBackend
    from dqcontrol.controllers.backends.osqp_dense import OsqpBackend

    if name in (None, "daqp"):
        return DaqpBackend(settings)
    if name == "osqp":
        return OsqpBackend(settings)
    raise ParameterError(f"solver must be 'daqp' or 'osqp', got {name!r}")

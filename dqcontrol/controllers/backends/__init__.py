"""QP backends behind two protocols (docs/theory.md §7.5): dense QPs per priority level
(:class:`Backend`) and single-level QPs with a block-diagonal Hessian (:class:`BlockBackend`,
structure-specialised: :class:`~dqcontrol.controllers.qp_daqp.DaqpQP`,
:class:`~dqcontrol.controllers.qp_solver.OsqpQP`)."""

from dqcontrol.controllers.backends.base import (
    DEFAULT_SOLVER,
    Backend,
    BlockBackend,
    make_backend,
    make_block_backend,
)
from dqcontrol.controllers.backends.daqp_dense import DaqpBackend
from dqcontrol.controllers.backends.osqp_dense import OsqpBackend

__all__ = [
    "DEFAULT_SOLVER",
    "Backend",
    "BlockBackend",
    "DaqpBackend",
    "OsqpBackend",
    "make_backend",
    "make_block_backend",
]

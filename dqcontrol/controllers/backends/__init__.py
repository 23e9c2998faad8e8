"""QP backends behind one protocol (docs/theory.md §7.5)."""

from dqcontrol.controllers.backends.base import Backend, make_backend
from dqcontrol.controllers.backends.daqp_dense import DaqpBackend
from dqcontrol.controllers.backends.osqp_dense import OsqpBackend

__all__ = ["Backend", "DaqpBackend", "OsqpBackend", "make_backend"]

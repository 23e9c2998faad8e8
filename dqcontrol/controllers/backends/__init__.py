"""QP backends behind one contract (docs/theory.md §7.5): :class:`Backend` and its
registry of names (:func:`register_backend`, :func:`make_backend`), DAQP (the default, with
its structure-specialised paths) and OSQP, and :class:`ForwardingBackend` for wrappers."""

from dqcontrol.controllers.backends.base import (
    DEFAULT_SOLVER,
    Backend,
    ForwardingBackend,
    backend_names,
    check_backend_name,
    make_backend,
    register_backend,
)
from dqcontrol.controllers.backends.daqp.backend import DaqpBackend
from dqcontrol.controllers.backends.osqp import OsqpBackend

__all__ = [
    "DEFAULT_SOLVER",
    "Backend",
    "DaqpBackend",
    "ForwardingBackend",
    "OsqpBackend",
    "backend_names",
    "check_backend_name",
    "make_backend",
    "register_backend",
]

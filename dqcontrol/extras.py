"""The optional dependencies, grouped as the package's extras.

The core (``pip install dqcontrol``) holds what the model, the controllers and the kinematic
loop need. The rest comes with an extra:

- ``sim``: MuJoCo, for :class:`~dqcontrol.sim.MujocoSimulation` and everything that steps
  physics (``dqcontrol run --simulator mujoco``, the default, and ``dqcontrol sim-server``),
  and CoACD, which splits a concave collision mesh into the convex parts MuJoCo collides;
- ``viz``: Meshcat and matplotlib, for the viewer, the HTML replays and the figures;
- ``dask``: Dask distributed, for ``dqcontrol table1 --scheduler``;
- ``ros2``: the ROS 2 client library (rclpy) and the message packages, for
  :mod:`dqcontrol.ros2` and ``dqcontrol ros2`` (a sourced ROS 2 installation provides them
  too).

A module of dqcontrol that needs one of them imports it through :func:`require` (or
:func:`lazy_module`, which defers the import to the first use, or catches the
``ImportError`` and raises :func:`missing_extra`), so that a missing extra raises
:class:`~dqcontrol.errors.MissingExtraError` with the command that installs it.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType
from typing import Any

from dqcontrol.errors import MissingExtraError

__all__ = ["EXTRAS", "available", "has_extra", "lazy_module", "missing_extra", "require"]

#: The top-level modules each extra provides.
EXTRAS: dict[str, tuple[str, ...]] = {
    "sim": ("mujoco", "coacd"),
    "viz": ("meshcat", "matplotlib"),
    "dask": ("dask", "distributed"),
    "ros2": (
        "rclpy",
        "sensor_msgs",
        "std_msgs",
        "std_srvs",
        "geometry_msgs",
        "nav_msgs",
        "visualization_msgs",
        "diagnostic_msgs",
    ),
}


def available(module: str) -> bool:
    """Whether ``module`` can be imported, looked up without importing it."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a parent that fails to import; a half-set-up module
        return False


def has_extra(extra: str) -> bool:
    """Whether every module of ``extra`` (a key of :data:`EXTRAS`) can be imported."""
    return all(available(name) for name in EXTRAS[extra])


def missing_extra(module: str, *, extra: str, purpose: str, reason: str = "") -> MissingExtraError:
    """The error for ``module`` missing: what needs it, its extra and the install command.

    Args:
        module: the module's name (``"mujoco"``, ``"matplotlib.figure"``...).
        extra: the extra that installs it (a key of :data:`EXTRAS`).
        purpose: what needs it, for the message (``"the MuJoCo simulation"``).
        reason: the import's own error, appended to the message.
    """
    top = module.partition(".")[0]
    return MissingExtraError(
        f"{purpose} needs {top}, which comes with the [{extra}] extra: "
        f"pip install 'dqcontrol[{extra}]'" + (f" ({reason})" if reason else "")
    )


def require(module: str, *, extra: str, purpose: str) -> ModuleType:
    """Import ``module`` (from the extra ``extra``) or say how to install it.

    Args:
        module: the module's name.
        extra: the extra that installs it (a key of :data:`EXTRAS`).
        purpose: what needs it, for the message.

    Returns:
        The imported module.

    Raises:
        MissingExtraError: the import failed (see :func:`missing_extra`).
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise missing_extra(module, extra=extra, purpose=purpose, reason=str(exc)) from None


class _LazyModule(ModuleType):
    """A module imported by :func:`require` on the first attribute read.

    Each attribute read once is then kept on this object, so later reads cost what a plain
    module's do (the control loops call MuJoCo at every period).
    """

    def __init__(self, module: str, extra: str, purpose: str) -> None:
        super().__init__(module)
        self._dq_extra = (module, extra, purpose)

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__") and attr.endswith("__"):  # copy, pickle and pydoc probes
            raise AttributeError(attr)
        module, extra, purpose = self._dq_extra
        value = getattr(require(module, extra=extra, purpose=purpose), attr)
        setattr(self, attr, value)
        return value


def lazy_module(module: str, *, extra: str, purpose: str) -> Any:
    """A stand-in for ``module`` that imports it (through :func:`require`) on first use.

    ``mujoco = lazy_module("mujoco", extra="sim", purpose="the MuJoCo simulation")`` at the
    top of a file lets the file be imported without MuJoCo; ``mujoco.MjModel`` then either
    works or raises :class:`~dqcontrol.errors.MissingExtraError`.
    """
    return _LazyModule(module, extra, purpose)

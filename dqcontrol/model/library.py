"""Ready-made robots: the thesis's KUKA LBR4p (package data in ``dqcontrol/robots/``, so an
installed wheel carries it) and the Franka Panda of example-robot-data, both loaded through
:meth:`RobotModel.from_urdf`."""

from __future__ import annotations

import atexit
import contextlib
import functools
import importlib.resources
from pathlib import Path

import numpy as np

from dqcontrol.errors import URDFError
from dqcontrol.model.robot import RobotModel

__all__ = ["LBR4P_Q0", "PANDA_Q0", "load_lbr4p", "load_panda", "lbr4p_urdf_path", "panda_urdf_path"]

#: Initial configuration of the experiments [rad] (the thesis does not give its own): the
#: flange points down at about (0.55, -0.21, 0.70) m with its x axis along world +y, so the
#: default-anchored circle (tool xy-plane) is horizontal and the sinusoid runs along +y and
#: oscillates vertically, both well inside the workspace; every joint is ≥ 0.64 rad from its
#: limits and the arm is far from singular (smallest non-zero singular value of J ≈ 0.1).
LBR4P_Q0 = np.array([-0.18, -0.76, -0.29, -1.45, 0.24, -0.97, 1.05])
#: The Panda's usual "ready" posture [rad].
PANDA_Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])

#: Resources extracted to temporary files when the package is not a folder on disk (a zip
#: import); closed at exit.
_EXTRACTED = contextlib.ExitStack()
atexit.register(_EXTRACTED.close)


@functools.cache
def _package_file(*parts: str) -> Path:
    """A real filesystem path of the package data file ``dqcontrol/robots/<parts>``.

    Pinocchio and MuJoCo open files by name, so this must be a path on disk, not just a
    readable resource. An installed (or editable) package is a folder, and
    :func:`importlib.resources.files` then returns a :class:`pathlib.Path` inside it, used
    as it is. Otherwise (the package imported from a zip archive) ``as_file`` extracts the
    file to a temporary one that lives until the interpreter exits.
    """
    resource = importlib.resources.files("dqcontrol") / "robots"
    for part in parts:
        resource = resource / part
    if not resource.is_file():
        raise URDFError(
            f"the package data file dqcontrol/robots/{'/'.join(parts)} is missing from the "
            "installed dqcontrol package; reinstall dqcontrol"
        )
    if isinstance(resource, Path):
        return resource
    return _EXTRACTED.enter_context(importlib.resources.as_file(resource))


def lbr4p_urdf_path() -> Path:
    """Path of the project's LBR4p URDF (``robots/lbr4p/lbr4p.urdf``)."""
    return _package_file("lbr4p", "lbr4p.urdf")


def load_lbr4p(**kwargs) -> RobotModel:
    """The KUKA LBR4p of the thesis, end-effector ``lbr4p_flange`` (= DH frame 7).

    Keyword arguments go to :meth:`RobotModel.from_urdf` (``base``, ``tool`` ...).
    """
    return RobotModel.from_urdf(lbr4p_urdf_path(), "lbr4p_flange", **kwargs)


def panda_urdf_path() -> tuple[Path, Path]:
    """Path of example-robot-data's Panda URDF and the folder its ``package://`` URIs use."""
    try:
        import example_robot_data as erd
    except ImportError as exc:  # pragma: no cover - it is a dependency
        raise URDFError(f"example-robot-data is not installed: {exc}") from None
    robots = Path(erd.getModelPath("panda_description/urdf/panda.urdf"))
    return robots / "panda_description" / "urdf" / "panda.urdf", robots.parent.parent


def load_panda(ee_frame: str = "panda_hand_tcp", **kwargs) -> RobotModel:
    """The Franka Panda of example-robot-data with its fingers locked (7 joints).

    ``ee_frame`` defaults to the hand's tool centre point; ``panda_hand`` is the flange of
    the hand.
    """
    path, package_dir = panda_urdf_path()
    kwargs.setdefault("locked_joints", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0})
    kwargs.setdefault("package_dirs", [package_dir])
    return RobotModel.from_urdf(path, ee_frame, **kwargs)

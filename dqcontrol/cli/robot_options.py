"""The robot of a command line: ``--robot``, ``--ee-frame``, ``--lock``, ``--package-dir`` and
``--tool``, shared by every subcommand that builds a robot, and the same robot rebuilt from
a saved run's ``meta``.

``--limits`` puts a limit profile on the robot (a shipped name or a ``FILE.toml``,
:mod:`dqcontrol.model.limit_profile`); the run's ``meta`` records it.

``--robot`` names the thesis's LBR4p (``lbr4p``), the Franka Panda of example-robot-data
with its fingers locked (``panda``), any robot of example-robot-data (``erd:NAME``) or a
URDF file. Errors in these options reach the user as :class:`ValueError` messages that
name the option; the subcommands turn them into argparse errors (exit code 2).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

__all__ = [
    "check_mujoco_meshes",
    "ERD_PREFIX",
    "RobotRequest",
    "add_limits_option",
    "add_robot_options",
    "limits_help",
    "erd_robot_names",
    "erd_urdf",
    "load_robot",
    "parse_lock",
    "parse_package_dir",
    "parse_tool",
    "robot_label",
]

#: ``--robot erd:NAME`` names a robot of example-robot-data.
ERD_PREFIX = "erd:"

ROBOT_HELP = (
    "lbr4p (default), panda (example-robot-data's Panda, fingers locked), erd:NAME (any "
    "robot of example-robot-data, e.g. erd:ur5) or the path of a URDF file"
)


# ---------------------------------------------------------------------- option types
def parse_lock(text: str) -> tuple[str, float]:
    """``JOINT=VALUE`` → ``(joint, value)``; the value in [rad] (or [m], prismatic)."""
    name, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not sep or not name.strip() or not math.isfinite(number):
        raise argparse.ArgumentTypeError(
            f"expected JOINT=VALUE with a finite VALUE [rad or m], e.g. "
            f"panda_finger_joint1=0, got {text!r}"
        )
    return name.strip(), number


def parse_tool(text: str) -> tuple[float, ...]:
    """``X,Y,Z[,RX,RY,RZ]``: tool offset in the flange frame [m] and roll-pitch-yaw [rad]."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) not in (3, 6) or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(
            "expected 3 or 6 comma-separated finite numbers X,Y,Z[,RX,RY,RZ] (offset in the "
            f"flange frame [m], then roll, pitch, yaw [rad]), got {text!r}"
        )
    return values


def parse_package_dir(text: str) -> str:
    """An existing folder (where ``package://`` mesh URIs resolve), as an absolute path."""
    path = Path(text).expanduser()
    if not path.is_dir():
        raise argparse.ArgumentTypeError(
            f"{text!r} is not an existing folder; give the folder that holds the packages "
            "named in the URDF's package:// URIs"
        )
    return str(path.resolve())


def limits_help() -> str:
    """The help of ``--limits``, listing the shipped profiles."""
    from dqcontrol.model.limit_profile import profile_names

    return (
        "joint limit profile of the robot: urdf (the URDF's own limits, default), "
        f"{', '.join(n for n in profile_names() if n != 'urdf')}, or a FILE.toml"
    )


def add_limits_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add ``--limits NAME|FILE.toml``."""
    parser.add_argument("--limits", metavar="NAME|FILE.toml", default=None, help=limits_help())


def add_robot_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add ``--robot``, ``--ee-frame``, ``--lock``, ``--package-dir``, ``--tool`` and
    ``--limits``."""
    parser.add_argument("--robot", default="lbr4p", metavar="ROBOT", help=ROBOT_HELP)
    parser.add_argument(
        "--ee-frame",
        metavar="FRAME",
        help="end-effector frame (required with erd:NAME or a URDF path; default: "
        "lbr4p_flange, panda_hand_tcp)",
    )
    parser.add_argument(
        "--lock",
        type=parse_lock,
        action="append",
        default=[],
        metavar="JOINT=VALUE",
        help="hold a joint at a position [rad or m] and leave it out of the control, e.g. "
        "--lock panda_finger_joint1=0 (repeatable)",
    )
    parser.add_argument(
        "--package-dir",
        type=parse_package_dir,
        action="append",
        default=[],
        metavar="DIR",
        help="a folder where the URDF's package:// mesh URIs resolve (repeatable)",
    )
    parser.add_argument(
        "--tool",
        type=parse_tool,
        metavar="X,Y,Z[,RX,RY,RZ]",
        help="control a tool frame offset from the end-effector frame: X,Y,Z [m] in that "
        "frame, then roll, pitch, yaw [rad] (e.g. --tool 0,0,0.1)",
    )
    add_limits_option(parser)


# ---------------------------------------------------------------------- the request
@dataclass(frozen=True)
class RobotRequest:
    """What the robot options ask for.

    Attributes:
        spec: ``lbr4p``, ``panda``, ``erd:NAME`` or a URDF path.
        ee_frame: the end-effector frame (``None``: the robot's default, if it has one).
        locked_joints: ``(joint, position)`` pairs [rad or m].
        package_dirs: folders for ``package://`` URIs.
        tool: ``(x, y, z[, roll, pitch, yaw])`` [m, rad] from the end-effector frame.
        limits: the limit profile (a name or a ``FILE.toml``; ``None``: the URDF's).
    """

    spec: str = "lbr4p"
    ee_frame: str | None = None
    locked_joints: tuple[tuple[str, float], ...] = ()
    package_dirs: tuple[str, ...] = ()
    tool: tuple[float, ...] | None = None
    limits: str | None = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RobotRequest:
        """The request of parsed options (:func:`add_robot_options`)."""
        return cls(
            spec=args.robot,
            ee_frame=args.ee_frame,
            locked_joints=tuple(args.lock),
            package_dirs=tuple(args.package_dir),
            tool=args.tool,
            limits=getattr(args, "limits", None),
        )

    @classmethod
    def from_meta(cls, meta: dict) -> RobotRequest:
        """The request that rebuilds the robot of a saved run (:meth:`to_meta`)."""
        kind = meta.get("robot")
        if not isinstance(kind, str):
            raise ValueError(f"the saved run does not name its robot (meta 'robot': {kind!r})")
        specs = {"urdf": str(meta.get("urdf")), "erd": ERD_PREFIX + str(meta.get("erd"))}
        spec = specs.get(kind, kind)
        tool = meta.get("tool")
        return cls(
            spec=spec,
            ee_frame=meta.get("ee_frame"),
            locked_joints=tuple((k, float(v)) for k, v in meta.get("locked_joints", {}).items()),
            package_dirs=tuple(meta.get("package_dirs", ())),
            tool=tuple(float(v) for v in tool) if tool is not None else None,
            limits=meta.get("limits"),
        )

    def to_meta(self, kind: dict, ee_frame: str) -> dict:
        """``meta`` entries that rebuild this robot; ``kind`` says which robot it is."""
        meta = {**kind, "ee_frame": ee_frame}
        if self.locked_joints:
            meta["locked_joints"] = dict(self.locked_joints)
        if self.package_dirs:
            meta["package_dirs"] = list(self.package_dirs)
        if self.tool is not None:
            meta["tool"] = list(self.tool)
        if self.limits is not None:
            meta["limits"] = _profile_meta(self.limits)
        return meta


def _profile_meta(limits: str) -> str:
    """A profile's name, or its file's absolute path (rebuilt from another folder)."""
    return str(Path(limits).expanduser().resolve()) if limits.endswith(".toml") else limits


def robot_label(meta: dict) -> str:
    """A short name of the robot of ``meta`` for folder names and titles."""
    kind = meta.get("robot")
    if kind == "erd":
        return str(meta.get("erd"))
    if kind == "urdf":
        return Path(str(meta.get("urdf"))).stem
    return str(kind)


# ---------------------------------------------------------------------- example-robot-data
def erd_robot_names() -> list[str]:
    """The robots of example-robot-data that have a URDF, sorted."""
    from example_robot_data.robots_loader import ROBOTS

    return sorted(name for name, loader in ROBOTS.items() if loader.urdf_filename)


def erd_urdf(name: str) -> tuple[Path, Path]:
    """The URDF of example-robot-data's robot ``name`` and the folder its ``package://`` URIs
    resolve in; :class:`ValueError` listing the names that exist for an unknown one."""
    from example_robot_data import getModelPath
    from example_robot_data.robots_loader import ROBOTS

    loader = ROBOTS.get(name)
    if loader is None or not loader.urdf_filename:
        raise ValueError(
            f"--robot: example-robot-data has no robot {name!r} with a URDF; its robots: "
            f"{', '.join(erd_robot_names())}"
        )
    relative = Path(loader.path) / loader.urdf_subpath / loader.urdf_filename
    models = Path(getModelPath(str(relative)))
    return models / relative, models.parent.parent


# ---------------------------------------------------------------------- loading
def _tool_se3(tool: tuple[float, ...] | None):
    import numpy as np
    import pinocchio as pin

    if tool is None:
        return None
    roll, pitch, yaw = tool[3:] if len(tool) == 6 else (0.0, 0.0, 0.0)
    return pin.SE3(pin.rpy.rpyToMatrix(roll, pitch, yaw), np.array(tool[:3], dtype=float))


def _urdf_of(request: RobotRequest) -> tuple[Path, dict, list[str]]:
    """The URDF file of a request that is not ``lbr4p``/``panda``, its ``meta`` kind and the
    package folders to search."""
    dirs = list(request.package_dirs)
    if request.spec.lower().startswith(ERD_PREFIX):
        name = request.spec[len(ERD_PREFIX) :].strip()
        path, package_dir = erd_urdf(name)
        return path, {"robot": "erd", "erd": name}, [*dirs, str(package_dir)]
    path = Path(request.spec).expanduser()
    if not path.is_file():
        raise ValueError(
            f"--robot: {request.spec!r} is neither lbr4p, panda, erd:NAME nor an existing URDF file"
        )
    return path, {"robot": "urdf", "urdf": str(path.resolve())}, dirs


#: The shipped robots: their URDF loader, default end-effector frame, start posture (by
#: joint name) and the joints held fixed unless ``--lock`` says otherwise.
_SHIPPED = {
    "lbr4p": ("lbr4p_flange", "lbr4p_joint_{}", "LBR4P_Q0", {}),
    "panda": (
        "panda_hand_tcp",
        "panda_joint{}",
        "PANDA_Q0",
        {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0},
    ),
}


def _link_names(path: Path) -> list[str]:
    import xml.etree.ElementTree as ET

    try:
        return [link.get("name", "") for link in ET.parse(path).getroot().findall("link")]
    except (ET.ParseError, OSError):
        return []


class _Resolved(NamedTuple):
    """A request made concrete: what :meth:`RobotModel.from_urdf` needs, and more."""

    path: Path  # the URDF file
    kind: dict  # which robot, for the meta ({"robot": ..., "urdf"/"erd": ...})
    package_dirs: list[str]
    ee_frame: str
    locked_joints: dict[str, float]  # [rad or m]
    posture: dict[str, float]  # start posture by joint name [rad] (shipped robots)


def _resolve(request: RobotRequest) -> _Resolved:
    """The URDF, frame, locks and start posture a request stands for."""
    import dqcontrol.model as models

    key = request.spec.strip().lower()
    locked = dict(request.locked_joints)
    if key in _SHIPPED:
        frame, joint, q0_name, default_locks = _SHIPPED[key]
        if key == "lbr4p":
            path, dirs = models.lbr4p_urdf_path(), list(request.package_dirs)
        else:
            path, package_dir = models.panda_urdf_path()
            dirs = [*request.package_dirs, str(package_dir)]
        q0 = getattr(models, q0_name)
        posture = {joint.format(i + 1): float(v) for i, v in enumerate(q0)}
        frame = request.ee_frame or frame
        return _Resolved(path, {"robot": key}, dirs, frame, default_locks | locked, posture)
    path, kind, dirs = _urdf_of(request)
    if not request.ee_frame:
        raise ValueError(
            "--ee-frame is required with erd:NAME or a URDF path (the frame to control); "
            f"links of this robot: {_link_names(path)}"
        )
    return _Resolved(path, kind, dirs, request.ee_frame, locked, {})


def check_mujoco_meshes(parser: argparse.ArgumentParser, robot) -> None:
    """A parser error (exit 2) when MuJoCo cannot read one of ``robot``'s collision meshes
    (a COLLADA file: the robot runs in the kinematic loop, not in MuJoCo)."""
    from dqcontrol.errors import URDFError
    from dqcontrol.sim.mjcf_builder import prepare_urdf_xml

    if robot.source is None:
        return
    try:
        prepare_urdf_xml(robot.source)
    except URDFError as exc:
        parser.error(f"--simulator mujoco: {exc} (--simulator kinematic runs this robot)")


def load_robot(request: RobotRequest):
    """The robot of a request, its start posture ``q0`` [rad] and the ``meta`` that
    rebuilds it (:meth:`RobotRequest.from_meta`).

    ``q0`` is the shipped robot's start posture, else the middle of each joint's limits
    (0 for a joint without limits). Raises :class:`ValueError` naming the option at fault.
    """
    import numpy as np

    from dqcontrol.errors import FrameError, ParameterError, URDFError
    from dqcontrol.model import RobotModel

    source = _resolve(request)
    try:
        robot = RobotModel.from_urdf(
            source.path,
            source.ee_frame,
            tool=_tool_se3(request.tool),
            locked_joints=source.locked_joints or None,
            package_dirs=source.package_dirs,
        )
    except FrameError as exc:
        option = "--lock" if str(exc).startswith("cannot lock") else "--ee-frame"
        raise ValueError(f"{option}: {exc}") from None
    except (URDFError, ParameterError) as exc:
        raise ValueError(f"--robot {request.spec}: {exc}") from None
    if request.limits is not None:
        try:
            robot = robot.with_limits(request.limits)
        except ParameterError as exc:
            raise ValueError(f"--limits: {exc}") from None
    lim = robot.limits
    bounded = np.isfinite(lim.q_min) & np.isfinite(lim.q_max)
    middle = np.zeros(robot.nq)
    middle[bounded] = 0.5 * (lim.q_min[bounded] + lim.q_max[bounded])
    names = zip(robot.joint_names, middle, strict=True)
    q0 = np.array([source.posture.get(name, mid) for name, mid in names])
    return robot, q0, request.to_meta(source.kind, source.ee_frame)


def robot_from_meta(meta: dict):
    """The robot of a saved run, rebuilt from its ``meta`` (written by ``dqcontrol run``).

    Raises:
        ParameterError: the meta names no robot, or the robot cannot be rebuilt.
    """
    from dqcontrol.errors import ParameterError

    if meta.get("robot") is None:
        raise ParameterError(
            "this run does not say which robot it used (no 'robot' in its meta); it was "
            "not written by 'dqcontrol run'"
        )
    try:
        robot, _, _ = load_robot(RobotRequest.from_meta(meta))
    except ValueError as exc:
        raise ParameterError(f"cannot rebuild the robot of this run: {exc}") from None
    return robot

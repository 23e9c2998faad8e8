"""Robot limit profiles: the joint limits a real arm's controller enforces, as data.

A profile is a small TOML file (the shipped ones in ``dqcontrol/robots/profiles/``, or any
``FILE.toml`` a user writes in the same format): per joint, by name and in the robot's
order, the position range [rad], the velocity [rad/s], acceleration [rad/s²] and jerk
[rad/s³] limits of the commanded joint velocity (``"unbounded"`` where the vendor gives no
figure), the control periods the robot's interface accepts [s], and the source of the
figures. The profile ``urdf`` holds no figures: it stands for the URDF's own limits (no
acceleration or jerk limit), today's behaviour and the default.

A profile is applied to a robot model (:meth:`~dqcontrol.model.robot.RobotModel.with_limits`,
or ``RobotModel.from_urdf(..., limits=NAME)``) and never to a controller: one robot
description feeds the controllers, the simulator's reflexes, the checker and the viewer, so
they cannot disagree about the limits (docs/user_guide.md, "Robot limit profiles").
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from dqcontrol.errors import ParameterError

__all__ = [
    "LimitProfile",
    "ProfileError",
    "load_profile",
    "profile_names",
    "URDF_PROFILE",
    "fitted_limits",
]

#: The name of the profile that keeps the URDF's own limits.
URDF_PROFILE = "urdf"
#: Relative tolerance of the comparison of a profile's entry with the URDF's.
URDF_TOLERANCE = 1e-7
#: The per-joint keys of a profile, their unit, and whether "unbounded" is accepted.
_ENTRIES = (
    ("velocity_rad_s", "rad/s", False),
    ("acceleration_rad_s2", "rad/s²", True),
    ("jerk_rad_s3", "rad/s³", True),
)
_UNBOUNDED = "unbounded"


class ProfileError(ParameterError):
    """A limit profile that cannot be used: unknown name, bad file, or one that does not
    fit the robot (looser than its URDF, other joints); the message says which entry."""


@dataclass(frozen=True)
class LimitProfile:
    """The limits of one robot, per joint (arrays in the order of :attr:`joint_names`).

    Attributes:
        name: the profile's name (a shipped name, or the file's).
        source: where the figures come from (a vendor document).
        joint_names: the joints, in order; empty for the ``urdf`` profile.
        q_min, q_max: position range [rad].
        qd_max: velocity limit [rad/s].
        qdd_max: acceleration limit [rad/s²]; ``inf``: none given.
        qddd_max: jerk limit of the commanded velocity [rad/s³]; ``inf``: none given.
        periods_s: the control periods the robot accepts [s]; empty: any.
        path: the file read.
    """

    name: str
    source: str
    joint_names: tuple[str, ...]
    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray
    qddd_max: np.ndarray
    periods_s: tuple[float, ...] = ()
    path: str = ""

    @property
    def is_urdf(self) -> bool:
        """Whether this is the ``urdf`` profile (the URDF's own limits, no figures)."""
        return not self.joint_names

    def __eq__(self, other: object) -> bool:
        """The same name, source, joints, periods and file, and every limit equal."""
        if not isinstance(other, LimitProfile):
            return NotImplemented
        arrays = ("q_min", "q_max", "qd_max", "qdd_max", "qddd_max")
        same = (self.name, self.source, self.joint_names, self.periods_s, self.path) == (
            other.name, other.source, other.joint_names, other.periods_s, other.path,
        )  # fmt: skip
        return same and all(np.array_equal(getattr(self, a), getattr(other, a)) for a in arrays)

    __hash__ = None  # type: ignore[assignment]  # mutable arrays: not hashable

    def accepts_period(self, period_s: float) -> bool:
        """Whether the robot accepts the control period ``period_s`` [s] (to 1e-9 s)."""
        return not self.periods_s or any(abs(period_s - p) <= 1e-9 for p in self.periods_s)


def _shipped() -> dict[str, Path]:
    folder = resources.files("dqcontrol") / "robots" / "profiles"
    return {
        Path(entry.name).stem: Path(str(entry))
        for entry in folder.iterdir()
        if entry.name.endswith(".toml")
    }


def profile_names() -> list[str]:
    """The names of the shipped profiles, sorted (``urdf`` among them)."""
    return sorted(_shipped())


def load_profile(name_or_path: str | os.PathLike) -> LimitProfile:
    """The shipped profile ``name_or_path`` or the profile in that ``.toml`` file.

    Raises:
        ProfileError: an unknown name (the message lists the shipped ones), an unreadable
            file, a missing, non-numeric or negative entry, a position range with
            ``min > max``.
    """
    text = str(name_or_path)
    shipped = _shipped()
    if text in shipped:
        path = shipped[text]
    elif text.endswith(".toml"):
        path = Path(text).expanduser()
        if not path.is_file():
            raise ProfileError(f"limit profile file {text!r} does not exist")
    else:
        raise ProfileError(
            f"unknown limit profile {text!r}; the profiles: {', '.join(profile_names())} "
            "(or the path of a FILE.toml)"
        )
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ProfileError(f"limit profile {str(path)!r} cannot be read: {exc}") from None
    return _parse(data, str(path), path.stem)


def _parse(data: dict, path: str, stem: str) -> LimitProfile:
    where = f"limit profile {path!r}"
    name = str(data.get("name", stem))
    source = data.get("source")
    if not isinstance(source, str) or not source.strip():
        raise ProfileError(f"{where}: 'source' (the document the figures come from) is missing")
    periods = _periods(data.get("control_periods_s"), where)
    if data.get("urdf") is True:
        empty = np.zeros(0)
        return LimitProfile(
            name, source.strip(), (), empty, empty, empty, empty, empty, periods, path
        )
    joints = data.get("joint")
    if not isinstance(joints, list) or not joints:
        raise ProfileError(f"{where}: no [[joint]] tables (one per joint, in order)")
    rows = [_joint(entry, k, where) for k, entry in enumerate(joints)]
    names = tuple(r[0] for r in rows)
    if len(set(names)) != len(names):
        raise ProfileError(f"{where}: a joint is named twice in {list(names)}")
    q_min, q_max, qd_max, qdd_max, qddd_max = (
        np.array([r[i] for r in rows], dtype=float) for i in range(1, 6)
    )
    return LimitProfile(
        name, source.strip(), names, q_min, q_max, qd_max, qdd_max, qddd_max, periods, path
    )


def _periods(value, where: str) -> tuple[float, ...]:
    if value == "any":
        return ()
    ok = isinstance(value, list) and value
    numbers = [v for v in value if _is_number(v)] if ok else []
    if not ok or len(numbers) != len(value) or min(numbers) <= 0:
        raise ProfileError(
            f"{where}: 'control_periods_s' must be a list of periods > 0 [s] or \"any\", "
            f"got {value!r}"
        )
    return tuple(float(v) for v in numbers)


def _is_number(value) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _joint(entry, k: int, where: str) -> tuple[str, float, float, float, float, float]:
    """``(name, q_min, q_max, qd_max, qdd_max, qddd_max)`` of the ``k``-th joint table."""
    if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
        raise ProfileError(f"{where}: joint #{k + 1} has no 'name'")
    joint = entry["name"]
    here = f"{where}, joint {joint!r}"
    rng = entry.get("position_rad")
    if "position_rad" not in entry:
        raise ProfileError(f"{here}: the entry 'position_rad' = [min, max] [rad] is missing")
    if not (isinstance(rng, list) and len(rng) == 2 and all(_is_number(v) for v in rng)):
        raise ProfileError(f"{here}: 'position_rad' must be [min, max] [rad], got {rng!r}")
    if rng[0] > rng[1]:
        raise ProfileError(f"{here}: 'position_rad' has min {rng[0]} > max {rng[1]} [rad]")
    values = [_entry(entry, key, unit, unbounded, here) for key, unit, unbounded in _ENTRIES]
    return (joint, float(rng[0]), float(rng[1]), *values)


def _entry(entry: dict, key: str, unit: str, unbounded: bool, here: str) -> float:
    if key not in entry:
        also = f' or "{_UNBOUNDED}"' if unbounded else ""
        raise ProfileError(f"{here}: the entry '{key}' [{unit}] is missing (a number > 0{also})")
    value = entry[key]
    if unbounded and value == _UNBOUNDED:
        return math.inf
    if not _is_number(value) or value <= 0:
        also = f' or "{_UNBOUNDED}"' if unbounded else ""
        raise ProfileError(f"{here}: '{key}' must be a number > 0 [{unit}]{also}, got {value!r}")
    return float(value)


def fitted_limits(
    profile: LimitProfile, joint_names: list[str], urdf: tuple[np.ndarray, ...]
) -> tuple[np.ndarray, ...]:
    """``(q_min, q_max, qd_max, qdd_max, qddd_max)`` of ``profile`` in the order of a robot's
    ``joint_names``, checked against the robot's URDF limits ``urdf = (q_min, q_max,
    qd_max)``; the ``urdf`` profile gives those with unbounded acceleration and jerk.

    Raises:
        ProfileError: the profile names other joints than the robot (both lists given), or
            is looser than the URDF in an entry (the joint, the entry and both values).
    """
    n = len(joint_names)
    if profile.is_urdf:
        return (*(np.array(a, dtype=float) for a in urdf), np.full(n, np.inf), np.full(n, np.inf))
    if sorted(profile.joint_names) != sorted(joint_names):
        raise ProfileError(
            f"limit profile {profile.name!r} is for the joints {list(profile.joint_names)}; "
            f"this robot's joints are {list(joint_names)}"
        )
    order = [profile.joint_names.index(name) for name in joint_names]
    mine = tuple(
        np.array(a[order], dtype=float)
        for a in (profile.q_min, profile.q_max, profile.qd_max, profile.qdd_max, profile.qddd_max)
    )
    _check_within(profile.name, joint_names, mine[:3], urdf)
    return mine


def _check_within(name: str, joints, mine: tuple[np.ndarray, ...], urdf) -> None:
    """:class:`ProfileError` at the first entry of ``mine`` looser than the URDF's (to a
    relative :data:`URDF_TOLERANCE`: a URDF's figures are written to about 8 digits, e.g.
    π as 3.14159265)."""
    entries = (
        ("position min", "rad", -1.0),
        ("position max", "rad", 1.0),
        ("velocity", "rad/s", 1.0),
    )
    for (entry, unit, sign), values, limits in zip(entries, mine, urdf, strict=True):
        for j, (value, limit) in enumerate(zip(values, limits, strict=True)):
            if unit == "rad/s" and not limit > 0.0:
                continue  # the URDF gives no velocity limit: any profile's is tighter
            slack = URDF_TOLERANCE * max(1.0, abs(limit)) if math.isfinite(limit) else 0.0
            if sign * value > sign * limit + slack:
                raise ProfileError(
                    f"limit profile {name!r} is looser than the URDF: joint {joints[j]!r}, "
                    f"{entry} {value:.6g} {unit} in the profile, {limit:.6g} {unit} in the URDF"
                )

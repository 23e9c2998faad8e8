"""The nodes' parameters, checked before anything starts: one clear line per bad value.

The nodes take ROS 2 parameters (``--ros-args -p name:=value``, a launch file's
``parameters``); rclpy hands them over as a dict of plain values, and
:meth:`ControlParams.from_values` and :meth:`SimParams.from_values` turn that dict into a
frozen record or raise :class:`~dqcontrol.errors.ParameterError` naming the parameter, what
it got and what it takes. Unknown names are refused too (a typo must not silently fall back
to a default). docs/ros2.md lists every parameter.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, TypeVar

from dqcontrol.errors import ParameterError

__all__ = ["ControlParams", "SimParams"]

_P = TypeVar("_P", bound="_Params")


def _bad(name: str, value: object, wants: str) -> ParameterError:
    return ParameterError(f"parameter '{name}' must be {wants}, got {value!r}")


def _coerce(name: str, value: object, default: object) -> object:
    """``value`` as the type of ``default`` (a number for a float, a list of strings...)."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise _bad(name, value, "true or false")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise _bad(name, value, "an integer")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _bad(name, value, "a number")
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise _bad(name, value, "a string")
        return value
    if isinstance(default, tuple):
        return _sequence(name, value, default)
    raise AssertionError(f"no rule for the type of {name}")  # pragma: no cover


def _sequence(name: str, value: object, default: tuple) -> tuple:
    if isinstance(value, str | bytes) or not hasattr(value, "__iter__"):
        raise _bad(name, value, "a list")
    items = tuple(value)
    want_float = name in _FLOAT_LISTS
    for item in items:
        ok = (
            isinstance(item, int | float) and not isinstance(item, bool)
            if want_float
            else (isinstance(item, str))
        )
        if not ok:
            raise _bad(name, value, "a list of numbers" if want_float else "a list of strings")
    return tuple(float(v) for v in items) if want_float else items


_FLOAT_LISTS = {"q0"}


def _choice(name: str, value: str, options: tuple[str, ...]) -> None:
    if value not in options:
        raise _bad(name, value, "one of " + ", ".join(repr(o) for o in options))


def _positive(name: str, value: float, unit: str, *, allow_zero: bool = False) -> None:
    ok = math.isfinite(value) and (value >= 0.0 if allow_zero else value > 0.0)
    if not ok:
        raise _bad(name, value, f"finite and {'≥' if allow_zero else '>'} 0 [{unit}]")


def _topic(name: str, value: str) -> None:
    if not value or any(c.isspace() for c in value):
        raise _bad(name, value, "a topic name such as /joint_states")


@dataclass(frozen=True)
class _Params:
    """Shared parsing: defaults from the fields, then each class's :meth:`_check`."""

    @classmethod
    def from_values(cls: type[_P], values: Mapping[str, Any]) -> _P:
        """The parameters of ``values`` (name → value), the defaults for the others.

        Raises:
            ParameterError: an unknown name, a value of the wrong type or out of range.
        """
        known = {f.name: f.default for f in fields(cls)}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ParameterError(
                f"unknown parameter {unknown[0]!r}; the parameters are: {', '.join(known)}"
            )
        given = {k: _coerce(k, v, known[k]) for k, v in values.items()}
        params = cls(**given)
        params._check()
        return params

    def _check(self) -> None:  # pragma: no cover - each node's class has its own
        raise NotImplementedError


@dataclass(frozen=True)
class ControlParams(_Params):
    """The control node's parameters (docs/ros2.md has the table)."""

    robot_description_file: str = ""
    robot_description_topic: str = "/robot_description"
    ee_frame: str = ""
    joints: tuple[str, ...] = ()
    locked_joints: tuple[str, ...] = ()
    controller: str = "pf"
    period_s: float = 0.01
    task: str = "circle"
    duration_s: float = 2.0
    mode: str = "wall"
    command_interface: str = "velocity"
    command_topic: str = "/forward_velocity_controller/commands"
    joint_states_topic: str = "/joint_states"
    stale_periods: int = 3
    max_lateness_s: float = 0.0
    realtime_priority: int = 0
    state_timeout_s: float = 1.0
    wait_s: float = 30.0
    servo_time_constant_s: float = 0.0
    path_start_tolerance_m: float = 0.01
    status_every: int = 1
    save_run: str = ""
    exit_when_done: bool = False

    def _check(self) -> None:
        from dqcontrol.registry import controller_spec

        if not self.ee_frame:
            raise _bad("ee_frame", self.ee_frame, "the end-effector frame (a link of the URDF)")
        try:
            controller_spec(self.controller)
        except ParameterError as exc:
            raise ParameterError(f"parameter 'controller': {exc}") from None
        _choice("task", self.task, ("circle", "sinusoid", "path"))
        _choice("mode", self.mode, ("wall", "stepped"))
        _choice("command_interface", self.command_interface, ("velocity", "position"))
        for name in ("period_s", "duration_s", "state_timeout_s", "wait_s"):
            _positive(name, getattr(self, name), "s")
        _positive("servo_time_constant_s", self.servo_time_constant_s, "s", allow_zero=True)
        _positive("path_start_tolerance_m", self.path_start_tolerance_m, "m")
        _positive("max_lateness_s", self.max_lateness_s, "s", allow_zero=True)
        if self.realtime_priority:
            from dqcontrol.sim.priority import check_priority

            try:
                check_priority(self.realtime_priority)
            except ParameterError as exc:
                raise ParameterError(f"parameter 'realtime_priority': {exc}") from None
        for name in ("stale_periods", "status_every"):
            if getattr(self, name) < 1:
                raise _bad(name, getattr(self, name), "an integer ≥ 1")
        for name in ("robot_description_topic", "command_topic", "joint_states_topic"):
            _topic(name, getattr(self, name))
        self.locks()

    def locks(self) -> dict[str, float]:
        """``locked_joints`` (``NAME=VALUE`` strings) as name → position [rad or m]."""
        return _locks(self.locked_joints)


def _locks(items: tuple[str, ...]) -> dict[str, float]:
    locks = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or not name.strip() or not math.isfinite(number):
            raise _bad("locked_joints", item, "NAME=VALUE entries with a finite VALUE")
        locks[name.strip()] = number
    return locks


@dataclass(frozen=True)
class SimParams(_Params):
    """The simulated robot node's parameters (docs/ros2.md has the table)."""

    robot: str = "lbr4p"
    ee_frame: str = ""
    locked_joints: tuple[str, ...] = ()
    q0: tuple[float, ...] = ()
    period_s: float = 0.01
    mode: str = "wall"
    command_interface: str = "velocity"
    command_topic: str = "/forward_velocity_controller/commands"
    joint_states_topic: str = "/joint_states"
    robot_description_topic: str = "/robot_description"
    motor: str = "velocity"
    mute_after: int = -1
    report_file: str = ""

    def _check(self) -> None:
        _choice("mode", self.mode, ("wall", "stepped"))
        _choice("command_interface", self.command_interface, ("velocity", "position"))
        _choice("motor", self.motor, ("velocity", "torque"))
        _positive("period_s", self.period_s, "s")
        if not all(math.isfinite(v) for v in self.q0):
            raise _bad("q0", list(self.q0), "finite joint positions [rad]")
        for name in ("command_topic", "joint_states_topic", "robot_description_topic"):
            _topic(name, getattr(self, name))
        self.locks()

    def locks(self) -> dict[str, float]:
        """``locked_joints`` (``NAME=VALUE`` strings) as name → position [rad or m]."""
        return _locks(self.locked_joints)

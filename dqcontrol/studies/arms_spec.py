"""The ``arms`` experiment's part of a study file: the arms, their starts and the tasks.

``[arms]`` gives ``periods_s`` and ``simulators`` (the grid's other axes), ``[[arms.robots]]``
the arms (``name``, ``robot``: ``lbr4p``, ``panda`` or ``erd:NAME`` as ``dqcontrol run
--robot`` takes it, ``ee_frame``, ``lock`` as a table of joint positions, and one start per
kind: ``nominal_q0_rad``, ``singular_q0_rad``; a shipped robot's nominal start defaults to
its own), and ``[[arms.tasks]]`` the tasks (``name``, ``trajectory``: a ``[[trajectories]]``
entry's name, ``start``: ``nominal`` or ``singular``).
"""

from __future__ import annotations

from dataclasses import dataclass

from dqcontrol.studies.reader import TableReader

__all__ = ["START_KINDS", "ArmSpec", "ArmsSettings", "TaskSpec", "read_arms_settings"]

#: The starts an arm gives: an ordinary posture, and one near a singular configuration.
START_KINDS = ("nominal", "singular")
#: The closed loops of the grid.
_SIMULATORS = ("kinematic", "mujoco")


@dataclass(frozen=True)
class ArmSpec:
    """One arm of the study.

    Attributes:
        name: its label in tables and file names.
        robot: ``lbr4p``, ``panda`` or ``erd:NAME``.
        ee_frame: the controlled frame (``None``: the shipped robot's).
        locked: ``(joint, position)`` pairs held fixed [rad or m].
        starts: ``(kind, q0 [rad] or None)`` pairs (``None``: the shipped robot's posture).
    """

    name: str
    robot: str
    ee_frame: str | None
    locked: tuple[tuple[str, float], ...]
    starts: tuple[tuple[str, tuple[float, ...] | None], ...]

    def start(self, kind: str) -> tuple[float, ...] | None:
        """The start configuration of ``kind`` (``None``: the shipped posture)."""
        return dict(self.starts)[kind]


@dataclass(frozen=True)
class TaskSpec:
    """A task: a trajectory entry run from one of each arm's starts."""

    name: str
    trajectory: str
    start: str


@dataclass(frozen=True)
class ArmsSettings:
    """The ``[arms]`` table, read.

    Attributes:
        arms, tasks: the arms and the tasks, in the table's order.
        periods_s: control periods ``T`` [s].
        simulators: closed loops (``kinematic``, ``mujoco``).
        max_time_factor: a run stops at this many times ``T_tot``.
    """

    arms: tuple[ArmSpec, ...]
    tasks: tuple[TaskSpec, ...]
    periods_s: tuple[float, ...]
    simulators: tuple[str, ...]
    max_time_factor: float = 3.0

    def arm(self, name: str) -> ArmSpec:
        """The arm called ``name``."""
        return next(a for a in self.arms if a.name == name)

    def task(self, name: str) -> TaskSpec:
        """The task called ``name``."""
        return next(t for t in self.tasks if t.name == name)


def _read_arm(reader: TableReader) -> ArmSpec:
    name = reader.take("name", "str")
    robot = reader.take("robot", "str")
    shipped = robot in ("lbr4p", "panda")
    ee_frame = reader.take("ee_frame", "str", None)
    if ee_frame is None and not shipped:
        raise reader.error("ee_frame", f"missing; {robot} needs the frame to control")
    lock = reader.take("lock", "table", {})
    bad = [k for k, v in lock.items() if isinstance(v, bool) or not isinstance(v, (int, float))]
    if bad:
        raise reader.error("lock", f"joint positions must be numbers, got {bad}")
    starts = []
    for kind in START_KINDS:
        q0 = reader.take(f"{kind}_q0_rad", "numbers", None, unit="rad")
        if q0 is None and not (shipped and kind == "nominal"):
            raise reader.error(f"{kind}_q0_rad", "missing; give the start configuration")
        starts.append((kind, None if q0 is None else tuple(float(v) for v in q0)))
    reader.finish()
    locked = tuple((str(k), float(v)) for k, v in lock.items())
    return ArmSpec(name, robot, ee_frame, locked, tuple(starts))


def _read_task(reader: TableReader, trajectories: tuple[str, ...]) -> TaskSpec:
    name = reader.take("name", "str")
    trajectory = reader.take("trajectory", "str")
    if trajectory not in trajectories:
        known = list(trajectories)
        problem = f"no [[trajectories]] entry {trajectory!r}; known: {known}"
        raise reader.error("trajectory", problem)
    start = reader.take("start", "str", "nominal")
    if start not in START_KINDS:
        raise reader.error("start", f"expected one of {list(START_KINDS)}, got {start!r}")
    reader.finish()
    return TaskSpec(name, trajectory, start)


def _unique(reader: TableReader, key: str, names: list[str]) -> None:
    if len(set(names)) != len(names):
        raise reader.error(key, f"a name is given twice: {names}")


def read_arms_settings(top: TableReader, draft: dict) -> ArmsSettings:
    """The ``[arms]`` table of a study file (``draft``: what was read before)."""
    reader = top.child("arms", default_empty=False)
    periods = tuple(float(v) for v in reader.take("periods_s", "positives", unit="s"))
    simulators = tuple(reader.take("simulators", "strs", list(_SIMULATORS)))
    bad = [s for s in simulators if s not in _SIMULATORS]
    if bad:
        raise reader.error("simulators", f"unknown {bad}; expected some of {list(_SIMULATORS)}")
    factor = float(reader.take("max_time_factor", "positive", 3.0))
    arms = tuple(
        _read_arm(TableReader(t, f"[[arms.robots]] #{i}", top.source))
        for i, t in enumerate(reader.take("robots", "tables"), start=1)
    )
    names = tuple(e.name for e in draft["trajectories"])
    tasks = tuple(
        _read_task(TableReader(t, f"[[arms.tasks]] #{i}", top.source), names)
        for i, t in enumerate(reader.take("tasks", "tables"), start=1)
    )
    _unique(reader, "robots", [a.name for a in arms])
    _unique(reader, "tasks", [t.name for t in tasks])
    reader.finish()
    return ArmsSettings(arms, tasks, periods, simulators, factor)

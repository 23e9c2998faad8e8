"""A study as data: what a study file describes, read and checked.

A study file (TOML) gives a robot, trajectories, controllers and their options, a grid of
``T_tot`` values, the simulator and its control period, and where the results go; the
``experiment`` of its ``[study]`` table says how each case is run and judged
(:mod:`dqcontrol.studies.kinds`). :func:`load_study` reads a file (or a shipped study by
name, :data:`SHIPPED`) into a :class:`Study`; every error is a
:class:`~dqcontrol.studies.reader.StudyFileError` naming the file, the table and the key.
"""

from __future__ import annotations

import importlib.resources
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dqcontrol.studies.reader import TOP_LEVEL, StudyFileError, TableReader

__all__ = [
    "SHIPPED",
    "SIMULATORS",
    "OutputSpec",
    "RobotSpec",
    "Study",
    "TrajectoryEntry",
    "load_study",
    "parse_study",
    "shipped_study_path",
]

#: The studies shipped in the package, by name (``dqcontrol study table1``).
SHIPPED = ("table1", "faults", "arms")
#: The closed loops a study can run in.
SIMULATORS = ("mujoco", "kinematic")
#: Table formats a study can write.
FORMATS = ("md", "csv")
#: Control period when the file gives none [s] (the thesis's).
DEFAULT_PERIOD_S = 0.05


@dataclass(frozen=True)
class RobotSpec:
    """The robot: the shipped LBR4p (``urdf = None``) or a URDF file and its tool frame.

    Attributes:
        urdf: absolute path of the URDF, or ``None`` for the LBR4p.
        tool_frame: the controlled frame (a link or joint of the URDF).
        q0_rad: start configuration [rad]; ``None``: the LBR4p's ``LBR4P_Q0``.
    """

    urdf: str | None = None
    tool_frame: str | None = None
    q0_rad: tuple[float, ...] | None = None


@dataclass(frozen=True)
class TrajectoryEntry:
    """One trajectory of the study and the ``T_tot`` values [s] it is run at.

    Attributes:
        name: its name in tables and file names (default: its kind).
        kind: a kind of :data:`~dqcontrol.trajectories.TRAJECTORY_KINDS`.
        durations_s: the ``T_tot`` values [s], in the order given.
        parameters: the kind's own parameters as ``(name, value)`` pairs (``radius_m``,
            ``positions_m``, ``orientations`` ...).
    """

    name: str
    kind: str
    durations_s: tuple[float, ...]
    parameters: tuple[tuple[str, Any], ...] = ()

    def metadata(self, duration_s: float) -> dict:
        """The trajectory at ``T_tot = duration_s`` as
        :func:`~dqcontrol.trajectories.trajectory_from_metadata` reads it."""
        return {"trajectory": self.kind, "duration_s": float(duration_s), **dict(self.parameters)}


@dataclass(frozen=True)
class OutputSpec:
    """Where the results go.

    Attributes:
        folder: results folder (relative to the working directory).
        formats: table formats written, of ``("md", "csv")``.
        save_runs: keep each run's log (``.npz`` + ``.json``) in ``<folder>/<name>_runs``.
    """

    folder: str = "results"
    formats: tuple[str, ...] = FORMATS
    save_runs: bool = False


@dataclass(frozen=True)
class Study:
    """A study file, read and checked (picklable: sent to every worker).

    Attributes:
        name: the study's name, the stem of its output files.
        experiment: how cases are run and judged (``tracking``, ``table1``, ``faults``).
        source: the file it was read from.
        robot, simulator, period_s: the robot, the closed loop and the control period [s].
        controllers: controller names (:mod:`dqcontrol.registry`), in the grid's order.
        trajectories: the trajectories and their ``T_tot`` values.
        settings: the experiment's own settings (its kind's settings object).
        output: where the results go.
        description: one line for the report.
    """

    name: str
    experiment: str
    source: str
    robot: RobotSpec
    simulator: str
    period_s: float
    controllers: tuple[str, ...]
    trajectories: tuple[TrajectoryEntry, ...]
    settings: Any
    output: OutputSpec
    description: str = ""

    def trajectory(self, name: str) -> TrajectoryEntry:
        """The trajectory entry called ``name``."""
        for entry in self.trajectories:
            if entry.name == name:
                return entry
        raise StudyFileError(
            f"{self.source}: no trajectory {name!r}; trajectories: "
            f"{[e.name for e in self.trajectories]}"
        )


def shipped_study_path(name: str) -> Path:
    """The path of the shipped study ``name`` (:data:`SHIPPED`), inside the package."""
    resource = importlib.resources.files("dqcontrol.studies") / f"{name}.toml"
    return Path(str(resource))


def load_study(source: str | Path) -> Study:
    """Read a study file, or a shipped study by name (``"table1"``, ``"faults"``).

    Raises:
        StudyFileError: the file is missing or not TOML, or its content is wrong (the
            message names the key and what would be right).
    """
    name = str(source)
    path = shipped_study_path(name) if name in SHIPPED else Path(source)
    if not path.is_file():
        raise StudyFileError(
            f"no study file {name!r} (looked for {path.resolve()}); give the path of a .toml "
            f"file or the name of a shipped study: {', '.join(SHIPPED)}"
        )
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise StudyFileError(f"{path}: not a valid TOML file: {exc}") from None
    return parse_study(data, source=str(path), base_dir=path.parent)


def parse_study(data: dict, *, source: str = "<study>", base_dir: Path | None = None) -> Study:
    """A :class:`Study` from a study file's parsed TOML ``data``; relative URDF paths are
    taken from ``base_dir`` (default: the working directory)."""
    from dqcontrol.studies.kinds import experiment_kind

    top = TableReader(data, TOP_LEVEL, source)
    head = top.child("study", default_empty=False)
    name = head.take("name", "str")
    if any(c in name for c in "/\\") or name in (".", ".."):
        raise head.error("name", f"must be usable as a file name (no '/' or '\\'), got {name!r}")
    experiment = head.take("experiment", "str", "tracking")
    description = head.take("description", "str", "")
    kind = experiment_kind(experiment, head)
    head.finish()
    top.finish(("study", "simulator", "grid", "trajectories", *kind.own_tables, "output"))
    sim = top.child("simulator")
    simulator = sim.take("kind", "str", "mujoco")
    if simulator not in SIMULATORS:
        raise sim.error("kind", f"expected one of {list(SIMULATORS)}, got {simulator!r}")
    period_s = float(sim.take("period_s", "positive", DEFAULT_PERIOD_S, unit="s"))
    sim.finish()
    robot = kind.read_robot(top, base_dir or Path.cwd())
    grid = top.child("grid", default_empty=False)
    controllers = tuple(kind.check_controller(grid, c) for c in grid.take("controllers", "strs"))
    if len(set(controllers)) != len(controllers):
        raise grid.error("controllers", f"lists a controller twice: {list(controllers)}")
    durations = grid.take("duration_s", "positives", None, unit="s")
    grid.finish()
    trajectories = _trajectories(top, durations, kind)
    draft = {
        "simulator": simulator,
        "period_s": period_s,
        "controllers": controllers,
        "robot": robot,
        "trajectories": trajectories,
    }
    settings = kind.read_settings(top, draft)
    output = _output(top.child("output"), kind)
    top.finish()
    return Study(
        name=name,
        experiment=kind.name,
        source=source,
        robot=robot,
        simulator=simulator,
        period_s=period_s,
        controllers=controllers,
        trajectories=trajectories,
        settings=settings,
        output=output,
        description=description,
    )


def _trajectories(top: TableReader, durations, kind) -> tuple[TrajectoryEntry, ...]:
    entries: list[TrajectoryEntry] = []
    for i, table in enumerate(top.take("trajectories", "tables"), start=1):
        reader = TableReader(table, f"[[trajectories]] #{i}", top.source)
        given = reader.take("duration_s", "positives", durations, unit="s")
        if given is None:
            raise reader.error(
                "duration_s", "missing; give the T_tot values [s] here or in [grid] duration_s"
            )
        entry = kind.read_trajectory(reader, tuple(float(d) for d in given))
        reader.finish()
        if entry.name in [e.name for e in entries]:
            raise reader.error("name", f"another trajectory is already called {entry.name!r}")
        entries.append(entry)
    return tuple(entries)


def _output(reader: TableReader, kind) -> OutputSpec:
    folder = reader.take("folder", "str", "results")
    formats = tuple(reader.take("formats", "strs", list(FORMATS)))
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise reader.error("formats", f"unknown format {bad}; expected some of {list(FORMATS)}")
    save_runs = reader.take("save_runs", "bool", kind.save_runs_default)
    if save_runs and not kind.can_save_runs:
        raise reader.error("save_runs", f"the {kind.name} experiment keeps no run logs")
    reader.finish()
    return OutputSpec(folder=folder, formats=formats, save_runs=save_runs)

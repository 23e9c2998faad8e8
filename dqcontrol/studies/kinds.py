"""The experiments a study can run, by name.

An :class:`ExperimentKind` is what a study needs of an experiment: how to read its part of
the study file (robot, trajectories, controller names, its own table), how to expand the
grid into cases, the job that runs one case in a worker, and how to write the case's record
and the study's tables. Four are known:

- ``tracking`` (:mod:`dqcontrol.studies.tracking`) — any robot, trajectory and registered
  controller; the metrics of docs/theory.md §9;
- ``table1`` (:mod:`dqcontrol.studies.table1_study`) — the cases of
  :mod:`dqcontrol.experiments.table1`, with its settings and report;
- ``faults`` (:mod:`dqcontrol.studies.faults_study`) — the cases of
  :mod:`dqcontrol.faults.campaign`, with its faults and report;
- ``arms`` (:mod:`dqcontrol.studies.arms_study`) — serial arms × controllers × tasks ×
  periods × both loops, with every controller's defaults, judged against docs/arms.md.

Every job runs its case through :func:`~dqcontrol.sim.run_loop`: ``tracking`` and
``table1`` through :func:`dqcontrol.experiments.runner.simulate`, ``faults`` with the
campaign's faulty drivers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from dqcontrol.studies.reader import TableReader

__all__ = ["EXPERIMENTS", "ExperimentKind", "RunInfo", "experiment_kind"]


@dataclass(frozen=True)
class RunInfo:
    """How a study ran, for its report.

    Attributes:
        wall_time_s: wall time of the cases [s].
        executor: where they ran (:attr:`~dqcontrol.experiments.executor.Executor.label`).
        command: the command line, quoted in the report.
        interrupted: whether the study was stopped before every case finished.
        total_cases: the cases of the grid.
    """

    wall_time_s: float
    executor: str
    command: str
    interrupted: bool
    total_cases: int


@dataclass(frozen=True)
class ExperimentKind:
    """An experiment a study file can name (see the module's text).

    Attributes:
        name: its name in ``[study] experiment``.
        read_robot: ``(top, base_dir) -> RobotSpec`` (reads ``[robot]`` if it takes one).
        check_controller: ``(grid, name) -> name``: a controller name it accepts (raises a
            StudyFileError listing the known ones otherwise).
        read_trajectory: ``(reader, durations_s) -> TrajectoryEntry``.
        read_settings: ``(top, draft) -> settings``: its own tables; ``draft`` holds what
            was read before (``simulator``, ``period_s``, ``controllers``, ``robot``,
            ``trajectories``).
        cases: ``study -> [case]``, in the table's order.
        case_name: ``case -> str``, file-name friendly and unique in the study.
        job: ``(study, runs_dir or None) -> callable(case) -> result`` (picklable).
        record: ``result -> dict`` of plain JSON data (the case's result file).
        render: ``(study, results in case order, RunInfo) -> {format: text}``.
        cost: ``case -> float``, a rough relative cost: the longest cases are submitted
            first, which balances the workers (default: ``T_tot``).
        own_tables: the top-level tables of the file that are its own (``robot``,
            ``options``, ``table1``, ``faults``).
        save_runs_default, can_save_runs: whether it keeps each run's log by default, and
            whether it can.
    """

    name: str
    read_robot: Callable[..., Any]
    check_controller: Callable[[TableReader, str], str]
    read_trajectory: Callable[..., Any]
    read_settings: Callable[..., Any]
    cases: Callable[[Any], list]
    case_name: Callable[[Any], str]
    job: Callable[..., Callable[[Any], Any]]
    record: Callable[[Any], dict]
    render: Callable[..., dict[str, str]]
    cost: Callable[[Any], float] = lambda case: case.duration_s
    own_tables: tuple[str, ...] = ()
    save_runs_default: bool = False
    can_save_runs: bool = True


def _experiments() -> dict[str, ExperimentKind]:
    from dqcontrol.studies.arms_study import ARMS_KIND
    from dqcontrol.studies.faults_study import FAULTS_KIND
    from dqcontrol.studies.table1_study import TABLE1_KIND
    from dqcontrol.studies.tracking import TRACKING_KIND

    return {k.name: k for k in (TRACKING_KIND, TABLE1_KIND, FAULTS_KIND, ARMS_KIND)}


#: The experiment names, in the order of the help texts.
EXPERIMENTS = ("tracking", "table1", "faults", "arms")


def experiment_kind(name: str, reader: TableReader | None = None) -> ExperimentKind:
    """The experiment called ``name``.

    Raises:
        StudyFileError: an unknown name (the message lists the known ones).
    """
    known = _experiments()
    if name not in known:
        problem = f"unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}"
        if reader is None:
            from dqcontrol.studies.reader import StudyFileError

            raise StudyFileError(problem)
        raise reader.error("experiment", problem)
    return known[name]

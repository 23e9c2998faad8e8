"""The ``table1`` experiment: the cases, settings and report of
:mod:`dqcontrol.experiments.table1`, from a study file.

Its part of the file: trajectories ``circle`` and ``sinusoid`` (no parameters: the
thesis's paths), controllers of :data:`~dqcontrol.experiments.table1.CONTROLLERS`, and a
``[table1]`` table whose keys are :class:`~dqcontrol.experiments.table1.Table1Settings`'
fields (``horizon_s``, ``velocity_limits``, ``acceleration_limit``, ``q0``,
``controller_options`` and ``path_following_options`` as tables, ``servo_model``,
``bound_samples``, ``between_samples``); the simulator and the period come from
``[simulator]``. Each case runs through :func:`dqcontrol.experiments.table1.run_case`, the
same job as ``dqcontrol table1``'s, and the report is the same ``.md`` and ``.csv``.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

from dqcontrol.errors import DQControlError
from dqcontrol.experiments import table1 as t1
from dqcontrol.studies.kinds import ExperimentKind, RunInfo
from dqcontrol.studies.reader import TableReader
from dqcontrol.studies.spec import RobotSpec, Study, TrajectoryEntry

__all__ = ["TABLE1_KIND", "select_table1"]


def _read_robot(top: TableReader, base_dir: Path) -> RobotSpec:
    return RobotSpec()  # the thesis's LBR4p; a [robot] table is an unknown key here


def _check_controller(grid: TableReader, name: str) -> str:
    try:
        return t1.Table1Case("circle", 1.0, name).controller
    except DQControlError as exc:
        raise grid.error("controllers", str(exc)) from None


def _read_trajectory(reader: TableReader, durations_s: tuple[float, ...]) -> TrajectoryEntry:
    kind = reader.take("kind", "str")
    if kind not in t1.TRAJECTORIES:
        raise reader.error("kind", f"expected one of {list(t1.TRAJECTORIES)}, got {kind!r}")
    return TrajectoryEntry(kind, kind, durations_s)


def _read_settings(top: TableReader, draft: dict) -> t1.Table1Settings:
    reader = top.child("table1")
    defaults = t1.Table1Settings()
    q0 = reader.take("q0", "numbers", None, unit="rad")
    values = {
        "horizon_s": reader.take("horizon_s", "positive", defaults.horizon_s, unit="s"),
        "velocity_limits": tuple(
            reader.take("velocity_limits", "positives", list(defaults.velocity_limits))
        ),
        "acceleration_limit": reader.take(
            "acceleration_limit", "positive", defaults.acceleration_limit, unit="rad/s²"
        ),
        "q0": None if q0 is None else tuple(float(v) for v in q0),
        "controller_options": tuple(
            reader.take("controller_options", "table", dict(defaults.controller_options)).items()
        ),
        "path_following_options": tuple(
            reader.take(
                "path_following_options", "table", dict(defaults.path_following_options)
            ).items()
        ),
        "servo_model": reader.take("servo_model", "bool", defaults.servo_model),
        "bound_samples": reader.take("bound_samples", "int", defaults.bound_samples),
        "between_samples": reader.take("between_samples", "bool", defaults.between_samples),
    }
    reader.finish()
    try:
        return t1.Table1Settings(period_s=draft["period_s"], simulator=draft["simulator"], **values)
    except DQControlError as exc:
        raise reader.error(None, str(exc)) from None


def _cases(study: Study) -> list[t1.Table1Case]:
    return [
        t1.Table1Case(entry.kind, d, c)
        for entry in study.trajectories
        for d in entry.durations_s
        for c in study.controllers
    ]


def _job(study: Study, save_dir: str | None):
    return functools.partial(t1.run_case, settings=study.settings, save_dir=save_dir)


def select_table1(
    study: Study,
    *,
    quick: bool = False,
    periods: Iterable[float] | None = None,
    trajectories: Iterable[str] | None = None,
    controllers: Iterable[str] | None = None,
    simulator: str | None = None,
    period_s: float | None = None,
    bound_samples: int | None = None,
    save_runs: bool | None = None,
) -> Study:
    """``study`` (a ``table1`` study) reduced to a selection of
    :func:`~dqcontrol.experiments.table1.table1_cases` (same arguments, same errors) and
    with another simulator, control period [s], bound resolution or run logs (``None``:
    the study's).

    Raises:
        ParameterError: an unknown name or period, or an empty selection.
    """
    wanted = t1.table1_cases(
        quick=quick, periods=periods, trajectories=trajectories, controllers=controllers
    )
    cells = {(c.trajectory, c.duration_s) for c in wanted}
    names = {c.controller for c in wanted}
    entries = []
    for entry in study.trajectories:
        kept = tuple(d for d in entry.durations_s if (entry.kind, d) in cells)
        if kept:
            entries.append(replace(entry, durations_s=kept))
    sim = study.simulator if simulator is None else simulator
    period = study.period_s if period_s is None else period_s
    settings = replace(study.settings, simulator=sim, period_s=period)
    if bound_samples is not None:
        settings = replace(settings, bound_samples=bound_samples)
    output = study.output if save_runs is None else replace(study.output, save_runs=save_runs)
    return replace(
        study,
        simulator=sim,
        period_s=period,
        settings=settings,
        trajectories=tuple(entries),
        controllers=tuple(c for c in study.controllers if c in names),
        output=output,
    )


def _render(study: Study, results: list[dict], info: RunInfo) -> dict[str, str]:
    rows = t1.table_rows(results)
    markdown = t1.format_markdown(
        rows,
        study.settings,
        wall_time_s=info.wall_time_s,
        executor=info.executor,
        command=info.command,
        interrupted=info.interrupted,
        physics_dt_s=next((r["meta"].get("physics_dt_s") for r in results), None),
    )
    return {"md": markdown, "csv": t1.format_csv(rows)}


TABLE1_KIND = ExperimentKind(
    name="table1",
    read_robot=_read_robot,
    check_controller=_check_controller,
    read_trajectory=_read_trajectory,
    read_settings=_read_settings,
    cases=_cases,
    case_name=lambda case: case.name,
    job=_job,
    record=lambda result: result,
    render=_render,
    cost=lambda case: case.cost_estimate(),
    own_tables=("table1",),
    save_runs_default=True,
)

"""The ``faults`` experiment: the cases, judgement and report of
:mod:`dqcontrol.faults.campaign`, from a study file.

Its part of the file: trajectories ``circle`` and ``sinusoid`` (the campaign's, whose
unreachable variants the ``unreachable`` fault uses), controllers by the campaign's names
(:data:`~dqcontrol.faults.scenarios.CONTROLLERS`) or any :mod:`dqcontrol.registry` name,
and a ``[faults]`` table: ``names`` (faults of :data:`~dqcontrol.faults.scenarios.FAULTS`,
default all) and ``seed`` (of the measurement noise). A fault that does not apply to a
controller or simulator is left out, as in the campaign. Each case runs through
:func:`dqcontrol.faults.campaign.run_case`, and the report is the campaign's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.faults import campaign, scenarios
from dqcontrol.registry import ControllerSpec, controller_spec
from dqcontrol.studies.kinds import ExperimentKind, RunInfo
from dqcontrol.studies.reader import TableReader
from dqcontrol.studies.spec import RobotSpec, Study, TrajectoryEntry

__all__ = ["FAULTS_KIND", "FaultSettings", "campaign_result", "select_faults"]


@dataclass(frozen=True)
class FaultSettings:
    """The ``[faults]`` of a study: the faults by name, and the noise's seed."""

    names: tuple[str, ...]
    seed: int = 0


def campaign_controller(name: str) -> ControllerSpec:
    """The campaign's controller ``name``, or the registry's under that name."""
    if name in scenarios.CONTROLLERS:
        return scenarios.CONTROLLERS[name]
    return controller_spec(name).renamed(name)


def _read_robot(top: TableReader, base_dir: Path) -> RobotSpec:
    return RobotSpec()  # the campaign's LBR4p; a [robot] table is an unknown key here


def _check_controller(grid: TableReader, name: str) -> str:
    try:
        campaign_controller(name)
    except DQControlError as exc:
        campaign_names = ", ".join(scenarios.CONTROLLERS)
        raise grid.error("controllers", f"{exc}; campaign names: {campaign_names}") from None
    return name


def _read_trajectory(reader: TableReader, durations_s: tuple[float, ...]) -> TrajectoryEntry:
    kind = reader.take("kind", "str")
    if kind not in scenarios.TRAJECTORIES:
        raise reader.error("kind", f"expected one of {list(scenarios.TRAJECTORIES)}, got {kind!r}")
    return TrajectoryEntry(kind, kind, durations_s)


def _read_settings(top: TableReader, draft: dict) -> FaultSettings:
    reader = top.child("faults")
    every = [f.name for f in scenarios.FAULTS]
    names = tuple(reader.take("names", "strs", every))
    for name in names:
        try:
            scenarios.fault_by_name(name)
        except DQControlError as exc:
            raise reader.error("names", str(exc)) from None
    seed = reader.take("seed", "int", 0)
    reader.finish()
    return FaultSettings(names, seed)


def _cases(study: Study) -> list[campaign.CaseSpec]:
    settings: FaultSettings = study.settings
    controllers = [campaign_controller(c) for c in study.controllers]
    cases = []
    for fault in map(scenarios.fault_by_name, settings.names):
        for entry in study.trajectories:
            for duration in entry.durations_s:
                cases += [
                    campaign.CaseSpec(
                        ctrl,
                        scenarios.TRAJECTORIES[entry.kind],
                        fault,
                        study.simulator,
                        duration,
                        study.period_s,
                        settings.seed,
                    )  # fmt: skip
                    for ctrl in controllers
                    if fault.applies_to(ctrl, study.simulator)
                ]
    return cases


def _case_name(case: campaign.CaseSpec) -> str:
    return f"{case.fault.name}_{case.trajectory.name}_T{case.duration_s:g}s_{case.controller.name}"


def select_faults(
    study: Study,
    *,
    controllers: Sequence[str] | None = None,
    trajectories: Sequence[str] | None = None,
    faults: Sequence[str] | None = None,
    simulator: str | None = None,
    quick: bool = False,
    seed: int | None = None,
) -> Study:
    """``study`` (a ``faults`` study) with the selection of
    :func:`~dqcontrol.faults.campaign.campaign_cases` (same arguments, same errors; ``None``
    keeps the study's, ``quick`` the reduced campaign's controllers, faults and circle).

    Raises:
        ParameterError: an unknown name, or a selection without a case.
    """
    sim = study.simulator if simulator is None else simulator
    settings: FaultSettings = study.settings
    if controllers is None:
        controllers = scenarios.QUICK_CONTROLLERS if quick else study.controllers
    if faults is None:
        faults = scenarios.QUICK_FAULTS if quick else settings.names
    kinds = [e.kind for e in study.trajectories]
    if trajectories is None:
        trajectories = ["circle"] if quick else kinds
    seed = settings.seed if seed is None else seed
    if not campaign.campaign_cases(controllers, trajectories, faults, sim, quick, seed):
        raise ParameterError("the selection has no case (check the controllers and faults)")
    entries = []
    for name in trajectories:
        spec = scenarios.TRAJECTORIES[name]
        given = [e for e in study.trajectories if e.kind == name]
        durations = given[0].durations_s if given else (spec.duration_s,)
        entries.append(
            TrajectoryEntry(name, name, (spec.quick_duration_s,) if quick else durations)
        )
    return replace(
        study,
        simulator=sim,
        controllers=tuple(controllers),
        trajectories=tuple(entries),
        settings=FaultSettings(tuple(faults), seed),
    )


def campaign_result(
    study: Study, rows: list, *, total_cases: int, interrupted: bool, wall_time_s: float
) -> campaign.CampaignResult:
    """The campaign's result of a study's finished rows (:class:`CaseResult`, case order);
    a selection smaller than the whole campaign is labelled reduced."""
    full = campaign.campaign_cases(simulator=study.simulator)
    return campaign.CampaignResult(
        rows=list(rows),
        simulator=study.simulator,
        quick=total_cases < len(full),
        total_cases=total_cases,
        interrupted=interrupted,
        note=f"interrupted after {len(rows)} of {total_cases} cases" if interrupted else "",
        wall_time_s=wall_time_s,
    )


def _render(study: Study, results: list, info: RunInfo) -> dict[str, str]:
    result = campaign_result(
        study,
        results,
        total_cases=info.total_cases,
        interrupted=info.interrupted,
        wall_time_s=info.wall_time_s,
    )
    return {
        "md": campaign.render_markdown(result, command=info.command),
        "csv": campaign.render_csv(result),
    }


FAULTS_KIND = ExperimentKind(
    name="faults",
    read_robot=_read_robot,
    check_controller=_check_controller,
    read_trajectory=_read_trajectory,
    read_settings=_read_settings,
    cases=_cases,
    case_name=_case_name,
    job=lambda study, save_dir: campaign.run_case,
    record=lambda row: row.row(),
    render=_render,
    own_tables=("faults",),
    can_save_runs=False,
)

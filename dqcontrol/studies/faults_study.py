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

from dataclasses import dataclass
from pathlib import Path

from dqcontrol.errors import DQControlError
from dqcontrol.faults import campaign, scenarios
from dqcontrol.registry import ControllerSpec, controller_spec
from dqcontrol.studies.kinds import ExperimentKind, RunInfo
from dqcontrol.studies.reader import TableReader
from dqcontrol.studies.spec import RobotSpec, Study, TrajectoryEntry

__all__ = ["FAULTS_KIND", "FaultSettings"]


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


def _render(study: Study, results: list, info: RunInfo) -> dict[str, str]:
    note = f"interrupted after {len(results)} of {info.total_cases} cases"
    result = campaign.CampaignResult(
        rows=list(results),
        simulator=study.simulator,
        quick=False,
        total_cases=info.total_cases,
        interrupted=info.interrupted,
        note=note if info.interrupted else "",
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

"""The ``tracking`` experiment: any robot, trajectory and registered controller, measured
with the metrics of docs/theory.md §9.

Its part of a study file: ``[robot]`` (``urdf``, ``tool_frame``, ``q0_rad``; default the
shipped LBR4p from ``LBR4P_Q0``), trajectories of any kind of
:data:`~dqcontrol.trajectories.TRAJECTORY_KINDS` with their parameters, controllers by
their :mod:`dqcontrol.registry` names, and ``[options]``: the settings every controller is
offered (:data:`~dqcontrol.registry.SHARED_OPTIONS`, each taking those it accepts), and
``[options.<controller>]`` tables of keyword arguments for one controller.
"""

from __future__ import annotations

import functools
import inspect
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dqcontrol.errors import DQControlError, FrameError, ParameterError
from dqcontrol.experiments.tables import csv_text, markdown_table
from dqcontrol.model.robot import RobotModel
from dqcontrol.studies.kinds import ExperimentKind, RunInfo
from dqcontrol.studies.reader import TableReader
from dqcontrol.studies.spec import RobotSpec, Study, TrajectoryEntry

__all__ = [
    "COLUMNS",
    "TRACKING_KIND",
    "TrackingCase",
    "TrackingSettings",
    "run_tracking_case",
]

#: Trajectory parameters a study file may not set (the grid gives ``T_tot``; the path is
#: anchored at the start pose).
_RESERVED = ("duration_s", "reference", "times_s")
_LOCAL = threading.local()
#: Columns of the tracking table: (key, header in the .md, format in the .md).
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("traj", "traj", "s"),
    ("T_tot_s", "T_tot [s]", "g"),
    ("controller", "controller", "s"),
    ("e_mean", "e_mean", ".2e"),
    ("u_mean_rad_s", "u_mean [rad/s]", ".4f"),
    ("s_mean", "s_mean", ".4f"),
    ("path_dev_mean_mm", "path dev. mean [mm]", ".3f"),
    ("path_dev_max_mm", "path dev. max [mm]", ".3f"),
    ("trans_err_mean_mm", "transl. err. mean [mm]", ".2f"),
    ("rot_err_mean_deg", "rot. err. mean [deg]", ".3f"),
    ("exec_time_s", "exec. time [s]", ".2f"),
    ("exec_ratio", "exec./T_tot", ".2f"),
    ("torque_peak_nm", "peak torque [N·m]", ".1f"),
    ("viol_position", "viol. pos.", "d"),
    ("viol_velocity", "viol. vel.", "d"),
    ("viol_acceleration", "viol. acc.", "d"),
    ("fallbacks", "fallbacks", "d"),
    ("relaxed_steps", "relaxed", "d"),
    ("completed", "completed", "s"),
)


@dataclass(frozen=True)
class TrackingSettings:
    """The ``[options]`` of a tracking study.

    Attributes:
        shared: settings offered to every controller, ``(name, value)`` pairs of
            :data:`~dqcontrol.registry.SHARED_OPTIONS`.
        per_controller: ``(controller, ((name, value), ...))``: keyword arguments of one
            controller (they override ``shared``).
        max_time_s: time limit of every run [s] (``None``: the loop's default).
    """

    shared: tuple[tuple[str, Any], ...] = ()
    per_controller: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    max_time_s: float | None = None

    def extra(self, controller: str) -> dict:
        """The keyword arguments of ``controller`` beyond the shared settings."""
        return dict(dict(self.per_controller).get(controller, ()))


@dataclass(frozen=True, order=True)
class TrackingCase:
    """One cell of the grid: a trajectory entry, ``T_tot`` [s] and a controller name."""

    trajectory: str
    duration_s: float
    controller: str

    @property
    def name(self) -> str:
        """File-name friendly label, e.g. ``circle_T2s_p10``."""
        return f"{self.trajectory}_T{self.duration_s:g}s_{self.controller}"


# ---------------------------------------------------------------------------- reading
def _read_robot(top: TableReader, base_dir: Path) -> RobotSpec:
    reader = top.child("robot")
    urdf = reader.take("urdf", "str", None)
    tool = reader.take("tool_frame", "str", None)
    q0 = reader.take("q0_rad", "numbers", None, unit="rad")
    if urdf is not None:
        for key, value in (("tool_frame", tool), ("q0_rad", q0)):
            if value is None:
                raise reader.error(key, "missing; a robot given by its URDF needs it")
        urdf = str((base_dir / urdf).resolve())
    elif tool is not None:
        raise reader.error("tool_frame", "only with urdf (the LBR4p's is lbr4p_flange)")
    reader.finish()
    spec = RobotSpec(urdf, tool, None if q0 is None else tuple(float(v) for v in q0))
    try:
        robot = load_robot(spec)
    except FrameError as exc:
        raise reader.error("tool_frame", str(exc)) from None
    except DQControlError as exc:
        raise reader.error("urdf", str(exc)) from None
    if len(start_configuration(spec)) != robot.nq:
        raise reader.error("q0_rad", f"expected {robot.nq} joint positions, got {len(q0)}")
    return spec


def _check_controller(grid: TableReader, name: str) -> str:
    from dqcontrol.registry import controller_spec

    try:
        controller_spec(name)
    except DQControlError as exc:
        raise grid.error("controllers", str(exc)) from None
    return name


def _read_trajectory(reader: TableReader, durations_s: tuple[float, ...]) -> TrajectoryEntry:
    from dqcontrol.trajectories import TRAJECTORY_KINDS, trajectory_from_metadata

    kind = reader.take("kind", "str")
    if kind not in TRAJECTORY_KINDS:
        raise reader.error(
            "kind", f"unknown trajectory {kind!r}; known: {sorted(TRAJECTORY_KINDS)}"
        )
    name = reader.take("name", "str", kind)
    accepted = [
        p for p in inspect.signature(TRAJECTORY_KINDS[kind].__init__).parameters
        if p != "self" and p not in _RESERVED
    ]  # fmt: skip
    parameters = tuple((key, reader.take(key, "any")) for key in accepted if reader.has(key))
    entry = TrajectoryEntry(name, kind, durations_s, parameters)
    try:
        trajectory_from_metadata(entry.metadata(durations_s[0]))
    except (DQControlError, TypeError, ValueError) as exc:
        raise reader.error(None, f"the {kind} cannot be built: {exc}") from None
    return entry


def _read_settings(top: TableReader, draft: dict) -> TrackingSettings:
    from dqcontrol.registry import SHARED_OPTIONS, controller_spec

    reader = top.child("options")
    shared = tuple((k, reader.take(k, "any")) for k in SHARED_OPTIONS if reader.has(k))
    max_time_s = reader.take("max_time_s", "positive", None, unit="s")
    per = []
    for controller in draft["controllers"]:
        if not reader.has(controller):
            continue
        table = reader.child(controller)
        cls = controller_spec(controller).cls
        accepted = [p for p in inspect.signature(cls.__init__).parameters if p not in (
            "self", "robot", "trajectory", "period_s")]  # fmt: skip
        per.append((controller, tuple((k, table.take(k, "any")) for k in accepted if table.has(k))))
        table.finish()
    reader.finish()
    settings = TrackingSettings(shared, tuple(per), max_time_s)
    _check_controllers(reader, settings, draft)
    return settings


def _check_controllers(reader: TableReader, settings: TrackingSettings, draft: dict) -> None:
    """Build every controller once (first trajectory, shortest ``T_tot``), so that a wrong
    option value stops the study before any case runs."""
    from dqcontrol.experiments.runner import build_trajectory
    from dqcontrol.registry import build_controller

    robot = load_robot(draft["robot"])
    entry = draft["trajectories"][0]
    trajectory = build_trajectory(entry.metadata(min(entry.durations_s)))
    for name in draft["controllers"]:
        try:
            build_controller(
                name, robot, trajectory, draft["period_s"],
                shared=_arrays(dict(settings.shared)), **_arrays(settings.extra(name)),
            )  # fmt: skip
        except (DQControlError, TypeError, ValueError) as exc:
            raise reader.error(
                None, f"controller {name!r} cannot be built with these options: {exc}"
            ) from None


# ---------------------------------------------------------------------------- running
def load_robot(spec: RobotSpec) -> RobotModel:
    """The study's robot, loaded once per thread."""
    from dqcontrol.experiments.runner import lbr4p

    if spec.urdf is None:
        return lbr4p()
    if spec.tool_frame is None:
        raise ParameterError("[robot] tool_frame: required with urdf (a link or joint name)")
    cache = getattr(_LOCAL, "robots", None)
    if cache is None:
        cache = _LOCAL.robots = {}
    key = (spec.urdf, spec.tool_frame)
    if key not in cache:
        cache[key] = RobotModel.from_urdf(spec.urdf, spec.tool_frame)
    return cache[key]


def start_configuration(spec: RobotSpec) -> np.ndarray:
    """``q0`` [rad]: the file's, or the LBR4p's ``LBR4P_Q0``."""
    from dqcontrol.experiments.thesis import THESIS_Q0

    return THESIS_Q0.copy() if spec.q0_rad is None else np.asarray(spec.q0_rad, dtype=float)


def _arrays(options: dict) -> dict:
    """Lists of numbers as arrays (the controllers' vector options)."""
    return {k: np.asarray(v, dtype=float) if isinstance(v, list) else v for k, v in options.items()}


def run_tracking_case(case: TrackingCase, study: Study, save_dir: str | None = None) -> dict:
    """Run one case and return plain data: ``{"case", "simulator", "metrics", "interrupted",
    "note", "wall_time_s", "files"}`` (``files``: ``[npz, json]`` when ``save_dir`` is
    given)."""
    from dqcontrol.experiments.runner import build_trajectory, simulate
    from dqcontrol.registry import build_controller
    from dqcontrol.runs.storage import save_run

    start = time.perf_counter()
    robot = load_robot(study.robot)
    entry = study.trajectory(case.trajectory)
    settings: TrackingSettings = study.settings
    controller = build_controller(
        case.controller, robot, build_trajectory(entry.metadata(case.duration_s)),
        study.period_s, shared=_arrays(dict(settings.shared)),
        **_arrays(settings.extra(case.controller)),
    )  # fmt: skip
    meta = {"study": study.name, "case": case.name, "trajectory_name": entry.name}
    q0 = start_configuration(study.robot)
    run = simulate(controller, q0, study.simulator, max_time_s=settings.max_time_s, meta=meta)
    result = run.result
    files = None if save_dir is None else [str(p) for p in save_run(result, save_dir, case.name)]
    return {
        "case": asdict(case),
        "simulator": study.simulator,
        "metrics": result.metrics.as_dict(),
        "interrupted": bool(result.interrupted),
        "note": result.note,
        "wall_time_s": time.perf_counter() - start,
        "files": files,
    }


def _cases(study: Study) -> list[TrackingCase]:
    return [
        TrackingCase(entry.name, d, c)
        for entry in study.trajectories
        for d in entry.durations_s
        for c in study.controllers
    ]


def _job(study: Study, save_dir: str | None):
    return functools.partial(run_tracking_case, study=study, save_dir=save_dir)


# ---------------------------------------------------------------------------- the tables
def table_row(result: dict) -> dict:
    """A row of the study's table (keys of :data:`COLUMNS`)."""
    import math

    from dqcontrol.registry import controller_spec

    case, m = result["case"], result["metrics"]
    return {
        "traj": case["trajectory"],
        "T_tot_s": case["duration_s"],
        "controller": controller_spec(case["controller"]).table_label,
        "e_mean": m["e_mean"],
        "u_mean_rad_s": m["u_mean_rad_s"],
        "s_mean": m["s_mean"],
        "path_dev_mean_mm": 1e3 * m["path_deviation_mean_m"],
        "path_dev_max_mm": 1e3 * m["path_deviation_max_m"],
        "trans_err_mean_mm": 1e3 * m["translation_error_mean_m"],
        "rot_err_mean_deg": math.degrees(m["rotation_error_mean_rad"]),
        "exec_time_s": m["execution_time_s"],
        "exec_ratio": m["execution_ratio"],
        "torque_peak_nm": m["torque_peak_nm"],
        "viol_position": m["position_violations"],
        "viol_velocity": m["velocity_violations"],
        "viol_acceleration": m["acceleration_violations"],
        "fallbacks": m["fallbacks"],
        "relaxed_steps": m["relaxed_steps"],
        "completed": "yes" if m["completed"] and not result["interrupted"] else "NO",
    }


def _render(study: Study, results: list[dict], info: RunInfo) -> dict[str, str]:
    rows = [table_row(r) for r in results]
    robot = study.robot.urdf or "the LBR4p (shipped), LBR4P_Q0"
    lines = [
        f"# Study {study.name}",
        "",
        *([study.description, ""] if study.description else []),
        f"Generated by `{info.command}` from `{study.source}`.",
        "",
        f"- robot: {robot}"
        + (f", tool frame `{study.robot.tool_frame}`" if study.robot.urdf else ""),
        f"- simulator: {study.simulator}; control period T = {study.period_s:g} s",
        f"- executor: {info.executor}; wall time {info.wall_time_s:.1f} s for {len(rows)} of "
        f"{info.total_cases} cases",
        "- units: e_mean = mean ‖vec8(x_d) - vec8(x)‖; u_mean = mean ‖qd_cmd‖ [rad/s]; metrics "
        "over the samples until σ reaches T_tot (docs/theory.md §9)",
    ]
    if info.interrupted:
        lines += ["", "**Interrupted: only the cases that completed are listed.**"]
    lines += ["", markdown_table(rows, COLUMNS)]
    return {"md": "\n".join(lines) + "\n", "csv": csv_text(rows, COLUMNS)}


TRACKING_KIND = ExperimentKind(
    name="tracking",
    read_robot=_read_robot,
    check_controller=_check_controller,
    read_trajectory=_read_trajectory,
    read_settings=_read_settings,
    cases=_cases,
    case_name=lambda case: case.name,
    job=_job,
    record=lambda result: result,
    render=_render,
    own_tables=("robot", "options"),
)

"""The ``arms`` experiment: serial arms × every controller × tasks × control periods × both
loops, every controller with its defaults, judged against the goals of docs/arms.md.

The file's part: ``[[trajectories]]`` (any kind, as for ``tracking``), ``[grid]
controllers`` (:mod:`dqcontrol.registry` names) and the ``[arms]`` table
(:mod:`dqcontrol.studies.arms_spec`). A case runs through
:func:`~dqcontrol.studies.arms_case.run_arms_case`; its judgement is :func:`goal_misses`.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

from dqcontrol.experiments.tables import csv_text, markdown_table
from dqcontrol.studies.arms_case import ArmsCase, run_arms_case
from dqcontrol.studies.arms_spec import ArmsSettings, read_arms_settings
from dqcontrol.studies.kinds import ExperimentKind, RunInfo
from dqcontrol.studies.reader import TableReader
from dqcontrol.studies.spec import RobotSpec, Study
from dqcontrol.studies.tracking import _check_controller, _read_trajectory

__all__ = ["ARMS_KIND", "EXECUTION_RATIO", "PF_DEVIATION_M", "TORQUE_SATURATED", "goal_misses"]

#: The goals: the path-following controller's largest path deviation at the samples [m] by
#: loop, the execution time against the TOPP-RA bound, and the share of the effort limit
#: that counts as saturated.
PF_DEVIATION_M = {"kinematic": 0.1e-3, "mujoco": 0.5e-3}
EXECUTION_RATIO = 1.3
TORQUE_SATURATED = 0.999
#: Below this ``σ_min`` a run passed near a singular configuration (docs/theory.md §8.3).
_NEAR_SINGULAR = 0.04

COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("arm", "arm", "s"),
    ("task", "task", "s"),
    ("loop", "loop", "s"),
    ("T_ms", "T [ms]", "g"),
    ("controller", "controller", "s"),
    ("done", "done", "s"),
    ("dev_mm", "dev. max [mm]", ".3f"),
    ("between_mm", "between [mm]", ".3f"),
    ("rot_deg", "rot. max [deg]", ".3f"),
    ("exec_bound", "exec./TOPP-RA", ".2f"),
    ("torque_ratio", "τ/τ_max", ".2f"),
    ("violations", "viol. p/v/a", "s"),
    ("fallbacks", "fallbacks", "d"),
    ("goals", "goals", "s"),
)


def _cases(study: Study) -> list[ArmsCase]:
    settings: ArmsSettings = study.settings
    return [
        ArmsCase(arm.name, task.name, sim, period, controller, duration)
        for arm in settings.arms
        for task in settings.tasks
        for sim in settings.simulators
        for period in settings.periods_s
        for controller in study.controllers
        for duration in study.trajectory(task.trajectory).durations_s
    ]


def _num(value) -> float:
    """A measured number, NaN where the record holds none (JSON writes NaN as null)."""
    return math.nan if value is None else float(value)


def _crossings(m: dict) -> int:
    return int(m["position_violations"]) + int(m["velocity_violations"])


def _causes(result: dict) -> list[str]:
    """What was measured that explains a miss: contacts, saturation, a near-singular pass."""
    causes = []
    contacts = result.get("contacts")
    if contacts and contacts["samples"]:
        causes.append(
            f"contact {', '.join(contacts['pairs'])} at {contacts['samples']} samples, "
            f"{1e3 * contacts['deepest_m']:.1f} mm deep"
        )
    if _num(result["torque_ratio"]) >= TORQUE_SATURATED:
        causes.append(f"joint {result['torque_joint'] + 1} at its effort limit")
    if _num(result.get("sigma_min")) < _NEAR_SINGULAR:
        causes.append(f"σ_min {result['sigma_min']:.3f} on the way")
    if result["bound_note"]:
        causes.append(_short(result["bound_note"]))
    return causes


def goal_misses(result: dict) -> list[str]:
    """The goals a case misses (empty: it meets them all)."""
    case, m = result["case"], result["metrics"]
    done = bool(m["completed"]) and not result["interrupted"]
    misses = []
    if not done:
        misses.append(f"not completed ({result['note'] or 'time limit'})")
    if _crossings(m):
        misses.append(f"{_crossings(m)} samples beyond a position/velocity bound")
    if _num(result["torque_ratio"]) >= TORQUE_SATURATED:
        misses.append("torque saturated")
    bound = _num(result["bound_s"])
    ratio = _num(m["execution_time_s"]) / bound if bound > 0 else math.nan
    if done and ratio > EXECUTION_RATIO:
        misses.append(f"execution {ratio:.2f}× the TOPP-RA bound")
    if case["controller"] == "pf" and done:
        limit = PF_DEVIATION_M[case["simulator"]]
        deviation_m = _num(m["path_deviation_max_m"])
        if not deviation_m <= limit:
            misses.append(f"deviation {1e3 * deviation_m:.2f} mm > {1e3 * limit} mm")
    return misses


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _short(note: str) -> str:
    """A TOPP-RA message up to its advice (the table's cell stays readable)."""
    for cut in (" (limits", "; choose", " within 50 Newton"):
        note = note.split(cut)[0]
    return note


def table_row(result: dict) -> dict:
    """A row of the study's table (keys of :data:`COLUMNS`)."""
    case, m = result["case"], result["metrics"]
    misses = goal_misses(result)
    goals = "ok" if not misses else "; ".join(misses + [f"cause: {c}" for c in _causes(result)])
    bound = _num(result["bound_s"])
    return {
        "arm": case["arm"],
        "task": case["task"],
        "loop": case["simulator"],
        "T_ms": 1e3 * case["period_s"],
        "controller": case["controller"],
        "done": "yes" if m["completed"] and not result["interrupted"] else "NO",
        "dev_mm": _finite(1e3 * _num(m["path_deviation_max_m"])),
        "between_mm": _finite(1e3 * _num(result["between_deviation_max_m"])),
        "rot_deg": _finite(math.degrees(_num(m["rotation_error_max_rad"]))),
        "exec_bound": _finite(_num(m["execution_time_s"]) / bound) if bound > 0 else None,
        "torque_ratio": _finite(_num(result["torque_ratio"])),
        "violations": "/".join(
            str(m[k])
            for k in ("position_violations", "velocity_violations", "acceleration_violations")
        ),  # fmt: skip
        "fallbacks": m["fallbacks"],
        "goals": goals,
    }


SUMMARY_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("loop", "loop", "s"),
    ("T_ms", "T [ms]", "g"),
    ("cases", "cases", "d"),
    ("ok", "meet every goal", "d"),
    ("pf_done", "pf completed", "s"),
    ("pf_dev_mm", "pf dev. max [mm] (completed)", ".3f"),
    ("pf_exec", "pf exec./TOPP-RA max", ".2f"),
    ("crossing", "cases with a bound crossed", "s"),
    ("saturated", "cases with τ at its limit", "s"),
)


def _by_controller(results: list[dict]) -> str:
    """``n (controller, ...)`` of the given cases, or 0."""
    if not results:
        return "0"
    names = sorted({r["case"]["controller"] for r in results})
    return f"{len(results)} ({', '.join(names)})"


def _summary_row(loop: str, period_s: float, results: list[dict]) -> dict:
    pf = [r for r in results if r["case"]["controller"] == "pf"]
    done = [r for r in pf if r["metrics"]["completed"] and not r["interrupted"]]
    devs = [_num(r["metrics"]["path_deviation_max_m"]) for r in done]
    execs = [_num(r["metrics"]["execution_time_s"]) / _num(r["bound_s"]) for r in done]
    execs = [e for e in execs if math.isfinite(e)]
    return {
        "loop": loop,
        "T_ms": 1e3 * period_s,
        "cases": len(results),
        "ok": sum(not goal_misses(r) for r in results),
        "pf_done": f"{len(done)} of {len(pf)}",
        "pf_dev_mm": 1e3 * max(devs) if devs else None,
        "pf_exec": max(execs) if execs else None,
        "crossing": _by_controller([r for r in results if _crossings(r["metrics"])]),
        "saturated": _by_controller(
            [r for r in results if _num(r["torque_ratio"]) >= TORQUE_SATURATED]
        ),
    }


def _summary(results: list[dict]) -> list[str]:
    """One row per loop and period: the goals met, the path-following controller's figures,
    the cases that crossed a bound or saturated a joint (and by which controllers)."""
    keys = sorted(
        {(r["case"]["simulator"], r["case"]["period_s"]) for r in results},
        key=lambda k: (k[0], -k[1]),
    )
    rows = [
        _summary_row(loop, period, [r for r in results if
                     (r["case"]["simulator"], r["case"]["period_s"]) == (loop, period)])
        for loop, period in keys
    ]  # fmt: skip
    return [markdown_table(rows, SUMMARY_COLUMNS)]


def _render(study: Study, results: list[dict], info: RunInfo) -> dict[str, str]:
    rows = [table_row(r) for r in results]
    lines = [
        f"# Study {study.name}",
        "",
        *([study.description, ""] if study.description else []),
        f"Generated by `{info.command}` from `{Path(study.source).name}`; executor "
        f"{info.executor}, wall time {info.wall_time_s:.0f} s for {len(rows)} of "
        f"{info.total_cases} cases.",
        "",
        *_summary(results),
    ]
    if info.interrupted:
        lines += ["", "**Interrupted: only the cases that completed are listed.**"]
    lines += ["", markdown_table(rows, COLUMNS)]
    return {"md": "\n".join(lines) + "\n", "csv": csv_text(rows, COLUMNS)}


def _job(study: Study, save_dir: str | None):
    return functools.partial(run_arms_case, study=study, save_dir=save_dir)


def _cost(case: ArmsCase) -> float:
    """Control steps, a MuJoCo step counting as four kinematic ones."""
    return case.duration_s / case.period_s * (4.0 if case.simulator == "mujoco" else 1.0)


def _read_robot(top: TableReader, base_dir: Path) -> RobotSpec:
    return RobotSpec()  # the arms are in [arms]


ARMS_KIND = ExperimentKind(
    name="arms",
    read_robot=_read_robot,
    check_controller=_check_controller,
    read_trajectory=_read_trajectory,
    read_settings=read_arms_settings,
    cases=_cases,
    case_name=lambda case: case.name,
    job=_job,
    record=lambda result: result,
    render=_render,
    cost=_cost,
    own_tables=("arms",),
)

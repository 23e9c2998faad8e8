"""The thesis's Table 1, reproduced (FORMULATION §7–8, issue 4).

The grid: the circle at ``T_tot`` = 8, 4, 2, 1 s and the sinusoid at 16, 8, 4, 2 s, each
run with the local method and the predictive method at p = 6 and p = 10; ``T = 0.05 s``,
``τ_p = 1 s``, the thesis's velocity bounds ``π·[1,1,1,1,2.5,2.5,2.5]`` rad/s and constant
acceleration bound 10 rad/s² (passed explicitly: the URDF carries the hardware's limits),
start configuration :data:`~dqcontrol.model.library.LBR4P_Q0`, simulated in MuJoCo (or with
the kinematic loop). The gains are the library's defaults (``K = 10 1/s``, ``T K = 0.5``,
FORMULATION §9), *not* the thesis's.

Each case is a :class:`Table1Case`; :func:`run_case` is a plain module-level function of
picklable arguments that builds the robot, trajectory, controller and simulation inside the
worker (Pinocchio and MuJoCo objects cannot be pickled) and returns a plain dict, so the
same job runs in-process, on a :class:`concurrent.futures.ProcessPoolExecutor` or on a Dask
distributed cluster (:func:`run_table1` with ``scheduler="tcp://host:port"``).

:func:`run_table1` writes ``table1.md`` and ``table1.csv`` atomically
(:mod:`dqcontrol.runs.storage`): our ``e_mean``, ``u_mean``, ``s_mean`` next to the
thesis's (:data:`THESIS_TABLE1`), plus path deviation, translation and rotation error,
execution time, peak torque, bound violations and fallbacks; the ``.md`` starts with the
settings, the machine and the wall time. With ``save_runs`` each run's log is kept as
``table1_runs/<case>.npz`` + ``.json`` (on a remote Dask cluster: on the worker's file
system, so use a shared folder).
"""

from __future__ import annotations

import csv
import io
import math
import os
import platform
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from dqcontrol.errors import ConfigurationError, ParameterError

__all__ = [
    "COLUMNS",
    "CONTROLLERS",
    "GRID_PERIODS",
    "QUICK_PERIODS",
    "SHORT_PERIODS",
    "THESIS_TABLE1",
    "THESIS_VELOCITY_LIMITS",
    "TRAJECTORIES",
    "Table1Case",
    "Table1Result",
    "Table1Settings",
    "format_markdown",
    "run_case",
    "run_table1",
    "table1_cases",
    "table_rows",
]

#: Trajectory kinds of the grid.
TRAJECTORIES = ("circle", "sinusoid")
#: Controller kinds of the grid: the local method, predictive with p = 6 and p = 10.
CONTROLLERS = ("local", "p6", "p10")
#: How each controller kind is written in the tables.
CONTROLLER_LABELS = {"local": "Local", "p6": "p=6", "p10": "p=10"}
#: The thesis's periods ``T_tot`` [s] per trajectory.
GRID_PERIODS = {"circle": (8.0, 4.0, 2.0, 1.0), "sinusoid": (16.0, 8.0, 4.0, 2.0)}
#: The reduced grid (``quick=True``, CI): one period per trajectory, the shortest (where the
#: thesis's claim is strongest).
QUICK_PERIODS = {"circle": (1.0,), "sinusoid": (2.0,)}
#: The "short periods" at which the thesis claims that p = 10 beats Local (issue 4).
SHORT_PERIODS = {"circle": (4.0, 2.0, 1.0), "sinusoid": (8.0, 4.0, 2.0)}
#: The thesis's velocity bounds (eq. 4.13) [rad/s].
THESIS_VELOCITY_LIMITS = tuple(float(v) for v in math.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5]))
#: The thesis's constant acceleration bound [rad/s²].
THESIS_ACCELERATION_LIMIT = 10.0

#: The thesis's Table 1 (CoppeliaSim, T = 0.05 s, τ_p = 1 s; FORMULATION §8):
#: ``(traj, T_tot) -> {metric: (Local, p=6, p=10)}``.
THESIS_TABLE1: dict[tuple[str, float], dict[str, tuple[float, float, float]]] = {
    ("circle", 8.0): {
        "e_mean": (3.0e-3, 3.4e-3, 2.0e-3),
        "u_mean": (1.5427, 1.7393, 1.8393),
        "s_mean": (0.9785, 0.9906, 0.9927),
    },
    ("circle", 4.0): {
        "e_mean": (3.36e-2, 3.2e-3, 2.5e-3),
        "u_mean": (3.6286, 2.8961, 2.6303),
        "s_mean": (0.4786, 0.5639, 0.5714),
    },
    ("circle", 2.0): {
        "e_mean": (1.44e-2, 3.2e-3, 2.9e-3),
        "u_mean": (3.4070, 2.6016, 2.8281),
        "s_mean": (0.1789, 0.2984, 0.3640),
    },
    ("circle", 1.0): {
        "e_mean": (8.23e-2, 2.8e-3, 2.6e-3),
        "u_mean": (4.0542, 3.0039, 3.0258),
        "s_mean": (0.0418, 0.1990, 0.2285),
    },
    ("sinusoid", 16.0): {
        "e_mean": (2.7e-3, 3.1e-3, 1.7e-3),
        "u_mean": (2.1787, 2.3175, 1.7413),
        "s_mean": (0.9996, 0.9400, 0.9863),
    },
    ("sinusoid", 8.0): {
        "e_mean": (2.6e-3, 3.5e-3, 2.2e-3),
        "u_mean": (4.0662, 3.1583, 2.6165),
        "s_mean": (0.7573, 0.5938, 0.6598),
    },
    ("sinusoid", 4.0): {
        "e_mean": (4.4e-3, 3.3e-3, 1.5e-3),
        "u_mean": (4.3542, 2.5370, 2.4295),
        "s_mean": (0.3394, 0.2444, 0.3196),
    },
    ("sinusoid", 2.0): {
        "e_mean": (8.57e-2, 3.0e-3, 1.3e-3),
        "u_mean": (5.0194, 2.4326, 2.3035),
        "s_mean": (0.1648, 0.1319, 0.1562),
    },
}


# ---------------------------------------------------------------------------- the cases
@dataclass(frozen=True)
class Table1Settings:
    """Everything the grid shares (picklable; sent to every worker).

    Attributes:
        period_s: control period ``T`` [s] (thesis: 0.05).
        horizon_s: prediction horizon ``τ_p`` [s] (thesis: 1).
        velocity_limits: ``qd_max`` per joint [rad/s] (thesis: π·[1,1,1,1,2.5,2.5,2.5]).
        acceleration_limit: constant ``a_max`` [rad/s²] (thesis: 10).
        simulator: ``"mujoco"`` (torque-limited velocity servos) or ``"kinematic"``.
        q0: start configuration [rad] (default :data:`LBR4P_Q0`).
        controller_options: extra keyword arguments for every controller, as ``(name,
            value)`` pairs (default: the library's gains and weights with the stall
            damping off, so that the cost is FORMULATION §5's exactly, as in the thesis).
    """

    period_s: float = 0.05
    horizon_s: float = 1.0
    velocity_limits: tuple[float, ...] = THESIS_VELOCITY_LIMITS
    acceleration_limit: float = THESIS_ACCELERATION_LIMIT
    simulator: str = "mujoco"
    q0: tuple[float, ...] | None = None
    controller_options: tuple[tuple[str, object], ...] = (("stall_damping", 0.0),)

    def __post_init__(self) -> None:
        if self.simulator not in ("mujoco", "kinematic"):
            raise ParameterError(
                f"simulator must be 'mujoco' or 'kinematic', got {self.simulator!r}"
            )
        for name in ("period_s", "horizon_s", "acceleration_limit"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be finite and > 0, got {value!r}")

    def start_configuration(self) -> np.ndarray:
        """``q0`` [rad] as an array (:data:`LBR4P_Q0` unless given)."""
        from dqcontrol.model.library import LBR4P_Q0

        return LBR4P_Q0.copy() if self.q0 is None else np.asarray(self.q0, dtype=float)


@dataclass(frozen=True, order=True)
class Table1Case:
    """One cell of the grid: trajectory kind, nominal duration ``T_tot`` [s], controller."""

    trajectory: str
    duration_s: float
    controller: str

    def __post_init__(self) -> None:
        if self.trajectory not in TRAJECTORIES:
            raise ParameterError(
                f"trajectory must be one of {TRAJECTORIES}, got {self.trajectory!r}"
            )
        if self.controller not in CONTROLLERS:
            raise ParameterError(
                f"controller must be one of {CONTROLLERS}, got {self.controller!r}"
            )
        d = self.duration_s
        if not (isinstance(d, int | float) and math.isfinite(d) and d > 0):
            raise ParameterError(f"duration_s (T_tot) must be finite and > 0 [s], got {d!r}")
        object.__setattr__(self, "duration_s", float(d))

    @property
    def name(self) -> str:
        """File-name friendly label, e.g. ``circle_T1s_p10``."""
        return f"{self.trajectory}_T{self.duration_s:g}s_{self.controller}"

    @property
    def label(self) -> str:
        """How the controller is written in the tables (``Local``, ``p=6``, ``p=10``)."""
        return CONTROLLER_LABELS[self.controller]

    def thesis(self, metric: str) -> float | None:
        """The thesis's value of ``metric`` (``e_mean``, ``u_mean``, ``s_mean``) or None."""
        entry = THESIS_TABLE1.get((self.trajectory, self.duration_s))
        if entry is None:
            return None
        return entry[metric][CONTROLLERS.index(self.controller)]

    def cost_estimate(self) -> float:
        """Rough relative cost (for scheduling the longest jobs first)."""
        factor = {"local": 1.0, "p6": 2.0, "p10": 3.0}[self.controller]
        return self.duration_s * factor

    def build(self, settings: Table1Settings):
        """``(robot, controller)`` for this case (fresh objects; call in the worker)."""
        from dqcontrol.controllers import LocalController, PredictiveController
        from dqcontrol.trajectories import Circle, Sinusoid

        robot = _lbr4p()
        trajectory = (Circle if self.trajectory == "circle" else Sinusoid)(self.duration_s)
        kwargs = dict(settings.controller_options)
        kwargs["velocity_limits"] = np.asarray(settings.velocity_limits, dtype=float)
        kwargs["acceleration_limit"] = float(settings.acceleration_limit)
        if self.controller == "local":
            controller = LocalController(robot, trajectory, settings.period_s, **kwargs)
        else:
            controller = PredictiveController(
                robot,
                trajectory,
                settings.period_s,
                num_instants=int(self.controller[1:]),
                horizon_s=settings.horizon_s,
                **kwargs,
            )
        return robot, controller


_LOCAL = threading.local()


def _lbr4p():
    """The LBR4p, loaded once per worker thread (the loops only read the model, but its
    Pinocchio workspace is shared by every call, so threads must not share it)."""
    robot = getattr(_LOCAL, "robot", None)
    if robot is None:
        from dqcontrol.model.library import load_lbr4p

        robot = _LOCAL.robot = load_lbr4p()
    return robot


def table1_cases(
    *,
    quick: bool = False,
    periods: Iterable[float] | None = None,
    trajectories: Iterable[str] | None = None,
    controllers: Iterable[str] | None = None,
) -> list[Table1Case]:
    """The cases of the grid, in the table's order.

    Args:
        quick: one period per trajectory (:data:`QUICK_PERIODS`; for CI).
        periods: keep only these ``T_tot`` [s] of the thesis's grid (for each trajectory
            the ones it has, e.g. ``[2]`` gives circle 2 s and sinusoid 2 s).
        trajectories: subset of :data:`TRAJECTORIES`.
        controllers: subset of :data:`CONTROLLERS`.

    Raises:
        ParameterError: an unknown name or period, or an empty selection.
    """
    trajs = list(TRAJECTORIES if trajectories is None else trajectories)
    ctrls = list(CONTROLLERS if controllers is None else controllers)
    for t in trajs:
        if t not in TRAJECTORIES:
            raise ParameterError(f"unknown trajectory {t!r}; choose from {TRAJECTORIES}")
    for c in ctrls:
        if c not in CONTROLLERS:
            raise ParameterError(f"unknown controller {c!r}; choose from {CONTROLLERS}")
    grid = QUICK_PERIODS if quick else GRID_PERIODS
    wanted = None
    if periods is not None:
        wanted = {float(p) for p in periods}
        known = {p for t in trajs for p in GRID_PERIODS[t]}
        unknown = sorted(wanted - known)
        if unknown:
            raise ParameterError(
                f"periods {unknown} are not in the thesis's grid; choose from "
                + ", ".join(f"{t}: {list(GRID_PERIODS[t])}" for t in trajs)
            )
    cases = [
        Table1Case(t, d, c)
        for t in TRAJECTORIES
        if t in trajs
        for d in grid[t]
        if wanted is None or d in wanted
        for c in CONTROLLERS
        if c in ctrls
    ]
    if not cases:
        raise ParameterError("the selection of trajectories, periods and controllers is empty")
    return cases


# ---------------------------------------------------------------------------- one job
def run_case(
    case: Table1Case,
    settings: Table1Settings | None = None,
    save_dir: str | None = None,
) -> dict:
    """Run one case and return a plain dict (picklable; the job of every executor).

    Returns ``{"case": {trajectory, duration_s, controller}, "simulator", "metrics":
    Metrics.as_dict(), "interrupted", "note", "meta", "wall_time_s", "files"}``; ``files``
    is ``[npz, json]`` when ``save_dir`` is given (the run saved as ``<case.name>``).
    """
    from dqcontrol.runs.storage import save_run
    from dqcontrol.sim.kinematic import run_kinematic
    from dqcontrol.sim.mujoco_loop import run_mujoco

    settings = Table1Settings() if settings is None else settings
    start = time.perf_counter()
    _robot, controller = case.build(settings)
    q0 = settings.start_configuration()
    meta = {
        "experiment": "table1",
        "case": case.name,
        "trajectory": case.trajectory,
        "duration_s": case.duration_s,
        "controller_kind": case.controller,
        "horizon_s": settings.horizon_s,
        "velocity_limits": list(settings.velocity_limits),
        "acceleration_limit": settings.acceleration_limit,
        "gain_per_s": controller.gain_per_s,
        "q0": q0.tolist(),
    }
    run = run_mujoco if settings.simulator == "mujoco" else run_kinematic
    result = run(controller, q0, meta=meta)
    files = None
    if save_dir is not None:
        files = [str(p) for p in save_run(result, save_dir, case.name)]
    return {
        "case": asdict(case),
        "simulator": settings.simulator,
        "metrics": result.metrics.as_dict(),
        "interrupted": bool(result.interrupted),
        "note": result.note,
        "meta": {k: v for k, v in result.log.meta.items() if k != "q0"},
        "wall_time_s": time.perf_counter() - start,
        "files": files,
    }


# ---------------------------------------------------------------------------- the table
#: Columns of ``table1.csv``: (key, header in the .md, format in the .md).
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("traj", "traj", "s"),
    ("T_tot_s", "T_tot [s]", "g"),
    ("controller", "controller", "s"),
    ("e_mean", "e_mean", ".2e"),
    ("e_mean_thesis", "e_mean thesis", ".2e"),
    ("u_mean_rad_s", "u_mean [rad/s]", ".4f"),
    ("u_mean_thesis", "u_mean thesis", ".4f"),
    ("s_mean", "s_mean", ".4f"),
    ("s_mean_thesis", "s_mean thesis", ".4f"),
    ("path_dev_mean_mm", "path dev. mean [mm]", ".2f"),
    ("path_dev_max_mm", "path dev. max [mm]", ".2f"),
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
    ("step_time_median_ms", "step [ms] (median)", ".2f"),
)
#: The .md's first table (beside the thesis) and second table (our further metrics).
_MD_KEYS = ("traj", "T_tot_s", "controller")
_MD_THESIS = _MD_KEYS + (
    "e_mean",
    "e_mean_thesis",
    "u_mean_rad_s",
    "u_mean_thesis",
    "s_mean",
    "s_mean_thesis",
)
_MD_MORE = _MD_KEYS + tuple(
    k for k, _, _ in COLUMNS if k not in _MD_THESIS and k not in ("traj", "T_tot_s")
)


def _row(result: dict) -> dict:
    case = Table1Case(**result["case"])
    m = result["metrics"]

    def mm(key: str) -> float:
        v = m[key]
        return float("nan") if v is None else 1e3 * v

    return {
        "traj": case.trajectory,
        "T_tot_s": case.duration_s,
        "controller": case.label,
        "e_mean": m["e_mean"],
        "e_mean_thesis": case.thesis("e_mean"),
        "u_mean_rad_s": m["u_mean_rad_s"],
        "u_mean_thesis": case.thesis("u_mean"),
        "s_mean": m["s_mean"],
        "s_mean_thesis": case.thesis("s_mean"),
        "path_dev_mean_mm": mm("path_deviation_mean_m"),
        "path_dev_max_mm": mm("path_deviation_max_m"),
        "trans_err_mean_mm": mm("translation_error_mean_m"),
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
        "step_time_median_ms": 1e3 * m["step_time_median_s"],
    }


def table_rows(results: Iterable[dict]) -> list[dict]:
    """Table rows (keys of :data:`COLUMNS`) of :func:`run_case` results, in grid order."""
    order = {(t, d, c): i for i, (t, d, c) in enumerate(_grid_order())}

    def key(r: dict) -> tuple:
        c = r["case"]
        return (order.get((c["trajectory"], c["duration_s"], c["controller"]), 10**6), str(c))

    return [_row(r) for r in sorted(results, key=key)]


def _grid_order() -> list[tuple[str, float, str]]:
    periods = {
        t: sorted(set(GRID_PERIODS[t]) | set(QUICK_PERIODS[t]), reverse=True) for t in TRAJECTORIES
    }
    return [(t, d, c) for t in TRAJECTORIES for d in periods[t] for c in CONTROLLERS]


def _fmt(value, spec: str) -> str:
    if value is None:
        return "—"
    if isinstance(value, float) and not math.isfinite(value):
        return "nan"
    if spec == "s":
        return str(value)
    return format(value, spec)


def _md_table(rows: list[dict], keys: Sequence[str]) -> str:
    spec = {k: (h, f) for k, h, f in COLUMNS}
    lines = [
        "| " + " | ".join(spec[k][0] for k in keys) + " |",
        "|" + "|".join("---" for _ in keys) + "|",
    ]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r[k], spec[k][1]) for k in keys) + " |")
    return "\n".join(lines)


def _csv_text(rows: list[dict]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow([k for k, _, _ in COLUMNS])
    for r in rows:
        out = []
        for k, _, _ in COLUMNS:
            v = r[k]
            out.append("" if v is None else (repr(v) if isinstance(v, float) else str(v)))
        writer.writerow(out)
    return buf.getvalue()


#: Relative difference below which p = 10 and Local count as a tie in the claim check.
CLAIM_TIE = 0.05


def _verdict(ratio: float) -> str:
    if not math.isfinite(ratio):
        return "n/a"
    if ratio < 1.0 - CLAIM_TIE:
        return "better"
    if ratio > 1.0 + CLAIM_TIE:
        return "WORSE"
    return "tie"


def _claim_check(rows: list[dict]) -> str:
    """p = 10 against Local at the short periods (the thesis's claim, issue 4)."""
    by = {(r["traj"], r["T_tot_s"], r["controller"]): r for r in rows}

    def ratio(a: float, b: float) -> float:
        return a / b if b > 0 else float("nan")

    lines = []
    counts = {"e_mean": {}, "path_dev_mean_mm": {}}
    for traj in TRAJECTORIES:
        for d in SHORT_PERIODS[traj]:
            loc = by.get((traj, d, "Local"))
            p10 = by.get((traj, d, "p=10"))
            if loc is None or p10 is None:
                continue
            r_e = ratio(p10["e_mean"], loc["e_mean"])
            r_dm = ratio(p10["path_dev_mean_mm"], loc["path_dev_mean_mm"])
            r_dx = ratio(p10["path_dev_max_mm"], loc["path_dev_max_mm"])
            for key, r in (("e_mean", r_e), ("path_dev_mean_mm", r_dm)):
                v = _verdict(r)
                counts[key][v] = counts[key].get(v, 0) + 1
            lines.append(
                f"| {traj} | {d:g} | {r_e:.2f} ({_verdict(r_e)}) | {r_dm:.2f} ({_verdict(r_dm)}) "
                f"| {r_dx:.2f} ({_verdict(r_dx)}) |"
            )
    if not lines:
        return ""
    head = [
        "## The thesis's claim at the short periods (p=10 vs Local)",
        "",
        f"Ratios p=10 / Local: < 1 means the predictive method is better; within "
        f"±{CLAIM_TIE:.0%} counts as a tie.",
        "",
        "| traj | T_tot [s] | e_mean | path dev. mean | path dev. max |",
        "|---|---|---|---|---|",
    ]

    def summary(key: str) -> str:
        c = counts[key]
        return ", ".join(f"{c[v]} {v}" for v in ("better", "tie", "WORSE", "n/a") if c.get(v))

    tail = [
        "",
        f"e_mean: {summary('e_mean')}; mean path deviation: {summary('path_dev_mean_mm')} "
        f"(of {len(lines)} short-period cases).",
    ]
    return "\n".join(head + lines + tail)


def _settings_lines(settings: Table1Settings, physics_dt_s: float | None = None) -> list[str]:
    """The settings as Markdown bullet lines (gains read from real controllers)."""
    local = Table1Case("circle", 1.0, "local").build(settings)[1]
    pred = Table1Case("circle", 1.0, "p10").build(settings)[1]
    vel = ", ".join(f"{v:.4f}" for v in settings.velocity_limits)
    thesis_vel = settings.velocity_limits == THESIS_VELOCITY_LIMITS
    thesis_acc = settings.acceleration_limit == THESIS_ACCELERATION_LIMIT
    q0 = ", ".join(f"{v:g}" for v in settings.start_configuration())
    sim = (
        "MuJoCo (torque-limited velocity servos from the URDF's effort limits, "
        + (f"physics step {1e3 * physics_dt_s:g} ms, " if physics_dt_s else "")
        + "command held over each period)"
        if settings.simulator == "mujoco"
        else "kinematic loop (ideal velocity tracking, q += T qd)"
    )
    extra = {k: v for k, v in settings.controller_options if k != "stall_damping"}
    return [
        f"- simulator: {sim}",
        "- robot: KUKA LBR4p (`robots/lbr4p/lbr4p.urdf`), end-effector `lbr4p_flange`; "
        f"start q0 = [{q0}] rad" + (" (`LBR4P_Q0`)" if settings.q0 is None else ""),
        f"- control period T = {settings.period_s:g} s; prediction horizon τ_p = "
        f"{settings.horizon_s:g} s, instants τ_i = τ_p (i-1)²/(p-1)², p = 6 and 10",
        f"- velocity bounds |qd| ≤ [{vel}] rad/s"
        + (
            " — the thesis's π·[1,1,1,1,2.5,2.5,2.5] (eq. 4.13), passed explicitly"
            if thesis_vel
            else ""
        ),
        f"- acceleration bound |qdd| ≤ {settings.acceleration_limit:g} rad/s² (constant"
        + (", the thesis's" if thesis_acc else "")
        + "); position bounds: the URDF's joint limits",
        f"- gains and weights: K = {local.gain_per_s:g} 1/s (T·K = "
        f"{settings.period_s * local.gain_per_s:g}), λ1 = {local.task_weight:g}, "
        f"λ2 = {local.scaling_weight:g}, μ = {local.regularization:g}, stall damping "
        f"{local.stall_damping:g}"
        + (" (off: FORMULATION §5's cost exactly)" if local.stall_damping == 0.0 else "")
        + f"; phase prediction "
        f"'{pred.phase_prediction}', solver '{pred.solver}'"
        + (f"; extra options {extra}" if extra else ""),
        "- the thesis: CoppeliaSim, same T and τ_p, K = 200·T_tot (circle) and 500/P "
        "(sinusoid), i.e. T·K ≥ 2 — outside the stable range (FORMULATION §9); its numbers "
        "are shown beside ours, not matched",
        "- units: e_mean = mean ‖vec8(x_d) - vec8(x)‖ (dimensionless, as in the thesis); "
        "u_mean = mean ‖qd_cmd‖ [rad/s]; metrics over the samples until σ reaches T_tot",
    ]


def format_markdown(
    rows: list[dict],
    settings: Table1Settings,
    *,
    wall_time_s: float,
    executor: str,
    command: str | None = None,
    interrupted: bool = False,
    physics_dt_s: float | None = None,
) -> str:
    """The ``table1.md`` text: header (settings, machine, wall time) and the tables."""
    now = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    machine = (
        f"{platform.platform()}, {platform.machine()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}"
    )
    lines = [
        "# Table 1 of the thesis, reproduced with dqcontrol",
        "",
        f"Generated {now}" + (f" by `{command}`" if command else "") + ".",
        "",
        *_settings_lines(settings, physics_dt_s),
        f"- machine: {machine}; executor: {executor}",
        f"- wall time: {wall_time_s:.1f} s for {len(rows)} cases",
    ]
    if interrupted:
        lines += ["", "**Interrupted: only the cases that completed are listed.**"]
    lines += [
        "",
        "## Beside the thesis's Table 1",
        "",
        _md_table(rows, _MD_THESIS),
        "",
        "## Further metrics (ours)",
        "",
        _md_table(rows, _MD_MORE),
    ]
    claim = _claim_check(rows)
    if claim:
        lines += ["", claim]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- the sweep
@dataclass
class Table1Result:
    """What :func:`run_table1` produced."""

    rows: list[dict]
    results: list[dict]
    markdown: str
    csv_path: Path
    md_path: Path
    wall_time_s: float
    executor: str
    interrupted: bool = False
    runs_dir: Path | None = None
    failures: list[str] = field(default_factory=list)


def _progress(total: int, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="table1", unit="case", disable=not enabled, file=sys.stderr)


def _run_serial(cases, settings, save_dir, on_done: Callable[[dict], None]) -> None:
    for case in cases:
        on_done(run_case(case, settings, save_dir))


#: How long to wait for a Dask scheduler to answer [s].
DASK_CONNECT_TIMEOUT_S = 30.0
#: Thread-count variables of the BLAS/OpenMP runtimes, set to 1 in the pool's workers.
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Environment for spawning workers: one BLAS/OpenMP thread each (N workers on N cores
    otherwise oversubscribe the cores), unless the user set these variables."""
    saved = {k: os.environ.get(k) for k in _THREAD_VARIABLES}
    for k, v in saved.items():
        if v is None:
            os.environ[k] = "1"
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)


def _run_pool(cases, settings, save_dir, workers: int, on_done) -> None:
    # spawn: fresh interpreters (no forked Pinocchio/MuJoCo/BLAS state), same on every OS
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        with _single_threaded_children():  # the workers start at the first submissions
            futures = [pool.submit(run_case, c, settings, save_dir) for c in cases]
        try:
            for fut in as_completed(futures):
                on_done(fut.result())
        except BrokenProcessPool as exc:
            raise ConfigurationError(
                f"a worker process of the pool died ({exc}). Called from a script? The workers "
                "are started with 'spawn', which re-imports the main module: put the call under "
                "\"if __name__ == '__main__':\" (or use workers=1)"
            ) from None
        except BaseException:
            for fut in futures:
                fut.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def _run_dask(cases, settings, save_dir, address: str, on_done) -> None:
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_as_completed
    except ImportError as exc:
        raise ConfigurationError(
            f"--scheduler needs Dask distributed ({exc}); install it with "
            "'pip install \"dqcontrol[dask]\"'"
        ) from None
    try:
        client = Client(address, timeout=DASK_CONNECT_TIMEOUT_S)
    except OSError as exc:
        raise ConfigurationError(
            f"cannot connect to the Dask scheduler at {address!r}: {exc}"
        ) from None
    with client:
        futures = client.map(
            run_case,
            cases,
            settings=settings,
            save_dir=save_dir,
            pure=False,
            key=[f"table1-{c.name}-{time.time_ns()}" for c in cases],
        )
        try:
            for fut in dask_as_completed(futures):
                on_done(fut.result())
        except BaseException:
            client.cancel(futures)
            raise


def run_table1(
    out: str | os.PathLike = "results",
    *,
    quick: bool = False,
    periods: Iterable[float] | None = None,
    trajectories: Iterable[str] | None = None,
    controllers: Iterable[str] | None = None,
    simulator: str = "mujoco",
    settings: Table1Settings | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    save_runs: bool = True,
    progress: bool = True,
    command: str | None = None,
) -> Table1Result:
    """Run the grid and write ``out/table1.md`` and ``out/table1.csv``.

    Args:
        out: results folder (created if needed).
        quick, periods, trajectories, controllers: the selection (:func:`table1_cases`).
        simulator: ``"mujoco"`` or ``"kinematic"`` (ignored if ``settings`` is given).
        settings: the shared settings (default: the thesis's, :class:`Table1Settings`).
        workers: processes of the local pool (default: all cores; 1 runs in this process).
        scheduler: address of a Dask distributed scheduler (``"tcp://host:8786"``); the
            same job then runs on the cluster's workers (``workers`` is ignored).
        save_runs: keep each run as ``out/table1_runs/<case>.npz`` + ``.json``.
        progress: show a progress bar (tqdm, on stderr).
        command: the command line, quoted in the ``.md`` header.

    Ctrl-C stops the sweep, writes the table of the cases that completed (marked as
    interrupted) and re-raises :class:`KeyboardInterrupt`.

    The pool's workers are started with ``spawn`` (fresh interpreters): a script that calls
    this function must do so under ``if __name__ == "__main__":``.
    """
    from dqcontrol.runs.storage import atomic_write_text

    if settings is None:
        settings = Table1Settings(simulator=simulator)
    cases = table1_cases(
        quick=quick, periods=periods, trajectories=trajectories, controllers=controllers
    )
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs_dir = out_dir / "table1_runs" if save_runs else None
    save_dir = None if runs_dir is None else str(runs_dir.resolve())
    # longest jobs first: better balance across workers
    ordered = sorted(cases, key=lambda c: -c.cost_estimate())
    if scheduler:
        executor = f"Dask distributed at {scheduler}"
    else:
        n = (os.cpu_count() or 1) if workers is None else int(workers)
        if n < 1:
            raise ParameterError(f"workers must be ≥ 1, got {workers!r}")
        n = min(n, len(cases))
        executor = "in-process (1 worker)" if n == 1 else f"process pool, {n} workers"

    results: list[dict] = []
    bar = _progress(len(cases), progress)

    def on_done(res: dict) -> None:
        results.append(res)
        bar.set_postfix_str(Table1Case(**res["case"]).name, refresh=False)
        bar.update(1)

    start = time.perf_counter()
    interrupted = False
    try:
        if scheduler:
            _run_dask(ordered, settings, save_dir, scheduler, on_done)
        elif n == 1:
            _run_serial(ordered, settings, save_dir, on_done)
        else:
            _run_pool(ordered, settings, save_dir, n, on_done)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
    wall = time.perf_counter() - start
    rows = table_rows(results)
    markdown = format_markdown(
        rows,
        settings,
        wall_time_s=wall,
        executor=executor,
        command=command,
        interrupted=interrupted,
        physics_dt_s=next((r["meta"].get("physics_dt_s") for r in results), None),
    )
    md_path = atomic_write_text(out_dir / "table1.md", markdown)
    csv_path = atomic_write_text(out_dir / "table1.csv", _csv_text(rows))
    if interrupted:
        raise KeyboardInterrupt
    failures = [Table1Case(**r["case"]).name for r in results if r["interrupted"]]
    return Table1Result(
        rows=rows,
        results=results,
        markdown=markdown,
        csv_path=csv_path,
        md_path=md_path,
        wall_time_s=wall,
        executor=executor,
        interrupted=interrupted,
        runs_dir=runs_dir,
        failures=failures,
    )

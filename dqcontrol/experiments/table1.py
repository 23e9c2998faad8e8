"""The thesis's Table 1, reproduced, with the path-following controller beside it
(docs/theory.md §4, §7, §8).

The grid: the circle at ``T_tot`` = 8, 4, 2, 1 s and the sinusoid at 16, 8, 4, 2 s, each
run with the local method, the predictive method at p = 6 and p = 10 (the thesis's three
rows) and the path-following controller (p = 10 intervals, label ``path-following``).
The experiment's numbers come from :mod:`dqcontrol.experiments.thesis`: ``T = 0.05 s``,
``τ_p = 1 s``, the velocity bounds ``π·[1,1,1,1,2.5,2.5,2.5]`` rad/s, the constant
acceleration bound 10 rad/s² (passed explicitly: the URDF carries the hardware's limits)
and the start configuration :data:`~dqcontrol.model.library.LBR4P_Q0`, simulated in MuJoCo
(or with the kinematic loop). The gains are the library's defaults (``K = 10 1/s``,
``T K = 0.5``, docs/theory.md §4.3), *not* the thesis's. The path-following rows take the
thesis's velocity bounds, ``T``, ``τ_p`` and :attr:`Table1Settings.path_following_options`
(default :data:`PATH_FOLLOWING_OPTIONS`).

Besides the thesis's metrics, every row has the TOPP-RA lower bound of its task's
execution time under the same velocity and acceleration bounds as its controller
(:mod:`dqcontrol.experiments.time_optimal`; the thesis's rows along the least-norm joint
path, the path-following rows along the joint path of their own posture level), the ratio
of the execution time to it, and the largest path deviation between the control samples
(along MuJoCo's physics steps, or the kinematic loop's straight joint motion).

Each case is a :class:`Table1Case`; :func:`run_case` is a plain module-level function of
picklable arguments that builds the robot, trajectory, controller and simulation inside the
worker (Pinocchio and MuJoCo objects cannot be pickled) through the case runner
(:mod:`dqcontrol.experiments.runner`) and returns a plain dict, so the same job runs
in-process, on a :class:`concurrent.futures.ProcessPoolExecutor` or on a Dask distributed
cluster (:func:`run_table1` with ``scheduler="tcp://host:port"``).

:func:`run_table1` writes ``table1.md`` and ``table1.csv`` atomically
(:mod:`dqcontrol.runs.storage`): our ``e_mean``, ``u_mean``, ``s_mean`` next to the
thesis's (:data:`THESIS_TABLE1`), plus path deviation, translation and rotation error,
execution time, the time-optimal bound, peak torque, bound violations and fallbacks; the
``.md`` starts with the settings, the machine and the wall time. With ``save_runs`` each
run's log is kept as ``table1_runs/<case>.npz`` + ``.json`` (on a remote Dask cluster: on
the worker's file system, so use a shared folder).
"""

from __future__ import annotations

import functools
import math
import os
import platform
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.experiments.executor import DASK_CONNECT_TIMEOUT_S
from dqcontrol.experiments.tables import csv_text, format_cell, markdown_table
from dqcontrol.experiments.thesis import (
    THESIS_ACCELERATION_LIMIT,
    THESIS_HORIZON_S,
    THESIS_PERIOD_S,
    THESIS_VELOCITY_LIMITS,
)

if TYPE_CHECKING:
    from dqcontrol.experiments.sweep import SweepOutcome

__all__ = [
    "COLUMNS",
    "CONTROLLERS",
    "GRID_PERIODS",
    "PATH_FOLLOWING_OPTIONS",
    "QUICK_PERIODS",
    "SHORT_PERIODS",
    "THESIS_CONTROLLERS",
    "THESIS_TABLE1",
    "THESIS_VELOCITY_LIMITS",
    "TRAJECTORIES",
    "Table1Case",
    "Table1Result",
    "Table1Settings",
    "format_csv",
    "format_markdown",
    "run_case",
    "run_table1",
    "table1_cases",
    "table_rows",
]

#: Trajectory kinds of the grid.
TRAJECTORIES = ("circle", "sinusoid")
#: The thesis's controllers: the local method, predictive with p = 6 and p = 10.
THESIS_CONTROLLERS = ("local", "p6", "p10")
#: Controllers of the grid (names of :mod:`dqcontrol.registry`): the thesis's and the
#: path-following controller.
CONTROLLERS = (*THESIS_CONTROLLERS, "pf")
#: The thesis's periods ``T_tot`` [s] per trajectory.
GRID_PERIODS = {"circle": (8.0, 4.0, 2.0, 1.0), "sinusoid": (16.0, 8.0, 4.0, 2.0)}
#: The reduced grid (``quick=True``, CI): one period per trajectory, the shortest (where the
#: thesis's claim is strongest).
QUICK_PERIODS = {"circle": (1.0,), "sinusoid": (2.0,)}
#: The "short periods" at which the thesis claims that p = 10 beats Local.
SHORT_PERIODS = {"circle": (4.0, 2.0, 1.0), "sinusoid": (8.0, 4.0, 2.0)}
#: Keyword arguments of the path-following rows besides the thesis's velocity bounds,
#: ``T``, ``τ_p`` and p = 10: none, the controller's defaults. Behind a velocity servo of
#: time constant ``τ_v`` a command step ``Δ`` asks for ``Δ/τ_v`` at once, so the
#: controller's dynamics-aware acceleration limit is scaled by ``τ_v/T``: at ``τ_v = 5 ms``
#: and ``T = 50 ms`` its 50 rad/s² cap becomes 5 rad/s² on the LBR4p, the figure at which
#: MuJoCo's servos stay below their torque limits in every case (docs/table1_analysis.md).
PATH_FOLLOWING_OPTIONS: tuple[tuple[str, object], ...] = ()
#: Path samples of the time-optimal bound (0: not computed).
BOUND_SAMPLES = 2001


#: The thesis's Table 1 (CoppeliaSim, T = 0.05 s, τ_p = 1 s):
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
        acceleration_limit: constant ``a_max`` of the thesis's controllers [rad/s²]
            (thesis: 10).
        simulator: ``"mujoco"`` (torque-limited velocity servos) or ``"kinematic"``.
        q0: start configuration [rad] (default :data:`LBR4P_Q0`).
        controller_options: extra keyword arguments for the thesis's controllers, as
            ``(name, value)`` pairs (default: the library's gains and weights with the
            stall damping off, so that the cost is the thesis's exactly, docs/theory.md
            §4.2).
        path_following_options: extra keyword arguments for the path-following rows
            (default :data:`PATH_FOLLOWING_OPTIONS`); without an ``acceleration_limit`` the
            controller's own default applies.
        servo_model: in MuJoCo, give the path-following rows the simulation's velocity-servo
            time constant (``servo_time_constant_s``, unless the options give one), so that
            their prediction includes the servos' lag; the kinematic loop has none.
        bound_samples: path samples of the time-optimal bound (0: not computed, NaN).
        between_samples: measure the path deviation between the control samples.
    """

    period_s: float = THESIS_PERIOD_S
    horizon_s: float = THESIS_HORIZON_S
    velocity_limits: tuple[float, ...] = THESIS_VELOCITY_LIMITS
    acceleration_limit: float = THESIS_ACCELERATION_LIMIT
    simulator: str = "mujoco"
    q0: tuple[float, ...] | None = None
    controller_options: tuple[tuple[str, object], ...] = (("stall_damping", 0.0),)
    path_following_options: tuple[tuple[str, object], ...] = PATH_FOLLOWING_OPTIONS
    servo_model: bool = True
    bound_samples: int = BOUND_SAMPLES
    between_samples: bool = True

    def __post_init__(self) -> None:
        if self.simulator not in ("mujoco", "kinematic"):
            raise ParameterError(
                f"simulator must be 'mujoco' or 'kinematic', got {self.simulator!r}"
            )
        for name in ("period_s", "horizon_s", "acceleration_limit"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be finite and > 0, got {value!r}")
        samples = self.bound_samples
        if (
            isinstance(samples, bool)
            or not isinstance(samples, int)
            or not (samples == 0 or samples >= 10)
        ):
            raise ParameterError(f"bound_samples must be 0 or an integer ≥ 10, got {samples!r}")

    def start_configuration(self) -> np.ndarray:
        """``q0`` [rad] as an array (:data:`LBR4P_Q0` unless given)."""
        from dqcontrol.experiments.thesis import THESIS_Q0

        return THESIS_Q0.copy() if self.q0 is None else np.asarray(self.q0, dtype=float)


def _canonical(controller: str) -> str:
    """The registry's canonical name of ``controller``, checked to be in the grid."""
    from dqcontrol.registry import controller_spec

    try:
        name = controller_spec(controller).name
    except ParameterError:
        name = None
    if name not in CONTROLLERS:
        raise ParameterError(
            f"unknown controller {controller!r} for Table 1; choose from {CONTROLLERS} "
            "(or an alias such as path-following)"
        )
    return name


@dataclass(frozen=True, order=True)
class Table1Case:
    """One cell of the grid: trajectory kind, nominal duration ``T_tot`` [s], controller
    (a name of :data:`CONTROLLERS` or an alias; kept as the canonical name)."""

    trajectory: str
    duration_s: float
    controller: str

    def __post_init__(self) -> None:
        if self.trajectory not in TRAJECTORIES:
            raise ParameterError(
                f"trajectory must be one of {TRAJECTORIES}, got {self.trajectory!r}"
            )
        object.__setattr__(self, "controller", _canonical(self.controller))
        d = self.duration_s
        if not (isinstance(d, int | float) and math.isfinite(d) and d > 0):
            raise ParameterError(f"duration_s (T_tot) must be finite and > 0 [s], got {d!r}")
        object.__setattr__(self, "duration_s", float(d))

    @property
    def name(self) -> str:
        """File-name friendly label, e.g. ``circle_T1s_p10``."""
        return f"{self.trajectory}_T{self.duration_s:g}s_{self.controller}"

    @property
    def thesis_row(self) -> bool:
        """Whether the thesis has this controller (its rows, its constant bounds)."""
        return self.controller in THESIS_CONTROLLERS

    @property
    def label(self) -> str:
        """How the controller is written in the tables (``Local``, ``p=6``, ``p=10``,
        ``path-following``): the registry's label."""
        from dqcontrol.registry import controller_spec

        return controller_spec(self.controller).table_label

    def thesis(self, metric: str) -> float | None:
        """The thesis's value of ``metric`` (``e_mean``, ``u_mean``, ``s_mean``) or None."""
        entry = THESIS_TABLE1.get((self.trajectory, self.duration_s))
        if entry is None or not self.thesis_row:
            return None
        return entry[metric][THESIS_CONTROLLERS.index(self.controller)]

    def cost_estimate(self) -> float:
        """Rough relative cost (for scheduling the longest jobs first)."""
        factor = {"local": 1.0, "p6": 2.0, "p10": 3.0, "pf": 8.0}[self.controller]
        return self.duration_s * factor

    def trajectory_metadata(self) -> dict:
        """The task, as :func:`~dqcontrol.trajectories.trajectory_from_metadata` reads it."""
        return {"trajectory": self.trajectory, "duration_s": self.duration_s}

    def controller_options(self, settings: Table1Settings) -> dict:
        """The controller's keyword arguments (besides robot, trajectory, period)."""
        velocity = np.asarray(settings.velocity_limits, dtype=float)
        if self.thesis_row:
            kwargs = dict(settings.controller_options)
            kwargs["velocity_limits"] = velocity
            kwargs["acceleration_limit"] = float(settings.acceleration_limit)
        else:
            # the thesis's convention for every row: the task ends at speed
            kwargs = {
                "velocity_limits": velocity,
                "end": "at_speed",
                **dict(settings.path_following_options),
            }
            if settings.servo_model and settings.simulator == "mujoco":
                kwargs.setdefault("servo_time_constant_s", _mujoco_servo_time_constant_s())
        if self.controller != "local":
            kwargs["horizon_s"] = settings.horizon_s
        return kwargs

    def build(self, settings: Table1Settings):
        """``(robot, controller)`` for this case (fresh objects; call in the worker)."""
        from dqcontrol.experiments.runner import build_trajectory, lbr4p
        from dqcontrol.registry import build_controller

        robot = lbr4p()
        trajectory = build_trajectory(self.trajectory_metadata())
        controller = build_controller(
            self.controller, robot, trajectory, settings.period_s,
            **self.controller_options(settings),
        )  # fmt: skip
        return robot, controller

    def bound_constraints(self, settings: Table1Settings) -> dict:
        """The keywords of the time-optimal bound with this row's limits: the thesis's rows
        along the least-norm joint path (``K_p = 0``, what their damping term picks) with
        their constant bounds; the path-following rows along their posture level's joint
        path with their own velocity, acceleration and torque limits. Speed cap ``s ≤ 1``."""
        options = self.controller_options(settings)
        out = {
            "velocity_limits": np.asarray(options["velocity_limits"], dtype=float),
            "speed_cap": 1.0,
            "samples": settings.bound_samples,
        }
        if self.thesis_row:
            out["acceleration_limit"] = float(settings.acceleration_limit)
            out["posture_gain_per_s"] = 0.0
            return out
        acceleration = options.get("acceleration_limit", "dynamics")
        out["acceleration_limit"] = acceleration
        if isinstance(acceleration, str):
            for key in ("acceleration_floor", "acceleration_cap"):
                if key in options:
                    out[key] = options[key]
        out["posture_gain_per_s"] = float(options.get("posture_gain_per_s", 1.0))
        fraction = options.get("torque_limit_fraction")
        if fraction is not None:
            from dqcontrol.experiments.runner import lbr4p

            out["torque_limits"] = float(fraction) * lbr4p().limits.effort_max
        return out


def _mujoco_servo_time_constant_s() -> float:
    """``τ_v`` [s] of :class:`~dqcontrol.sim.MujocoSimulation`'s velocity servos (its
    default, which the runs use)."""
    from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S

    return SERVO_TIME_CONSTANT_S


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
        controllers: subset of :data:`CONTROLLERS` (aliases of the registry accepted).

    Raises:
        ParameterError: an unknown name or period, or an empty selection.
    """
    trajs = list(TRAJECTORIES if trajectories is None else trajectories)
    ctrls = [_canonical(c) for c in (CONTROLLERS if controllers is None else controllers)]
    for t in trajs:
        if t not in TRAJECTORIES:
            raise ParameterError(f"unknown trajectory {t!r}; choose from {TRAJECTORIES}")
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
    Metrics.as_dict(), "path_dev_max_between_m", "torque_peak_ratio", "toppra_bound_s",
    "interrupted", "note", "meta", "wall_time_s", "files"}``; ``files`` is ``[npz, json]``
    when ``save_dir`` is given (the run saved as ``<case.name>``).
    """
    from dqcontrol.experiments.runner import simulate, time_optimal_duration
    from dqcontrol.runs.storage import save_run

    settings = Table1Settings() if settings is None else settings
    start = time.perf_counter()
    robot, controller = case.build(settings)
    q0 = settings.start_configuration()
    options = case.controller_options(settings)
    meta = {
        "experiment": "table1",
        "case": case.name,
        **case.trajectory_metadata(),
        "controller_kind": case.controller,
        "horizon_s": settings.horizon_s,
        "velocity_limits": list(settings.velocity_limits),
        "acceleration_limit": options.get("acceleration_limit", "dynamics"),
        "gain_per_s": getattr(controller, "gain_per_s", None),
        "q0": q0.tolist(),
    }
    run = simulate(
        controller, q0, settings.simulator, meta=meta, between_samples=settings.between_samples
    )
    result = run.result
    notes = [result.note] if result.note else []
    bound = math.nan
    if settings.bound_samples:
        bound, why = time_optimal_duration(
            robot, controller.trajectory, q0, **case.bound_constraints(settings)
        )
        if why:
            notes.append(why)
    files = None
    if save_dir is not None:
        files = [str(p) for p in save_run(result, save_dir, case.name)]
    return {
        "case": asdict(case),
        "simulator": settings.simulator,
        "metrics": result.metrics.as_dict(),
        "path_dev_max_between_m": run.between_deviation_max_m,
        "torque_peak_ratio": _torque_peak_ratio(result, robot),
        "toppra_bound_s": bound,
        "interrupted": bool(result.interrupted),
        "note": "; ".join(notes),
        "meta": {k: v for k, v in result.log.meta.items() if k != "q0"},
        "wall_time_s": time.perf_counter() - start,
        "files": files,
    }


def _torque_peak_ratio(result, robot) -> float:
    """Largest ``|τ_j| / τ_max_j`` over the task's samples and the joints (1: a joint at its
    torque limit); NaN without torques (kinematic loop)."""
    peak = result.log.torque_peak[: result.metrics.samples]
    if peak.size == 0 or not np.all(np.isfinite(peak)):
        return math.nan
    return float(np.max(np.abs(peak) / robot.limits.effort_max))


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
    ("path_dev_mean_mm", "path dev. mean [mm]", ".3f"),
    ("path_dev_max_mm", "path dev. max [mm]", ".3f"),
    ("path_dev_max_between_mm", "path dev. max between samples [mm]", ".3f"),
    ("trans_err_mean_mm", "transl. err. mean [mm]", ".2f"),
    ("rot_err_mean_deg", "rot. err. mean [deg]", ".3f"),
    ("exec_time_s", "exec. time [s]", ".2f"),
    ("exec_ratio", "exec./T_tot", ".2f"),
    ("toppra_bound_s", "TOPP-RA bound [s]", ".3f"),
    ("exec_over_bound", "exec./bound", ".3f"),
    ("torque_peak_nm", "peak torque [N·m]", ".1f"),
    ("torque_peak_ratio", "peak torque / limit", ".3f"),
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

    def mm(value: float | None) -> float:
        return float("nan") if value is None else 1e3 * value

    bound = result.get("toppra_bound_s", math.nan)
    bound = math.nan if bound is None else float(bound)
    exec_time = m["execution_time_s"]
    exec_over = exec_time / bound if exec_time is not None and bound > 0 else math.nan
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
        "path_dev_mean_mm": mm(m["path_deviation_mean_m"]),
        "path_dev_max_mm": mm(m["path_deviation_max_m"]),
        "path_dev_max_between_mm": mm(result.get("path_dev_max_between_m")),
        "trans_err_mean_mm": mm(m["translation_error_mean_m"]),
        "rot_err_mean_deg": math.degrees(m["rotation_error_mean_rad"]),
        "exec_time_s": exec_time,
        "exec_ratio": m["execution_ratio"],
        "toppra_bound_s": bound,
        "exec_over_bound": exec_over,
        "torque_peak_nm": m["torque_peak_nm"],
        "torque_peak_ratio": result.get("torque_peak_ratio", math.nan),
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
    return format_cell(value, spec)


def _md_table(rows: list[dict], keys: Sequence[str]) -> str:
    spec = {k: (k, h, f) for k, h, f in COLUMNS}
    return markdown_table(rows, [spec[k] for k in keys])


def format_csv(rows: list[dict]) -> str:
    """``table1.csv``'s text: the keys of :data:`COLUMNS`, floats at full precision."""
    return csv_text(rows, COLUMNS)


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
    """The predictive p = 10 against Local at the short periods (the thesis's claim)."""
    by = {(r["traj"], r["T_tot_s"], r["controller"]): r for r in rows}

    def ratio(a: float, b: float) -> float:
        return a / b if b > 0 else float("nan")

    lines = []
    counts: dict[str, dict[str, int]] = {"e_mean": {}, "path_dev_mean_mm": {}}
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


def _path_following_check(rows: list[dict]) -> str:
    """Per case: the path-following row's largest path deviation and time against the
    thesis's rows (their best deviation) and the time-optimal bound."""
    label = Table1Case("circle", 1.0, "pf").label
    by = {(r["traj"], r["T_tot_s"], r["controller"]): r for r in rows}
    lines = []
    for traj in TRAJECTORIES:
        for d in sorted({r["T_tot_s"] for r in rows if r["traj"] == traj}, reverse=True):
            pf = by.get((traj, d, label))
            others = [r for (t, dd, c), r in by.items() if t == traj and dd == d and c != label]
            if pf is None:
                continue
            best = min((r["path_dev_max_mm"] for r in others), default=math.nan)
            lines.append(
                f"| {traj} | {d:g} | {_fmt(pf['path_dev_max_mm'], '.3f')} | "
                f"{_fmt(best, '.3f')} | {_fmt(pf['path_dev_max_between_mm'], '.3f')} | "
                f"{_fmt(pf['exec_time_s'], '.2f')} | {_fmt(pf['exec_over_bound'], '.3f')} | "
                f"{_fmt(pf['torque_peak_ratio'], '.3f')} | {pf['completed']} |"
            )
    if not lines:
        return ""
    head = [
        f"## The path-following rows ({label})",
        "",
        "Largest path deviation at the control samples against the best of the thesis's "
        "rows of the same case, the largest between the samples, the execution time and "
        "its ratio to the time-optimal bound, and the peak torque over its limit (1: a "
        "joint at its torque limit).",
        "",
        "| traj | T_tot [s] | dev. max [mm] | thesis's best dev. max [mm] | dev. max between "
        "[mm] | exec. time [s] | exec./bound | peak torque / limit | completed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    return "\n".join(head + lines)


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
        "- acceleration bound of the thesis's rows |qdd| ≤ "
        f"{settings.acceleration_limit:g} rad/s² (constant"
        + (", the thesis's" if thesis_acc else "")
        + "); position bounds: the URDF's joint limits",
        f"- gains and weights: K = {local.gain_per_s:g} 1/s (T·K = "
        f"{settings.period_s * local.gain_per_s:g}), λ1 = {local.task_weight:g}, "
        f"λ2 = {local.scaling_weight:g}, μ = {local.regularization:g}, stall damping "
        f"{local.stall_damping:g}"
        + (" (off: the thesis's cost exactly)" if local.stall_damping == 0.0 else "")
        + f"; phase prediction "
        f"'{pred.phase_prediction}', solver '{pred.solver}'"
        + (f"; extra options {extra}" if extra else ""),
        "- the thesis: CoppeliaSim, "
        + (
            "same T and τ_p"
            if settings.period_s == THESIS_PERIOD_S
            else f"T = {THESIS_PERIOD_S:g} s (not this table's), same τ_p"
        )
        + ", K = 200·T_tot (circle) and 500/P (sinusoid), i.e. T·K ≥ 2 — outside the stable "
        "range (docs/theory.md §4.3); its numbers are shown beside ours, not matched",
        "- units: e_mean = mean ‖vec8(x_d) - vec8(x)‖ (dimensionless, as in the thesis); "
        "u_mean = mean ‖qd_cmd‖ [rad/s]; metrics over the samples until σ reaches T_tot",
        _path_following_line(settings),
        _bound_line(settings),
    ]


def _path_following_line(settings: Table1Settings) -> str:
    options = dict(settings.path_following_options)
    acceleration = options.pop("acceleration_limit", "dynamics")
    acc = (
        f"|qdd| ≤ {acceleration:g} rad/s² (constant)"
        if not isinstance(acceleration, str)
        else "its own dynamics-aware acceleration limit ((τ_max - |g|)/M_jj)"
    )
    return (
        "- path-following rows (registry name `pf`): p = 10 intervals over τ_p = "
        f"{settings.horizon_s:g} s, the same velocity bounds, {acc}"
        + (f", options {options}" if options else "")
        + (
            f", the servos' time constant τ_v = {1e3 * _mujoco_servo_time_constant_s():g} ms "
            "in its prediction"
            if settings.servo_model and settings.simulator == "mujoco"
            else ""
        )
        + "; path first, progress second, posture third (docs/theory.md §8)"
    )


def _bound_line(settings: Table1Settings) -> str:
    if not settings.bound_samples:
        return "- TOPP-RA bound: not computed (bound_samples = 0)"
    return (
        "- TOPP-RA bound: the time-optimal execution of the same geometric path from rest at "
        f"q0 ({settings.bound_samples} path samples, speed cap s ≤ 1) under the row's own "
        "velocity and acceleration bounds — the thesis's rows along the least-norm joint "
        "path, the path-following rows along their posture level's; exec./bound ≥ 1. Path "
        "dev. between samples: "
        + (
            "at every MuJoCo physics step"
            if settings.simulator == "mujoco"
            else "at 10 points per period of the kinematic loop's straight joint motion"
        )
    )


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
    following = _path_following_check(rows)
    if following:
        lines += ["", following]
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


def _run_dask(cases, settings, save_dir, address: str, on_done) -> None:
    """The cases on the Dask scheduler at ``address`` (the shared executor's Dask path)."""
    from dqcontrol.experiments.executor import Executor, run_jobs

    job = functools.partial(run_case, settings=settings, save_dir=save_dir)
    executor = Executor(workers=1, scheduler=address)
    run_jobs(job, cases, executor, on_done, connect_timeout_s=DASK_CONNECT_TIMEOUT_S)


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
        quick: the selection of :func:`table1_cases`, as are ``periods``,
            ``trajectories`` and ``controllers``.
        periods: see ``quick``.
        trajectories: see ``quick``.
        controllers: see ``quick``.
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
    if settings is None:
        settings = Table1Settings(simulator=simulator)
    cases = table1_cases(
        quick=quick, periods=periods, trajectories=trajectories, controllers=controllers
    )
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs_dir = out_dir / "table1_runs" if save_runs else None
    outcome, executor = _sweep_cases(cases, settings, runs_dir, workers, scheduler, progress)
    return _write_tables(out_dir, outcome, settings, executor, command, runs_dir)


def _sweep_cases(
    cases: list[Table1Case],
    settings: Table1Settings,
    runs_dir: Path | None,
    workers: int | None,
    scheduler: str | None,
    progress: bool,
) -> tuple[SweepOutcome, str]:
    """Run every case on the executor that ``workers`` and ``scheduler`` select.

    Args:
        cases: the cases of the grid.
        settings: the shared settings.
        runs_dir: folder each run is saved in, or ``None`` not to save them.
        workers: processes of the local pool (see :func:`run_table1`).
        scheduler: address of a Dask distributed scheduler, or ``None``.
        progress: show a progress bar.

    Returns:
        The sweep's outcome (the longest cases are started first) and the executor's label.
    """
    from dqcontrol.experiments.executor import resolve_executor
    from dqcontrol.experiments.sweep import sweep

    save_dir = None if runs_dir is None else str(runs_dir.resolve())
    executor = resolve_executor(workers, scheduler, len(cases))
    outcome = sweep(
        functools.partial(run_case, settings=settings, save_dir=save_dir),
        cases,
        executor,
        # longest jobs first: better balance across workers
        order=sorted(range(len(cases)), key=lambda i: -cases[i].cost_estimate()),
        name=lambda case: case.name,
        progress="table1" if progress else None,
    )
    return outcome, executor.label


def _write_tables(
    out_dir: Path,
    outcome: SweepOutcome,
    settings: Table1Settings,
    executor: str,
    command: str | None,
    runs_dir: Path | None,
) -> Table1Result:
    """Write ``table1.md`` and ``table1.csv`` of the sweep's results into ``out_dir``.

    Args:
        out_dir: the results folder.
        outcome: the sweep's outcome.
        settings: the shared settings.
        executor: the executor's label, quoted in the ``.md`` header.
        command: the command line, quoted in the ``.md`` header.
        runs_dir: folder the runs were saved in, or ``None``.

    Returns:
        The tables and where they were written.

    Raises:
        KeyboardInterrupt: the sweep was interrupted (once both tables are written).
    """
    from dqcontrol.runs.storage import atomic_write_text

    results, wall, interrupted = outcome.results, outcome.wall_time_s, outcome.interrupted
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
    csv_path = atomic_write_text(out_dir / "table1.csv", format_csv(rows))
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

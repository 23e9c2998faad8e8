"""Run metrics (docs/theory.md §9), computed from a :class:`~dqcontrol.runs.log.RunLog`.

All metrics are taken over the control samples until σ reaches ``T_tot`` or a stop begins
(the task); the ``stop_*`` ones over the samples of the stop (flagged ``stopping`` in the
log, docs/theory.md §8.10).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import cast

import numpy as np

from dqcontrol.dq.algebra import pose_error, translation
from dqcontrol.runs.log import RunLog
from dqcontrol.trajectories import Trajectory

__all__ = ["BoundSpec", "Metrics", "compute_metrics", "run_figures"]

#: Tolerance on bound checks [rad, rad/s, rad/s²]: commands are projected exactly onto their
#: box, so anything above rounding is a real violation.
VIOLATION_TOL = 1e-9


@dataclass(frozen=True)
class BoundSpec:
    """The hard bounds a run is judged against.

    ``a_max`` is a per-joint array [rad/s²], or ``None`` when the controller used
    dynamics-aware limits (then ``a_max_per_sample`` holds the bound at each sample).
    """

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    a_max: np.ndarray | None
    a_max_per_sample: np.ndarray | None = None


@dataclass(frozen=True)
class Metrics:
    """The figures of one run (docs/theory.md §9). Units in the names."""

    completed: bool
    sigma_reached_s: float
    duration_s: float
    execution_time_s: float
    execution_ratio: float
    samples: int
    e_mean: float
    e_max: float
    translation_error_mean_m: float
    translation_error_max_m: float
    rotation_error_mean_rad: float
    rotation_error_max_rad: float
    path_deviation_mean_m: float
    path_deviation_max_m: float
    u_mean_rad_s: float
    s_mean: float
    torque_peak_nm: float
    torque_rms_nm: float
    position_violations: int
    position_violation_max_rad: float
    velocity_violations: int
    velocity_violation_max_rad_s: float
    acceleration_violations: int
    acceleration_violation_max_rad_s2: float
    fallbacks: int
    relaxed_steps: int
    nan_seen: bool
    solve_time_median_s: float
    step_time_median_s: float
    #: the stop's samples, its duration [s], how far the phase advanced during it [s of
    #: nominal time], how far the tool travelled [m], its largest deviation from the path
    #: [m], its samples beyond the velocity or acceleration bound, and the largest
    #: ``|qd_command|`` of its last sample [rad/s] (0: ended at rest).
    stop_samples: int = 0
    stop_duration_s: float = 0.0
    stop_phase_advance_s: float = 0.0
    stop_tool_travel_m: float = 0.0
    stop_path_deviation_max_m: float = 0.0
    stop_limit_violations: int = 0
    stop_last_command_rad_s: float = 0.0
    #: on the wall clock, the commands written after the end of their period (the loop's
    #: count); of a streamed run, the plans' age at their samples (median, max) [s] and the
    #: planner's step time (median) [s] (NaN for a run without plans; docs/theory.md §12.4)
    late_commands: int = 0
    plan_age_median_s: float = float("nan")
    plan_age_max_s: float = float("nan")
    planner_step_median_s: float = float("nan")

    def as_dict(self) -> dict:
        """Plain-Python dictionary (JSON-ready)."""
        return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in asdict(self).items()}


def _nanmax(values: np.ndarray) -> float:
    return float(np.max(values)) if values.size else 0.0


def _excess_max(excess: np.ndarray) -> float:
    """The largest excess over a bound, 0 when none is above it (or there are no samples)."""
    return float(max(0.0, _nanmax(excess)))


def _mean(values: np.ndarray) -> float:
    """The mean of per-sample values, NaN when there are no samples."""
    return float(np.mean(values)) if values.size else float("nan")


def _median(values: np.ndarray) -> float:
    """The median of per-sample values, NaN when there are no samples."""
    return float(np.median(values)) if values.size else float("nan")


def _task_end(log: RunLog, duration: float, period_s: float) -> tuple[bool, int]:
    """Whether σ reached ``T_tot``, and the number of samples of the task.

    The task ends with the first sample whose step takes σ to ``T_tot``; without one it is
    the whole log.
    """
    reached = np.flatnonzero(log.sigma + period_s * log.s >= duration - 1e-12)
    completed = reached.size > 0
    end = int(reached[0]) + 1 if completed else len(log)
    stops = np.flatnonzero(cast(np.ndarray, log.stopping))  # filled by RunLog
    if stops.size and stops[0] < end:
        return False, int(stops[0])
    return completed, end


def _nan_seen(log: RunLog) -> bool:
    """Whether any joint position, velocity command or pose of the whole log is not finite."""
    return bool(
        not np.all(np.isfinite(log.q))
        or not np.all(np.isfinite(log.qd_command))
        or not np.all(np.isfinite(log.pose))
    )


def _tracking_errors(
    log: RunLog, trajectory: Trajectory, end: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample errors over the first ``end`` samples (empty arrays when ``end`` is 0).

    Returns:
        ``‖vec8(x_d) - vec8(x)‖``, the translation error [m], the rotation error [rad] and
        the deviation from the geometric path [m], each of shape ``(end,)``.
    """
    if not end:
        return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)
    pose, target = log.pose[:end], log.target[:end]
    err = np.linalg.norm(target - pose, axis=1)
    terr, rerr = (np.asarray(e) for e in pose_error(pose, target))
    dev = trajectory.path_deviation(translation(pose))
    return err, terr, rerr, dev


def _acceleration_excess(
    qd_cmd: np.ndarray, bounds: BoundSpec, period_s: float, end: int
) -> np.ndarray:
    """Per-sample, per-joint excess of the commanded acceleration over its bound [rad/s²].

    The acceleration is taken between consecutive commands, the first against the initial
    command (0); the bound is ``a_max``, else ``a_max_per_sample``, else none (``-inf``
    excess).
    """
    prev = np.vstack((np.zeros((1, qd_cmd.shape[1])), qd_cmd[:-1])) if end else qd_cmd
    acc = np.abs(qd_cmd - prev) / period_s
    if bounds.a_max is not None:
        a_lim = np.broadcast_to(bounds.a_max, acc.shape)
    elif bounds.a_max_per_sample is not None:
        a_lim = bounds.a_max_per_sample[:end]
    else:
        a_lim = np.full(acc.shape, np.inf)
    return acc - a_lim


def _stop_metrics(log: RunLog, trajectory: Trajectory, bounds: BoundSpec, period_s: float) -> dict:
    """The ``stop_*`` metrics over the samples flagged ``stopping`` (none: zeros)."""
    idx = np.flatnonzero(cast(np.ndarray, log.stopping))
    if not idx.size:
        return {}
    tool = translation(log.pose[idx])
    dev = trajectory.path_deviation(tool)
    qd_cmd = log.qd_command
    acc = _acceleration_excess(qd_cmd, bounds, period_s, len(log))[idx]
    vel = np.abs(qd_cmd[idx]) - bounds.qd_max
    beyond = np.any(vel > VIOLATION_TOL, axis=1) | np.any(
        acc > VIOLATION_TOL * max(1.0, 1.0 / period_s), axis=1
    )
    last = idx[-1]
    return {
        "stop_samples": int(idx.size),
        "stop_duration_s": float(idx.size * period_s),
        "stop_phase_advance_s": float(log.sigma[last] + period_s * log.s[last] - log.sigma[idx[0]]),
        "stop_tool_travel_m": float(np.sum(np.linalg.norm(np.diff(tool, axis=0), axis=1))),
        "stop_path_deviation_max_m": _nanmax(np.asarray(dev)),
        "stop_limit_violations": int(np.count_nonzero(beyond)),
        "stop_last_command_rad_s": float(np.max(np.abs(qd_cmd[last]))),
    }


def compute_metrics(
    log: RunLog, trajectory: Trajectory, bounds: BoundSpec, period_s: float
) -> Metrics:
    """Metrics of a run; ``trajectory`` must be the anchored one the controller used."""
    duration = trajectory.duration
    completed, end = _task_end(log, duration, period_s)
    sl = slice(0, end)
    err, terr, rerr, dev = _tracking_errors(log, trajectory, end)
    qd_cmd, q = log.qd_command[sl], log.q[sl]
    pos_excess = np.maximum(q - bounds.q_max, bounds.q_min - q)
    vel_excess = np.abs(qd_cmd) - bounds.qd_max
    acc_excess = _acceleration_excess(qd_cmd, bounds, period_s, end)
    acc_tol = VIOLATION_TOL * max(1.0, 1.0 / period_s)
    torque, peak = log.torque[sl], log.torque_peak[sl]
    has_torque = bool(torque.size) and bool(np.all(np.isfinite(torque)))
    exec_time = float(log.t_s[end - 1] + period_s) if completed else float("nan")
    return Metrics(
        completed=bool(completed),
        sigma_reached_s=float(min(duration, log.sigma[-1] + period_s * log.s[-1]))
        if len(log)
        else 0.0,
        duration_s=float(duration),
        execution_time_s=exec_time,
        execution_ratio=exec_time / duration if completed else float("nan"),
        samples=int(end),
        e_mean=_mean(err),
        e_max=_nanmax(err),
        translation_error_mean_m=_mean(terr),
        translation_error_max_m=_nanmax(terr),
        rotation_error_mean_rad=_mean(rerr),
        rotation_error_max_rad=_nanmax(rerr),
        path_deviation_mean_m=_mean(dev),
        path_deviation_max_m=_nanmax(dev),
        u_mean_rad_s=_mean(np.linalg.norm(qd_cmd, axis=1)),
        s_mean=_mean(log.s[sl]),
        torque_peak_nm=float(np.max(np.abs(peak))) if has_torque else float("nan"),
        torque_rms_nm=float(np.sqrt(np.mean(torque**2))) if has_torque else float("nan"),
        position_violations=int(np.count_nonzero(pos_excess > VIOLATION_TOL)),
        position_violation_max_rad=_excess_max(pos_excess),
        velocity_violations=int(np.count_nonzero(vel_excess > VIOLATION_TOL)),
        velocity_violation_max_rad_s=_excess_max(vel_excess),
        acceleration_violations=int(np.count_nonzero(acc_excess > acc_tol)),
        acceleration_violation_max_rad_s2=_excess_max(acc_excess),
        fallbacks=int(np.count_nonzero(log.fallback[sl])),
        relaxed_steps=int(np.count_nonzero(log.relaxed[sl])),
        nan_seen=_nan_seen(log),
        solve_time_median_s=_median(log.solve_time_s[sl]),
        step_time_median_s=_median(log.step_time_s[sl]),
        **_stop_metrics(log, trajectory, bounds, period_s),
        **run_figures(log.meta),
    )


def run_figures(meta: dict) -> dict:
    """The late commands, plan ages and planner step time of :class:`Metrics` from a run
    log's ``meta`` (its ``stop`` and ``stream`` entries, where the loop and a streamed
    controller put them); nothing for a run without them."""
    out: dict = {}
    late = (meta.get("stop") or {}).get("late_commands")
    if late is not None:
        out["late_commands"] = int(late)
    stream = meta.get("stream") or {}
    for key, name in (
        ("plan_age_median_ms", "plan_age_median_s"),
        ("plan_age_max_ms", "plan_age_max_s"),
        ("planner_step_median_ms", "planner_step_median_s"),
    ):
        if key in stream:
            out[name] = 1e-3 * float(stream[key])
    return out

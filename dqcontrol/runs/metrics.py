"""Run metrics (docs/theory.md §9), computed from a :class:`~dqcontrol.runs.log.RunLog`.

All metrics are taken over the control samples until σ reaches ``T_tot`` (the task).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from dqcontrol.dq.algebra import pose_error, translation
from dqcontrol.runs.log import RunLog
from dqcontrol.trajectories import Trajectory

__all__ = ["BoundSpec", "Metrics", "compute_metrics"]

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

    def as_dict(self) -> dict:
        """Plain-Python dictionary (JSON-ready)."""
        return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in asdict(self).items()}


def _nanmax(values: np.ndarray) -> float:
    return float(np.max(values)) if values.size else 0.0


def compute_metrics(
    log: RunLog, trajectory: Trajectory, bounds: BoundSpec, period_s: float
) -> Metrics:
    """Metrics of a run; ``trajectory`` must be the anchored one the controller used."""
    duration = trajectory.duration
    reached = np.flatnonzero(log.sigma + period_s * log.s >= duration - 1e-12)
    completed = reached.size > 0
    end = int(reached[0]) + 1 if completed else len(log)
    sl = slice(0, end)
    pose, target = log.pose[sl], log.target[sl]
    nan_seen = bool(
        not np.all(np.isfinite(log.q))
        or not np.all(np.isfinite(log.qd_command))
        or not np.all(np.isfinite(log.pose))
    )
    err = np.linalg.norm(target - pose, axis=1) if end else np.zeros(0)
    if end:
        terr, rerr = (np.asarray(e) for e in pose_error(pose, target))
        dev = trajectory.path_deviation(translation(pose))
    else:
        terr = rerr = dev = np.zeros(0)
    qd_cmd = log.qd_command[sl]
    q = log.q[sl]
    # position: measured joint positions outside the limits
    pos_excess = np.maximum(q - bounds.q_max, bounds.q_min - q)
    pos_bad = pos_excess > VIOLATION_TOL
    vel_excess = np.abs(qd_cmd) - bounds.qd_max
    vel_bad = vel_excess > VIOLATION_TOL
    # acceleration: between consecutive commands, the first against the initial command (0)
    prev = np.vstack((np.zeros((1, qd_cmd.shape[1])), qd_cmd[:-1])) if end else qd_cmd
    acc = np.abs(qd_cmd - prev) / period_s
    if bounds.a_max is not None:
        a_lim = np.broadcast_to(bounds.a_max, acc.shape)
    elif bounds.a_max_per_sample is not None:
        a_lim = bounds.a_max_per_sample[sl]
    else:
        a_lim = np.full(acc.shape, np.inf)
    acc_excess = acc - a_lim
    acc_bad = acc_excess > VIOLATION_TOL * max(1.0, 1.0 / period_s)
    torque = log.torque[sl]
    peak = log.torque_peak[sl]
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
        e_mean=float(np.mean(err)) if end else float("nan"),
        e_max=_nanmax(err),
        translation_error_mean_m=float(np.mean(terr)) if end else float("nan"),
        translation_error_max_m=_nanmax(terr),
        rotation_error_mean_rad=float(np.mean(rerr)) if end else float("nan"),
        rotation_error_max_rad=_nanmax(rerr),
        path_deviation_mean_m=float(np.mean(dev)) if end else float("nan"),
        path_deviation_max_m=_nanmax(dev),
        u_mean_rad_s=float(np.mean(np.linalg.norm(qd_cmd, axis=1))) if end else float("nan"),
        s_mean=float(np.mean(log.s[sl])) if end else float("nan"),
        torque_peak_nm=float(np.max(np.abs(peak))) if has_torque else float("nan"),
        torque_rms_nm=float(np.sqrt(np.mean(torque**2))) if has_torque else float("nan"),
        position_violations=int(np.count_nonzero(pos_bad)),
        position_violation_max_rad=float(max(0.0, _nanmax(pos_excess))),
        velocity_violations=int(np.count_nonzero(vel_bad)),
        velocity_violation_max_rad_s=float(max(0.0, _nanmax(vel_excess))),
        acceleration_violations=int(np.count_nonzero(acc_bad)),
        acceleration_violation_max_rad_s2=float(max(0.0, _nanmax(acc_excess))),
        fallbacks=int(np.count_nonzero(log.fallback[sl])),
        relaxed_steps=int(np.count_nonzero(log.relaxed[sl])),
        nan_seen=nan_seen,
        solve_time_median_s=float(np.median(log.solve_time_s[sl])) if end else float("nan"),
        step_time_median_s=float(np.median(log.step_time_s[sl])) if end else float("nan"),
    )

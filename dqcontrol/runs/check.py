"""The checker: every sample of a saved run that a real arm's controller would have refused.

:func:`check_run` replays a run's applied commands ``u_k`` (``qd_command``) at its period
through :class:`~dqcontrol.runs.reflexes.CommandMonitor`: the measured position of each
sample, then the velocity, acceleration and jerk of its command (the arm at rest before the
first), then whether the last command is 0. The first violation found is the reflex that
would have fired (:func:`summary_line` names it).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.model.limit_profile import LimitProfile, ProfileError
from dqcontrol.model.robot import JointLimits
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.reflexes import KINDS, CommandMonitor, Violation

__all__ = ["check_run", "run_period", "summary_line"]


def run_period(log: RunLog, period_s: float | None = None) -> float:
    """The control period of ``log`` [s]: ``period_s`` if given, else its ``meta``'s.

    Raises:
        ParameterError: none given and none in the meta, or not a number > 0.
    """
    value = log.meta.get("period_s") if period_s is None else period_s
    try:
        period = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ParameterError(
            "the run does not state its control period (meta 'period_s'); give it (--period S)"
        ) from None
    if not (np.isfinite(period) and period > 0.0):
        raise ParameterError(f"the control period must be a number > 0 [s], got {value!r}")
    return period


def _monitor(
    log: RunLog, limits: JointLimits | LimitProfile, period_s: float, names: Sequence[str]
) -> CommandMonitor:
    if isinstance(limits, LimitProfile):
        if limits.is_urdf:
            raise ProfileError(
                "the 'urdf' profile holds no figures of its own: check against the robot's "
                "limits (robot.limits of the robot the run used)"
            )
        if sorted(limits.joint_names) != sorted(names):
            raise ProfileError(
                f"limit profile {limits.name!r} is for the joints {list(limits.joint_names)}; "
                f"the run's joints are {list(names)}"
            )
        order = [limits.joint_names.index(name) for name in names]
        arrays = (limits.q_min, limits.q_max, limits.qd_max, limits.qdd_max, limits.qddd_max)
        q_min, q_max, qd_max, qdd_max, qddd_max = (a[order] for a in arrays)
    else:
        q_min, q_max, qd_max = limits.q_min, limits.q_max, limits.qd_max
        qdd_max, qddd_max = limits.qdd_max, limits.qddd_max  # type: ignore[assignment]
    return CommandMonitor(
        names, period_s, qd_max, q_min=q_min, q_max=q_max, qdd_max=qdd_max, qddd_max=qddd_max
    )


def check_run(
    log: RunLog,
    limits: JointLimits | LimitProfile,
    *,
    period_s: float | None = None,
    joint_names: Sequence[str] | None = None,
) -> list[Violation]:
    """Every violation of ``limits`` in the run ``log``, in the order a robot meets them
    (by sample; within a sample position, velocity, acceleration, jerk; by joint).

    Args:
        log: the run (its ``q`` and ``qd_command``; ``t_s`` for the times).
        limits: a limit profile (its joints matched to the run's by name) or a robot's
            :class:`~dqcontrol.model.robot.JointLimits` (in the run's joint order).
        period_s: the control period ``T`` [s]; default: the run's ``meta["period_s"]``.
        joint_names: the run's joints; default: its ``meta["joint_names"]``, else the
            profile's, else ``joint1..n``.

    Raises:
        ParameterError: no period, a profile for other joints, arrays of the wrong width.
    """
    period = run_period(log, period_s)
    n = log.qd_command.shape[1] if log.qd_command.ndim == 2 else 0
    names = _names(log, limits, joint_names, n)
    monitor = _monitor(log, limits, period, names)
    if log.q.shape != log.qd_command.shape or len(names) != n:
        raise ParameterError(
            f"the run's q {log.q.shape} and qd_command {log.qd_command.shape} must both have "
            f"one column per joint {list(names)}"
        )
    found: list[Violation] = []
    for k in range(len(log)):
        t_s = float(log.t_s[k])
        found += monitor.position(k, t_s, log.q[k])
        found += monitor.command(k, t_s, log.qd_command[k])
    if len(log):
        found += monitor.at_rest(len(log) - 1, float(log.t_s[-1]))
    return found


def _names(log: RunLog, limits, joint_names, n: int) -> list[str]:
    if joint_names is not None:
        return list(joint_names)
    if log.meta.get("joint_names"):
        return [str(v) for v in log.meta["joint_names"]]
    if isinstance(limits, LimitProfile) and len(limits.joint_names) == n:
        return list(limits.joint_names)
    return [f"joint{j + 1}" for j in range(n)]


def summary_line(
    violations: Sequence[Violation], samples: int, period_s: float, profile: str, run: str
) -> str:
    """One greppable line: ``check PASS`` or ``check FAIL``, the run, the profile, the count
    of each kind and the first violation (the reflex that would have fired)."""
    counts = Counter(v.kind for v in violations)
    kinds = ", ".join(f"{kind} {counts.get(kind, 0)}" for kind in KINDS)
    head = f"{run}: {samples} samples at T = {period_s:g} s against {profile!r}"
    if not violations:
        return f"check PASS {head}: no violation"
    return (
        f"check FAIL {head}: {len(violations)} violations ({kinds}); the reflex that would "
        f"have fired: {violations[0].describe()}"
    )

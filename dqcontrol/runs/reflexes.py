"""What a real arm's controller checks on the stream of commands it receives.

A robot receives joint-velocity commands ``u_k`` at period ``T`` and differentiates them
(docs/user_guide.md, "Robot limit profiles"): per joint it refuses the stream — a *reflex*
— as soon as one of

* position: ``q_min ≤ q_k ≤ q_max`` (the measured joint position),
* velocity: ``|u_k| ≤ v̄``,
* acceleration: ``|(u_k - u_{k-1}) / T| ≤ ā``,
* jerk: ``|(u_k - 2 u_{k-1} + u_{k-2}) / T²| ≤ j̄``

fails, with ``u_{-1} = u_{-2} = 0`` (the arm starts at rest), or when the stream does not end
at rest (its last command is not 0: ``|u| > 1e-9 v̄``). A limit of ``inf`` is never
violated. A value beyond its limit by no more than a relative ``1e-9``
(:data:`RELATIVE_TOLERANCE`) counts as within.

:class:`CommandMonitor` holds the last two commands and checks one sample at a time: the
same arithmetic serves the checker of saved runs (:func:`~dqcontrol.runs.check.check_run`)
and the simulation server's reflexes (:class:`~dqcontrol.sim.bridge.SimServer`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["KINDS", "RELATIVE_TOLERANCE", "CommandMonitor", "Violation"]

#: The kinds of violation, in the order they are checked within a sample.
KINDS = ("position", "velocity", "acceleration", "jerk", "not_at_rest")
#: Relative tolerance of every comparison with a limit.
RELATIVE_TOLERANCE = 1e-9
_UNITS = {
    "position": "rad",
    "velocity": "rad/s",
    "acceleration": "rad/s²",
    "jerk": "rad/s³",
    "not_at_rest": "rad/s",
}


@dataclass(frozen=True)
class Violation:
    """One entry a real arm would have refused.

    Attributes:
        kind: one of :data:`KINDS` (``"not_at_rest"``: the last command is not 0).
        sample: index ``k`` of the sample.
        t_s: its time [s].
        joint: the joint's name.
        value: the offending value (signed) in the kind's unit.
        limit: the limit it exceeds (signed like ``value``; 0 for ``"not_at_rest"``).
    """

    kind: str
    sample: int
    t_s: float
    joint: str
    value: float
    limit: float

    @property
    def unit(self) -> str:
        """The unit of :attr:`value` and :attr:`limit`."""
        return _UNITS[self.kind]

    def describe(self) -> str:
        """One line: the kind, the joint, the sample and time, the value against its limit."""
        if self.kind == "not_at_rest":
            what = f"last command {self.value:.6g} {self.unit}, not 0"
        else:
            sign = ">" if self.value > 0 else "<"
            what = f"{self.value:.6g} {sign} {self.limit:.6g} {self.unit}"
        where = f"sample {self.sample} (t = {self.t_s:.6g} s)"
        return f"{self.kind} of {self.joint} at {where}: {what}"


def _beyond(values: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Where ``|values| > limits`` beyond the relative tolerance (``inf`` never)."""
    return np.abs(values) > limits * (1.0 + RELATIVE_TOLERANCE)


class CommandMonitor:
    """The checks of a real arm's controller over a stream of commands, one at a time.

    Args:
        joint_names: the joints, in the order of the commands.
        period_s: the control period ``T`` [s].
        q_min, q_max: position limits [rad] (``None``: not checked).
        qd_max: velocity limits [rad/s].
        qdd_max, qddd_max: acceleration [rad/s²] and jerk [rad/s³] limits (``None`` or
            ``inf``: not checked).
    """

    def __init__(
        self,
        joint_names: Sequence[str],
        period_s: float,
        qd_max: np.ndarray,
        *,
        q_min: np.ndarray | None = None,
        q_max: np.ndarray | None = None,
        qdd_max: np.ndarray | None = None,
        qddd_max: np.ndarray | None = None,
    ) -> None:
        n = len(joint_names)
        self.joint_names = tuple(joint_names)
        self.period_s = float(period_s)
        inf = np.full(n, np.inf)

        def vector(value) -> np.ndarray:
            return inf if value is None else np.broadcast_to(np.asarray(value, float), (n,))

        self.q_min = -inf if q_min is None else vector(q_min)
        self.q_max = vector(q_max)
        self.qd_max, self.qdd_max, self.qddd_max = vector(qd_max), vector(qdd_max), vector(qddd_max)
        self.reset()

    def reset(self) -> None:
        """Start again from rest: ``u_{-1} = u_{-2} = 0``."""
        n = len(self.joint_names)
        self.u_1, self.u_2 = np.zeros(n), np.zeros(n)

    def position(self, k: int, t_s: float, q: np.ndarray) -> list[Violation]:
        """The position violations of the joint positions ``q`` [rad] at sample ``k``."""
        out = []
        for j in range(len(self.joint_names)):
            lo, hi = self.q_min[j], self.q_max[j]
            if q[j] > hi + RELATIVE_TOLERANCE * max(1.0, abs(hi)):
                out.append(_violation("position", k, t_s, self.joint_names[j], q[j], hi))
            elif q[j] < lo - RELATIVE_TOLERANCE * max(1.0, abs(lo)):
                out.append(_violation("position", k, t_s, self.joint_names[j], q[j], lo))
        return out

    def command(self, k: int, t_s: float, u: np.ndarray) -> list[Violation]:
        """The velocity, acceleration and jerk violations of command ``u_k`` [rad/s]; the
        command then becomes the last one (whatever was found)."""
        u = np.asarray(u, dtype=float)
        period = self.period_s
        acc = (u - self.u_1) / period
        jerk = (u - 2.0 * self.u_1 + self.u_2) / (period * period)
        out = []
        for kind, values, limits in (
            ("velocity", u, self.qd_max),
            ("acceleration", acc, self.qdd_max),
            ("jerk", jerk, self.qddd_max),
        ):
            for j in np.flatnonzero(_beyond(values, limits)):
                limit = math.copysign(limits[j], values[j])
                out.append(_violation(kind, k, t_s, self.joint_names[j], values[j], limit))
        self.u_2, self.u_1 = self.u_1, u.copy()
        return out

    def at_rest(self, k: int, t_s: float) -> list[Violation]:
        """A ``"not_at_rest"`` violation per joint whose last command (sample ``k``) is not 0:
        ``|u_k| > 1e-9 v̄`` (1e-9 rad/s for a joint without velocity limit)."""
        scale = np.where(np.isfinite(self.qd_max), self.qd_max, 1.0)
        moving = np.abs(self.u_1) > RELATIVE_TOLERANCE * scale
        return [
            Violation("not_at_rest", k, t_s, self.joint_names[j], float(self.u_1[j]), 0.0)
            for j in np.flatnonzero(moving)
        ]


def _violation(kind: str, k: int, t_s: float, joint: str, value, limit) -> Violation:
    return Violation(kind, int(k), float(t_s), joint, float(value), float(limit))

"""The check of each ``sensor_msgs/JointState`` before the controller sees it.

A message becomes a :class:`~dqcontrol.sim.Measurement` in the command joint order only if
it names every controlled joint once, names nothing else than the controlled and the locked
joints, carries as many positions as names (and as many velocities and efforts, or none),
and its controlled joints' positions and velocities are finite. Anything else is a
:class:`Rejected` with a short reason (the counters' key) and a detail for the log line;
the control node never commands from it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["REASONS", "JointStateCheck", "Rejected"]

#: The reasons a message is rejected for (the keys of the control node's counters).
REASONS = ("duplicate names", "wrong length", "unknown joints", "missing joints", "non-finite")


class Rejected(NamedTuple):
    """A rejected message: ``reason`` (one of :data:`REASONS`) and ``detail`` (for the log)."""

    reason: str
    detail: str


class JointStateCheck:
    """Turns joint-state fields into measurements in the command joint order, or rejects them.

    Args:
        joint_names: the controlled joints, in the order of the commands.
        locked_names: joints that may appear in the messages and are ignored (held fixed by
            the model, e.g. gripper fingers).

    Raises:
        ParameterError: no joint, or a name given twice.
    """

    def __init__(self, joint_names: Sequence[str], locked_names: Sequence[str] = ()) -> None:
        self.joint_names = tuple(str(n) for n in joint_names)
        self.locked_names = tuple(str(n) for n in locked_names)
        every = self.joint_names + self.locked_names
        if not self.joint_names or len(set(every)) != len(every):
            raise ParameterError(
                f"the controlled and locked joints must be distinct names, at least one "
                f"controlled: got {list(self.joint_names)} and {list(self.locked_names)}"
            )
        self._known = set(every)
        self._nan = np.full(len(self.joint_names), np.nan)

    def check(
        self,
        names: Sequence[str],
        position: Sequence[float],
        velocity: Sequence[float] = (),
        effort: Sequence[float] = (),
        stamp_s: float = 0.0,
    ) -> Measurement | Rejected:
        """The measurement of one message (``q`` [rad], ``qd`` [rad/s], torque [N·m] or NaN)
        at ``stamp_s`` [s], or why it is rejected."""
        names = [str(n) for n in names]
        if len(set(names)) != len(names):
            dupes = sorted({n for n in names if names.count(n) > 1})
            return Rejected("duplicate names", f"joints named more than once: {dupes}")
        sizes = (len(position), len(velocity), len(effort))
        if sizes[0] != len(names) or any(s not in (0, len(names)) for s in sizes[1:]):
            return Rejected(
                "wrong length",
                f"{len(names)} names but {sizes[0]} positions, {sizes[1]} velocities, "
                f"{sizes[2]} efforts (each must be {len(names)}; velocities, efforts may be 0)",
            )
        unknown = [n for n in names if n not in self._known]
        if unknown:
            return Rejected("unknown joints", f"joints {unknown} are not controlled nor locked")
        index = {n: k for k, n in enumerate(names)}
        missing = [n for n in self.joint_names if n not in index]
        if missing:
            return Rejected("missing joints", f"joints {missing} are missing (got {names})")
        order = [index[n] for n in self.joint_names]
        q = np.asarray(position, dtype=float)[order]
        qd = np.asarray(velocity, dtype=float)[order] if sizes[1] else np.zeros(len(order))
        if not (np.isfinite(q).all() and np.isfinite(qd).all() and math.isfinite(stamp_s)):
            return Rejected("non-finite", f"a position, velocity or stamp is not finite: q = {q}")
        torque = np.asarray(effort, dtype=float)[order] if sizes[2] else self._nan
        return Measurement(float(stamp_s), q, qd, torque, np.abs(torque))

"""Robot-like reflexes for a simulated arm: refuse a command a real arm's controller would.

:class:`Reflexes` checks each command a simulation server receives with a
:class:`~dqcontrol.runs.reflexes.CommandMonitor` (velocity, acceleration and jerk of the
commands, the arm at rest at each reset) and the simulated arm's position after each
period. The first violation *fires the reflex*: the server stops the arm (holds it) and
answers an error naming the violation; every later motion command is refused until the
next reset (:class:`~dqcontrol.sim.bridge.SimServer`).
"""

from __future__ import annotations

import numpy as np

from dqcontrol.model.robot import RobotModel
from dqcontrol.runs.reflexes import CommandMonitor, Violation

__all__ = ["Reflexes"]


class Reflexes:
    """The reflexes of one simulated arm.

    Args:
        monitor: the checks, in the driver's joint order.
        profile: the name of the limits checked (for the messages).

    Attributes:
        fired: the violation that fired the reflex (``None``: none since the last reset).
    """

    def __init__(self, monitor: CommandMonitor, profile: str) -> None:
        self.monitor = monitor
        self.profile = profile
        self.fired: Violation | None = None
        self._k = 0

    @classmethod
    def of_robot(
        cls, robot: RobotModel, joint_names, period_s: float, *, velocity_only: bool = False
    ) -> Reflexes:
        """The reflexes of ``robot``'s limits (:attr:`~dqcontrol.model.robot.RobotModel.limits`:
        its limit profile's, or its URDF's) for a driver with ``joint_names``;
        ``velocity_only``: only the velocity limit is checked."""
        order = [robot.joint_names.index(name) for name in joint_names]
        lim = robot.limits
        assert lim.qdd_max is not None and lim.qddd_max is not None, "JointLimits fills them"
        # a URDF velocity of 0 means "not given" (as for the controllers): not checked
        qd_max = np.where(lim.qd_max > 0.0, lim.qd_max, np.inf)[order]
        if velocity_only:
            monitor = CommandMonitor(joint_names, period_s, qd_max)
        else:
            monitor = CommandMonitor(
                joint_names, period_s, qd_max, q_min=lim.q_min[order],
                q_max=lim.q_max[order], qdd_max=lim.qdd_max[order],
                qddd_max=lim.qddd_max[order],
            )  # fmt: skip
        return cls(monitor, robot.limit_profile + (" velocity" if velocity_only else ""))

    def reset(self) -> None:
        """A new motion from rest: the reflex re-armed."""
        self.monitor.reset()
        self.fired = None
        self._k = 0

    def refusal(self) -> str | None:
        """Why a motion command is refused now (the reflex has fired), or ``None``."""
        if self.fired is None:
            return None
        return f"refused: the reflex fired ({self.fired.describe()}); send RESET"

    def command(self, t_s: float, u: np.ndarray) -> str | None:
        """Check command ``u`` [rad/s] at time ``t_s`` [s]; the message if the reflex fires."""
        found = self.monitor.command(self._k, t_s, u)
        self._k += 1
        return self._fire(found)

    def position(self, t_s: float, q: np.ndarray) -> str | None:
        """Check the arm's position ``q`` [rad]; the message if the reflex fires."""
        return self._fire(self.monitor.position(self._k - 1, t_s, q))

    def _fire(self, found: list[Violation]) -> str | None:
        if not found:
            return None
        self.fired = found[0]
        return (
            f"reflex ({self.profile} limits): {self.fired.describe()}; the arm is stopped, "
            "commands are refused until RESET"
        )

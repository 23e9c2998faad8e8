"""Robot-like reflexes for a simulated arm: refuse a command a real arm's controller would.

:class:`Reflexes` checks each command a simulation server receives with a
:class:`~dqcontrol.runs.reflexes.CommandMonitor` (velocity, acceleration and jerk of the
commands, the arm at rest at each reset) and the simulated arm's position after each
period. The first violation *fires the reflex*: the server stops the arm (holds it) and
answers an error naming the violation; every later motion command is refused until the
next reset. :class:`ReflexDriver` gives any simulated driver these reflexes (the MuJoCo
driver in this process, or the one a :class:`~dqcontrol.sim.bridge.SimServer` serves): a
refused command raises :class:`ReflexError`, which stops
:func:`~dqcontrol.sim.loop.run_loop` with the reflex in its note and in
``meta["driver_report"]["reflex"]``.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.errors import DQControlError
from dqcontrol.model.robot import RobotModel
from dqcontrol.runs.reflexes import CommandMonitor, Violation
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["ReflexDriver", "ReflexError", "Reflexes"]


class ReflexError(DQControlError):
    """A command refused as a real arm would refuse it: its reflex fired (the message names
    the violation: kind, joint, sample, value and limit); the arm is stopped until the next
    reset."""


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


class ReflexDriver:
    """A simulated driver with a real arm's reflexes (:class:`Reflexes`).

    Args:
        driver: a simulated driver (``reset``, ``write``, ``hold``, ``read``, ``period_s``,
            ``joint_names``).
        reflexes: the checks, in the driver's joint order.

    ``write`` checks the command, then the arm's position after the period; ``hold`` is a
    zero command (accepted without check once the reflex has fired: the arm is held). At
    the first violation the arm is held and :class:`ReflexError` raised; every later
    ``write`` raises it until ``reset``.
    """

    def __init__(self, driver, reflexes: Reflexes) -> None:
        self.driver = driver
        self.reflexes = reflexes
        self.joint_names = tuple(driver.joint_names)
        self.period_s = driver.period_s
        self.message = ""

    @property
    def meta(self) -> dict:
        """The driver's ``meta`` and the limits checked (``"reflexes"``)."""
        return {**dict(getattr(self.driver, "meta", {})), "reflexes": self.reflexes.profile}

    def report(self) -> dict:
        """The driver's own report and, once it fired, the reflex (``"reflex"``)."""
        own = getattr(self.driver, "report", None)
        report = dict(own()) if callable(own) else {}
        if self.message:
            report["reflex"] = self.message
        return report

    def reset(self, q0: np.ndarray) -> Measurement:
        """Reset the arm at rest at ``q0`` [rad]; the reflexes re-armed."""
        self.reflexes.reset()
        self.message = ""
        return self.driver.reset(q0)

    def read(self) -> Measurement:
        """The driver's latest measurement."""
        return self.driver.read()

    def write(self, qd_command: np.ndarray) -> None:
        """Execute the command [rad/s] for one period, or raise :class:`ReflexError`."""
        self._move(np.asarray(qd_command, dtype=float), hold=False)

    def hold(self) -> None:
        """Hold the arm for one period (a zero command)."""
        if self.reflexes.fired is not None:
            self.driver.hold()
            return
        self._move(np.zeros(len(self.joint_names)), hold=True)

    def _move(self, u: np.ndarray, hold: bool) -> None:
        reflexes = self.reflexes
        refused = reflexes.refusal()
        if refused is None:
            refused = reflexes.command(self.driver.read().t_s, u)
        if refused is None:
            self.driver.hold() if hold else self.driver.write(u)
            m = self.driver.read()
            refused = reflexes.position(m.t_s, m.q)
            if refused is None:
                return
        self.driver.hold()
        if not self.message:
            self.message = refused
        raise ReflexError(refused)

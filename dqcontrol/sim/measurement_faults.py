"""Measurement faults around any joint driver: seeded Gaussian noise and a delay of whole
periods on what the controller *sees*, never on the arm.

- :class:`MeasurementFaults` — the noise generator and the delay line (a FIFO of
  :class:`~dqcontrol.sim.Measurement`); the delayed state is stamped with the present time
  and torques, so that the loop's clock and log stay on time;
- :class:`FaultyDriver` — a driver whose ``read`` goes through them; it records the *true*
  (noise-free, undelayed) measurement after ``reset`` and after every period, so that a
  campaign can judge what the arm really did rather than what the sensors reported.

The faults that change the arm itself (an unknown payload, lower torque limits) are
:mod:`dqcontrol.sim.model_faults`.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.sim.driver import JointDriver, SimulatedDriver
from dqcontrol.sim.mujoco_sim import Measurement

__all__ = ["FaultyDriver", "MeasurementFaults", "true_copy"]


def _non_negative(name: str, value: float, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}") from None
    if not math.isfinite(v) or v < 0.0:
        raise ParameterError(f"{name} must be finite and ≥ 0 [{unit}], got {value!r}")
    return v


class MeasurementFaults:
    """Seeded Gaussian noise and a delay line of whole periods on joint measurements.

    Args:
        q_noise_rad: standard deviation of the noise on each joint position [rad], ≥ 0.
        qd_noise_rad_s: standard deviation of the noise on each joint velocity [rad/s], ≥ 0.
        delay_periods: what is observed is the measurement of this many periods ago
            (the initial one until then), stamped with the present time and torques.
        seed: seed of the noise; :meth:`restart` restarts the same sequence.
    """

    def __init__(
        self,
        q_noise_rad: float = 0.0,
        qd_noise_rad_s: float = 0.0,
        delay_periods: int = 0,
        seed: int = 0,
    ) -> None:
        self.q_noise_rad = _non_negative("q_noise_rad", q_noise_rad, "rad")
        self.qd_noise_rad_s = _non_negative("qd_noise_rad_s", qd_noise_rad_s, "rad/s")
        if (
            isinstance(delay_periods, bool)
            or not isinstance(delay_periods, int | np.integer)
            or delay_periods < 0
        ):
            raise ParameterError(
                f"delay_periods must be an integer ≥ 0 [control periods], got {delay_periods!r}"
            )
        self.delay_periods = int(delay_periods)
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
            raise ParameterError(f"seed must be an integer, got {seed!r}")
        self.seed = int(seed)
        self._rng = np.random.default_rng(self.seed)
        self._fifo: deque[Measurement] = deque()

    def observe(self, old: Measurement, now: Measurement) -> Measurement:
        """The joint state of ``old`` with noise, stamped with ``now``'s time and torques."""
        q, qd = np.array(old.q, dtype=float), np.array(old.qd, dtype=float)
        if self.q_noise_rad > 0.0:
            q = q + self._rng.normal(0.0, self.q_noise_rad, q.shape)
        if self.qd_noise_rad_s > 0.0:
            qd = qd + self._rng.normal(0.0, self.qd_noise_rad_s, qd.shape)
        return Measurement(t_s=now.t_s, q=q, qd=qd, torque=now.torque, torque_peak=now.torque_peak)

    def restart(self, first: Measurement) -> Measurement:
        """Restart the noise sequence and fill the delay line with ``first``; observe it."""
        self._rng = np.random.default_rng(self.seed)
        self._fifo = deque([first] * (self.delay_periods + 1), maxlen=self.delay_periods + 1)
        return self.observe(self._fifo[0], first)

    def push(self, now: Measurement) -> Measurement:
        """The observation after a period whose true measurement is ``now``."""
        self._fifo.append(now)  # maxlen: drops the oldest
        return self.observe(self._fifo[0], now)


def true_copy(m: Measurement) -> Measurement:
    """A measurement with its own float arrays (a record that later steps cannot change)."""
    return Measurement(
        t_s=float(m.t_s),
        q=np.array(m.q, dtype=float),
        qd=np.array(m.qd, dtype=float),
        torque=np.array(m.torque, dtype=float),
        torque_peak=np.array(m.torque_peak, dtype=float),
    )


class FaultyDriver:
    """A driver whose measurements are noisy and/or delayed (:class:`MeasurementFaults`).

    The commands reach the inner driver unchanged; :attr:`true_measurements` keeps the
    noise-free, undelayed measurement after ``reset`` and after every period.

    Args:
        inner: the driver to wrap (simulated: with ``reset`` and ``period_s``).
        q_noise_rad, qd_noise_rad_s, delay_periods, seed: as :class:`MeasurementFaults`.
    """

    def __init__(
        self,
        inner: JointDriver,
        *,
        q_noise_rad: float = 0.0,
        qd_noise_rad_s: float = 0.0,
        delay_periods: int = 0,
        seed: int = 0,
    ) -> None:
        if not isinstance(inner, JointDriver):
            raise ParameterError(
                f"inner must be a JointDriver (joint_names/read/write/hold), got "
                f"{type(inner).__name__}"
            )
        self.inner = inner
        self.faults = MeasurementFaults(q_noise_rad, qd_noise_rad_s, delay_periods, seed)
        self.joint_names = tuple(inner.joint_names)
        self.period_s = getattr(inner, "period_s", None)
        self.true_measurements: list[Measurement] = []
        self._last: Measurement | None = None

    @property
    def meta(self) -> dict:
        """The inner driver's description, with the faults."""
        f = self.faults
        return {
            **getattr(self.inner, "meta", {}),
            "q_noise_rad": f.q_noise_rad,
            "qd_noise_rad_s": f.qd_noise_rad_s,
            "delay_periods": f.delay_periods,
            "seed": f.seed,
        }

    @property
    def simulation(self):
        """The wrapped driver's simulation (``None`` if it has none): the model faults of
        :mod:`dqcontrol.sim.model_faults` may wrap this driver too."""
        return getattr(self.inner, "simulation", None)

    @property
    def true_q(self) -> np.ndarray:
        """True joint positions [rad] after reset and after every period, ``(K + 1, n)``."""
        return np.array([m.q for m in self.true_measurements])

    @property
    def true_qd(self) -> np.ndarray:
        """True joint velocities [rad/s] after reset and after every period, ``(K + 1, n)``."""
        return np.array([m.qd for m in self.true_measurements])

    def reset(self, q0: np.ndarray) -> Measurement:
        """Reset the inner driver, the noise sequence and the delay line."""
        if not isinstance(self.inner, SimulatedDriver):
            raise ParameterError(
                f"only a simulated driver resets; {type(self.inner).__name__} has no reset"
            )
        first = true_copy(self.inner.reset(q0))
        self.true_measurements = [first]
        self._last = self.faults.restart(first)
        return self._last

    def _advance(self) -> None:
        now = true_copy(self.inner.read())
        self.true_measurements.append(now)
        self._last = self.faults.push(now)

    def read(self) -> Measurement:
        """The observed measurement: noisy and/or delayed (driver's joint order)."""
        if self._last is None:
            first = true_copy(self.inner.read())
            self.true_measurements = [first]
            self._last = self.faults.restart(first)
        return self._last

    def write(self, qd_command: np.ndarray) -> None:
        """Pass the command to the inner driver and observe the period's end."""
        self.inner.write(qd_command)
        self._advance()

    def hold(self) -> None:
        """Hold the inner driver and observe the period's end."""
        self.inner.hold()
        self._advance()

    def __repr__(self) -> str:
        f = self.faults
        return (
            f"FaultyDriver({self.inner!r}, q_noise_rad={f.q_noise_rad}, "
            f"qd_noise_rad_s={f.qd_noise_rad_s}, delay_periods={f.delay_periods}, seed={f.seed})"
        )

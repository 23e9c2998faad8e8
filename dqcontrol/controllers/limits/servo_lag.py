"""The servo's lag counted in the position bounds (docs/theory.md §5).

The command box keeps ``q + T q̇`` and the stop-before-the-limit distance inside the
position bounds, as if the joint moved at the commanded velocity. A joint behind a velocity
servo follows each command with a lag; for a first-order lag of time constant ``τ`` the
joint, once its commands have come to rest, has travelled ``τ v`` beyond their integral
(``v`` its velocity when they started to slow down). Where ``τ |v|`` exceeds the margin the
bounds keep from the URDF's limits, braking at ``a_max`` ends beyond the limit.

:class:`ServoLagMargin` measures the lag and moves the bounds by it:

- the lag's time constant of each joint, ``τ_lag``, is identified from the measurements:
  while a joint's command changes at a rate ``|a| ≥`` :data:`EXCITATION` ``· a_max`` (a
  clear acceleration or braking), the measured velocity trails the command by ``e``, and
  ``e / |a|`` is a sample of ``τ_lag``; the smallest of :data:`SAMPLES` consecutive samples
  counts (a lag that persists, not one noisy measurement), and the largest count is kept
  (capped at :data:`TAU_CAP_S`). With ideal velocity tracking ``e = 0`` and nothing moves;
- each step the bound of a joint moving towards a limit stays
  ``max(margin, τ_lag |q̇_meas|)`` inside the URDF's limit, the bound on the other side at
  the margin. The bounds move only where the lag's travel exceeds the margin.
"""

from __future__ import annotations

import numpy as np

__all__ = ["EXCITATION", "SAMPLES", "TAU_CAP_S", "ServoLagMargin"]

#: A command rate of at least this share of ``a_max`` samples the lag.
EXCITATION = 0.5
#: Largest lag time constant taken [s].
TAU_CAP_S = 0.1
#: Consecutive samples that must all show the lag.
SAMPLES = 3


class ServoLagMargin:
    """The lag-aware position bounds of one controller.

    Args:
        q_min, q_max: the URDF's limits [rad] ``(n,)``.
        margin_rad: the margin the bounds keep at least [rad].
        period_s: the control period ``T`` [s].
        a_max: ``a_max`` [rad/s²] ``(n,)`` (the rate that counts as a clear acceleration).
    """

    def __init__(
        self,
        q_min: np.ndarray,
        q_max: np.ndarray,
        margin_rad: float,
        period_s: float,
        a_max: np.ndarray,
    ) -> None:
        self.q_min = np.asarray(q_min, dtype=float)
        self.q_max = np.asarray(q_max, dtype=float)
        self.margin_rad = float(margin_rad)
        self.period_s = float(period_s)
        self.a_min = EXCITATION * np.broadcast_to(np.asarray(a_max, dtype=float), self.q_min.shape)
        self.reset()

    def restore(self, values: np.ndarray) -> None:
        """Put the margin's bounds back into ``values`` (if moved) and forget the lag."""
        if self._margin_bounds is not None:
            values[:2] = self._margin_bounds
        self.reset()

    def reset(self) -> None:
        """Forget the identified lag and the commands."""
        self.tau_s = np.zeros(self.q_min.shape)
        self._before: np.ndarray | None = None
        self._margin_bounds: np.ndarray | None = None
        self._samples = np.full((SAMPLES, self.q_min.size), -np.inf)

    def update(self, qd_meas: np.ndarray | None, qd_cmd: np.ndarray, values: np.ndarray) -> None:
        """One step: ``qd_meas`` measured now, ``qd_cmd`` the command held over the last
        period; the bounds written into ``values`` (``[q_min; q_max; qd_max]``, in place)
        where the lag's travel exceeds the margin."""
        before, self._before = self._before, qd_cmd.copy()
        if qd_meas is None:
            return
        sample = np.full(self.q_min.shape, -np.inf)  # no sample where not excited
        if before is not None:
            rate = (qd_cmd - before) / self.period_s
            excited = np.abs(rate) >= self.a_min
            lag = (qd_cmd - qd_meas) * np.sign(rate)
            sample[excited] = lag[excited] / np.abs(rate[excited])
        self._samples = np.roll(self._samples, 1, axis=0)
        self._samples[0] = sample
        # a lag seen on SAMPLES steps in a row (a noisy sample alone does not count)
        held = self._samples.min(axis=0)
        self.tau_s = np.minimum(np.maximum(self.tau_s, held), TAU_CAP_S)
        travel = self.tau_s * np.abs(qd_meas)
        if not (travel > self.margin_rad).any():
            if self._margin_bounds is not None:  # back to the margin's bounds, as given
                values[:2] = self._margin_bounds
                self._margin_bounds = None
            return
        if self._margin_bounds is None:
            self._margin_bounds = values[:2].copy()
        towards_max = np.where(qd_meas > 0.0, travel, 0.0)
        towards_min = np.where(qd_meas < 0.0, travel, 0.0)
        values[0] = np.maximum(self._margin_bounds[0], self.q_min + towards_min)
        values[1] = np.minimum(self._margin_bounds[1], self.q_max - towards_max)

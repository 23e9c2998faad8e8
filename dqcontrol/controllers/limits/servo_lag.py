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

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = [
    "DEFAULT_A_MAX",
    "EXCITATION",
    "SAMPLES",
    "TAU_CAP_S",
    "ServoLagMargin",
    "lag_samples_into",
]

#: A command rate of at least this share of ``a_max`` samples the lag.
EXCITATION = 0.5
#: Largest lag time constant taken [s].
TAU_CAP_S = 0.1
#: Consecutive samples that must all show the lag.
SAMPLES = 3
#: The acceleration bound [rad/s²] a clear acceleration is judged against where the
#: controller has no constant one (a dynamics-aware bound changes with the state).
DEFAULT_A_MAX = 10.0


class ServoLagMargin:
    """The lag-aware position bounds of one controller.

    Args:
        q_min, q_max: the URDF's limits [rad] ``(n,)``.
        margin_rad: the margin the bounds keep at least [rad].
        period_s: the control period ``T`` [s].
        a_max: ``a_max`` [rad/s²] ``(n,)`` (the rate that counts as a clear acceleration;
            ``None``: :data:`DEFAULT_A_MAX`).
    """

    def __init__(
        self,
        q_min: np.ndarray,
        q_max: np.ndarray,
        margin_rad: float,
        period_s: float,
        a_max: float | np.ndarray | None,
    ) -> None:
        self.q_min = np.asarray(q_min, dtype=float)
        self.q_max = np.asarray(q_max, dtype=float)
        self.margin_rad = float(margin_rad)
        self.period_s = float(period_s)
        a_max = DEFAULT_A_MAX if a_max is None else a_max
        self.a_min = EXCITATION * np.broadcast_to(np.asarray(a_max, dtype=float), self.q_min.shape)
        self.reset()

    def restore(self, values: np.ndarray) -> bool:
        """Put the margin's bounds back into ``values`` (if moved) and forget the lag; whether
        they had moved."""
        moved = self._margin_bounds is not None
        if moved:
            values[:2] = self._margin_bounds
        self.reset()
        return moved

    def reset(self) -> None:
        """Forget the identified lag and the commands."""
        n = self.q_min.size
        self.tau_s = np.zeros(self.q_min.shape)
        self._last = np.zeros(n)  # the command of the last update
        self._spare = np.zeros(n)
        self._has_before = False
        self._margin_bounds: np.ndarray | None = None
        self._samples = np.full((SAMPLES, n), -np.inf)  # a ring, oldest at ``_head``
        self._head = 0

    def update(self, qd_meas: np.ndarray | None, qd_cmd: np.ndarray, values: np.ndarray) -> bool:
        """One step: ``qd_meas`` measured now, ``qd_cmd`` the command held over the last
        period; the bounds written into ``values`` (``[q_min; q_max; qd_max]``, in place)
        where the lag's travel exceeds the margin. Whether they were written (moved, or put
        back to the margin's)."""
        before, self._last, self._spare = self._last, self._spare, self._last
        self._last[:] = qd_cmd
        had_before, self._has_before = self._has_before, True
        if qd_meas is None:
            return False
        exceeds = lag_samples_into(
            qd_meas, qd_cmd, before, had_before, self.period_s, self.a_min, self._samples,
            self._head, self.tau_s, TAU_CAP_S, self.margin_rad,
        )  # fmt: skip
        self._head = (self._head + 1) % SAMPLES
        if not exceeds:
            if self._margin_bounds is not None:  # back to the margin's bounds, as given
                values[:2] = self._margin_bounds
                self._margin_bounds = None
                return True
            return False
        travel = self.tau_s * np.abs(qd_meas)
        if self._margin_bounds is None:
            self._margin_bounds = values[:2].copy()
        towards_max = np.where(qd_meas > 0.0, travel, 0.0)
        towards_min = np.where(qd_meas < 0.0, travel, 0.0)
        values[0] = np.maximum(self._margin_bounds[0], self.q_min + towards_min)
        values[1] = np.minimum(self._margin_bounds[1], self.q_max - towards_max)
        return True


@compiled
def lag_samples_into(
    qd_meas: np.ndarray,
    qd_cmd: np.ndarray,
    before: np.ndarray,
    had_before: bool,
    period_s: float,
    a_min: np.ndarray,
    samples: np.ndarray,
    head: int,
    tau_s: np.ndarray,
    tau_cap_s: float,
    margin_rad: float,
) -> bool:
    """One step of the lag's identification, in place: each joint's sample ``e/|a|``
    (``-inf`` where the command's rate ``a = (qd_cmd - before)/T`` is below ``a_min``, or
    without a command ``before``) written to row ``head`` of the ring ``samples``
    ``(SAMPLES, n)``, ``tau_s`` raised to the smallest sample of the ring (a lag seen on
    every one of the last SAMPLES steps) and capped at ``tau_cap_s``; returns whether some
    joint's travel ``tau_s |qd_meas|`` exceeds ``margin_rad``."""
    exceeds = False
    for j in range(qd_cmd.shape[0]):
        sample = -math.inf
        if had_before:
            rate = (qd_cmd[j] - before[j]) / period_s
            if abs(rate) >= a_min[j]:
                sign = 1.0 if rate > 0.0 else -1.0
                sample = ((qd_cmd[j] - qd_meas[j]) * sign) / abs(rate)
        samples[head, j] = sample
        held = samples[0, j]
        for k in range(1, samples.shape[0]):
            held = min(held, samples[k, j])
        tau = min(max(tau_s[j], held), tau_cap_s)
        tau_s[j] = tau
        exceeds = exceeds or tau * abs(qd_meas[j]) > margin_rad
    return exceeds

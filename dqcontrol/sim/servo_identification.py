"""The velocity servo a driver commands: stated by the driver, or identified from the first
commands (docs/theory.md §8.7).

A velocity servo that follows each command ``u_k`` (held over one period ``T``) as a
first-order lag of time constant ``τ_v`` moves the joint velocity by

    qd(k+1) - qd(k) = α (u_k - qd(k)),      α = 1 - exp(-T/τ_v),

per period (``α ≈ T/τ_v`` for ``T ≪ τ_v``). Over the first commands of a run, ``α`` is the
least-squares slope of the velocity steps against the command errors, every joint and
period pooled (one servo law for every joint); ``τ_v = -T / ln(1 - α)``. A slope at or
above 1 is a servo that settles within a period: ``τ_v = 0`` (ideal tracking).

:func:`stated_servo_time_constant` reads what a driver states (``servo_time_constant_s`` of
the driver or of the simulation it steps; 0 for the ideal kinematic loop), ``None`` where it
states nothing.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from dqcontrol.errors import ParameterError

__all__ = ["ServoFit", "identify_servo_time_constant", "stated_servo_time_constant"]

#: Smallest mean squared command error [(rad/s)²] that identifies the servo: below it the
#: commands did not move the joints enough to tell a lag from noise.
MIN_EXCITATION_RAD2_S2 = 1e-8


class ServoFit(NamedTuple):
    """A first-order lag fitted to measured joint velocities.

    Attributes:
        time_constant_s: ``τ_v`` [s] (0: settles within a period).
        step_fraction: ``α``, the share of the command error closed per period.
        residual_rad_s: RMS of the velocity steps the lag does not explain [rad/s].
        samples: the (period, joint) pairs the fit used.
    """

    time_constant_s: float
    step_fraction: float
    residual_rad_s: float
    samples: int


def identify_servo_time_constant(
    qd_measured_rad_s: np.ndarray, commands_rad_s: np.ndarray, period_s: float
) -> ServoFit:
    """Fit ``τ_v`` to the measured velocities ``(K + 1, n)`` that followed the commands
    ``(K, n)`` (``qd_measured[k]`` read before ``commands[k]`` was sent).

    Raises:
        ParameterError: shapes that do not match, non-finite values, a period that is not
            > 0, or commands that leave the joints too still to identify a lag.
    """
    qd = np.asarray(qd_measured_rad_s, dtype=float)
    u = np.asarray(commands_rad_s, dtype=float)
    if not (math.isfinite(period_s) and period_s > 0.0):
        raise ParameterError(f"period_s must be finite and > 0 [s], got {period_s!r}")
    if u.ndim != 2 or qd.shape != (u.shape[0] + 1, u.shape[1]) or u.shape[0] < 1:
        raise ParameterError(
            "expected the measured velocities (K + 1, n) around the commands (K, n), K ≥ 1; "
            f"got {qd.shape} and {u.shape}"
        )
    if not (np.isfinite(qd).all() and np.isfinite(u).all()):
        raise ParameterError("the measured velocities and the commands must be finite")
    error = (u - qd[:-1]).ravel()
    step = np.diff(qd, axis=0).ravel()
    excitation = float(error @ error)
    if excitation < MIN_EXCITATION_RAD2_S2 * error.size:
        raise ParameterError(
            "the commands hardly differ from the measured velocities (mean squared error "
            f"{excitation / error.size:.3g} (rad/s)²): send commands that move the joints "
            "to identify the servo"
        )
    alpha = float(error @ step) / excitation
    residual = float(np.sqrt(np.mean((step - alpha * error) ** 2)))
    if alpha >= 1.0:
        tau = 0.0
    elif alpha <= 0.0:
        raise ParameterError(
            f"the joints did not follow the commands (fitted step fraction {alpha:.3g} ≤ 0): "
            "no velocity servo of first order explains them"
        )
    else:
        tau = -period_s / math.log1p(-alpha)
    return ServoFit(tau, min(alpha, 1.0), residual, int(error.size))


def stated_servo_time_constant(driver: object) -> float | None:
    """``τ_v`` [s] as ``driver`` states it: its own ``servo_time_constant_s``, else that of the
    simulation it steps, else 0 for an ideal driver (``ideal_tracking = True``); ``None``
    where it states nothing (a real arm's driver that documents no lag: identify it)."""
    for owner in (driver, getattr(driver, "simulation", None)):
        value = getattr(owner, "servo_time_constant_s", None)
        if value is not None:
            return float(value)
    if getattr(driver, "ideal_tracking", False):
        return 0.0
    return None

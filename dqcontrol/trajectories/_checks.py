"""Input checks shared by the trajectory classes (private).

Every check raises :class:`~dqcontrol.errors.ParameterError` naming the parameter and the
accepted range, and returns the value converted to the type the code uses.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol.errors import ParameterError

#: Tolerance on ``|r| = 1`` and ``r·d = 0`` for a user-given unit dual quaternion.
UNIT_TOL = 1e-6


def positive(name: str, value: float, unit: str) -> float:
    """``value`` as a finite float ``> 0`` or :class:`ParameterError`."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}") from None
    if not (math.isfinite(v) and v > 0.0):
        raise ParameterError(f"{name} must be finite and > 0 [{unit}], got {value!r}")
    return v


def unit_dq(name: str, value: object) -> np.ndarray:
    """``value`` as a unit dual quaternion vec8 of shape ``(8,)`` or :class:`ParameterError`.

    Accepted: finite, ``| |r| - 1 | ≤ 1e-6`` and ``|r·d| ≤ 1e-6`` (docs/theory.md §1). The value is
    returned as given (not renormalised), so that anchoring reproduces it bit for bit.
    """
    try:
        x = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{name} must be a unit dual quaternion vec8 of shape (8,), got {value!r}"
        ) from None
    if x.shape != (8,):
        raise ParameterError(
            f"{name} must be a unit dual quaternion vec8 of shape (8,), got shape {x.shape}"
        )
    if not np.all(np.isfinite(x)):
        raise ParameterError(f"{name} must be finite, got {x!r}")
    norm_r = float(np.linalg.norm(x[:4]))
    r_dot_d = float(np.dot(x[:4], x[4:]))
    if abs(norm_r - 1.0) > UNIT_TOL or abs(r_dot_d) > UNIT_TOL:
        raise ParameterError(
            f"{name} must be a unit dual quaternion (| |r| - 1 | ≤ {UNIT_TOL:g} and "
            f"|r·d| ≤ {UNIT_TOL:g}), got |r| = {norm_r!r}, r·d = {r_dot_d!r}"
        )
    return x

"""The consistent prediction: states linear in the decision (docs/theory.md §8.1).

The horizon is cut into intervals at the breakpoints ``b_0 = 0 < b_1 = T < … < b_p = τ_p``
(the first interval is the control period, the rest spaced parabolically as eq. 3.15).
``qd_i`` and ``s_i`` are held over interval ``i``, so the state at the end of interval
``i`` is exactly

    q_{i+1} = q + Σ_{j≤i} Δ_j qd_j,        σ_{i+1} = σ + Σ_{j≤i} Δ_j s_j,

(``weights[i, j] = Δ_j`` for ``j ≤ i``). With a joint velocity loop that follows each new
command as a first-order lag of time constant ``τ_v`` (``lag_s``), a joint starting interval
``j`` at velocity ``v`` moves ``Δ_j qd_j + c_j (v - qd_j)`` with ``c_j = τ_v (1 - e^{-Δ_j/τ_v})``;
taking ``v`` as the previous interval's command (the measured velocity for the first), the
states stay exact and linear in the decision:

    q_{i+1} = q + c_0 qd_meas + Σ_{j≤i} [(Δ_j - c_j) qd_j + c_{j+1} qd_j [j < i]].

The phase has no lag. The kinematics are linearised at the previous
plan shifted by one period (interval averages of the old piecewise-constant plan over the
new intervals, the last value held past the horizon), integrated the same way, so the
linearisation point is itself a decision whose states are exact.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.prediction.base import Prediction, PredictionModel
from dqcontrol.controllers.problem import DecisionLayout
from dqcontrol.errors import ParameterError

__all__ = ["ConsistentPrediction", "interval_breakpoints", "shift_matrix"]


def interval_breakpoints(num_intervals: int, horizon_s: float, period_s: float) -> np.ndarray:
    """``[b_0 = 0, b_1 = T, …, b_p = τ_p]`` [s]: the first interval is the control period,
    the others grow parabolically, ``b_k = T + (τ_p - T) ((k - 1)/(p - 1))²``."""
    if isinstance(num_intervals, bool) or int(num_intervals) != num_intervals or num_intervals < 2:
        raise ParameterError(f"num_intervals (p) must be an integer ≥ 2, got {num_intervals!r}")
    if not (np.isfinite(horizon_s) and horizon_s > 0.0):
        raise ParameterError(f"horizon_s (tau_p) must be finite and > 0 [s], got {horizon_s!r}")
    p = int(num_intervals)
    if not horizon_s > period_s:
        raise ParameterError(
            f"horizon_s (tau_p) must be longer than the control period T = {period_s:g} s, "
            f"got {horizon_s!r} s"
        )
    k = np.arange(1, p + 1, dtype=float)
    inner = period_s + (horizon_s - period_s) * ((k - 1.0) / (p - 1.0)) ** 2
    return np.concatenate(([0.0], inner))


def shift_matrix(breaks: np.ndarray, shift_s: float) -> np.ndarray:
    """``S`` ``(p, p)``: ``(S v)_i`` is the mean over ``[b_i + shift, b_{i+1} + shift)`` of the
    piecewise-constant ``v`` (``v_j`` on ``[b_j, b_{j+1})``, ``v_{p-1}`` after ``b_p``)."""
    p = breaks.size - 1
    out = np.zeros((p, p))
    ends = breaks.copy()
    ends[-1] = np.inf
    for i in range(p):
        a, b = breaks[i] + shift_s, breaks[i + 1] + shift_s
        for j in range(p):
            overlap = min(b, ends[j + 1]) - max(a, breaks[j])
            if overlap > 0.0:
                out[i, j] = overlap / (b - a)
    return out


class ConsistentPrediction(PredictionModel):
    """States ``q_{i+1}``, ``σ_{i+1}`` at the breakpoints, affine in the decision.

    Args:
        breaks: ``[b_0 = 0, …, b_p]`` [s] (:func:`interval_breakpoints`).
        num_joints: ``n``.
        period_s: control period ``T`` [s] (the shift between steps).
        s_max: largest time scaling (the shifted plan's ``s`` is clipped to it).
        lag_s: time constant ``τ_v`` of the joint velocity loop [s] (0: the joints follow
            each command at once).
    """

    def __init__(
        self,
        breaks: np.ndarray,
        num_joints: int,
        period_s: float,
        s_max: float = 1.0,
        lag_s: float = 0.0,
    ) -> None:
        durations = np.diff(breaks)
        self.layout = DecisionLayout(num_joints, breaks[:-1], durations, with_scaling=True)
        self.breaks = np.asarray(breaks, dtype=float)
        self.period_s = float(period_s)
        self.s_max = float(s_max)
        p = durations.size
        self.sigma_weights = np.tril(np.broadcast_to(durations, (p, p)))
        self.lag_s = float(lag_s)
        if self.lag_s > 0.0:
            c = self.lag_s * (1.0 - np.exp(-durations / self.lag_s))
            follow = np.tril(np.broadcast_to(np.append(c[1:], 0.0), (p, p)), -1)
            self.weights = np.tril(np.broadcast_to(durations - c, (p, p))) + follow
            self._c0 = float(c[0])
        else:
            self.weights = self.sigma_weights
            self._c0 = 0.0
        self.qd_measured = np.zeros(num_joints)
        self._shift = shift_matrix(self.breaks, self.period_s)
        self.plan_qd = np.zeros((p, num_joints))
        self.plan_s = np.zeros(p)

    def reset(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        p = self.layout.num_blocks
        self.plan_qd = np.tile(np.asarray(qd0, dtype=float), (p, 1))
        self.plan_s = np.zeros(p)

    def at(self, q: np.ndarray, sigma: float, qd_lin: np.ndarray, s_lin: np.ndarray) -> Prediction:
        """The prediction linearised at the decision ``(qd_lin, s_lin)``."""
        base = q + self._c0 * self.qd_measured if self._c0 else q
        q_lin = base + self.weights @ qd_lin
        sigma_lin = sigma + self.sigma_weights @ s_lin
        p = self.layout.num_blocks
        return Prediction(
            q_lin,
            sigma_lin,
            np.broadcast_to(base, (p, q.size)),
            np.full(p, float(sigma)),
            self.weights,
            qd_lin,
            s_lin,
            self.sigma_weights,
        )

    def state_after_first(self, q: np.ndarray, qd_0: np.ndarray) -> np.ndarray:
        """``q_1`` after the first interval with the command ``qd_0`` [rad]."""
        return q + self._c0 * self.qd_measured + self.weights[0, 0] * qd_0

    def predict(self, q: np.ndarray, sigma: float) -> Prediction:
        qd_lin = self._shift @ self.plan_qd
        s_lin = np.clip(self._shift @ self.plan_s, 0.0, self.s_max)
        return self.at(q, sigma, qd_lin, s_lin)

    def commit(self, qd: np.ndarray, s: np.ndarray) -> None:
        self.plan_qd = np.array(qd, dtype=float)
        self.plan_s = np.array(s, dtype=float)

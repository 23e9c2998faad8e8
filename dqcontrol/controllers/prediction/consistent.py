"""The consistent prediction: states linear in the decision (docs/theory.md §8.1).

The horizon is cut into intervals at the breakpoints ``b_0 = 0 < b_1 = T < … < b_p = τ_p``
(the first interval is the control period, the rest spaced parabolically as eq. 3.15).
``qd_i`` and ``s_i`` are held over interval ``i``, so the state at the end of interval
``i`` is exactly

    q_{i+1} = q + Σ_{j≤i} Δ_j qd_j,        σ_{i+1} = σ + Σ_{j≤i} Δ_j s_j,

(``weights[i, j] = Δ_j`` for ``j ≤ i``). With a joint velocity loop that follows each new
command as a first-order lag of time constant ``τ_v`` (``lag_s``), a joint entering
interval ``j`` at velocity ``v_j`` moves ``(Δ_j - c_j) qd_j + c_j v_j`` with
``c_j = τ_v (1 - e_j)``, ``e_j = e^{-Δ_j/τ_v}``, and leaves it at
``v_{j+1} = e_j v_j + (1 - e_j) qd_j`` (``v_0``: the measured velocity). The velocities, and
so the states, stay exact and linear in the decision and in ``v_0``.

The phase has no lag. The kinematics are linearised at the previous
plan shifted by one period (interval averages of the old piecewise-constant plan over the
new intervals, the last value held past the horizon), integrated the same way, so the
linearisation point is itself a decision whose states are exact.
"""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.problem import DecisionLayout
from dqcontrol.controllers.prediction.base import Prediction, PredictionModel
from dqcontrol.controllers.prediction.consistent_kernels import clip_into, states_into
from dqcontrol.errors import ParameterError

__all__ = ["ConsistentPrediction", "interval_breakpoints", "shift_matrix"]


def interval_breakpoints(
    num_intervals: int, horizon_s: float, period_s: float, growth: float = 2.0
) -> np.ndarray:
    """``[b_0 = 0, b_1 = T, …, b_p = τ_p]`` [s]: the first interval is the control period,
    the others grow as a power ``g = growth`` (2: parabolically),
    ``b_k = T + (τ_p - T) ((k - 1)/(p - 1))^g``."""
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
    if not (np.isfinite(growth) and growth >= 1.0):
        raise ParameterError(f"growth must be finite and ≥ 1, got {growth!r}")
    k = np.arange(1, p + 1, dtype=float)
    inner = period_s + (horizon_s - period_s) * ((k - 1.0) / (p - 1.0)) ** growth
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


def _lag_weights(durations: np.ndarray, lag_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``(W, w_v)``: ``q_{i+1} - q = Σ_j W[i, j] qd_j + w_v[i] v_0`` behind a first-order
    velocity lag of time constant ``lag_s`` (module docstring); ``lag_s = 0``: ``W[i, j] = Δ_j``
    for ``j ≤ i``, ``w_v = 0``."""
    p = durations.size
    if lag_s <= 0.0:
        return np.tril(np.broadcast_to(durations, (p, p))), np.zeros(p)
    e = np.exp(-durations / lag_s)
    c = lag_s * (1.0 - e)
    v_coef = np.zeros((p, p))  # v_j = v_coef[j] · qd + v0_coef[j] v_0
    v0_coef = np.ones(p)
    for j in range(1, p):
        v_coef[j] = e[j - 1] * v_coef[j - 1]
        v_coef[j, j - 1] += 1.0 - e[j - 1]
        v0_coef[j] = e[j - 1] * v0_coef[j - 1]
    step = np.diag(durations - c) + c[:, None] * v_coef  # displacement of interval j
    return np.cumsum(step, axis=0), np.cumsum(c * v0_coef)


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
        self.weights, self._v0_weights = _lag_weights(durations, self.lag_s)
        self._first_weight = float(self.weights[0, 0])
        self._lagging = self.lag_s > 0.0  # the measured velocity enters the states
        self.qd_measured = np.zeros(num_joints)
        self._shift = shift_matrix(self.breaks, self.period_s)
        self.plan_qd = np.zeros((p, num_joints))
        self.plan_s = np.zeros(p)

    def reset(self, q0: np.ndarray, qd0: np.ndarray) -> None:
        """Start with the plan ``qd0`` held over the horizon and ``s = 0``."""
        p = self.layout.num_blocks
        self.plan_qd = np.tile(np.asarray(qd0, dtype=float), (p, 1))
        self.plan_s = np.zeros(p)

    def at(self, q: np.ndarray, sigma: float, qd_lin: np.ndarray, s_lin: np.ndarray) -> Prediction:
        """The prediction linearised at the decision ``(qd_lin, s_lin)``."""
        p, n = self.weights.shape[0], self.qd_measured.shape[0]
        q_lin = self.weights @ qd_lin  # the states once the zero decision's are added
        sigma_lin = self.sigma_weights @ s_lin
        base, sigma_base = np.empty((p, n)), np.empty(p)
        sigma = float(sigma)
        measured = self.qd_measured
        lag = self._lagging
        states_into(q, self._v0_weights, measured, lag, sigma, q_lin, sigma_lin, base, sigma_base)
        return Prediction(
            q_lin, sigma_lin, base, sigma_base, self.weights, qd_lin, s_lin, self.sigma_weights
        )

    def state_after_first(self, q: np.ndarray, qd_0: np.ndarray) -> np.ndarray:
        """``q_1`` after the first interval with the command ``qd_0`` [rad]."""
        start = q if not self._lagging else q + self._v0_weights[0] * self.qd_measured
        return start + self._first_weight * qd_0

    def predict(self, q: np.ndarray, sigma: float) -> Prediction:
        """The prediction linearised at the previous plan, shifted by one period."""
        qd_lin = self._shift @ self.plan_qd
        s_lin = self._shift @ self.plan_s
        clip_into(s_lin, 0.0, self.s_max)
        return self.at(q, sigma, qd_lin, s_lin)

    def commit(self, qd: np.ndarray, s: np.ndarray) -> None:
        """Remember the plan ``qd`` ``(p, n)``, ``s`` ``(p,)`` chosen this step."""
        self.plan_qd = np.array(qd, dtype=float)
        self.plan_s = np.array(s, dtype=float)

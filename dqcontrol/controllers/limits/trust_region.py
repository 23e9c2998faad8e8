"""A trust region around the linearisation point (docs/theory.md §8.5).

The path error is linearised at the shifted previous plan ``(q̄_i, σ̄_i)``; its error grows
with the square of the distance from that point. The rows

    |q_i(z) - q̄_i| ≤ ρ_q (1 + t_i / t_g),        |σ_i(z) - σ̄_i| ≤ ρ_σ (1 + t_i / t_g)

(``t_i`` the time of state ``i`` from now, ``t_g`` the growth time) keep every predicted
state where the linear model holds: tight at the first state, which is applied, wider
further out, where the plan is revised many times before it is executed (the radius grows
like the deviation a constant change of the commands would make). The plan may move further
over several steps, or over several linearise-and-solve rounds of one step.
"""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled
from dqcontrol.controllers.core.context import StepContext
from dqcontrol.controllers.core.problem import DecisionLayout, Inequality
from dqcontrol.controllers.limits.limit import Limit
from dqcontrol.controllers.linalg.gram import frozen

__all__ = ["TrustRegionLimit"]


class TrustRegionLimit(Limit):
    """State trust region: ``ρ_q`` [rad] per joint, ``ρ_σ`` [s] on the phase.

    Args:
        layout: the decision layout.
        radius_rad: ``ρ_q`` at the first state [rad] (``inf``: no joint rows).
        radius_phase_s: ``ρ_σ`` at the first state [s] (``inf``: no phase rows).
        growth_time_s: ``t_g`` [s]: the radius doubles every ``t_g`` of prediction time.
    """

    name = "trust_region"

    def __init__(
        self,
        layout: DecisionLayout,
        radius_rad: float,
        radius_phase_s: float,
        growth_time_s: float,
    ) -> None:
        self.layout = layout
        ends = layout.instants_s + layout.durations_s
        self._growth = 1.0 + ends / float(growth_time_s)
        self.radius_rad = float(radius_rad)
        self.radius_phase_s = float(radius_phase_s)
        self._weights: np.ndarray | None = None
        self._radii_q = np.repeat(self.radius_rad * self._growth, layout.num_joints)
        self._radii_phase = self.radius_phase_s * self._growth

    @property
    def radii_rad(self) -> np.ndarray:
        """``ρ_q (1 + t_i/t_g)`` per state [rad] (``inf`` without joint rows)."""
        return self.radius_rad * self._growth

    def _matrices(self, weights: np.ndarray, phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self._weights is not weights:
            layout = self.layout
            p, n = layout.num_blocks, layout.num_joints
            cq = np.zeros((p * n, layout.num_vars))
            cs = np.zeros((p, layout.num_vars))
            idx, sdx = layout.qd_index(), layout.s_index()
            for i in range(p):
                for j in range(i + 1):
                    cq[i * n + np.arange(n), idx[j]] = weights[i, j]
                    cs[i, sdx[j]] = phase[i, j]
            self._weights, self._cq, self._cs = weights, frozen(cq), frozen(cs)
        return self._cq, self._cs

    def rows(self, ctx: StepContext) -> tuple:
        """The rows that keep the predicted states near their linearisation points."""
        pred = ctx.prediction
        cq, cs = self._matrices(pred.weights, pred.phase_weights)
        joints, phase = math.isfinite(self.radius_rad), math.isfinite(self.radius_phase_s)
        if joints and phase:
            nq, p = self._radii_q.shape[0], self._radii_phase.shape[0]
            lower, upper = np.empty(nq + p), np.empty(nq + p)
            bands_into(
                pred.q_lin, pred.q_base, self._radii_q, pred.sigma_lin, pred.sigma_base,
                self._radii_phase, lower, upper,
            )  # fmt: skip
            return (
                Inequality("trust_region_q", cq, lower[:nq], upper[:nq]),
                Inequality("trust_region_phase", cs, lower[nq:], upper[nq:]),
            )
        out = []
        if joints:
            lower, upper = _band(pred.q_lin.ravel(), pred.q_base.ravel(), self._radii_q)
            out.append(Inequality("trust_region_q", cq, lower, upper))
        if phase:
            lower, upper = _band(pred.sigma_lin, pred.sigma_base, self._radii_phase)
            out.append(Inequality("trust_region_phase", cs, lower, upper))
        return tuple(out)


def _band(point: np.ndarray, base: np.ndarray, radius: np.ndarray) -> tuple:
    """``(c - r, c + r)`` with ``c = point - base`` (1-D arrays)."""
    lower, upper = np.empty(point.shape[0]), np.empty(point.shape[0])
    band_into(point, base, radius, lower, upper)
    return lower, upper


@compiled
def band_into(
    point: np.ndarray, base: np.ndarray, radius: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> None:
    """``lower = c - r``, ``upper = c + r`` with ``c = point - base``, entry by entry."""
    for k in range(point.shape[0]):
        centre = point[k] - base[k]
        lower[k] = centre - radius[k]
        upper[k] = centre + radius[k]


@compiled
def bands_into(
    q_point: np.ndarray,
    q_base: np.ndarray,
    q_radius: np.ndarray,
    s_point: np.ndarray,
    s_base: np.ndarray,
    s_radius: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> None:
    """:func:`band_into` of the joints (``(p, n)`` states, row by row) into the first
    ``p n`` entries of ``lower``/``upper``, then of the phases ``(p,)`` into the rest."""
    p, n = q_point.shape
    for i in range(p):
        for k in range(n):
            centre = q_point[i, k] - q_base[i, k]
            lower[i * n + k] = centre - q_radius[i * n + k]
            upper[i * n + k] = centre + q_radius[i * n + k]
    for i in range(s_point.shape[0]):
        centre = s_point[i] - s_base[i]
        lower[p * n + i] = centre - s_radius[i]
        upper[p * n + i] = centre + s_radius[i]

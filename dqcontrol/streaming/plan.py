"""A plan: the path-following controller's solved horizon as a joint trajectory
(docs/theory.md §12.1).

The controller holds ``qd_i`` and ``s_i`` over interval ``i`` of lengths ``Δ_i``; its
predicted states are exact integrals of them, so the horizon is itself a feasible joint
trajectory that can be played out without solving again. A plan starts at a sample of the
stream (``start_k``), from the state the stream will have reached there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dqcontrol.controllers.base import StepResult

__all__ = ["Plan", "plan_from_result"]


@dataclass(frozen=True)
class Plan:
    """A piecewise-constant joint-velocity plan.

    Attributes:
        plan_id: its number (1, 2, … in the order the planner made them).
        start_k: the stream sample at which it starts.
        made_s: stream time [s] of the measurement it was computed from.
        q_start: joint positions at its start [rad] ``(n,)``.
        sigma_start: phase at its start [s].
        durations_s: interval lengths ``Δ_i`` [s] ``(p,)``.
        qd: interval velocities [rad/s] ``(p, n)``.
        s: interval time scalings ``(p,)``.
        stop_after_first: the planner fell back (no solution): after the first interval
            the plan asks for rest instead of its held command.
    """

    plan_id: int
    start_k: int
    made_s: float
    q_start: np.ndarray
    sigma_start: float
    durations_s: np.ndarray
    qd: np.ndarray
    s: np.ndarray
    stop_after_first: bool = False
    #: the breakpoints ``[0, Δ_0, Δ_0 + Δ_1, …]`` [s], the states there ``(p + 1, n)`` [rad]
    #: and the phase there ``(p + 1,)`` [s] (derived)
    ends_s: np.ndarray = field(init=False, repr=False)
    q_at: np.ndarray = field(init=False, repr=False)
    sigma_at: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        ends = np.concatenate(([0.0], np.cumsum(self.durations_s)))
        q_at = self.q_start + np.concatenate(
            (np.zeros((1, self.q_start.size)), np.cumsum(self.durations_s[:, None] * self.qd, 0))
        )
        sigma_at = self.sigma_start + np.concatenate(([0.0], np.cumsum(self.durations_s * self.s)))
        object.__setattr__(self, "ends_s", ends)
        object.__setattr__(self, "q_at", q_at)
        object.__setattr__(self, "sigma_at", sigma_at)

    @property
    def duration_s(self) -> float:
        """The horizon ``τ_p`` [s]."""
        return float(self.ends_s[-1])

    def states(self) -> np.ndarray:
        """The predicted joint positions at the breakpoints ``(p + 1, n)`` [rad]."""
        return self.q_at.copy()

    def _index(self, tau_s: float) -> int:
        ends = self.ends_s
        return int(min(max(int(np.searchsorted(ends, tau_s, side="right")) - 1, 0), ends.size - 2))

    def velocity(self, tau_s: float) -> np.ndarray:
        """The plan's velocity at plan time ``tau_s`` [rad/s] (zero past its end, and past
        the first interval of a fallback plan)."""
        if tau_s >= self.duration_s or tau_s < 0.0:
            return np.zeros(self.q_start.size)
        i = self._index(tau_s)
        if i > 0 and self.stop_after_first:
            return np.zeros(self.q_start.size)
        return self.qd[i]

    def mean_velocity(self, tau0_s: float, tau1_s: float) -> np.ndarray:
        """The mean velocity over ``[tau0_s, tau1_s)`` [rad/s]: the command that reaches
        :meth:`position` at ``tau1_s`` from ``tau0_s`` exactly."""
        span = tau1_s - tau0_s
        if span <= 0.0:
            return self.velocity(tau0_s)
        return (self.position(tau1_s) - self.position(tau0_s)) / span

    def position(self, tau_s: float) -> np.ndarray:
        """The joint positions at plan time ``tau_s`` [rad] (held past the end)."""
        ends, q_at = self.ends_s, self.q_at
        tau = min(max(tau_s, 0.0), self.duration_s)
        i = self._index(tau)
        if i > 0 and self.stop_after_first:
            return q_at[1]
        return q_at[i] + (tau - ends[i]) * self.qd[i]

    def phase(self, tau_s: float) -> float:
        """The phase ``σ`` at plan time ``tau_s`` [s] (held past the end; a fallback plan
        holds it after its first interval)."""
        ends, sigma_at = self.ends_s, self.sigma_at
        tau = min(max(tau_s, 0.0), self.duration_s)
        i = self._index(tau)
        if i > 0 and self.stop_after_first:
            return float(sigma_at[1])
        return float(sigma_at[i] + (tau - ends[i]) * self.s[i])


def plan_from_result(
    result: StepResult,
    durations_s: np.ndarray,
    *,
    plan_id: int,
    start_k: int,
    made_s: float,
    q_start: np.ndarray,
) -> Plan:
    """The plan of one path-following step solved from ``q_start`` at phase
    ``result.sigma``: its applied command first, then the rest of its horizon."""
    assert result.horizon_qd is not None and result.horizon_s is not None, (
        "a path-following step reports its horizon"
    )
    qd = np.array(result.horizon_qd, dtype=float)
    s = np.array(result.horizon_s, dtype=float)
    qd[0], s[0] = result.qd_command, result.s
    return Plan(
        plan_id=plan_id,
        start_k=start_k,
        made_s=made_s,
        q_start=np.array(q_start, dtype=float),
        sigma_start=float(result.sigma),
        durations_s=np.asarray(durations_s, dtype=float),
        qd=qd,
        s=s,
        stop_after_first=bool(result.diagnostics.fallback),
    )

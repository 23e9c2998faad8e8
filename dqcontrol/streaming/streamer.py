"""The streamer: a command every period ``T`` from the latest plan, never waiting for a
solve (docs/theory.md §12.2–12.3).

Each sample it evaluates the current plan at its plan time: the mean velocity of the next
period (which integrates to the plan's positions exactly), plus a pull of the positions it
has integrated back onto the plan's, and sends what the
:class:`~dqcontrol.streaming.tracker.JerkLimitedTracker` allows of it. A new plan is taken
at its start sample (a blend: the tracker carries the command and its acceleration over);
a plan offered after its start is refused and counted. With no new plan for
``patience_k`` samples it plays the last plan out: plan time slows to a stop along the
plan's own joint path (a stop on the path), within the limits and the plan's horizon.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dqcontrol.streaming.kernels import stream_period
from dqcontrol.streaming.plan import Plan
from dqcontrol.streaming.tracker import JerkLimitedTracker

__all__ = ["StreamSample", "Streamer"]

#: The shortest play-out [periods].
STOP_MIN_PERIODS = 20


@dataclass(frozen=True)
class StreamSample:
    """One streamed period.

    Attributes:
        u: the command [rad/s] ``(n,)``.
        plan_id: the plan it came from (0: none yet).
        plan_age_s: time since the measurement that plan was computed from [s].
        sigma, sigma_next: phase at this sample and the next [s].
        mode: ``"plan"``, ``"playout"`` (no new plan: stopping along the last one),
            ``"stopped"`` (played out, at rest) or ``"rest"`` (no plan yet: the last
            command held, zero from a start at rest).
    """

    u: np.ndarray
    plan_id: int
    plan_age_s: float
    sigma: float
    sigma_next: float
    mode: str


class Streamer:
    """Plans in, one command per period out.

    Args:
        tracker: the limits' tracker (its ``period_s`` is ``T``).
        feedback_s: time constant of the pull onto the plan's positions [s].
        patience_k: samples a plan is played as planned after its start before, with no
            newer plan, the play-out begins.
        lookahead_s: the velocity asked for is the plan's this much later [s], so that a
            blend starts before its breakpoint (0: at it).
    """

    def __init__(
        self,
        tracker: JerkLimitedTracker,
        feedback_s: float,
        patience_k: int,
        lookahead_s: float = 0.0,
    ) -> None:
        self.tracker = tracker
        self.lookahead_s = float(lookahead_s)
        self.period_s = tracker.period_s
        self.gain_per_s = 1.0 / feedback_s
        self.patience_k = int(patience_k)
        self.restart(np.zeros(tracker.qd_max.size), 0.0)

    def restart(self, q0: np.ndarray, sigma0: float) -> None:
        """At rest at ``q0`` [rad], phase ``sigma0`` [s], sample 0, no plan."""
        self.k = 0
        self.q = np.array(q0, dtype=float)
        self.sigma0 = float(sigma0)
        self.s_hold = 0.0
        self.plan: Plan | None = None
        self.pending: Plan | None = None
        self.tau_s = 0.0
        self.rate = 1.0
        self.rate_step = 0.0
        self.refused = 0
        self.switches = 0
        self.playout_note = ""
        self.tracker.restart(np.zeros_like(self.q), np.zeros_like(self.q))

    def take_over(
        self, q: np.ndarray, sigma: float, u: np.ndarray, a: np.ndarray, s: float
    ) -> None:
        """Restart at ``q`` [rad], phase ``sigma`` [s], sample 0, no plan, from another
        controller's last command ``u`` [rad/s], its acceleration ``a`` [rad/s²] and time
        scaling ``s``: held until a plan starts, and the first plan's switch blends from
        them (§12.3)."""
        self.restart(q, sigma)
        self.tracker.restart(u, a)
        self.s_hold = float(s)

    def follow(self, u: np.ndarray, sigma_next: float) -> None:
        """Sample ``k``'s command ``u`` [rad/s] and the phase after it ``sigma_next`` [s]
        came from another controller (before the first plan starts): they become the
        tracker's command and acceleration and the held phase rate, the integrated
        positions move by it; advances to ``k + 1``."""
        tr, T = self.tracker, self.period_s
        tr.restart(u, (u - tr.u) / T)
        self.q += T * tr.u
        self.s_hold = (float(sigma_next) - self.sigma0) / T
        self.sigma0 = float(sigma_next)
        self.k += 1

    def copy(self) -> Streamer:
        """An independent copy (for projecting the committed stream ahead)."""
        twin = object.__new__(Streamer)
        twin.__dict__.update(self.__dict__)
        twin.tracker = self.tracker.copy()
        twin.q = self.q.copy()
        return twin

    def offer(self, plan: Plan) -> bool:
        """Take ``plan`` for its start sample; ``False`` (refused, counted) if that has passed."""
        if plan.start_k < self.k:
            self.refused += 1
            return False
        self.pending = plan
        return True

    @property
    def playing_out(self) -> bool:
        """Whether the last plan is being played out to rest (no newer plan came)."""
        return bool(self.playout_note)

    def take_due(self) -> None:
        """Switch to the pending plan if it starts at this sample."""
        pending = self.pending
        if pending is not None and pending.start_k <= self.k:
            self._switch(pending)

    def step(self) -> StreamSample:
        """The command of sample ``k``; advances to ``k + 1``."""
        self.take_due()
        plan = self.plan
        if plan is None:  # the last command and phase rate held (acceleration to zero)
            u = self.tracker.step(self.tracker.u)
            self.q += self.period_s * u
            self.k += 1
            sigma = self.sigma0
            self.sigma0 = sigma + self.period_s * self.s_hold
            return StreamSample(u, 0, 0.0, sigma, self.sigma0, "rest")
        if not self.playing_out and self.k - plan.start_k >= self.patience_k:
            self._begin_playout(plan)
        return self._play(plan)

    def _switch(self, plan: Plan) -> None:
        self.plan, self.pending = plan, None
        self.q = plan.q_start.copy()
        self.tau_s, self.rate, self.rate_step = 0.0, 1.0, 0.0
        self.playout_note = ""
        self.switches += 1

    def _begin_playout(self, plan: Plan) -> None:
        left_s = max(plan.duration_s - self.tau_s, self.period_s)
        self.rate_step = self.period_s / min(left_s, self._stop_time_s(plan))
        waited_ms = 1e3 * (self.k - plan.start_k) * self.period_s
        self.playout_note = (
            f"no new plan for {waited_ms:.0f} ms: playing out plan {plan.plan_id} to rest "
            f"along its path from sample {self.k}"
        )

    def _stop_time_s(self, plan: Plan) -> float:
        """How long the play-out's slowing takes [s]: at least twice what the acceleration
        limit needs from the present command to rest, plus the jerk's ramps, and at least
        ``STOP_MIN_PERIODS`` periods: the plan's nearest part, where it is closest to the
        path, is the part played."""
        tr = self.tracker
        u = np.abs(tr.u)
        a_max = tr.qdd_max
        jerk = tr.jerk_step / self.period_s
        need = np.where(np.isfinite(a_max), 2.0 * u / a_max, 0.0)
        need = need + np.where(np.isfinite(jerk) & np.isfinite(a_max), 2.0 * a_max / jerk, 0.0)
        return max(float(np.max(need)), STOP_MIN_PERIODS * self.period_s)

    def _play(self, plan: Plan) -> StreamSample:
        T, rate, tr = self.period_s, self.rate, self.tracker
        tau1, sigma, sigma_next = stream_period(
            plan.ends_s, plan.q_at, plan.qd, plan.sigma_at, plan.s, plan.stop_after_first,
            self.tau_s, rate, self.gain_per_s, T, self.lookahead_s,
            self.q, tr.u, tr.a, tr.qd_max, tr.qdd_max, tr.jerk_step,
        )  # fmt: skip
        u = tr.u.copy()
        self.tau_s = tau1
        mode = "plan"
        if self.playing_out:
            self.rate = max(rate - self.rate_step, 0.0)
            mode = "stopped" if rate == 0.0 and float(np.max(np.abs(u))) < 1e-9 else "playout"
        age = (self.k * T) - plan.made_s
        self.k += 1
        return StreamSample(u, plan.plan_id, age, sigma, sigma_next, mode)

"""The compiled period of the streamer (docs/theory.md §12.2): the plan evaluated at plan
time, the pull onto its positions, and one step of the jerk-limited tracker, per joint in
one pass (the same arithmetic as :class:`~dqcontrol.streaming.tracker.JerkLimitedTracker`,
which stays the readable reference)."""

from __future__ import annotations

import math

import numpy as np

from dqcontrol._compiled import compiled

__all__ = ["stream_period"]


@compiled
def _reach(gap: float, jerk_step: float, period_s: float) -> float:
    """The largest ``a ≥ 0`` with ``D(a) ≤ gap`` (``reachable_acceleration``)."""
    if gap <= 0.0:
        return 0.0
    if not math.isfinite(jerk_step):
        return gap / period_s
    d = jerk_step * period_s
    m = float(math.floor(0.5 * (math.sqrt(1.0 + 8.0 * gap / d) - 1.0)))
    m = max(m, 0.0)
    used = 0.5 * d * m * (m + 1.0)
    if used > gap:
        m -= 1.0
        used = 0.5 * d * m * (m + 1.0)
    return m * jerk_step + (gap - used) / (period_s * (m + 1.0))


@compiled
def _locate(ends: np.ndarray, tau: float, stop_after_first: bool) -> tuple[int, float]:
    """The interval of plan time ``tau`` (clipped to the plan) and the time into it; a
    fallback plan is held at the end of its first interval."""
    p = ends.shape[0] - 1
    t = min(max(tau, 0.0), ends[p])
    i = 0
    while i < p - 1 and ends[i + 1] <= t:
        i += 1
    if stop_after_first and i > 0:
        return 1, 0.0
    return i, t - ends[i]


@compiled
def _position(ends, q_at, qd, stop_after_first: bool, tau: float, j: int) -> float:
    i, into = _locate(ends, tau, stop_after_first)
    return q_at[i, j] + into * qd[i, j]


@compiled
def _phase(ends, sigma_at, s, stop_after_first: bool, tau: float) -> float:
    i, into = _locate(ends, tau, stop_after_first)
    return sigma_at[i] + into * s[i]


@compiled
def stream_period(
    ends, q_at, qd, sigma_at, s, stop_after_first: bool,
    tau0: float, rate: float, gain_per_s: float, period_s: float, lookahead_s: float,
    q, u, a, qd_max, qdd_max, jerk_step,
) -> tuple[float, float, float]:  # fmt: skip
    """One streamed period from plan time ``tau0`` at ``rate``: updates the command ``u``,
    its acceleration ``a`` and the integrated positions ``q`` in place; returns the plan
    time of the next period and the phase now and then. The velocity asked for is the
    plan's mean over the period ``lookahead_s`` later (the blends then start before the
    breakpoints, about centred on them); the pull is onto the plan's positions now."""
    tau1 = tau0 + rate * period_s
    span = tau1 - tau0
    ahead = rate * lookahead_s
    for j in range(q.shape[0]):
        p0 = _position(ends, q_at, qd, stop_after_first, tau0, j)
        wanted = 0.0
        if span > 0.0:
            start = _position(ends, q_at, qd, stop_after_first, tau0 + ahead, j)
            end = _position(ends, q_at, qd, stop_after_first, tau1 + ahead, j)
            wanted = rate * (end - start) / span
        r = wanted + gain_per_s * (p0 - q[j])
        v_max, a_max, js = qd_max[j], qdd_max[j], jerk_step[j]
        r = min(max(r, -v_max), v_max)
        uj, aj = u[j], a[j]
        hi = min(min(aj + js, a_max), _reach(v_max - uj, js, period_s))
        lo = max(max(aj - js, -a_max), -_reach(v_max + uj, js, period_s))
        gap = r - uj
        want = _reach(gap, js, period_s) if gap >= 0.0 else -_reach(-gap, js, period_s)
        a_new = min(max(want, lo), hi)
        u_new = uj + a_new * period_s
        if a_new == want and abs(u_new - r) <= 1e-12 * (1.0 + abs(r)):
            u_new = r
        a[j] = (u_new - uj) / period_s
        u[j] = u_new
        q[j] += period_s * u_new
    sigma0 = _phase(ends, sigma_at, s, stop_after_first, tau0)
    sigma1 = _phase(ends, sigma_at, s, stop_after_first, tau1)
    return tau1, sigma0, sigma1

"""dqcontrol/streaming/kernels.py: the compiled streamer period against the jerk-limited
tracker (numpy) given the same plan, pull and limits."""

from __future__ import annotations

import numpy as np

from dqcontrol.streaming.kernels import stream_period
from dqcontrol.streaming.plan import Plan
from dqcontrol.streaming.tracker import JerkLimitedTracker

T = 0.001
N_JOINTS = 3
V_MAX, A_MAX, J_MAX = 2.0, 10.0, 5000.0


def _random_plan(rng, start_k: int, q0, sigma0: float, scale: float, grid=False) -> Plan:
    p = 6
    durations = np.concatenate(([0.01], rng.uniform(0.02, 0.2, p - 1)))
    if grid:  # breakpoints on the stream's samples
        durations = np.round(durations / T) * T
    qd = rng.uniform(-scale, scale, (p, N_JOINTS))
    return Plan(start_k + 1, start_k, start_k * T, np.array(q0), sigma0, durations, qd,
                rng.uniform(0, 1, p))  # fmt: skip


def _limits() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (np.full(N_JOINTS, V_MAX), np.full(N_JOINTS, A_MAX), np.full(N_JOINTS, J_MAX))


def test_kernel_is_the_tracker():
    rng = np.random.default_rng(3)
    limits = _limits()
    reference = JerkLimitedTracker(*limits, T)
    plan = _random_plan(rng, 0, np.zeros(N_JOINTS), 0.0, 1.5)
    q, u, a = np.zeros(N_JOINTS), np.zeros(N_JOINTS), np.zeros(N_JOINTS)
    tau, q_ref = 0.0, np.zeros(N_JOINTS)
    for _ in range(400):
        wanted = plan.mean_velocity(tau, tau + T) + 50.0 * (plan.position(tau) - q_ref)
        expected = reference.step(wanted)
        q_ref = q_ref + T * expected
        tau, _, _ = stream_period(plan.ends_s, plan.q_at, plan.qd, plan.sigma_at, plan.s,
                                  False, tau, 1.0, 50.0, T, 0.0, q, u, a, limits[0], limits[1],
                                  limits[2] * T)  # fmt: skip
        np.testing.assert_allclose(u, expected, rtol=0, atol=1e-12)

"""dqcontrol/streaming/kernels.py: the compiled streamer period against the jerk-limited
tracker (numpy) given the same plan, pull and limits."""

from __future__ import annotations

import numpy as np
from streaming.test_streamer import A_MAX, J_MAX, N_JOINTS, V_MAX, T, _random_plan

from dqcontrol.streaming.kernels import stream_period
from dqcontrol.streaming.tracker import JerkLimitedTracker


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

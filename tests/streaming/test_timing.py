"""dqcontrol/streaming/timing.py: the wall-clock figures against a hand computation from
given readiness times and host stalls, and a short run of a stand-in controller."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol.streaming import timing
from dqcontrol.streaming.timing import HOST_STALL_S, time_on_wall_clock

T = 0.01


def test_the_figures_by_hand():
    ready_s = np.array([0.001, 0.012, 0.002, 0.015, 0.003])  # samples 1 and 3 late
    start = 100.0
    # (end time, overrun) [s]: one stall during sample 1's period, one short overrun
    # during sample 3's, one long stall after the run
    stalls = [(100.013, 0.004), (100.035, 0.001), (100.2, 0.01)]
    figures = timing._figures(ready_s, T, start, stalls)
    assert figures.samples == 5 and figures.late == 2
    assert figures.late_during_host_stalls == 1  # sample 1's; sample 3's overrun is short
    ms = 1e3 * ready_s
    assert figures.lateness_median_ms == pytest.approx(np.median(ms))
    assert figures.lateness_p99_ms == pytest.approx(np.percentile(ms, 99))
    assert figures.lateness_max_ms == pytest.approx(15.0)
    assert figures.host_stalls == 2 and figures.host_stall_max_ms == pytest.approx(10.0)
    assert figures.host_stall_p99_ms == pytest.approx(np.percentile([4.0, 1.0, 10.0], 99))
    assert 0.004 >= HOST_STALL_S > 0.001  # the stalls above straddle the threshold


def test_without_a_measured_stall_no_lateness_is_the_hosts():
    figures = timing._figures(np.array([0.02, 0.001]), T, 0.0, [])
    assert figures.late == 1 and figures.late_during_host_stalls == 0
    assert figures.host_stalls == 0 and figures.host_stall_max_ms == 0.0


class _Stepper:
    """A stand-in controller: a constant command, done after ``steps`` steps; records the
    calls the timing loop makes."""

    period_s = T

    def __init__(self, steps: int) -> None:
        self.steps, self.calls, self.done = steps, [], False

    def reset(self, q0) -> None:
        self.calls.append(("reset", np.array(q0)))

    def use_wall_clock(self, on: bool) -> None:
        self.calls.append(("use_wall_clock", on))

    def step(self, q):
        self.calls.append(("step", np.array(q)))
        self.done = sum(1 for c in self.calls if c[0] == "step") >= self.steps
        return SimpleNamespace(qd_command=np.ones(2))

    def close(self) -> None:
        self.calls.append(("close", None))


@pytest.mark.wall_clock
def test_a_short_run_steps_the_integrated_state_and_closes_the_controller():
    ctrl = _Stepper(steps=4)
    figures = time_on_wall_clock(ctrl, np.zeros(2), seconds=0.1)
    assert figures.samples == 4  # done after 4 of the 10 periods
    kinds = [c[0] for c in ctrl.calls]
    assert kinds == ["reset", "use_wall_clock", "step", "step", "step", "step", "close"]
    assert ctrl.calls[1][1] is True
    for k, (_, q) in enumerate(c for c in ctrl.calls if c[0] == "step"):
        np.testing.assert_allclose(q, np.full(2, k * T))  # q_{k+1} = q_k + T u_k

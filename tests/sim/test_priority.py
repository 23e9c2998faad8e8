"""The wall-clock loop's real-time priority: taken for the loop only, given back after,
refused with a message that says how to grant it."""

from __future__ import annotations

import errno
import os

import pytest
from sim.test_loop import kinematic_run

from dqcontrol.errors import ParameterError
from dqcontrol.sim.priority import check_priority, realtime_priority

pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_FIFO"), reason="Linux scheduling")


def _may_use_fifo() -> bool:
    try:
        check_priority(1)
    except ParameterError:
        return False
    return True


@pytest.mark.parametrize("bad", [0, 100, True, 2.5, "10"])
def test_a_priority_outside_the_fifo_range_is_refused(bad):
    with pytest.raises(ParameterError, match=r"realtime_priority must be an integer in \[1, 99\]"):
        check_priority(bad)


def test_without_the_privilege_the_message_says_how_to_grant_it(monkeypatch):
    def refuse(*_args):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    with pytest.raises(ParameterError, match=r"CAP_SYS_NICE or an rtprio limit of at least 20"):
        check_priority(20)


def test_none_leaves_the_scheduler_alone():
    before = os.sched_getscheduler(0)
    with realtime_priority(None):
        assert os.sched_getscheduler(0) == before


@pytest.mark.skipif(not _may_use_fifo(), reason="this process may not use SCHED_FIFO")
def test_the_loop_samples_in_fifo_and_gives_it_back(lbr4p):
    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    seen = []

    def record(_k, _driver, _result):
        seen.append((os.sched_getscheduler(0), os.sched_getparam(0).sched_priority))

    res = kinematic_run(
        lbr4p,
        0.2,
        0.01,
        on_sample=record,
        realtime=True,
        realtime_priority=7,
    )
    assert res.metrics.completed and seen and set(seen) == {(os.SCHED_FIFO, 7)}
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before


@pytest.mark.skipif(not _may_use_fifo(), reason="this process may not use SCHED_FIFO")
def test_a_stepped_run_keeps_the_ordinary_scheduler(lbr4p):
    seen = []
    kinematic_run(
        lbr4p,
        0.1,
        0.01,
        on_sample=lambda *_: seen.append(os.sched_getscheduler(0)),
        realtime_priority=7,
    )
    assert seen and os.SCHED_FIFO not in seen

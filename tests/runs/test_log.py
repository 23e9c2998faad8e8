"""dqcontrol/runs/log.py: the recorder's rows against the samples it was given, the empty log,
a streamed controller's plan columns, and a log saved before the ``stopping`` flag existed."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.runs.log import NO_PLAN, LogRecorder, RunLog, stream_values
from dqcontrol.streaming.streamed import StreamDiagnostics

N = 3


def _result(rng, k: int, status: str = "solved", plan_id: int | None = None) -> StepResult:
    """Controller output of sample ``k``: random command and poses, diagnostics from ``k``
    (a streamed controller's when ``plan_id`` is given)."""
    fields = {
        "status": status,
        "iterations": k,
        "solve_time_s": 1e-4 * k,
        "step_time_s": 2e-4 * k,
        "fallback": k % 2 == 0,
        "relaxed": k % 3 == 0,
        "saturated": k % 5 == 0,
    }
    if plan_id is None:
        diagnostics = StepDiagnostics(**fields)
    else:
        diagnostics = StreamDiagnostics(
            **fields, plan_id=plan_id, plan_age_s=0.01 * k, lateness_s=-0.001
        )
    return StepResult(
        qd_command=rng.standard_normal(N), s=0.5 + 0.01 * k, sigma=0.1 * k,
        sigma_next=0.1 * k + 0.05, pose=rng.standard_normal(8), target=rng.standard_normal(8),
        diagnostics=diagnostics,
    )  # fmt: skip


def test_the_recorder_keeps_every_sample_in_its_row():
    rng = np.random.default_rng(1)
    rec = LogRecorder(N, meta={"robot": "test"})
    given = []
    for k in range(4):
        result = _result(rng, k, status="solved" if k else "closed_form")
        q, qd = rng.standard_normal(N), rng.standard_normal(N)
        torque = None if k == 1 else rng.standard_normal(N)
        rec.record(0.01 * k, q, qd, result, torque, torque, stopping=k == 3)
        given.append((q, qd, result, torque))
    log = rec.finish()
    assert len(log) == len(rec) == 4 and log.meta == {"robot": "test"}
    for k, (q, qd, result, torque) in enumerate(given):
        d = result.diagnostics
        assert log.t_s[k] == 0.01 * k and log.sigma[k] == result.sigma and log.s[k] == result.s
        np.testing.assert_array_equal(log.q[k], q)
        np.testing.assert_array_equal(log.qd_measured[k], qd)
        np.testing.assert_array_equal(log.qd_command[k], result.qd_command)
        np.testing.assert_array_equal(log.pose[k], result.pose)
        np.testing.assert_array_equal(log.target[k], result.target)
        if torque is None:
            assert np.isnan(log.torque[k]).all() and np.isnan(log.torque_peak[k]).all()
        else:
            np.testing.assert_array_equal(log.torque[k], torque)
        assert log.solver_status[k] == d.status and log.iterations[k] == d.iterations
        assert log.solve_time_s[k] == d.solve_time_s and log.step_time_s[k] == d.step_time_s
        assert (log.fallback[k], log.relaxed[k], log.saturated[k]) == (
            d.fallback,
            d.relaxed,
            d.saturated,
        )
    np.testing.assert_array_equal(log.stopping, [False, False, False, True])
    assert log.plan_id is None and "plan_id" not in log.arrays()


def test_an_empty_recorder_gives_empty_arrays_of_the_right_shapes():
    log = LogRecorder(N).finish()
    assert len(log) == 0
    assert log.q.shape == (0, N) and log.pose.shape == (0, 8) and log.stopping.shape == (0,)


def test_the_arrays_rebuild_the_same_log():
    rng = np.random.default_rng(2)
    rec = LogRecorder(N)
    for k in range(3):
        rec.record(0.1 * k, rng.standard_normal(N), np.zeros(N), _result(rng, k, plan_id=k))
    log = rec.finish()
    back = RunLog.from_arrays(log.arrays(), meta={"a": 1})
    for name, values in log.arrays().items():
        np.testing.assert_array_equal(getattr(back, name), values, err_msg=name)
    assert back.meta == {"a": 1}


def test_a_streamed_controllers_samples_carry_their_plan():
    rng = np.random.default_rng(3)
    first = _result(rng, 0)
    streamed = _result(rng, 4, plan_id=7)
    assert stream_values(first) is None
    assert stream_values(streamed) == (7, 0.04, -0.001)
    rec = LogRecorder(N)
    rec.record(0.0, np.zeros(N), np.zeros(N), first)
    rec.record(0.1, np.zeros(N), np.zeros(N), streamed)
    log = rec.finish()
    np.testing.assert_array_equal(log.plan_id, [NO_PLAN[0], 7])
    assert np.isnan(log.plan_age_s[0]) and log.plan_age_s[1] == 0.04
    assert np.isnan(log.lateness_s[0]) and log.lateness_s[1] == -0.001


def test_a_log_without_the_flag_reads_as_no_stop(stopped, tmp_path):
    _ctrl, result = stopped
    arrays = result.log.arrays()
    del arrays["stopping"]
    log = RunLog.from_arrays(arrays)
    assert log.stopping.shape == log.t_s.shape and not log.stopping.any()

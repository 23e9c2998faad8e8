"""dqcontrol/runs/stream.py: the streamed recorder's blocks, an unexpected error leaving the
samples before it flagged, and, in a separate process, SIGKILL at seeded random moments
leaving a readable file complete up to a block and flagged, and a run of 10× the samples
peaking within 1.2× the memory."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.log import LogRecorder
from dqcontrol.runs.storage import load_run
from dqcontrol.runs.stream import StreamRecorder, block_capacity
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle

#: A kinematic run at 1 kHz streaming to argv[1] in blocks of argv[2] seconds, for argv[3]
#: seconds of trajectory; prints "started" at the first sample, then the peak RSS [kB].
_CHILD = """
import resource, sys
from dqcontrol import load_lbr4p
from dqcontrol.controllers import LocalController
from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle

robot = load_lbr4p()
controller = LocalController(robot, Circle(float(sys.argv[3])), 0.001)
started = []

def progress(sigma, duration):
    if not started:
        started.append(1)
        print("started", flush=True)

run_loop(controller, KinematicDriver(robot, 0.001), q0=LBR4P_Q0, log_file=sys.argv[1],
         log_chunk_s=float(sys.argv[2]), on_progress=progress, brake=False)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, flush=True)
"""

posix_only = pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL is POSIX")


def _child(path, chunk_s: float, duration_s: float) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(path), str(chunk_s), str(duration_s)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


@posix_only
def test_sigkill_leaves_a_readable_flagged_file_complete_up_to_a_block(tmp_path):
    rng = np.random.default_rng(20261204)
    block = 50  # samples of 0.05 s at 1 kHz
    for trial, delay_s in enumerate(rng.uniform(0.2, 1.5, size=2)):
        path = tmp_path / f"killed{trial}.mcap"
        child = _child(path, 0.05, 60.0)
        assert child.stdout is not None and child.stdout.readline().strip() == "started"
        time.sleep(delay_s)
        child.send_signal(signal.SIGKILL)
        child.wait()
        log, record = load_run(path)
        assert not record["complete"] and record["interrupted"], trial
        assert "cut short" in record["note"]
        assert len(log) > 0 and len(log) % block == 0, (trial, len(log))
        np.testing.assert_allclose(log.t_s, 0.001 * np.arange(len(log)), atol=1e-9)
        assert log.meta["joint_names"] and log.meta["period_s"] == 0.001


def _peak_rss_kb(path, duration_s: float) -> int:
    child = _child(path, 1.0, duration_s)
    out, _ = child.communicate(timeout=300)
    assert child.returncode == 0
    return int(out.split()[-1])


@posix_only
def test_ten_times_the_samples_within_1_2_times_the_memory(tmp_path):
    short = _peak_rss_kb(tmp_path / "short.mcap", 1.0)
    long = _peak_rss_kb(tmp_path / "long.mcap", 10.0)
    assert len(load_run(tmp_path / "long.mcap", max_samples=10)[0]) <= 11
    assert long <= 1.2 * short, (short, long)


class _BrokenDriver(KinematicDriver):
    """A driver whose 120th read raises an error no loop expects."""

    reads = 0

    def read(self):
        self.reads += 1
        if self.reads == 120:
            raise RuntimeError("driver bug")
        return super().read()


def test_an_unexpected_error_leaves_the_samples_before_it_flagged(lbr4p, tmp_path):
    controller = LocalController(lbr4p, Circle(3.0), 0.01)
    with pytest.raises(RuntimeError, match="driver bug"):
        run_loop(controller, _BrokenDriver(lbr4p, 0.01), q0=LBR4P_Q0,
                 log_file=tmp_path / "r.mcap", log_chunk_s=0.5)  # fmt: skip
    log, record = load_run(tmp_path / "r.mcap")
    assert not record["complete"] and len(log) == 118  # the first read is the start


@pytest.mark.parametrize(
    ("period_s", "chunk_s", "capacity"),
    [(0.001, 0.05, 50), (0.01, 1.0, 100), (0.003, 0.01, 3), (0.3, 0.1, 1), (0.001, 0.003, 3)],
)
def test_a_block_holds_the_samples_of_one_chunk(period_s, chunk_s, capacity):
    assert block_capacity(period_s, chunk_s) == capacity


@pytest.mark.parametrize("chunk_s", [0.0, -1.0, float("inf"), float("nan")])
def test_a_bad_chunk_is_refused(chunk_s):
    with pytest.raises(ParameterError, match="chunk_s must be a finite duration > 0"):
        block_capacity(0.01, chunk_s)


def _result(rng, k: int) -> StepResult:
    return StepResult(
        qd_command=rng.standard_normal(3), s=1.0, sigma=0.01 * k, sigma_next=0.01 * (k + 1),
        pose=rng.standard_normal(8), target=rng.standard_normal(8),
        diagnostics=StepDiagnostics("solved", iterations=k),
    )  # fmt: skip


def test_the_recorder_keeps_two_blocks_and_writes_every_sample(tmp_path):
    rng = np.random.default_rng(21)
    rec = StreamRecorder(tmp_path / "r.mcap", 3, 0.01, {"robot": "test"}, chunk_s=0.03,
                         fsync=False)  # fmt: skip
    memory = LogRecorder(3)
    for k in range(7):
        args = (0.01 * k, rng.standard_normal(3), np.zeros(3), _result(rng, k))
        rec.record(*args)
        memory.record(*args)
    assert len(rec) == 7
    window = rec.window()  # the full block of samples 3..5 and sample 6 being filled
    np.testing.assert_array_equal(window.t_s, 0.01 * np.arange(3, 7))
    assert window.meta == {"robot": "test"}
    rec.close({"reason": "end"})
    log, _ = load_run(tmp_path / "r.mcap")
    for name, values in memory.finish().arrays().items():
        np.testing.assert_array_equal(log.arrays()[name], values, err_msg=name)

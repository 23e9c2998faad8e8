"""The streamed run log in a separate process: SIGKILL at seeded random moments leaves a
readable file, complete up to a block and flagged; and a run of 10× the samples peaks
within 1.2× the memory."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from dqcontrol.runs.storage import load_run

#: A kinematic run at 1 kHz streaming to argv[1] in blocks of argv[2] seconds, for argv[3]
#: seconds of trajectory; prints "started" at the first sample, then the peak RSS [kB].
_CHILD = """
import resource, sys
from dqcontrol import load_lbr4p
from dqcontrol.controllers import LocalController
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

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL is POSIX")


def _child(path, chunk_s: float, duration_s: float) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(path), str(chunk_s), str(duration_s)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


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


def test_ten_times_the_samples_within_1_2_times_the_memory(tmp_path):
    short = _peak_rss_kb(tmp_path / "short.mcap", 1.0)
    long = _peak_rss_kb(tmp_path / "long.mcap", 10.0)
    assert len(load_run(tmp_path / "long.mcap", max_samples=10)[0]) <= 11
    assert long <= 1.2 * short, (short, long)

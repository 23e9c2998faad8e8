"""dqcontrol/runs/mcap_log.py: the streamed log is plain MCAP (any reader opens it, with its
JSON preview), and a log that cannot be written (full disk, unwritable folder) stops the
run and the arm, or is refused before the arm moves."""

from __future__ import annotations

import errno

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.errors import DQControlError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.mcap_log import McapRunWriter, RunLogWriteError
from dqcontrol.runs.storage import load_run
from dqcontrol.sim import KinematicDriver, run_kinematic, run_loop
from dqcontrol.trajectories import Circle


def _streamed(lbr4p, path, duration_s=1.0, **kwargs):
    controller = LocalController(lbr4p, Circle(duration_s), 0.01)
    return controller, run_kinematic(controller, LBR4P_Q0, log_file=path, **kwargs)


def test_the_file_is_plain_mcap_with_a_json_preview(lbr4p, tmp_path):
    """Any MCAP reader opens the file: its summary, the run records and the preview."""
    import json

    from mcap.reader import make_reader

    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap")
    log, _ = load_run(streamed.log_file)
    with open(streamed.log_file, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        topics = {c.topic: summary.statistics.channel_message_counts[i]
                  for i, c in summary.channels.items()}  # fmt: skip
        previews = [json.loads(m.data) for _, _, m in reader.iter_messages(["/dqcontrol/preview"])]
    assert topics["/dqcontrol/run"] == 2 and topics["/dqcontrol/samples"] == 2
    stride = 2  # 50 Hz at T = 0.01 s
    assert len(previews) == len(log.t_s[::stride])
    np.testing.assert_array_equal([p["t_s"] for p in previews], log.t_s[::stride])
    np.testing.assert_array_equal(previews[3]["q"], log.q[3 * stride])


def _failing_sync(after: int):
    """A ``McapRunWriter._sync`` that raises ENOSPC from its ``after``-th call on."""
    calls = []

    def sync(writer: McapRunWriter) -> None:
        calls.append(1)
        if len(calls) >= after:
            raise OSError(errno.ENOSPC, "No space left on device")
        writer._file.flush()

    return sync


class _HeldDriver(KinematicDriver):
    held = 0

    def hold(self) -> None:
        self.held += 1
        super().hold()


def test_a_full_disk_stops_the_run_and_the_arm(lbr4p, tmp_path, monkeypatch):
    monkeypatch.setattr(McapRunWriter, "_sync", _failing_sync(after=3))
    controller = LocalController(lbr4p, Circle(1.0), 0.01)
    driver = _HeldDriver(lbr4p, 0.01)
    result = run_loop(controller, driver, q0=LBR4P_Q0, log_file=tmp_path / "r.mcap",
                      log_chunk_s=0.05)  # fmt: skip
    assert result.interrupted and result.reason == "log" and driver.held == 1
    assert "No space left on device" in result.note and "r.mcap" in result.note
    assert len(result.log) < 100  # it stopped well before the end (1 s at 0.01 s)
    _, record = load_run(tmp_path / "r.mcap")
    assert not record["complete"] and "cut short" in record["note"]


def test_an_unwritable_log_raises_before_the_arm_moves(lbr4p, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    driver = _HeldDriver(lbr4p, 0.01)
    with pytest.raises(RunLogWriteError, match="cannot write the run log"):
        run_loop(LocalController(lbr4p, Circle(1.0), 0.01), driver, q0=LBR4P_Q0,
                 log_file=blocker / "r.mcap")  # fmt: skip
    np.testing.assert_array_equal(driver.read().q, LBR4P_Q0)
    assert issubclass(RunLogWriteError, DQControlError)

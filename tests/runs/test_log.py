"""The streamed run log: round trip of every field, metrics from the file, decimated
loading, old ``.npz`` runs, and a log that cannot be written (full disk, unwritable folder)."""

from __future__ import annotations

import errno

import numpy as np
import pytest

from dqcontrol.cli import main
from dqcontrol.controllers import LocalController
from dqcontrol.errors import DQControlError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs import stream_metrics
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.mcap_log import McapRunWriter, RunLogWriteError
from dqcontrol.runs.metrics import compute_metrics
from dqcontrol.runs.storage import load_run, save_run
from dqcontrol.sim import KinematicDriver, run_kinematic, run_loop
from dqcontrol.trajectories import Circle

TIMING = ("solve_time_s", "step_time_s")


def _streamed(lbr4p, path, duration_s=1.0, **kwargs):
    controller = LocalController(lbr4p, Circle(duration_s), 0.01)
    return controller, run_kinematic(controller, LBR4P_Q0, log_file=path, **kwargs)


def _assert_metrics_close(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key, x in a.items():
        if isinstance(x, float):  # a JSON record holds NaN as None
            y = float("nan") if b[key] is None else b[key]
            np.testing.assert_allclose(y, x, rtol=1e-12, atol=1e-12, err_msg=key)
        else:
            assert b[key] == x, key


def test_every_field_meta_and_joint_names_round_trip(lbr4p, tmp_path):
    memory = run_kinematic(LocalController(lbr4p, Circle(3.0), 0.01), LBR4P_Q0)
    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap", 3.0)
    log, record = load_run(streamed.log_file)
    assert record["complete"] and not record["interrupted"] and record["samples"] == len(log)
    assert len(log) == len(memory.log) > 200 >= len(streamed.log)  # a window of <= 2 s
    for name, x in memory.log.arrays().items():
        y = log.arrays()[name]
        assert y.dtype == x.dtype, name
        if name not in TIMING:
            np.testing.assert_array_equal(y, x, err_msg=name)
    assert log.meta["joint_names"] == list(lbr4p.joint_names)
    assert log.meta["stop"]["reason"] == "end" and log.meta["period_s"] == 0.01
    np.testing.assert_array_equal(streamed.log.t_s, log.t_s[-len(streamed.log) :])


def test_metrics_from_the_file_equal_the_in_memory_ones(lbr4p, tmp_path):
    controller, streamed = _streamed(lbr4p, tmp_path / "run.mcap")
    log, record = load_run(streamed.log_file)
    direct = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), 0.01)
    _assert_metrics_close(direct.as_dict(), streamed.metrics.as_dict())
    _assert_metrics_close(direct.as_dict(), record["metrics"])


def test_exact_medians_without_keeping_the_values(lbr4p, tmp_path, monkeypatch):
    """Beyond MEDIAN_KEEP samples the medians come from a selection over the bit patterns."""
    monkeypatch.setattr(stream_metrics, "MEDIAN_KEEP", 7)
    controller, streamed = _streamed(lbr4p, tmp_path / "run.mcap")
    log, _ = load_run(streamed.log_file)
    direct = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), 0.01)
    assert streamed.metrics.step_time_median_s == direct.step_time_median_s
    assert streamed.metrics.solve_time_median_s == direct.solve_time_median_s


def test_selection_finds_every_rank_with_negative_values():
    rng = np.random.default_rng(7)
    values = np.concatenate((rng.normal(size=300), [0.0, -0.0, 1e-300, -5.0, 5.0, 5.0]))
    blocks = [{"v": part, "w": -part} for part in np.array_split(values, 7)]
    ranks = (0, 1, 150, 305)
    wanted = [(name, rank) for name in ("v", "w") for rank in ranks]
    found = stream_metrics._select(lambda: iter(blocks), wanted)
    assert found == [*np.sort(values)[list(ranks)], *np.sort(-values)[list(ranks)]]


def test_a_long_run_loads_decimated_for_display(lbr4p, tmp_path):
    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap", max_time_s=0.5)
    full, _ = load_run(streamed.log_file)
    small, record = load_run(streamed.log_file, max_samples=10)
    assert record["stride"] == 5 and len(small) <= 11
    np.testing.assert_array_equal(small.t_s[:-1], full.t_s[::5][: len(small) - 1])
    assert small.t_s[-1] == full.t_s[-1]


def test_an_old_npz_run_still_loads(lbr4p, tmp_path):
    result = run_kinematic(LocalController(lbr4p, Circle(0.3), 0.05), LBR4P_Q0)
    npz, js = save_run(result, tmp_path, "old")
    for path in (npz, js, tmp_path / "old"):
        log, record = load_run(path)
        np.testing.assert_array_equal(log.q, result.log.q)
        assert "complete" not in record and record["meta"]["joint_names"]


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


_CLI = ["run", "--short", "--simulator", "kinematic", "--controllers", "local",
        "--duration", "0.5"]  # fmt: skip


def _no_figures(monkeypatch) -> None:
    """Figures and replays off (tested elsewhere): only the run and its files here."""
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    monkeypatch.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])


def test_cli_full_disk_exits_1_with_a_clear_message(tmp_path, capsys, monkeypatch):
    _no_figures(monkeypatch)
    monkeypatch.setattr(McapRunWriter, "_sync", _failing_sync(after=2))
    code = main([*_CLI, "--period", "0.001", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 1
    assert "cannot write the run log" in err and "No space left on device" in err
    assert "Traceback" not in err


def test_cli_unwritable_folder_exits_1_with_a_clear_message(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code = main([*_CLI, "--out", str(blocker)])
    err = capsys.readouterr().err
    assert code == 1 and "cannot write the run log" in err and "Traceback" not in err


def test_cli_read_only_folder_exits_1(tmp_path, capsys):
    import os

    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    tmp_path.chmod(0o500)
    try:
        code = main([*_CLI, "--out", str(tmp_path)])
    finally:
        tmp_path.chmod(0o700)
    assert code == 1 and "cannot write the run log" in capsys.readouterr().err


def test_cli_streams_the_log_beside_the_saved_run(tmp_path, monkeypatch):
    _no_figures(monkeypatch)
    assert main([*_CLI, "--out", str(tmp_path)]) == 0
    folder = tmp_path / "lbr4p_circle_T0.5s_kinematic"
    streamed, _ = load_run(folder / "local.mcap")
    saved, record = load_run(folder / "local.json")
    assert record["log"] == "local.mcap" and record["npz"] == "local.npz"
    np.testing.assert_array_equal(streamed.q, saved.q)


def test_view_reads_a_streamed_run_and_flags_a_cut(lbr4p, tmp_path, capsys, monkeypatch):
    import dqcontrol.viz.figures as figures

    drawn = []
    monkeypatch.setattr(figures, "plot_run", lambda log, *a, **k: drawn.append(log) or [])
    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap", 0.3)
    data = streamed.log_file.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) - 200])  # the end record and summary lost
    for path in (streamed.log_file, cut):
        code = main(["view", str(path), "--no-viewer", "--figures", "--out", str(tmp_path / "v")])
        assert code == 0
    full, _ = load_run(streamed.log_file)
    assert [len(log) for log in drawn] == [len(full), len(full)]  # one block of 0.31 s
    err = capsys.readouterr().err
    assert "cut.mcap is incomplete" in err and "run.mcap" not in err


def test_a_newer_cut_log_is_not_taken_for_the_run_saved_before(lbr4p, tmp_path):
    """A run that crashed after an earlier one was saved under the same name is read from
    its own (newer, incomplete) log."""
    import os

    earlier = run_kinematic(LocalController(lbr4p, Circle(0.3), 0.05), LBR4P_Q0)
    save_run(earlier, tmp_path, "local")
    _, streamed = _streamed(lbr4p, tmp_path / "full.mcap", 0.3)
    data = streamed.log_file.read_bytes()
    cut = tmp_path / "local.mcap"
    cut.write_bytes(data[: len(data) - 200])
    stamp = (tmp_path / "local.json").stat().st_mtime_ns + 10**9
    os.utime(cut, ns=(stamp, stamp))
    for path in (tmp_path / "local", tmp_path / "local.json"):
        _, record = load_run(path)
        assert record["complete"] is False


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


def test_a_long_streamed_run_is_saved_without_npz(lbr4p, tmp_path, monkeypatch):
    """Past FULL_LOAD_SAMPLES the CLI keeps a decimated log: the .json then names the .mcap."""
    from dqcontrol.cli import run_output

    monkeypatch.setattr(run_output, "FULL_LOAD_SAMPLES", 20)
    _, streamed = _streamed(lbr4p, tmp_path / "long.mcap")
    shown = run_output.loaded_result(streamed)
    assert shown.log_stride > 1 and len(shown.log) <= 21
    (js,) = save_run(shown, tmp_path, "long")
    log, record = load_run(js)
    assert record["npz"] is None and record["log"] == "long.mcap" and record["complete"]
    assert len(log) == record["samples"] > 100

"""dqcontrol/runs/storage.py: atomic writes (permissions from the umask without touching it, a
crash mid-write leaves no file or the previous version), and saving and loading runs: a round
trip of every array and metric, names with a path refused, the stop flag, old ``.npz`` runs,
cut and decimated logs."""

from __future__ import annotations

import math
import os
import stat
import subprocess
import sys
import threading

import numpy as np
import pytest

from dqcontrol.controllers import LocalController
from dqcontrol.errors import ParameterError
from dqcontrol.experiments import table1 as t1
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs import storage
from dqcontrol.runs.storage import atomic_write_bytes, atomic_write_text, load_run, save_run
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle


def test_writes_replace_atomically_and_leave_no_temporary(tmp_path):
    target = tmp_path / "sub" / "run.json"
    atomic_write_text(target, "first")
    atomic_write_text(target, "second")
    assert target.read_text() == "second"
    assert sorted(p.name for p in target.parent.iterdir()) == ["run.json"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "run.json"
    atomic_write_text(target, "kept")

    def broken(*_args):
        raise OSError("disk full")

    monkeypatch.setattr(storage.os, "fsync", broken)
    with pytest.raises(OSError, match="disk full"):
        atomic_write_bytes(target, b"lost")
    assert target.read_text() == "kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.json"]


def test_the_process_umask_is_never_changed(tmp_path, monkeypatch):
    def forbidden(_mask):
        raise AssertionError("os.umask called: it changes the mask of every thread")

    monkeypatch.setattr(os, "umask", forbidden)
    for k in range(20):
        atomic_write_text(tmp_path / f"f{k}.txt", "x")


def test_permissions_follow_the_umask():
    """In a fresh process with umask 027 the file is 0640 (0666 less the mask), as a plain
    ``open`` would make it."""
    code = (
        "import os, stat, sys, tempfile\n"
        "from dqcontrol.runs.storage import atomic_write_text\n"
        "os.umask(0o027)\n"
        "d = tempfile.mkdtemp()\n"
        "p = atomic_write_text(os.path.join(d, 'x.json'), '{}')\n"
        "print(oct(stat.S_IMODE(os.stat(p).st_mode)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "0o640"


def test_threads_writing_at_once_all_get_the_normal_mode(tmp_path):
    mask = os.umask(0o022)  # the test's own, restored below (no other thread runs yet)
    try:
        errors = []

        def writer(k: int) -> None:
            try:
                for j in range(30):
                    atomic_write_text(tmp_path / f"t{k}_{j}.txt", "x")
            except Exception as exc:  # noqa: BLE001 - collected for the assertion
                errors.append(exc)

        threads = [threading.Thread(target=writer, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert not errors
        modes = {stat.S_IMODE(p.stat().st_mode) for p in tmp_path.iterdir()}
        assert modes == {0o644}
    finally:
        os.umask(mask)


def _streamed(lbr4p, path, duration_s=1.0, **kwargs):
    controller = LocalController(lbr4p, Circle(duration_s), 0.01)
    return controller, run_kinematic(controller, LBR4P_Q0, log_file=path, **kwargs)


def test_the_flag_survives_npz_and_json(stopped, tmp_path):
    _ctrl, result = stopped
    assert result.log.stopping.any() and not result.log.stopping.all()
    save_run(result, tmp_path, "stopped")
    log, record = load_run(tmp_path / "stopped")
    np.testing.assert_array_equal(log.stopping, result.log.stopping)
    assert record["metrics"]["stop_samples"] == int(result.log.stopping.sum())


def test_an_old_npz_run_still_loads(lbr4p, tmp_path):
    result = run_kinematic(LocalController(lbr4p, Circle(0.3), 0.05), LBR4P_Q0)
    npz, js = save_run(result, tmp_path, "old")
    for path in (npz, js, tmp_path / "old"):
        log, record = load_run(path)
        np.testing.assert_array_equal(log.q, result.log.q)
        assert "complete" not in record and record["meta"]["joint_names"]


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


_THESIS_BOUNDS = {
    "velocity_limits": np.array(t1.THESIS_VELOCITY_LIMITS),
    "acceleration_limit": 10.0,
}


@pytest.fixture(scope="module")
def short_run(lbr4p):
    """A finished kinematic run (circle, 1 s, local method, thesis bounds)."""
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05, **_THESIS_BOUNDS)
    return run_kinematic(ctrl, LBR4P_Q0, meta={"purpose": "test", "q0": LBR4P_Q0})


def test_save_and_load_round_trip(tmp_path, short_run):
    npz, js = save_run(short_run, tmp_path / "runs", "circle_local")
    assert npz.name == "circle_local.npz" and js.name == "circle_local.json"
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [js.name, npz.name]
    for path in (js, npz, tmp_path / "runs" / "circle_local"):
        log, record = load_run(path)
        for name, arr in short_run.log.arrays().items():
            got = getattr(log, name)
            assert got.dtype == arr.dtype and got.shape == arr.shape, name
            np.testing.assert_array_equal(got, arr, err_msg=name)
        assert log.meta["purpose"] == "test"
        assert log.meta["q0"] == pytest.approx(LBR4P_Q0.tolist())
        assert record["interrupted"] is False and record["note"] == ""
        metrics = short_run.metrics.as_dict()
        # NaN (no torque in the kinematic loop) is stored as null: strict JSON
        assert math.isnan(metrics["torque_peak_nm"]) and record["metrics"]["torque_peak_nm"] is None
        for key, value in metrics.items():
            if not (isinstance(value, float) and math.isnan(value)):
                assert record["metrics"][key] == value, key
    assert "NaN" not in js.read_text()


def test_save_run_rejects_path_in_name(tmp_path, short_run):
    with pytest.raises(ParameterError, match="separator"):
        save_run(short_run, tmp_path, "a/b")


@pytest.mark.parametrize("fail_at", ["write", "fsync", "replace", "interrupt"])
def test_crash_while_writing_leaves_no_file(tmp_path, short_run, monkeypatch, fail_at):
    """A failure in the middle of a write leaves no target file and no stray temp file."""

    def bad_fsync(fd):
        raise OSError(28, "No space left on device (simulated)")

    def bad_replace(src, dst):
        raise OSError(5, "I/O error (simulated)")

    class Boom(BaseException):  # like KeyboardInterrupt: not an Exception
        pass

    if fail_at == "write":
        real_fdopen = os.fdopen

        class HalfWriter:
            def __init__(self, fh):
                self.fh = fh

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.fh.close()

            def write(self, data):
                self.fh.write(data[: len(data) // 2])  # half the bytes reach the disk
                raise OSError(28, "No space left on device (simulated)")

            def __getattr__(self, name):
                return getattr(self.fh, name)

        monkeypatch.setattr(
            storage.os, "fdopen", lambda fd, mode: HalfWriter(real_fdopen(fd, mode))
        )
        expected = OSError
    elif fail_at == "fsync":
        monkeypatch.setattr(storage.os, "fsync", bad_fsync)
        expected = OSError
    elif fail_at == "replace":
        monkeypatch.setattr(storage.os, "replace", bad_replace)
        expected = OSError
    else:

        def interrupted_fsync(fd):
            raise Boom

        monkeypatch.setattr(storage.os, "fsync", interrupted_fsync)
        expected = Boom
    folder = tmp_path / "runs"
    with pytest.raises(expected):
        save_run(short_run, folder, "crash")
    assert list(folder.iterdir()) == []


def test_crash_keeps_the_previous_version(tmp_path, monkeypatch):
    target = tmp_path / "table.md"
    atomic_write_text(target, "version 1\n")

    def bad_replace(src, dst):
        raise OSError(5, "I/O error (simulated)")

    monkeypatch.setattr(storage.os, "replace", bad_replace)
    with pytest.raises(OSError):
        atomic_write_text(target, "version 2, longer\n")
    assert target.read_text() == "version 1\n"
    assert [p.name for p in tmp_path.iterdir()] == ["table.md"]

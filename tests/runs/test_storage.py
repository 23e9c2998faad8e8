"""Atomic writes of run results: permissions from the umask without touching it."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading

import pytest

from dqcontrol.runs import storage
from dqcontrol.runs.storage import atomic_write_bytes, atomic_write_text


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

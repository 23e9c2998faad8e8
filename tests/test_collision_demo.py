"""The collision demo (``demos/collision.py --short``, as CI runs it) in its own process."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_collision_demo_runs(tmp_path):
    cmd = [sys.executable, str(ROOT / "demos" / "collision.py"), "--short", "--out", str(tmp_path)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    for scene in ("ball_on_path", "ball_at_elbow"):
        line = re.search(rf"{scene}: min distance ([\d.]+) mm .* contacts (\d+)", proc.stdout)
        assert line is not None, proc.stdout
        assert float(line.group(1)) >= 19.5 and line.group(2) == "0"
        assert (tmp_path / f"{scene}_replay.html").is_file()

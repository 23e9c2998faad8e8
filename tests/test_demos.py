"""The demos (``demos/*.py --short``, as CI runs them) and the code of the user guide
(``docs/user_guide.md``) and of the README's tour, each in its own Python process, all
started at once. No wall-time assertions (shared, noisy machines): a hang is caught by a
generous timeout."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DEMOS = ("circle", "sinusoid", "compare_controllers", "custom_robot_panda")
#: A demo that has not finished after this long [s] is stuck.
HANG_TIMEOUT_S = 240.0


def markdown_code(path: Path) -> str:
    """The ``python`` code blocks of a markdown page, in order, as one script."""
    text = path.read_text(encoding="utf-8")
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    assert blocks, f"{path.name} has no python code blocks"
    return "\n".join(blocks)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """Start every demo and the user guide's code together; wait for all of them."""
    base = tmp_path_factory.mktemp("demos")
    jobs = {}
    for name in DEMOS:
        out = base / name
        cmd = [sys.executable, str(ROOT / "demos" / f"{name}.py"), "--short", "--out", str(out)]
        jobs[name] = (cmd, base, out)
    guide = base / "user_guide.py"
    guide.write_text(markdown_code(ROOT / "docs" / "user_guide.md"), encoding="utf-8")
    guide_dir = base / "guide"
    guide_dir.mkdir()
    jobs["user_guide"] = ([sys.executable, str(guide)], guide_dir, guide_dir)
    readme = base / "readme_tour.py"
    readme.write_text(markdown_code(ROOT / "README.md"), encoding="utf-8")
    jobs["readme"] = ([sys.executable, str(readme)], ROOT, None)
    procs = {}
    for name, (cmd, cwd, out) in jobs.items():
        procs[name] = (
            subprocess.Popen(
                cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
            ),
            time.perf_counter(),
            out,
        )
    results = {}
    for name, (proc, start, out) in procs.items():
        try:
            stdout, stderr = proc.communicate(timeout=HANG_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, stderr = proc.communicate()
        results[name] = (proc.returncode, time.perf_counter() - start, stdout, stderr, out)
    return results


@pytest.mark.parametrize("name", DEMOS)
def test_demo_runs_headless_in_short_mode(finished, name):
    code, wall, stdout, stderr, out = finished[name]
    assert code == 0, f"{name} failed:\n{stdout}\n{stderr[-3000:]}"
    assert "completed=True" in stdout or "yes" in stdout
    written = [p for p in out.iterdir() if p.suffix in (".png", ".html")]
    assert written, f"{name} wrote nothing to {out}"
    for path in written:
        assert path.stat().st_size > 3000, path


@pytest.mark.parametrize("name", DEMOS)
def test_demo_is_a_script_with_short_and_viewer_options(name):
    source = (ROOT / "demos" / f"{name}.py").read_text(encoding="utf-8")
    assert 'if __name__ == "__main__":' in source
    assert '"--short"' in source and '"--viewer"' in source


def test_user_guide_code_runs(finished):
    code, wall, stdout, stderr, out = finished["user_guide"]
    assert code == 0, f"the user guide's code failed:\n{stdout}\n{stderr[-3000:]}"
    assert list(out.rglob("*.png")) and list(out.rglob("*.html"))


def test_readme_tour_runs(finished):
    code, wall, stdout, stderr, out = finished["readme"]
    assert code == 0, f"the README's code failed:\n{stdout}\n{stderr[-3000:]}"
    assert "(8, 7)" in stdout and "e_mean" in stdout

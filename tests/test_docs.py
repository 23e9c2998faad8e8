"""The documentation stays true: every file the README and the docs link to exists, the
README opens with its two commands, and the README's and the getting-started page's code
runs. (The site and its API reference are built by ``mkdocs build --strict`` in CI, which
fails on a broken link or anchor; ``tests/test_demos.py`` runs the user guide's code.)"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _local_links(page: Path) -> list[Path]:
    """Files a page points to: markdown links and images (relative to the page) and
    backticked repository paths (relative to the repository's root)."""
    text = page.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)\)", text)
    out = [page.parent / link for link in links if not re.match(r"[a-z]+://", link)]
    named = re.findall(r"`((?:docs|robots|demos|benchmarks|tests|dqcontrol)/[\w./-]+\.\w+)`", text)
    return out + [ROOT / path for path in named]


def test_every_linked_file_exists():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    missing = [
        f"{page.relative_to(ROOT)} → {target.relative_to(ROOT)}"
        for page in pages
        for target in _local_links(page)
        if not target.exists()
    ]
    assert not missing, "broken links:\n" + "\n".join(missing)


def test_readme_opens_with_the_two_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```bash\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    assert blocks[0].strip() == (
        "python3 -m venv .venv && .venv/bin/pip install -e '.[sim,viz]' && .venv/bin/dqcontrol run"
    )
    test_command = (
        "python3 -m venv .venv && .venv/bin/pip install -e '.[dev]' && .venv/bin/python -m pytest"
    )
    assert blocks[1].strip() == test_command
    assert test_command in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def _run_python_blocks(page: Path, folder: Path) -> str:
    """The page's Python blocks, in order, in a fresh process from ``folder``; its output."""
    text = page.read_text(encoding="utf-8")
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    assert blocks, f"{page.name} has no Python block"
    proc = subprocess.run(
        [sys.executable, "-c", "\n".join(blocks)],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def test_getting_started_code_runs(tmp_path):
    """The getting-started page's Python from an empty folder."""
    out = _run_python_blocks(ROOT / "docs" / "getting_started.md", tmp_path)
    assert "completed: True" in out


def test_readme_code_runs_from_an_empty_folder(tmp_path):
    """The README's Python example outside the checkout: the robot it loads comes from the
    installed package."""
    out = _run_python_blocks(ROOT / "README.md", tmp_path)
    assert out.strip().endswith("True 0")


def test_site_configuration_lists_every_page():
    """Every page of docs/ is in the site's navigation, and each API page documents its
    sub-package (``::: dqcontrol...``)."""
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    pages = sorted(p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md"))
    missing = [page for page in pages if f": {page}" not in config]
    assert not missing, f"not in mkdocs.yml's nav: {missing}"
    for page in (ROOT / "docs" / "reference").glob("*.md"):
        assert re.search(r"^::: dqcontrol", page.read_text(encoding="utf-8"), re.MULTILINE), page

"""The documentation stays true: the API page matches the code, and every file the README
and the docs link to exists."""

from __future__ import annotations

import re
import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_api_page_is_up_to_date():
    generator = runpy.run_path(str(ROOT / "docs" / "generate_api.py"))
    expected = generator["render"]()
    current = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    assert current == expected, "docs/api.md is stale: run `python docs/generate_api.py`"


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

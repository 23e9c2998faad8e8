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


def _local_links(page: Path) -> list[str]:
    text = page.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)\)", text)  # markdown links and images
    links += re.findall(r"`((?:docs|robots|demos|benchmarks)/[\w./-]+\.\w+)`", text)
    return [link for link in links if not re.match(r"[a-z]+://", link)]


def test_every_linked_file_exists():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    missing = []
    for page in pages:
        for link in _local_links(page):
            base = (
                ROOT
                if page.name == "README.md" or link.startswith(("docs/", "robots/"))
                else page.parent
            )
            if not (base / link).exists():
                missing.append(f"{page.relative_to(ROOT)} → {link}")
    assert not missing, "broken links:\n" + "\n".join(missing)


def test_readme_opens_with_the_two_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```bash\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    assert blocks[0].strip() == (
        "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/dqcontrol run"
    )
    test_command = (
        "python3 -m venv .venv && .venv/bin/pip install -e '.[dev]' && .venv/bin/python -m pytest"
    )
    assert blocks[1].strip() == test_command
    assert test_command in (ROOT / ".ci" / "run").read_text(encoding="utf-8")

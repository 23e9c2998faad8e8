"""The installed package stands on its own: its robot data is package data found through
``importlib.resources`` (never through the repository around it), the wheel's package-data
patterns cover that data, the repository's copies agree with it, and the version comes from
the package metadata. (CI also builds the wheel and runs it from a fresh environment: see
``.ci/run``.)"""

from __future__ import annotations

import fnmatch
import importlib.metadata
import importlib.resources
import runpy
import tomllib
import zipfile
from pathlib import Path

import pytest

import dqcontrol
from dqcontrol.cli import main
from dqcontrol.errors import URDFError
from dqcontrol.model import lbr4p_urdf_path, library

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_DIR = Path(dqcontrol.__file__).resolve().parent


@pytest.fixture
def fresh_cache():
    """Forget the paths resolved so far, before and after the test."""
    library._package_file.cache_clear()
    yield
    library._package_file.cache_clear()


def test_lbr4p_urdf_is_package_data():
    resource = importlib.resources.files("dqcontrol") / "robots" / "lbr4p" / "lbr4p.urdf"
    assert resource.is_file()
    path = lbr4p_urdf_path()
    assert isinstance(path, Path) and path.is_file()  # a real file: Pinocchio and MuJoCo open it
    assert path.resolve() == Path(str(resource)).resolve()
    assert path.resolve().is_relative_to(PACKAGE_DIR)
    assert path.read_bytes() == resource.read_bytes()


def test_package_data_patterns_cover_the_robot_files():
    """Every file under dqcontrol/robots/ matches a package-data pattern, so the wheel
    carries it (checked without building the wheel)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["package-data"]["dqcontrol"]
    files = [
        p.relative_to(PACKAGE_DIR).as_posix()
        for p in (PACKAGE_DIR / "robots").rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    ]
    assert "robots/lbr4p/lbr4p.urdf" in files
    missed = [f for f in files if not any(fnmatch.fnmatchcase(f, pat) for pat in patterns)]
    assert not missed, f"not shipped in the wheel: {missed}"


def test_repository_copies_match_the_package_data():
    """``robots/lbr4p/generate_urdf.py`` writes the package's URDF and the repository's copy;
    both are its current output, and the package's README is the repository's under a
    header comment."""
    generator = runpy.run_path(str(ROOT / "robots" / "lbr4p" / "generate_urdf.py"))
    expected = generator["build"]()
    package_urdf = PACKAGE_DIR / "robots" / "lbr4p" / "lbr4p.urdf"
    repo_urdf = ROOT / "robots" / "lbr4p" / "lbr4p.urdf"
    hint = "run `python robots/lbr4p/generate_urdf.py`"
    assert package_urdf.read_text(encoding="utf-8") == expected, hint
    assert repo_urdf.read_text(encoding="utf-8") == expected, hint
    package_readme = (PACKAGE_DIR / "robots" / "lbr4p" / "README.md").read_text(encoding="utf-8")
    repo_readme = (ROOT / "robots" / "lbr4p" / "README.md").read_text(encoding="utf-8")
    assert package_readme == generator["README_NOTE"] + repo_readme, hint


def test_urdf_is_extracted_when_the_package_is_not_a_folder(tmp_path, monkeypatch, fresh_cache):
    """From a zip import, ``importlib.resources`` gives no filesystem path; the file is
    extracted to a real temporary file."""
    archive = tmp_path / "dqcontrol.zip"
    urdf_bytes = lbr4p_urdf_path().read_bytes()
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("dqcontrol/robots/lbr4p/lbr4p.urdf", urdf_bytes)
    library._package_file.cache_clear()
    monkeypatch.setattr(
        importlib.resources, "files", lambda name: zipfile.Path(archive, f"{name}/")
    )
    path = lbr4p_urdf_path()
    assert isinstance(path, Path) and path.is_file()
    assert path.read_bytes() == urdf_bytes


def test_missing_package_data_is_a_urdf_error(tmp_path, monkeypatch, fresh_cache):
    monkeypatch.setattr(importlib.resources, "files", lambda name: tmp_path / name)
    with pytest.raises(URDFError, match="dqcontrol/robots/lbr4p/lbr4p.urdf is missing"):
        lbr4p_urdf_path()


def test_version_comes_from_the_metadata(capsys):
    version = importlib.metadata.version("dqcontrol")
    assert dqcontrol.__version__ == version
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out == f"dqcontrol {version}\n"


def test_installed_metadata_matches_pyproject():
    """The one definition of the version is pyproject.toml; an editable install whose
    metadata is older than it needs ``pip install -e .`` again."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert importlib.metadata.version("dqcontrol") == config["project"]["version"]

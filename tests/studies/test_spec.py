"""``dqcontrol.studies.spec``: a small study file parsed to its cases, the shipped studies and the
user guide's example, and keys a study's experiment does not take refused, naming the key."""

from __future__ import annotations

import fnmatch
import tomllib
from pathlib import Path

import pytest
from studies.small_study import SMALL, write_study

from dqcontrol.studies import (
    StudyFileError,
    load_study,
    parse_study,
    shipped_study_path,
    study_cases,
)

ROOT = Path(__file__).resolve().parents[2]


def test_small_study_parses_to_two_cases(tmp_path):
    study = load_study(write_study(tmp_path, SMALL))
    assert study.name == "small" and study.experiment == "tracking"
    assert study.simulator == "kinematic" and study.period_s == 0.05
    assert study.controllers == ("local", "p10")
    (circle,) = study.trajectories
    assert circle.name == "circle" and circle.durations_s == (1.0,)
    assert circle.metadata(1.0) == {"trajectory": "circle", "duration_s": 1.0, "radius_m": 0.05}
    assert dict(study.settings.shared) == {"acceleration_limit": 10.0}
    assert study.settings.extra("p10") == {"horizon_s": 0.5} and study.settings.extra("local") == {}
    assert [c.name for c in study_cases(study)] == ["circle_T1s_local", "circle_T1s_p10"]
    assert study.output.formats == ("md", "csv") and study.output.folder == "results"


def test_shipped_studies_are_package_data():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["package-data"]["dqcontrol"]
    for name in ("table1", "faults"):
        path = shipped_study_path(name)
        assert path.is_file()
        relative = path.relative_to(ROOT / "dqcontrol").as_posix()
        assert any(fnmatch.fnmatchcase(relative, p) for p in patterns), relative


def test_the_experiments_refuse_what_is_not_theirs(tmp_path):
    table1 = SMALL.replace('name = "small"', 'name = "t"\nexperiment = "table1"')
    with pytest.raises(StudyFileError, match="unknown key 'options' at the top level"):
        load_study(write_study(tmp_path, table1))
    faults = SMALL.replace('name = "small"', 'name = "f"\nexperiment = "faults"')
    faults = faults.split("[options]")[0] + '[faults]\nnames = ["nominal", "gremlins"]\n'
    with pytest.raises(StudyFileError, match=r"unknown key 'radius_m' in \[\[trajectories\]\] #1"):
        load_study(write_study(tmp_path, faults))  # the campaign's paths have no parameters
    faults = faults.replace("radius_m = 0.05\n", "")
    with pytest.raises(StudyFileError, match=r"\[faults\] names: unknown fault 'gremlins'"):
        load_study(write_study(tmp_path, faults))
    robot = SMALL + '[robot]\nurdf = "arm.urdf"\n'
    with pytest.raises(StudyFileError, match=r"\[robot\] tool_frame: missing"):
        load_study(write_study(tmp_path, robot))


def test_the_user_guide_s_example_study_parses():
    """The example of docs/user_guide.md is a valid study (its URDF replaced by the shipped
    LBR4p, which has the same 7 joints)."""
    import re

    text = (ROOT / "docs" / "user_guide.md").read_text(encoding="utf-8")
    (block,) = re.findall(r"^```toml\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    data = tomllib.loads(block)
    assert data["robot"]["tool_frame"] == "tool0"
    del data["robot"]
    study = parse_study(data, source="user_guide.md")
    cases = study_cases(study)
    assert len(cases) == 12 and {c.trajectory for c in cases} == {"circle", "turn"}
    assert study.settings.extra("pf") == {"horizon_s": 1.0}

"""The ``arms`` study: the shipped file, its errors, and a reduced grid in CI (two arms
besides the LBR4p, one short path each, the kinematic loop, every controller with its
defaults) meeting the goals of docs/arms.md."""

from __future__ import annotations

import copy
import tomllib

import pytest

from dqcontrol.studies import StudyFileError, load_study, parse_study, shipped_study_path
from dqcontrol.studies.arms_case import ArmsCase, run_arms_case
from dqcontrol.studies.arms_study import goal_misses, table_row


def _shipped() -> dict:
    return tomllib.loads(shipped_study_path("arms").read_text(encoding="utf-8"))


def _reduced(arm: str, task: str) -> dict:
    """The shipped study with one arm and one task, kinematic, T = 50 ms."""
    data = copy.deepcopy(_shipped())
    data["arms"]["robots"] = [r for r in data["arms"]["robots"] if r["name"] == arm]
    data["arms"]["tasks"] = [t for t in data["arms"]["tasks"] if t["name"] == task]
    data["arms"]["periods_s"] = [0.05]
    data["arms"]["simulators"] = ["kinematic"]
    return data


def test_the_shipped_study_covers_every_arm_controller_task_period_and_loop():
    study = load_study("arms")
    s = study.settings
    assert study.controllers == ("local", "p6", "p10", "noscale", "proportional", "pf")
    assert [t.start for t in s.tasks] == ["nominal", "nominal", "singular"]
    assert s.periods_s == (0.05, 0.01, 0.001)
    assert s.simulators == ("kinematic", "mujoco")
    assert {"lbr4p", "panda", "ur5", "xarm7", "z1"} <= {a.name for a in s.arms}
    from dqcontrol.studies import study_cases

    assert len(study_cases(study)) == len(s.arms) * 3 * 2 * 3 * 6


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["arms"]["tasks"][0].update(start="upright"), "start: expected one of"),
        (lambda d: d["arms"]["tasks"][0].update(trajectory="square"), "no \\[\\[trajectories"),
        (lambda d: d["arms"]["robots"][2].pop("ee_frame"), "ee_frame: missing"),
        (lambda d: d["arms"]["robots"][2].pop("singular_q0_rad"), "singular_q0_rad: missing"),
        (lambda d: d["arms"].update(simulators=["gazebo"]), "simulators: unknown"),
        (lambda d: d["arms"].update(colour="red"), "unknown key 'colour'"),
    ],
)
def test_a_wrong_arms_table_is_a_clear_error(edit, message):
    data = _shipped()
    edit(data)
    with pytest.raises(StudyFileError, match=message):
        parse_study(data, source="arms.toml")


@pytest.mark.parametrize(("arm", "task"), [("ur5", "circle"), ("xarm7", "turn")])
def test_the_reduced_study_meets_its_goals(arm, task):
    pytest.importorskip("toppra")
    study = parse_study(_reduced(arm, task), source="arms.toml")
    from dqcontrol.studies import study_cases

    cases = study_cases(study)
    assert len(cases) == 6 and all(isinstance(c, ArmsCase) for c in cases)
    for case in cases:
        result = run_arms_case(case, study)
        m = result["metrics"]
        assert goal_misses(result) == [], (case.name, table_row(result))
        assert m["position_violations"] == m["velocity_violations"] == 0
        assert result["bound_s"] > 0.0
        if case.controller == "pf":
            assert m["path_deviation_max_m"] <= 0.1e-3
            assert result["between_deviation_max_m"] >= m["path_deviation_max_m"]

"""``dqcontrol.studies.arms_case``: a reduced ``arms`` grid in CI (two arms, one short path each,
the kinematic loop, every controller with its defaults) meets the goals of docs/arms.md."""

from __future__ import annotations

import copy
import tomllib

import pytest

from dqcontrol.studies import parse_study, shipped_study_path
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


@pytest.mark.parametrize(("arm", "task"), [("ur5", "circle"), ("xarm7", "turn")])
def test_the_reduced_study_meets_its_goals(arm, task):
    pytest.importorskip("toppra")
    study = parse_study(_reduced(arm, task), source="arms.toml")
    from dqcontrol.studies import study_cases

    cases = study_cases(study)
    assert len(cases) == 6 and all(isinstance(c, ArmsCase) for c in cases)
    bounds = {}
    for case in cases:
        result = run_arms_case(case, study)
        bounds[case.controller] = result["bound_s"]
        m = result["metrics"]
        assert goal_misses(result) == [], (case.name, table_row(result))
        assert m["position_violations"] == m["velocity_violations"] == 0
        assert result["bound_s"] > 0.0
        if case.controller == "pf":
            assert m["path_deviation_max_m"] <= 0.1e-3
            assert result["between_deviation_max_m"] >= m["path_deviation_max_m"]
    # the path-following controller ends at rest, and so does its bound; the others' ends
    # are free
    assert bounds["pf"] > bounds["local"] == bounds["p10"]

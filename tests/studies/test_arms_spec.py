"""The ``arms`` part of a study file (``dqcontrol.studies.arms_spec``): the shipped file covers
every arm, controller, task, period and loop, and a wrong ``[arms]`` table is a clear error."""

from __future__ import annotations

import tomllib

import pytest

from dqcontrol.studies import StudyFileError, load_study, parse_study, shipped_study_path


def _shipped() -> dict:
    return tomllib.loads(shipped_study_path("arms").read_text(encoding="utf-8"))


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

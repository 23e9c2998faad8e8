"""The ``table1`` experiment of studies (``dqcontrol.studies.table1_study``): the shipped study
is the ``table1`` command's grid and settings, and its selections are the command's."""

from __future__ import annotations

import pytest

from dqcontrol.experiments import table1 as t1
from dqcontrol.studies import load_study, study_cases


def test_shipped_table1_study_is_the_table1_command():
    study = load_study("table1")
    assert study.settings == t1.Table1Settings()  # the thesis's settings, every field
    assert study_cases(study) == t1.table1_cases()  # 32 cases, same identities and order
    assert study.output.save_runs


@pytest.mark.parametrize(
    "selection",
    [
        {"quick": True},
        {"periods": [2.0], "controllers": ["local", "path-following"]},
        {"trajectories": ["sinusoid"], "controllers": ["p6"]},
        {},
    ],
)
def test_table1_command_selects_its_cases_from_the_shipped_study(selection):
    from dqcontrol.studies.table1_study import select_table1

    study = select_table1(load_study("table1"), simulator="kinematic", **selection)
    assert study_cases(study) == t1.table1_cases(**selection)
    assert study.settings == t1.Table1Settings(simulator="kinematic")
    faster = select_table1(load_study("table1"), period_s=0.001, **selection)
    assert study_cases(faster) == t1.table1_cases(**selection)
    assert faster.period_s == 0.001
    assert faster.settings == t1.Table1Settings(period_s=0.001)

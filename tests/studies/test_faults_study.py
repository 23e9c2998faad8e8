"""The ``faults`` experiment of studies (``dqcontrol.studies.faults_study``): the shipped study is
the fault campaign's case list in either simulator, and its selections are the command's."""

from __future__ import annotations

import tomllib

import pytest

from dqcontrol.faults import campaign
from dqcontrol.studies import load_study, parse_study, shipped_study_path, study_cases


def test_shipped_faults_study_is_the_fault_campaign():
    study = load_study("faults")
    cases = study_cases(study)
    assert cases == campaign.campaign_cases(simulator="mujoco")
    assert len(cases) == 228 and len({campaign_name(c) for c in cases}) == 228
    kinematic = parse_study(
        tomllib.loads(shipped_study_path("faults").read_text().replace('"mujoco"', '"kinematic"'))
    )
    assert study_cases(kinematic) == campaign.campaign_cases(simulator="kinematic")


def campaign_name(case) -> str:
    from dqcontrol.studies.kinds import experiment_kind

    return experiment_kind("faults").case_name(case)


@pytest.mark.parametrize(
    "selection",
    [
        {"quick": True},
        {"controllers": ["local", "proportional"], "faults": ["nominal", "solver_fails"]},
        {"trajectories": ["sinusoid"], "seed": 3},
        {},
    ],
)
@pytest.mark.parametrize("simulator", ["kinematic", "mujoco"])
def test_faults_command_selects_its_cases_from_the_shipped_study(selection, simulator):
    from dqcontrol.studies.faults_study import select_faults

    study = select_faults(load_study("faults"), simulator=simulator, **selection)
    assert study_cases(study) == campaign.campaign_cases(simulator=simulator, **selection)

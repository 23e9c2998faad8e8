"""``dqcontrol.faults.cases``: time limits, labels, the case list (order, defaults, what applies,
name errors) and the judged rows' ``safe`` and table fields, on hand-built cases."""

from __future__ import annotations

import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.faults.cases import CampaignResult, CaseResult, CaseSpec, campaign_cases
from dqcontrol.faults.scenarios import (
    CONTROLLERS,
    FAULTS,
    QUICK_CONTROLLERS,
    QUICK_FAULTS,
    TRAJECTORIES,
    Fault,
    fault_by_name,
)


def _spec(fault: str = "nominal", duration_s: float = 2.0) -> CaseSpec:
    return CaseSpec(
        CONTROLLERS["local"], TRAJECTORIES["circle"], fault_by_name(fault), "kinematic", duration_s
    )


def test_time_limit_and_label():
    assert _spec(duration_s=2.0).max_time_s == 3.0 * 2.0 + 2.0
    impossible = _spec("unreachable", duration_s=2.0)
    assert not impossible.fault.expect_completion and impossible.max_time_s == 2.0 + 3.0
    assert impossible.label == "unreachable/circle/local/kinematic"
    assert _spec().period_s == 0.05 and _spec().seed == 0


def test_cases_are_in_table_order_and_skip_what_does_not_apply():
    cases = campaign_cases(
        ["local", "proportional"], ["circle", "sinusoid"],
        ["nominal", "payload_3kg_torque_half", "qp_crossed"], "kinematic", seed=3,
    )  # fmt: skip
    # the payload needs MuJoCo, the solver fault a QP controller
    assert [(c.fault.name, c.trajectory.name, c.controller.name) for c in cases] == [
        ("nominal", "circle", "local"),
        ("nominal", "circle", "proportional"),
        ("nominal", "sinusoid", "local"),
        ("nominal", "sinusoid", "proportional"),
        ("qp_crossed", "circle", "local"),
        ("qp_crossed", "sinusoid", "local"),
    ]
    assert {c.seed for c in cases} == {3} and {c.simulator for c in cases} == {"kinematic"}
    assert [c.duration_s for c in cases[:3]] == [2.0, 2.0, 4.0]


def test_the_defaults_are_everything_or_the_quick_selection():
    quick = campaign_cases(simulator="kinematic", quick=True)
    assert {c.controller.name for c in quick} == set(QUICK_CONTROLLERS)
    assert {c.fault.name for c in quick} <= set(QUICK_FAULTS)
    assert {c.trajectory.name for c in quick} == {"circle"}
    assert {c.duration_s for c in quick} == {TRAJECTORIES["circle"].quick_duration_s}
    full = campaign_cases(simulator="mujoco")
    expected = sum(
        f.applies_to(c, "mujoco")
        for f in FAULTS
        for _ in TRAJECTORIES
        for c in CONTROLLERS.values()
    )
    assert len(full) == expected


def test_given_specs_are_taken_as_they_are():
    fault = Fault("custom", "task", "a fault of one's own", start="singular")
    (case,) = campaign_cases([CONTROLLERS["local"]], [TRAJECTORIES["circle"]], [fault], "kinematic")
    assert case.fault is fault and case.controller is CONTROLLERS["local"]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"controllers": ["pid"]}, "unknown controllers ['pid']; known: "),
        ({"trajectories": ["square"]}, "unknown trajectories ['square']; known: ['circle'"),
        ({"faults": ["gremlins"]}, "unknown fault 'gremlins'"),
        ({"simulator": "gazebo"}, "simulator must be one of ('mujoco', 'kinematic')"),
    ],
)
def test_unknown_names_are_refused_with_the_known_ones(kwargs, message):
    with pytest.raises(ParameterError) as info:
        campaign_cases(**({"simulator": "kinematic"} | kwargs))
    assert message in str(info.value)


def _row(**changes) -> CaseResult:
    fields = dict(
        fault="nominal", group="none", trajectory="circle", controller="local", qp=True,
        simulator="kinematic", status="completed", completed=True, sigma_reached_s=2.0,
        duration_s=2.0, time_s=2.5, s_mean=1.0, s_end=1.0, e_mean=0.0, path_dev_mean_m=0.0,
        path_dev_max_m=0.0, path_dev_end_m=0.0, speed_end_rad_s=0.0, velocity_violations=0,
        acceleration_violations=0, q_violations_true=0, q_excess_true_rad=0.0,
        q_violations_measured=0, q_excess_measured_rad=0.0, fallbacks=0, relaxed_steps=0,
        false_successes=0, nan_seen=False, sigma_monotone=True, s_in_range=True, raised="",
        note="", wall_time_s=0.0,
    )  # fmt: skip
    return CaseResult(**(fields | changes))


@pytest.mark.parametrize(
    "change",
    [
        {"raised": "RuntimeError"},
        {"nan_seen": True},
        {"velocity_violations": 1},
        {"acceleration_violations": 2},
        {"q_violations_true": 1},
        {"sigma_monotone": False},
        {"s_in_range": False},
    ],
    ids=lambda c: next(iter(c)),
)
def test_a_row_is_safe_unless_one_check_fails(change):
    assert _row().safe
    assert not _row(**change).safe


def test_measured_violations_and_fallbacks_do_not_make_a_row_unsafe():
    assert _row(q_violations_measured=4, fallbacks=3, status="stopped").safe


def test_the_table_fields_leave_the_arrays_out():
    row = _row(log=[1, 2], true_q=[3], path_dev=[4], anchored_trajectory=object()).row()
    assert not {"log", "true_q", "path_dev", "anchored_trajectory"} & set(row)
    assert row["safe"] is True and row["controller"] == "local" and len(row) == 34


def test_a_campaign_splits_its_rows_by_controller_kind():
    qp, prop = _row(), _row(controller="proportional", qp=False)
    result = CampaignResult([qp, prop], "kinematic", True, 2)
    assert result.qp_rows == [qp] and result.proportional_rows == [prop]
    assert not result.interrupted and result.note == ""

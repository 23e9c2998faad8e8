"""The judgement of the ``arms`` experiment (``dqcontrol.studies.arms_study``): the goals of
docs/arms.md a case misses, and its table row, from hand-made case records."""

from __future__ import annotations

import math

import pytest

from dqcontrol.studies.arms_study import (
    EXECUTION_RATIO,
    PF_DEVIATION_M,
    TORQUE_SATURATED,
    goal_misses,
    table_row,
)


def _result(controller: str = "pf", simulator: str = "kinematic", **changes) -> dict:
    """A completed case that meets every goal; ``changes`` to the record or (``m_`` prefix)
    to its metrics."""
    metrics = {
        "completed": True, "position_violations": 0, "velocity_violations": 0,
        "acceleration_violations": 0, "execution_time_s": 2.2, "path_deviation_max_m": 5e-5,
        "rotation_error_max_rad": 0.01, "fallbacks": 0,
    }  # fmt: skip
    result = {
        "case": {"arm": "ur5", "task": "circle", "simulator": simulator, "period_s": 0.05,
                 "controller": controller},
        "metrics": metrics, "interrupted": False, "note": "", "torque_ratio": 0.4,
        "torque_joint": 1, "bound_s": 2.0, "bound_note": "", "between_deviation_max_m": 6e-5,
        "contacts": None, "sigma_min": 0.2,
    }  # fmt: skip
    for key, value in changes.items():
        if key.startswith("m_"):
            metrics[key[2:]] = value
        else:
            result[key] = value
    return result


def test_a_case_meeting_every_goal():
    result = _result()
    assert goal_misses(result) == []
    row = table_row(result)
    assert row["goals"] == "ok" and row["done"] == "yes" and row["violations"] == "0/0/0"
    assert row["T_ms"] == 50.0 and row["arm"] == "ur5" and row["loop"] == "kinematic"
    assert row["dev_mm"] == pytest.approx(0.05) and row["between_mm"] == pytest.approx(0.06)
    assert row["rot_deg"] == pytest.approx(math.degrees(0.01))
    assert row["exec_bound"] == pytest.approx(1.1) and row["torque_ratio"] == 0.4


@pytest.mark.parametrize(
    ("changes", "miss"),
    [
        ({"m_completed": False}, "not completed (time limit)"),
        ({"interrupted": True, "note": "unstable"}, "not completed (unstable)"),
        (
            {"m_position_violations": 2, "m_velocity_violations": 1},
            "3 samples beyond a position/velocity bound",
        ),
        ({"torque_ratio": TORQUE_SATURATED}, "torque saturated"),
        ({"m_execution_time_s": 2.0 * EXECUTION_RATIO + 0.1}, "execution 1.35× the TOPP-RA bound"),
        ({"m_path_deviation_max_m": 2e-4}, "deviation 0.20 mm > 0.1 mm"),
        ({"m_path_deviation_max_m": math.nan}, "deviation nan mm > 0.1 mm"),
        ({"m_path_deviation_max_m": None}, "deviation nan mm > 0.1 mm"),  # NaN read from JSON
    ],
)
def test_each_goal_missed_is_named(changes, miss):
    misses = goal_misses(_result(**changes))
    assert len(misses) == 1 and misses[0].startswith(miss)


def test_the_deviation_goal_is_the_path_following_controller_s_and_the_loop_s():
    assert goal_misses(_result("p10", m_path_deviation_max_m=0.05)) == []
    limit = PF_DEVIATION_M["mujoco"]
    assert goal_misses(_result(simulator="mujoco", m_path_deviation_max_m=0.9 * limit)) == []
    # an unfinished case is judged on completion, not on its execution time or its path
    assert goal_misses(_result(m_completed=False, m_execution_time_s=99.0)) == [
        "not completed (time limit)"
    ]


def test_a_missed_goal_lists_its_measured_causes():
    result = _result(
        m_completed=False, torque_ratio=1.0, torque_joint=3, sigma_min=0.01,
        contacts={"samples": 4, "pairs": ["link_2/link_5"], "deepest_m": 0.0031},
        bound_note="toppra failed (limits too tight); choose another path",
    )  # fmt: skip
    row = table_row(result)
    assert row["done"] == "NO"
    assert row["goals"] == (
        "not completed (time limit); torque saturated; cause: contact link_2/link_5 at 4 "
        "samples, 3.1 mm deep; cause: joint 4 at its effort limit; cause: σ_min 0.010 on the "
        "way; cause: toppra failed"
    )


def test_missing_numbers_are_empty_cells():
    row = table_row(_result(bound_s=None, between_deviation_max_m=None, torque_ratio=None))
    assert row["exec_bound"] is None and row["between_mm"] is None and row["torque_ratio"] is None

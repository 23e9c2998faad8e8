"""The ``tracking`` experiment of studies (``dqcontrol.studies.tracking``): a robot named by its
URDF and tool frame runs a case with the shipped robot's figures."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest
from studies.small_study import SMALL, write_study

from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0, lbr4p_urdf_path
from dqcontrol.studies import StudyFileError, load_study, study_cases, tracking


def test_a_urdf_and_tool_frame_give_the_shipped_robot_s_figures(tmp_path):
    """The LBR4p named by its URDF path and flange frame is the shipped LBR4p: the same
    waypoint case (positions and orientations) gives the same figures."""
    waypoints = """\
        [[trajectories]]
        name = "turn"
        kind = "waypoints"
        positions_m = [[0.0, 0.0, 0.0], [0.03, 0.02, 0.0], [0.05, 0.0, 0.02]]
        orientations = [[1.0, 0.0, 0.0, 0.0], [0.9962, 0.0872, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]
        """
    base = SMALL.split("[[trajectories]]")[0].replace('["local", "p10"]', '["local"]')
    base += textwrap.dedent(waypoints)
    shipped = load_study(write_study(tmp_path, base, "shipped.toml"))
    q0 = ", ".join(repr(float(v)) for v in tracking.start_configuration(shipped.robot))
    urdf = f'[robot]\nurdf = "{lbr4p_urdf_path()}"\ntool_frame = "lbr4p_flange"\nq0_rad = [{q0}]\n'
    named = load_study(write_study(tmp_path, base + urdf, "urdf.toml"))
    assert named.robot.urdf == str(lbr4p_urdf_path().resolve())
    (case,) = study_cases(named)
    a = tracking.run_tracking_case(case, shipped)["metrics"]
    b = tracking.run_tracking_case(case, named)["metrics"]
    assert a["completed"] and a["samples"] > 10
    for key in a.keys() - {"solve_time_median_s", "step_time_median_s"}:
        assert a[key] == b[key] or (math.isnan(a[key]) and math.isnan(b[key])), key
    bad = base + urdf.replace("lbr4p_flange", "flange")
    with pytest.raises(StudyFileError, match="unknown end-effector frame 'flange'"):
        load_study(write_study(tmp_path, bad, "bad.toml"))


def test_the_robot_and_its_start():
    from dqcontrol.studies.spec import RobotSpec

    shipped = RobotSpec()
    assert tracking.load_robot(shipped).ee_frame == "lbr4p_flange"
    q0 = tracking.start_configuration(shipped)
    np.testing.assert_array_equal(q0, LBR4P_Q0)
    assert q0 is not LBR4P_Q0  # a copy the caller may change
    named = RobotSpec(str(lbr4p_urdf_path()), "lbr4p_link_6", (0.1,) * 7)
    robot = tracking.load_robot(named)
    assert robot.ee_frame == "lbr4p_link_6" and tracking.load_robot(named) is robot  # cached
    np.testing.assert_array_equal(tracking.start_configuration(named), np.full(7, 0.1))
    with pytest.raises(ParameterError, match="\\[robot\\] tool_frame: required with urdf"):
        tracking.load_robot(RobotSpec(str(lbr4p_urdf_path())))


def test_a_table_row_in_the_table_s_units():
    metrics = {
        "e_mean": 1e-3, "u_mean_rad_s": 0.2, "s_mean": 0.9, "path_deviation_mean_m": 1e-4,
        "path_deviation_max_m": 3e-4, "translation_error_mean_m": 2e-3,
        "rotation_error_mean_rad": math.pi / 180, "execution_time_s": 2.1,
        "execution_ratio": 1.05, "torque_peak_nm": math.nan, "position_violations": 0,
        "velocity_violations": 1, "acceleration_violations": 0, "fallbacks": 2,
        "relaxed_steps": 0, "completed": True,
    }  # fmt: skip
    result = {
        "case": {"trajectory": "circle", "duration_s": 2.0, "controller": "p10"},
        "metrics": metrics, "interrupted": False,
    }  # fmt: skip
    row = tracking.table_row(result)
    assert [k for k, _, _ in tracking.COLUMNS] == list(row)
    assert row["controller"] == "p=10" and row["completed"] == "yes"
    assert row["path_dev_max_mm"] == pytest.approx(0.3) and row["trans_err_mean_mm"] == 2.0
    assert row["rot_err_mean_deg"] == pytest.approx(1.0) and row["viol_velocity"] == 1
    assert tracking.table_row(result | {"interrupted": True})["completed"] == "NO"

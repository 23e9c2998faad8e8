"""The fault campaign's singular start (q = 0, the LBR4p stretched straight up) for the
path-following controller.

The campaign's circle and sinusoid are anchored at the start pose, so both leave the tool
at the top of the arm's reach and move it sideways at that height: almost every point of
either path lies farther from the shoulder than the stretched arm reaches. No motion keeps
the tool on those paths; the promise (slow down, never deform) leaves σ = 0 with the arm
at rest on the path as the only answer, and the controller gives it. The thesis's
controllers advance there only by leaving the path (docs/faults.md).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dqcontrol.dq import translation
from dqcontrol.faults.campaign import run_case
from dqcontrol.faults.cases import campaign_cases
from dqcontrol.model import load_lbr4p


def _shoulder_and_reach(robot, q: np.ndarray) -> tuple[np.ndarray, float]:
    """The shoulder (the second joint's origin, on the first joint's axis) and the tool's
    distance from it at ``q``: the reach, when the arm is stretched (the LBR4p's links
    carry no lateral offsets, so no configuration puts the tool farther)."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    shoulder = data.oMi[2].translation.copy()
    return shoulder, float(np.linalg.norm(robot.placement(q).translation - shoulder))


@pytest.fixture(scope="module")
def cases():
    specs = campaign_cases(
        controllers=["path_following"],
        trajectories=["circle", "sinusoid"],
        faults=["singular_start"],
        simulator="kinematic",
    )
    return {spec.trajectory.name: run_case(spec, keep_log=True) for spec in specs}


def test_no_configuration_reaches_farther_than_the_stretched_arm():
    robot = load_lbr4p()
    shoulder, reach = _shoulder_and_reach(robot, np.zeros(robot.nq))
    rng = np.random.default_rng(7)
    lim = robot.limits
    for q in rng.uniform(lim.q_min, lim.q_max, size=(3000, robot.nq)):
        moved, _ = _shoulder_and_reach(robot, q)
        assert np.allclose(moved, shoulder)  # on the first joint's axis: it stays
        assert np.linalg.norm(robot.placement(q).translation - shoulder) <= reach + 1e-12


@pytest.mark.parametrize(("name", "beyond_min"), [("circle", 0.95), ("sinusoid", 0.5)])
def test_the_paths_from_the_stretched_arm_leave_its_reach(cases, name, beyond_min):
    robot = load_lbr4p()
    shoulder, reach = _shoulder_and_reach(robot, np.zeros(robot.nq))
    trajectory = cases[name].anchored_trajectory
    sigmas = np.linspace(0.0, trajectory.duration, 401)
    points = np.array([translation(trajectory.target(s)) for s in sigmas])
    distance = np.linalg.norm(points - shoulder, axis=1)
    assert distance[0] == pytest.approx(reach, abs=1e-9)  # the start: the top of the reach
    assert np.mean(distance > reach + 1e-6) >= beyond_min
    assert distance.max() > reach + 0.02  # 23 mm (circle) to 158 mm (sinusoid) beyond


@pytest.mark.parametrize("name", ["circle", "sinusoid"])
def test_the_controller_holds_the_arm_at_rest_on_the_path(cases, name):
    row = cases[name]
    assert row.safe and row.sigma_monotone and row.raised == ""
    assert row.sigma_reached_s < 1e-9 and row.status == "stopped"
    assert row.path_dev_max_m < 1e-6 and row.speed_end_rad_s < 1e-6

"""``dqcontrol.trajectories.functional.FunctionTrajectory``: the finite-difference derivative
against the helix's analytic one, across sign flips, and only inside the interval."""

from __future__ import annotations

import numpy as np
import pytest
from trajectories.trajectory_cases import _HELIX_T, REF, helix_derivative, helix_pose

from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import FunctionTrajectory


def test_function_trajectory_finite_difference_matches_analytic() -> None:
    traj = FunctionTrajectory(helix_pose, None, _HELIX_T)
    for sigma in (0.0, 1e-7, 0.4, 1.7, _HELIX_T - 1e-7, _HELIX_T):
        np.testing.assert_allclose(
            traj.local_derivative(sigma), helix_derivative(sigma), rtol=0, atol=1e-9
        )


def test_function_trajectory_finite_difference_survives_sign_flips() -> None:
    def flipping(sigma: float) -> np.ndarray:  # -x on a grid of sigmas: the same poses
        return helix_pose(sigma) * (-1.0 if int(sigma * 1e6) % 2 else 1.0)

    traj = FunctionTrajectory(flipping, None, _HELIX_T)
    for sigma in (0.3, 1.1, 2.9):
        x = traj.local_pose(sigma)
        sign = np.sign(np.dot(x, helix_pose(sigma)))
        np.testing.assert_allclose(
            traj.local_derivative(sigma), sign * helix_derivative(sigma), atol=1e-9
        )


def test_function_trajectory_calls_pose_fn_only_inside_the_interval() -> None:
    seen: list[float] = []

    def pose(sigma: float) -> np.ndarray:
        seen.append(sigma)
        return helix_pose(sigma)

    traj = FunctionTrajectory(pose, None, _HELIX_T, REF)
    traj.targets(np.array([-1.0, 0.0, 1.0, _HELIX_T, 10.0]))
    assert min(seen) >= 0.0 and max(seen) <= _HELIX_T


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: FunctionTrajectory(lambda s: np.ones(8), None, 1.0), "pose_fn\\(0\\)"),
        (lambda: FunctionTrajectory(lambda s: np.ones(4), None, 1.0), "shape"),
        (lambda: FunctionTrajectory("pose", None, 1.0), "callable"),
        (lambda: FunctionTrajectory(helix_pose, lambda s: np.zeros(3), 1.0), "shape"),
    ],
)
def test_bad_input_raises_parameter_error(build, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        build()

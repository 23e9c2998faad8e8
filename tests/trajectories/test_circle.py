"""``dqcontrol.trajectories.circle.Circle``: its geometry in the reference frame and when
anchored at a tool pose, against hand computations."""

from __future__ import annotations

import numpy as np
import pytest
from trajectories.trajectory_cases import REF, random_pose

from dqcontrol.dq import qto_matrix, translation
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import Circle


def test_circle_geometry() -> None:
    R = 0.1
    circle = Circle(4.0, R, reference=REF)
    local = translation(circle.local_poses(np.linspace(0, 4.0, 101))[0])
    np.testing.assert_allclose(local[0], [R, 0.0, 0.0], atol=1e-17)
    np.testing.assert_allclose(np.linalg.norm(local[:, :2], axis=1), R, rtol=1e-15)
    np.testing.assert_array_equal(local[:, 2], 0.0)
    np.testing.assert_allclose(local[-1], local[0], atol=1e-16)  # one full turn
    # World: every point at R from the centre (the reference origin), in the plane ⟂ its z.
    world = circle.path_positions(500)
    centre = translation(REF)
    normal = qto_matrix(REF[:4])[:, 2]
    np.testing.assert_allclose(np.linalg.norm(world - centre, axis=1), R, rtol=1e-14)
    np.testing.assert_allclose((world - centre) @ normal, 0.0, atol=1e-15)
    # Identity rotation relative to ref.
    np.testing.assert_allclose(circle.target(1.3)[:4], REF[:4], atol=1e-15)


def test_anchored_circle_lies_in_the_start_tool_xy_plane() -> None:
    x0 = random_pose(np.random.default_rng(2))
    circle = Circle(3.0, 0.1).anchored_at(x0)
    rot = qto_matrix(x0[:4])
    centre = translation(x0) - 0.1 * rot[:, 0]
    world = circle.path_positions(300)
    np.testing.assert_allclose(np.linalg.norm(world - centre, axis=1), 0.1, rtol=1e-13)
    np.testing.assert_allclose((world - centre) @ rot[:, 2], 0.0, atol=1e-15)
    for sigma in (0.0, 1.0, 2.5):  # tool orientation held at the start orientation
        np.testing.assert_allclose(circle.target(sigma)[:4], x0[:4], atol=1e-15)


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: Circle(1.0, radius_m=0.0), "radius_m"),
    ],
)
def test_bad_input_raises_parameter_error(build, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        build()

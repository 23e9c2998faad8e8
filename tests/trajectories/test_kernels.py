"""The compiled loops of ``dqcontrol.trajectories._kernels`` against the numpy expressions they
replace: ``min``/``max`` with NaN, and the circle's local poses and derivatives."""

from __future__ import annotations

import numpy as np

from dqcontrol.trajectories._kernels import circle_rows_into, value_range


def test_value_range_is_numpys_min_and_max():
    rng = np.random.default_rng(41)
    for size in (1, 2, 7, 100):
        values = rng.normal(size=size)
        assert value_range(values) == (values.min(), values.max())


def test_value_range_of_an_array_with_a_nan_is_nan():
    values = np.array([0.5, -1.0, np.nan, 3.0])
    low, high = value_range(values)
    assert np.isnan(low) and np.isnan(high)
    assert np.isnan(value_range(np.array([np.nan]))[0])


def test_circle_rows_are_the_numpy_rows():
    rng = np.random.default_rng(42)
    angles = rng.uniform(-10.0, 10.0, 25)
    cos, sin = np.cos(angles), np.sin(angles)
    half_r, half_r_omega = 0.05, 0.05 * 2.0 * np.pi / 3.0
    poses = np.full((25, 8), 7.0)  # every entry must be written
    derivatives = np.full((25, 8), 7.0)
    circle_rows_into(cos, sin, half_r, half_r_omega, poses, derivatives)
    expected_poses = np.zeros((25, 8))
    expected_poses[:, 0] = 1.0
    expected_poses[:, 5] = half_r * cos
    expected_poses[:, 6] = half_r * sin
    expected_derivatives = np.zeros((25, 8))
    expected_derivatives[:, 5] = -half_r_omega * sin
    expected_derivatives[:, 6] = half_r_omega * cos
    np.testing.assert_array_equal(poses, expected_poses)
    np.testing.assert_array_equal(derivatives, expected_derivatives)

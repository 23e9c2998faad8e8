"""``dqcontrol.trajectories.sinusoid.Sinusoid``: its four periods along x, against the
formula of the path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.dq import translation
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import Sinusoid


def test_sinusoid_spans_four_periods() -> None:
    T = 5.0
    sinus = Sinusoid(T, amplitude_m=0.1, omega_x_rad_per_m=60.0)
    t = translation(sinus.local_poses(np.linspace(0.0, T, 40001))[0])
    np.testing.assert_allclose(t[0], 0.0, atol=1e-17)
    np.testing.assert_allclose(t[-1], [2 * math.pi / 15, 0.0, 0.0], atol=1e-15)
    assert np.all(np.diff(t[:, 0]) > 0)
    np.testing.assert_array_equal(t[:, 1], 0.0)
    z = t[:, 2]
    maxima = np.flatnonzero((z[1:-1] > z[:-2]) & (z[1:-1] > z[2:]))
    assert maxima.size == 4
    np.testing.assert_allclose(z[maxima + 1], 0.1, rtol=1e-6)
    np.testing.assert_allclose(np.diff(t[maxima + 1, 0]), 2 * math.pi / 15 / 4, rtol=1e-3)


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: Sinusoid(1.0, amplitude_m=-0.1), "amplitude_m"),
        (lambda: Sinusoid(1.0, omega_x_rad_per_m=float("inf")), "omega_x_rad_per_m"),
    ],
)
def test_bad_input_raises_parameter_error(build, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        build()

"""The input checks of ``dqcontrol.trajectories._checks``: the values they accept, returned as
the code uses them, and the ParameterError naming the parameter for each kind of bad value."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.dq import dq_from_rt, qfrom_axis_angle
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories._checks import UNIT_TOL, positive, unit_dq


@pytest.mark.parametrize("value", [2, 0.5, "3.25", np.float32(1.5)], ids=repr)
def test_positive_returns_a_float(value):
    result = positive("duration_s", value, "s")
    assert type(result) is float and result == float(value)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("fast", "duration_s must be a number [s], got 'fast'"),
        (None, "duration_s must be a number [s], got None"),
        (0.0, "duration_s must be finite and > 0 [s], got 0.0"),
        (-1, "duration_s must be finite and > 0 [s], got -1"),
        (math.nan, "duration_s must be finite and > 0 [s], got nan"),
        (math.inf, "duration_s must be finite and > 0 [s], got inf"),
    ],
    ids=repr,
)
def test_positive_refuses_with_name_and_unit(value, message):
    with pytest.raises(ParameterError) as info:
        positive("duration_s", value, "s")
    assert str(info.value) == message


def test_unit_dq_returns_the_value_as_given():
    x = dq_from_rt(qfrom_axis_angle([1.0, 2.0, 3.0], 0.7), [0.1, -0.2, 0.3])
    slightly_off = x * (1.0 + 0.5 * UNIT_TOL)  # within the tolerance: kept, not renormalised
    result = unit_dq("reference", list(slightly_off))
    assert result.dtype == np.float64 and result.shape == (8,)
    np.testing.assert_array_equal(result, slightly_off)


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ("pose", "reference must be a unit dual quaternion vec8 of shape (8,), got 'pose'"),
        (np.ones(7), "got shape (7,)"),
        (np.eye(4), "got shape (4, 4)"),
        ([1.0, 0, 0, 0, 0, 0, 0, math.nan], "reference must be finite"),
        ([2.0, 0, 0, 0, 0, 0, 0, 0], "|r| = 2.0"),
        ([1.0, 0, 0, 0, 0.1, 0, 0, 0], "r·d = 0.1"),
    ],
    ids=["text", "vec7", "matrix", "nan", "not unit", "dual not orthogonal"],
)
def test_unit_dq_refuses_with_name_and_evidence(value, fragment):
    with pytest.raises(ParameterError) as info:
        unit_dq("reference", value)
    assert fragment in str(info.value)

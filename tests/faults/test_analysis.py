"""The safeguard switches of ``dqcontrol.faults.analysis`` on controller instances, against the
options the constructors take, and the Markdown of the mitigation table from hand-made rows."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import LocalController, PathFollowingController, ProportionalController
from dqcontrol.errors import ParameterError
from dqcontrol.faults.analysis import compensate_delay, position_margin, render_mitigations
from dqcontrol.trajectories import Circle


def test_compensating_a_delay_is_the_constructor_s_option(lbr4p):
    switched = compensate_delay(LocalController(lbr4p, Circle(1.0), 0.05), 2)
    built = LocalController(lbr4p, Circle(1.0), 0.05, measurement_delay_periods=2)
    assert switched.measurement_delay_periods == built.measurement_delay_periods == 2
    assert switched._sent.maxlen == built._sent.maxlen
    assert compensate_delay(switched, 0).measurement_delay_periods == 0
    with pytest.raises(ParameterError, match="delay_periods must be ≥ 0, got -1"):
        compensate_delay(switched, -1)


@pytest.mark.parametrize("cls", [LocalController, ProportionalController])
def test_a_position_margin_is_the_constructor_s_option(lbr4p, cls):
    switched = position_margin(cls(lbr4p, Circle(1.0), 0.05), 0.02)
    built = cls(lbr4p, Circle(1.0), 0.05, position_margin_rad=0.02)
    assert switched.position_margin_rad == built.position_margin_rad == 0.02
    np.testing.assert_allclose(switched.q_min, built.q_min, rtol=0, atol=1e-15)
    np.testing.assert_allclose(switched.q_max, built.q_max, rtol=0, atol=1e-15)
    off = position_margin(switched, 0.0)
    np.testing.assert_array_equal(off.q_max, lbr4p.limits.q_max)


def test_a_position_margin_needs_joint_position_bounds_of_the_controller_s_own(lbr4p):
    with pytest.raises(ParameterError, match="got PathFollowingController"):
        position_margin(PathFollowingController(lbr4p, Circle(1.0), 0.05), 0.01)


def test_the_mitigation_table_in_markdown():
    rows = [
        {"case": "near_limits/circle", "variant": "no margin", "status": "completed",
         "sigma": 2.0, "dev_max_mm": 1.234, "q_viol": 3, "q_excess_mrad": 0.456,
         "fallbacks": 0, "speed_end": 0.0},
        {"case": "unreachable/circle/local", "variant": "default", "status": "stopped",
         "sigma": 0.41, "dev_max_mm": 7.0, "q_viol": 0, "q_excess_mrad": 0.0,
         "fallbacks": 2, "speed_end": 0.012},
    ]  # fmt: skip
    lines = render_mitigations(rows).splitlines()
    assert lines[0].startswith("| case | variant | status | σ reached [s] |")
    assert lines[1] == "|---|---|---|---|---|---|---|---|"
    assert (
        lines[2]
        == "| near_limits/circle | no margin | completed | 2.00 | 1.2 | 3 [0.46] | 0 | 0.00 |"
    )
    assert (
        lines[3] == "| unreachable/circle/local | default | stopped | 0.41 | 7.0 | 0 | 2 | 0.01 |"
    )
    assert render_mitigations([]).count("\n") == 2

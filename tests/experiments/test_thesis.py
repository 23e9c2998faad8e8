"""``dqcontrol.experiments.thesis``: the thesis's numbers, against the thesis's values and
against what Table 1, the fault campaign, the CLI and the registry's controllers use."""

from __future__ import annotations

import numpy as np

from dqcontrol.experiments import table1 as t1
from dqcontrol.experiments import thesis
from dqcontrol.registry import build_controller
from dqcontrol.trajectories import Circle


def test_the_thesis_numbers_are_shared(lbr4p):
    from dqcontrol.cli import build_parser
    from dqcontrol.faults.campaign import PERIOD_S

    settings = t1.Table1Settings()
    assert settings.velocity_limits == thesis.THESIS_VELOCITY_LIMITS
    assert settings.acceleration_limit == thesis.THESIS_ACCELERATION_LIMIT == 10.0
    assert settings.period_s == thesis.THESIS_PERIOD_S == PERIOD_S == 0.05
    assert settings.horizon_s == thesis.THESIS_HORIZON_S == 1.0
    np.testing.assert_array_equal(settings.start_configuration(), thesis.THESIS_Q0)
    np.testing.assert_allclose(
        thesis.THESIS_VELOCITY_LIMITS, np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5]), rtol=0
    )
    args = build_parser().parse_args(["run"])
    assert args.period == thesis.THESIS_PERIOD_S and args.horizon == thesis.THESIS_HORIZON_S
    assert args.controllers == ("local", "p10", "pf")
    # without --acceleration-limit each controller keeps its own bound: the thesis's for the
    # thesis's controllers, the dynamics-aware one for path following
    assert args.acceleration_limit is None
    for name in ("local", "p10", "noscale"):
        a_max = build_controller(name, lbr4p, Circle(2.0), thesis.THESIS_PERIOD_S).a_const
        np.testing.assert_array_equal(a_max, thesis.THESIS_ACCELERATION_LIMIT)
    assert build_controller("pf", lbr4p, Circle(2.0), 0.05).dynamic_acceleration


def test_thesis_bounds_are_fresh_keyword_arguments():
    first, second = thesis.thesis_bounds(), thesis.thesis_bounds()
    assert set(first) == {"velocity_limits", "acceleration_limit"}
    np.testing.assert_array_equal(first["velocity_limits"], thesis.THESIS_VELOCITY_LIMITS)
    assert first["acceleration_limit"] == thesis.THESIS_ACCELERATION_LIMIT
    first["velocity_limits"][:] = 0.0  # a caller may change its copy
    np.testing.assert_array_equal(second["velocity_limits"], thesis.THESIS_VELOCITY_LIMITS)
    np.testing.assert_array_equal(
        thesis.thesis_bounds()["velocity_limits"], second["velocity_limits"]
    )

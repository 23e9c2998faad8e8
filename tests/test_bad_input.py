"""Bad parameters of the controllers and the control loops, across every controller class:
each raises the documented dqcontrol error with a message that names the parameter."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
    TrackingController,
)
from dqcontrol.errors import ConfigurationError, ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_kinematic, run_mujoco
from dqcontrol.trajectories import Circle

# tests/controllers/thesis/test_controller.py covers: gain, weights, 'fast'/negative
# acceleration_limit, velocity_limits = 0, phase_prediction, p = 1, tau_p = 0; tests/controllers/
# test_base.py a negative period and q of the wrong shape / NaN in step();
# tests/sim/test_mujoco_sim.py the simulation's options.
CONTROLLER_CLASSES = {
    "local": LocalController,
    "predictive": PredictiveController,
    "noscale": PredictiveNoScalingController,
    "proportional": ProportionalController,
}


_PERIODS = (0.0, -0.05, math.nan, math.inf, "50 ms", None)


_BAD_PERIODS = [
    pytest.param(cls, period, id=f"{cls}-{period!r}")
    for cls in CONTROLLER_CLASSES
    for period in _PERIODS
]


@pytest.mark.parametrize(("cls", "period"), _BAD_PERIODS)
def test_bad_period_of_every_controller(lbr4p, cls, period):
    with pytest.raises(ParameterError, match=r"period_s \(T\) must be") as info:
        CONTROLLER_CLASSES[cls](lbr4p, Circle(1.0), period)
    assert "[s]" in str(info.value)


@pytest.mark.parametrize("p", [0, -3, 1.5, True, "6"], ids=repr)
def test_bad_number_of_instants(lbr4p, p):
    with pytest.raises(ParameterError, match="p must be an integer ≥ 2"):
        PredictiveController(lbr4p, Circle(1.0), 0.05, num_instants=p)


@pytest.mark.parametrize("tau", [-1.0, math.nan, -math.inf], ids=repr)
def test_bad_horizon(lbr4p, tau):
    with pytest.raises(ParameterError, match="tau_p must be > 0"):
        PredictiveController(lbr4p, Circle(1.0), 0.05, horizon_s=tau)


@pytest.mark.parametrize(
    "instants", [[0.1, 0.5], [0.0, 0.5, 0.5], [0.0, 0.5, 0.2], [], [[0.0, 0.1]]], ids=repr
)
def test_bad_prediction_instants(lbr4p, instants):
    with pytest.raises(ParameterError, match="instants_s must start at 0 and increase"):
        TrackingController(lbr4p, Circle(1.0), 0.05, instants_s=instants)


@pytest.mark.parametrize("cls", list(CONTROLLER_CLASSES), ids=str)
@pytest.mark.parametrize("name", ["velocity_limits", "acceleration_limit"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -1.0], ids=repr)
def test_non_finite_or_negative_limits(lbr4p, cls, name, value):
    with pytest.raises(ParameterError, match=name) as info:
        CONTROLLER_CLASSES[cls](lbr4p, Circle(1.0), 0.05, **{name: value})
    assert "> 0" in str(info.value)


@pytest.mark.parametrize("cls", list(CONTROLLER_CLASSES), ids=str)
@pytest.mark.parametrize("name", ["velocity_limits", "acceleration_limit"])
def test_limits_of_the_wrong_shape(lbr4p, cls, name):
    with pytest.raises(ParameterError, match=f"{name}.*shape"):
        CONTROLLER_CLASSES[cls](lbr4p, Circle(1.0), 0.05, **{name: np.ones(3)})


@pytest.mark.parametrize("cls", list(CONTROLLER_CLASSES), ids=str)
@pytest.mark.parametrize("margin", [-1e-3, math.nan, 3.5, "1 mrad"], ids=repr)
def test_bad_position_margin(lbr4p, cls, margin):
    with pytest.raises(ParameterError, match=r"position_margin_rad must be"):
        CONTROLLER_CLASSES[cls](lbr4p, Circle(1.0), 0.05, position_margin_rad=margin)


@pytest.mark.parametrize("cls", list(CONTROLLER_CLASSES), ids=str)
@pytest.mark.parametrize("delay", [-1, 1.5, True, "2"], ids=repr)
def test_bad_measurement_delay(lbr4p, cls, delay):
    with pytest.raises(ParameterError, match=r"measurement_delay_periods must be an integer ≥ 0"):
        CONTROLLER_CLASSES[cls](lbr4p, Circle(1.0), 0.05, measurement_delay_periods=delay)


def test_unknown_daqp_setting_is_refused_at_construction(lbr4p):
    pytest.importorskip("daqp")
    with pytest.raises(ParameterError, match="iter_limitz"):
        LocalController(
            lbr4p, Circle(1.0), 0.05, solver="daqp", solver_settings={"iter_limitz": 10}
        )


def test_unknown_solver_setting_is_refused_at_construction(lbr4p):
    with pytest.raises(ParameterError, match="max_iterz"):
        LocalController(lbr4p, Circle(1.0), 0.05, solver_settings={"max_iterz": 10})


def test_bad_reset_arguments(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), 0.05)
    with pytest.raises(ConfigurationError, match=re.escape("qd0 must have shape (7,)")):
        ctrl.reset(LBR4P_Q0, qd0=np.zeros(3))
    with pytest.raises(ConfigurationError, match="q0 must be finite"):
        ctrl.reset(np.full(7, np.inf))
    with pytest.raises(ParameterError, match=r"sigma0 must be finite and ≥ 0 \[s\]"):
        ctrl.reset(LBR4P_Q0, sigma0=-1.0)


@pytest.mark.parametrize("run", [run_kinematic, run_mujoco], ids=["kinematic", "mujoco"])
@pytest.mark.parametrize("limit", [0.0, -1.0, math.nan], ids=repr)
def test_bad_time_limit_of_the_loops(lbr4p, run, limit):
    with pytest.raises(ParameterError, match=r"max_time_s must be finite and > 0 \[s\]"):
        run(LocalController(lbr4p, Circle(1.0), 0.05), LBR4P_Q0, max_time_s=limit)


def test_period_not_a_multiple_of_the_physics_step(lbr4p):
    with pytest.raises(ParameterError, match="not a whole number of physics steps"):
        run_mujoco(LocalController(lbr4p, Circle(1.0), 0.0015), LBR4P_Q0, max_time_s=0.1)

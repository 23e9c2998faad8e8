"""``dqcontrol.faults.scenarios``: the campaign's controllers, tasks, faults (options and where they
apply) and start configurations, against the registry and hand computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.experiments.thesis import THESIS_Q0
from dqcontrol.faults.scenarios import (
    CONTROLLERS,
    FAULTS,
    NEAR_LIMIT_MARGIN_RAD,
    QUICK_CONTROLLERS,
    QUICK_FAULTS,
    TRAJECTORIES,
    Fault,
    TrajectorySpec,
    fault_by_name,
    near_limit_configuration,
)
from dqcontrol.registry import controller_spec
from dqcontrol.studies import load_study
from dqcontrol.trajectories import Circle, Sinusoid

PF = "path_following"


def test_path_following_is_a_campaign_controller():
    assert CONTROLLERS[PF].qp and CONTROLLERS[PF].num_instants == 10
    assert PF in QUICK_CONTROLLERS
    assert PF in load_study("faults").controllers


def test_the_controllers_are_the_registrys_under_their_own_names():
    for name, spec in CONTROLLERS.items():
        reg = controller_spec(name)
        assert spec.name == name and (spec.cls, spec.kwargs) == (reg.cls, reg.kwargs)
    assert set(QUICK_CONTROLLERS) <= set(CONTROLLERS)


def test_the_tasks_and_their_unreachable_variants():
    circle, sinusoid = TRAJECTORIES["circle"], TRAJECTORIES["sinusoid"]
    assert circle.metadata(2.0) == {"trajectory": "circle", "duration_s": 2.0, "radius_m": 0.1}
    assert circle.metadata(3.0, unreachable=True)["radius_m"] == 0.4
    assert sinusoid.metadata(4.0) == {"trajectory": "sinusoid", "duration_s": 4.0}
    far = sinusoid.metadata(4.0, unreachable=True)
    assert (far["amplitude_m"], far["omega_x_rad_per_m"]) == (0.6, 15.0)
    built = circle.build(1.5, unreachable=True)
    assert isinstance(built, Circle) and built.duration == 1.5 and built.radius_m == 0.4
    assert isinstance(sinusoid.build(4.0), Sinusoid) and sinusoid.build(4.0).reference is None
    with pytest.raises(ParameterError, match="unknown trajectory 'square'"):
        TrajectorySpec("square", 1.0, 1.0).metadata(1.0)


def test_fault_names_are_unique_and_found_by_name():
    names = [f.name for f in FAULTS]
    assert len(names) == len(set(names)) and set(QUICK_FAULTS) <= set(names)
    for fault in FAULTS:
        assert fault_by_name(fault.name) is fault
        assert fault.group in ("none", "measurement", "model", "task", "solver")
    with pytest.raises(ParameterError, match="unknown fault 'gremlins'; known: \\['nominal'"):
        fault_by_name("gremlins")


def test_a_compensated_fault_tells_the_controller_of_its_sensors():
    fault = Fault("x", "measurement", "", q_noise_rad=4e-3, delay_periods=2)
    assert fault.measurement and not fault.mujoco_only and not fault.qp_only
    assert fault.controller_options() == {
        "measurement_delay_periods": 2,
        "position_margin_rad": pytest.approx(0.012),  # 3σ, above the 5 mrad default
    }
    assert Fault("y", "measurement", "", q_noise_rad=1e-3).controller_options() == {
        "position_margin_rad": 5e-3
    }
    assert (
        Fault("z", "measurement", "", delay_periods=2, compensated=False).controller_options() == {}
    )
    assert Fault("n", "none", "").controller_options() == {}


def test_which_faults_apply_to_which_case():
    payload = Fault("p", "model", "", payload_kg=3.0)
    crossed = Fault("c", "solver", "", contradiction="crossed")
    coupled = Fault("u", "solver", "", contradiction="coupled")
    local, p6, prop = (
        CONTROLLERS["local"],
        CONTROLLERS["predictive_p6"],
        CONTROLLERS["proportional"],
    )
    assert payload.mujoco_only and payload.applies_to(local, "mujoco")
    assert not payload.applies_to(local, "kinematic")
    assert Fault("t", "model", "", effort_scale=0.5).mujoco_only
    assert crossed.qp_only and crossed.applies_to(local, "kinematic")
    assert not crossed.applies_to(prop, "kinematic")
    assert coupled.applies_to(p6, "kinematic") and not coupled.applies_to(local, "kinematic")


def test_start_configurations(lbr4p):
    np.testing.assert_array_equal(Fault("d", "none", "").start_configuration(lbr4p), THESIS_Q0)
    assert Fault("d", "none", "").start_configuration(lbr4p) is not THESIS_Q0  # a copy
    np.testing.assert_array_equal(
        Fault("s", "task", "", start="singular").start_configuration(lbr4p), np.zeros(7)
    )
    near = Fault("l", "task", "", start="near_limits").start_configuration(lbr4p)
    np.testing.assert_array_equal(near, near_limit_configuration(lbr4p))
    with pytest.raises(
        ParameterError, match="start must be 'default', 'singular' or 'near_limits'"
    ):
        Fault("b", "task", "", start="folded").start_configuration(lbr4p)


def test_near_limit_configuration_is_inside_on_the_side_of_the_thesis_start(lbr4p):
    q = near_limit_configuration(lbr4p)
    # the values of its docstring, 0.8° inside the ±170° / ±120° limits
    np.testing.assert_allclose(
        q, [-2.953, -2.080, -2.953, -2.080, 2.953, -2.080, 2.953], rtol=0, atol=5e-4
    )
    lim = lbr4p.limits
    gap = np.where(THESIS_Q0 > 0, lim.q_max - q, q - lim.q_min)
    np.testing.assert_allclose(gap, NEAR_LIMIT_MARGIN_RAD, rtol=0, atol=1e-15)
    assert NEAR_LIMIT_MARGIN_RAD == math.radians(0.8)
    np.testing.assert_allclose(
        near_limit_configuration(lbr4p, margin_rad=0.1) - q,
        np.where(THESIS_Q0 > 0, -1, 1) * (0.1 - NEAR_LIMIT_MARGIN_RAD),
        atol=1e-15,
    )

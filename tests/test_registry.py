"""The controller registry (``dqcontrol.registry``): every name and alias builds its controller
with its options, and Table 1 and the fault campaign build theirs from it."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
)
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.errors import ParameterError
from dqcontrol.experiments import table1 as t1
from dqcontrol.experiments import thesis
from dqcontrol.faults import scenarios
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.registry import (
    KNOWN_NAMES,
    ControllerSpec,
    build_controller,
    controller_spec,
)
from dqcontrol.trajectories import (
    Circle,
)

#: name → (canonical name, class, p, table label)
NAMES = {
    "local": ("local", LocalController, 1, "Local"),
    "p6": ("p6", PredictiveController, 6, "p=6"),
    "p10": ("p10", PredictiveController, 10, "p=10"),
    "p3": ("p3", PredictiveController, 3, "p=3"),
    "noscale": ("noscale", PredictiveNoScalingController, 10, "no scaling, p=10"),
    "noscale6": ("noscale6", PredictiveNoScalingController, 6, "no scaling, p=6"),
    "proportional": ("proportional", ProportionalController, 1, "proportional"),
    "pf": ("pf", PathFollowingController, 10, "path-following"),
    "pf6": ("pf6", PathFollowingController, 6, "path-following p=6"),
    "pf20": ("pf20", PathFollowingController, 20, "path-following p=20"),
}
#: alias → canonical name
ALIASES = {
    "path-following": "pf",
    "path_following": "pf",
    "pf10": "pf",
    "PF": "pf",
    " Local ": "local",
    "predictive_p6": "p6",
    "predictive_p10": "p10",
    "predictive_noscale_p6": "noscale6",
    "noscale10": "noscale",
    "predictive_noscale_p10": "noscale",
}


@pytest.mark.parametrize("name", list(NAMES))
def test_every_name_builds_its_controller(lbr4p, name):
    canonical, cls, p, label = NAMES[name]
    spec = controller_spec(name)
    assert spec.name == canonical and spec.cls is cls and spec.table_label == label
    assert spec.num_instants == p and spec.description
    assert spec.qp == (cls is not ProportionalController)
    ctrl = build_controller(
        name, lbr4p, Circle(1.0), 0.05, shared={**thesis.thesis_bounds(), "horizon_s": 1.0}
    )
    assert type(ctrl) is cls
    np.testing.assert_array_equal(ctrl.qd_max, thesis.THESIS_VELOCITY_LIMITS)
    count = getattr(ctrl, "num_instants", getattr(ctrl, "num_intervals", 1))
    assert count == p
    ctrl.reset(LBR4P_Q0)
    assert np.all(np.isfinite(ctrl.step(LBR4P_Q0).qd_command))


@pytest.mark.parametrize(("alias", "canonical"), list(ALIASES.items()))
def test_aliases(alias, canonical):
    assert controller_spec(alias).name == canonical


def test_known_names_resolve():
    for name in KNOWN_NAMES:
        controller_spec(name.replace("N", "4"))


@pytest.mark.parametrize("name", ["mpc", "p1", "pf1", "noscale1", "", "p", "local2", 10])
def test_unknown_name_lists_the_known_ones(name):
    with pytest.raises(ParameterError) as info:
        controller_spec(name)
    message = str(info.value)
    assert message.startswith(f"unknown controller {str(name).strip()!r}")
    for known in ("local", "p10", "pN", "noscale", "proportional", "pf", "path-following"):
        assert known in message, known


def test_shared_options_go_where_they_are_taken(lbr4p):
    shared = {"velocity_limits": 2.0, "acceleration_limit": 7.0, "gain_per_s": 4.0,
              "horizon_s": 0.5, "solver": None}  # fmt: skip
    local = controller_spec("local").options(shared)
    assert local == {"velocity_limits": 2.0, "acceleration_limit": 7.0, "gain_per_s": 4.0}
    pf = controller_spec("pf").options(shared)
    assert pf == {"velocity_limits": 2.0, "acceleration_limit": 7.0, "horizon_s": 0.5}
    ctrl = build_controller("pf", lbr4p, Circle(1.0), 0.05, shared=shared, num_intervals=4)
    assert ctrl.num_intervals == 4 and ctrl.horizon_s == 0.5
    np.testing.assert_array_equal(ctrl.a_const, 7.0)
    assert build_controller("p10", lbr4p, Circle(1.0), 0.05, shared=shared).gain_per_s == 4.0


def test_every_tool_builds_from_the_registry():
    # Table 1: its controllers and labels are the registry's
    for name in t1.CONTROLLERS:
        assert t1.Table1Case("circle", 1.0, name).label == controller_spec(name).table_label
    assert t1.Table1Case("circle", 1.0, "path-following").controller == "pf"
    # the fault campaign: registry specs under the campaign's names
    for name, spec in scenarios.CONTROLLERS.items():
        assert isinstance(spec, ControllerSpec) and spec.name == name
        reg = controller_spec(name)
        assert (spec.cls, spec.kwargs, spec.qp) == (reg.cls, reg.kwargs, reg.qp)
    assert scenarios.ControllerSpec is ControllerSpec

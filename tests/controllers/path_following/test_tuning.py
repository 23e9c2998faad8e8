"""The path-following controller's tuning (dqcontrol/controllers/path_following/tuning.py):
its checks name the setting, the intervals' growth against the second interval it must
give, and the acceleration reserve by how often the loop re-plans, also as the controller's
coupling rows take it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dqcontrol.controllers import PathFollowingController
from dqcontrol.controllers.path_following.tuning import (
    GROWTH_PARABOLIC,
    RESERVE_REPLANNED_OFTEN,
    RESERVE_REPLANNED_ONCE,
    PathFollowingTuning,
)
from dqcontrol.errors import ParameterError
from dqcontrol.experiments.thesis import THESIS_VELOCITY_LIMITS
from dqcontrol.trajectories import Circle


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"path_tolerance": 0.0}, "path_tolerance"),
        ({"progress_tolerance": -1.0}, "progress_tolerance"),
        ({"max_linearisations": 0}, "max_linearisations"),
        ({"acceleration_reserve": 1.5}, "acceleration_reserve"),
        ({"trust_radius_rad": float("nan")}, "trust_radius_rad"),
        ({"interval_growth": 0.5}, "interval_growth"),
        ({"interval_growth": "cubic"}, "interval_growth"),
    ],
)
def test_bad_tuning_names_itself(kwargs, name):
    with pytest.raises(ParameterError, match=name):
        PathFollowingTuning(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"rest_deceleration_share": 1.5}, "rest_deceleration_share"),
        ({"max_linearisations": True}, "max_linearisations"),
        ({"max_linearisations": 2.5}, "max_linearisations"),
        ({"acceleration_reserve": 0.0}, "acceleration_reserve"),
        ({"interval_growth": True}, "interval_growth"),
        ({"interval_growth": float("inf")}, "interval_growth"),
        ({"damping": "small"}, "damping must be a number"),
    ],
)
def test_more_bad_settings_name_themselves(kwargs, name):
    with pytest.raises(ParameterError, match=name):
        PathFollowingTuning(**kwargs)


def test_a_negative_position_slack_is_refused():
    with pytest.raises(ParameterError, match="position_slack_rad"):
        PathFollowingTuning(position_slack_rad=-1e-3)


def test_settings_are_kept_as_numbers_and_frozen():
    tuning = PathFollowingTuning(max_linearisations=3.0, damping=2, acceleration_reserve=1)
    assert type(tuning.max_linearisations) is int and tuning.max_linearisations == 3
    assert type(tuning.damping) is float and type(tuning.acceleration_reserve) is float
    with pytest.raises(dataclasses.FrozenInstanceError):
        tuning.damping = 1.0  # type: ignore[misc]


def test_the_growth_gives_a_second_interval_no_longer_than_the_turn():
    tuning = PathFollowingTuning()
    horizon, period, p = 1.0, 1e-3, 10
    # no jerk bound, too few intervals, or a turn longer than the horizon: parabolic
    assert tuning.growth_for(horizon, period, p, None) == GROWTH_PARABOLIC
    assert tuning.growth_for(horizon, period, 2, 1e-3) == GROWTH_PARABOLIC
    assert tuning.growth_for(horizon, period, p, 2.0) == GROWTH_PARABOLIC
    # a turn the parabolic second interval (12.3 ms) already fits: parabolic
    assert tuning.growth_for(horizon, period, p, 0.02) == GROWTH_PARABOLIC
    for turn_s in (4e-3, 1e-3, 1e-4):
        growth = tuning.growth_for(horizon, period, p, turn_s)
        assert growth > GROWTH_PARABOLIC
        second = (horizon - period) / (p - 1.0) ** growth  # b_2 - b_1
        assert second == pytest.approx(turn_s, rel=1e-12)
    given = PathFollowingTuning(interval_growth=3)
    assert given.growth_for(horizon, period, p, 1e-4) == 3.0


def test_the_reserve_follows_the_second_interval_against_the_period():
    tuning = PathFollowingTuning()
    assert tuning.reserve_for(0.01, 0.0122) == RESERVE_REPLANNED_ONCE
    assert tuning.reserve_for(0.01, 0.02) == RESERVE_REPLANNED_OFTEN  # re-planned twice
    assert tuning.reserve_for(0.001, 0.0123) == RESERVE_REPLANNED_OFTEN
    assert PathFollowingTuning(acceleration_reserve=0.7).reserve_for(0.001, 0.0123) == 0.7


def _controller(robot, period_s: float, trajectory=None, **kwargs) -> PathFollowingController:
    return PathFollowingController(
        robot, Circle(2.0) if trajectory is None else trajectory, period_s,
        velocity_limits=THESIS_VELOCITY_LIMITS, acceleration_limit=5.0, **kwargs,
    )  # fmt: skip


def test_the_default_reserve_follows_how_often_the_loop_replans_the_second_interval(lbr4p):
    given = PathFollowingTuning(acceleration_reserve=0.8)
    for period_s, tuning, reserve in (
        (0.05, None, RESERVE_REPLANNED_ONCE),
        (0.01, None, RESERVE_REPLANNED_ONCE),  # the second interval is 12.2 ms
        (0.005, None, RESERVE_REPLANNED_OFTEN),
        (0.001, None, RESERVE_REPLANNED_OFTEN),
        (0.001, given, 0.8),
        (0.05, given, 0.8),
    ):
        ctrl = _controller(lbr4p, period_s, tuning=tuning)
        coupling = ctrl.layout.durations_s[1:] + ctrl.layout.durations_s[:-1]
        limit = next(lim for lim in ctrl.limits if lim.name == "acceleration")
        np.testing.assert_allclose(limit.coupling_s, 0.5 * coupling * reserve, rtol=1e-15)

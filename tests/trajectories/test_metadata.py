"""``dqcontrol.trajectories.metadata``: trajectories rebuilt from their own metadata give the same
targets; metadata that describes no trajectory is an error naming what is wrong."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.trajectories import (
    Circle,
    FunctionTrajectory,
    Sinusoid,
    WaypointTrajectory,
    trajectory_from_metadata,
)

_C, _S = np.cos(0.4), np.sin(0.4)


@pytest.mark.parametrize(
    "trajectory",
    [
        Circle(2.0),
        Circle(1.5, radius_m=0.4),
        Sinusoid(4.0, amplitude_m=0.6, omega_x_rad_per_m=15.0),
        WaypointTrajectory([[0, 0, 0], [0.1, 0.05, 0], [0, 0.1, 0.05]], duration_s=2.0),
        WaypointTrajectory(
            [[0, 0, 0], [0.1, 0, 0]], orientations=[[1, 0, 0, 0], [_C, _S, 0, 0]], times_s=[0, 1.5]
        ),
    ],
    ids=["circle", "circle_r04", "sinusoid", "waypoints", "waypoints_turning"],
)
def test_trajectories_describe_themselves(lbr4p, trajectory):
    sigmas = np.linspace(0.0, trajectory.duration, 11)
    for traj in (trajectory, trajectory.anchored_at(lbr4p.pose(LBR4P_Q0))):
        meta = json.loads(json.dumps(traj.to_metadata()))  # plain JSON values
        again = trajectory_from_metadata({**meta, "label": "p10", "q0": [0.0] * 7})
        assert type(again) is type(traj) and again.duration == traj.duration
        if traj.reference is None:
            assert "reference" not in meta and again.reference is None
            traj, again = (t.anchored_at(lbr4p.pose(LBR4P_Q0)) for t in (traj, again))
        for a, b in zip(traj.targets(sigmas), again.targets(sigmas), strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)


def test_metadata_errors():
    code = FunctionTrajectory(lambda s: np.array([1.0, 0, 0, 0, 0, 0, 0, 0]), None, 1.0)
    with pytest.raises(ParameterError, match="FunctionTrajectory cannot describe itself"):
        code.to_metadata()
    with pytest.raises(ParameterError, match=r"known: \['circle', 'sinusoid', 'waypoints'\]"):
        trajectory_from_metadata({"trajectory": "square", "duration_s": 1.0})
    with pytest.raises(ParameterError, match="no duration_s"):
        trajectory_from_metadata({"trajectory": "circle"})
    with pytest.raises(ParameterError, match="radius_m"):
        trajectory_from_metadata({"trajectory": "circle", "duration_s": 1.0, "radius_m": -1})

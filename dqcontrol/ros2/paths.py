"""A ``nav_msgs/Path`` as a task: the waypoints' poses in the robot's base frame, their
stamps as the nominal timing, a C² spline through them
(:class:`~dqcontrol.trajectories.WaypointTrajectory`)."""

from __future__ import annotations

import numpy as np

from dqcontrol.dq.algebra import qconj, qmul, rotation, translation
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import WaypointTrajectory

__all__ = ["START_ANGLE_TOLERANCE_RAD", "trajectory_from_poses"]

#: Largest angle [rad] between the path's first orientation and the end effector's.
START_ANGLE_TOLERANCE_RAD = 0.05

_IDENTITY = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])


def trajectory_from_poses(
    positions_m: np.ndarray,
    quaternions_wxyz: np.ndarray,
    stamps_s: np.ndarray,
    start_pose: np.ndarray,
    start_tolerance_m: float,
) -> WaypointTrajectory:
    """The trajectory through the poses of a path, which must start where the robot is.

    Args:
        positions_m: ``(N, 3)`` waypoint positions [m] in the robot's base frame.
        quaternions_wxyz: ``(N, 4)`` orientations, ``[w, x, y, z]`` (normalised).
        stamps_s: ``(N,)`` stamps [s]; the time from the first is the nominal timing.
        start_pose: the end effector's pose now (vec8, base frame).
        start_tolerance_m: largest distance [m] from the end effector to the first position
            (the angle's is :data:`START_ANGLE_TOLERANCE_RAD`).

    Returns:
        The trajectory, in the base frame (reference: the identity).

    Raises:
        ParameterError: fewer than two poses, stamps not strictly increasing, a bad
            quaternion, or a first pose away from the end effector (the message says how
            far).
    """
    stamps = np.asarray(stamps_s, dtype=float)
    if stamps.shape[0] < 2:
        raise ParameterError(f"a path needs at least 2 poses, got {stamps.shape[0]}")
    times = stamps - stamps[0]
    if not (np.isfinite(times).all() and (np.diff(times) > 0.0).all()):
        raise ParameterError(
            "the poses' header stamps must be strictly increasing (they are the nominal "
            f"timing); got times {np.round(times, 6).tolist()} s from the first"
        )
    positions = np.asarray(positions_m, dtype=float)
    gap_m = float(np.linalg.norm(positions[0] - translation(start_pose)))
    if gap_m > start_tolerance_m:
        raise ParameterError(
            f"the path starts {gap_m * 1e3:.1f} mm from the end effector (at most "
            f"{start_tolerance_m * 1e3:.1f} mm): its first pose must be where the robot is"
        )
    quats = np.asarray(quaternions_wxyz, dtype=float)
    norm = np.linalg.norm(quats[0])
    if norm > 0.0:
        rel = qmul(qconj(rotation(start_pose)), quats[0] / norm)
        angle = 2.0 * float(np.arctan2(np.linalg.norm(rel[1:]), abs(rel[0])))
        if angle > START_ANGLE_TOLERANCE_RAD:
            raise ParameterError(
                f"the path's first orientation is {angle:.3f} rad from the end effector's "
                f"(at most {START_ANGLE_TOLERANCE_RAD} rad)"
            )
    return WaypointTrajectory(positions, quats, times_s=times, reference=_IDENTITY.copy())

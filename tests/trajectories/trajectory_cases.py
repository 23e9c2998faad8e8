"""Shared cases of the trajectory tests: seeded random poses, one anchored trajectory of each
kind (``FACTORIES``) and a helix given as plain functions with its analytic derivative."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import settings

from dqcontrol.dq import dq_from_rt, qconj, qfrom_axis_angle, qmul
from dqcontrol.trajectories import Circle, FunctionTrajectory, Sinusoid, WaypointTrajectory

SETTINGS = settings(derandomize=True, deadline=None, max_examples=30)


def random_pose(rng: np.random.Generator, scale_m: float = 0.5) -> np.ndarray:
    q = rng.normal(size=4)
    return dq_from_rt(q / np.linalg.norm(q), rng.normal(size=3) * scale_m)


def random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


REF = random_pose(np.random.default_rng(7))


# A helix with a rotation about a tilted axis, as plain functions (for FunctionTrajectory).
_HELIX_T = 3.0


_HELIX_AXIS = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])


_HELIX_RATE = 0.9  # [rad/s]


def helix_pose(sigma: float) -> np.ndarray:
    w = 2.0 * math.pi / _HELIX_T
    r = qfrom_axis_angle(_HELIX_AXIS, _HELIX_RATE * sigma)
    t = [0.05 * math.cos(w * sigma), 0.05 * math.sin(w * sigma), 0.02 * sigma]
    return dq_from_rt(r, np.array(t))


def helix_derivative(sigma: float) -> np.ndarray:
    w = 2.0 * math.pi / _HELIX_T
    r = qfrom_axis_angle(_HELIX_AXIS, _HELIX_RATE * sigma)
    dr = 0.5 * _HELIX_RATE * qmul(np.concatenate(([0.0], _HELIX_AXIS)), r)
    t = np.array([0.0, 0.05 * math.cos(w * sigma), 0.05 * math.sin(w * sigma), 0.02 * sigma])
    dt = np.array([0.0, -0.05 * w * math.sin(w * sigma), 0.05 * w * math.cos(w * sigma), 0.02])
    return np.concatenate((dr, 0.5 * (qmul(dt, r) + qmul(t, dr))))


def make_waypoints(reference: np.ndarray | None = REF) -> WaypointTrajectory:
    rng = np.random.default_rng(3)
    positions = rng.normal(size=(5, 3)) * 0.1
    return WaypointTrajectory(
        positions,
        random_quaternions(rng, 5),
        times_s=np.array([0.0, 0.7, 1.5, 2.6, 3.0]),
        reference=reference,
    )


FACTORIES = {
    "circle": lambda: Circle(4.0, 0.1, reference=REF),
    "sinusoid": lambda: Sinusoid(8.0, reference=REF),
    "waypoints": make_waypoints,
    "waypoints_chord": lambda: WaypointTrajectory(
        np.random.default_rng(4).normal(size=(4, 3)) * 0.1, None, duration_s=2.0, reference=REF
    ),
    "function": lambda: FunctionTrajectory(helix_pose, helix_derivative, _HELIX_T, REF),
    "function_fd": lambda: FunctionTrajectory(helix_pose, None, _HELIX_T, REF),
}


KINDS = sorted(FACTORIES)


def translation_velocity(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """``dt/dσ`` from ``t = 2 d r*``."""
    return 2.0 * (qmul(dx[4:], qconj(x[:4])) + qmul(x[4:], qconj(dx[:4])))[1:]


def angular_velocity(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """``ω = 2 r' r*`` (in the trajectory's frame)."""
    return 2.0 * qmul(dx[:4], qconj(x[:4]))[1:]

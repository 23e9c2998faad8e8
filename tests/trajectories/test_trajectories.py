"""Tests of dqcontrol.trajectories: the contract of docs/theory.md §3 and path deviation (§9)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from dqcontrol.dq import (
    dq_conj,
    dq_from_rt,
    dq_is_unit,
    dq_mul,
    qconj,
    qfrom_axis_angle,
    qmul,
    qto_matrix,
    rotation_angle,
    translation,
)
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import (
    Circle,
    FunctionTrajectory,
    Sinusoid,
    Trajectory,
    WaypointTrajectory,
)
from dqcontrol.trajectories.base import _segment_distances

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


def brute_force_deviation(traj: Trajectory, points: np.ndarray, segments: int) -> np.ndarray:
    v = traj.path_positions(segments + 1)
    a = v[:-1]
    ab = v[1:] - a
    inv = 1.0 / np.sum(ab * ab, axis=1)
    return np.array([_segment_distances(p, a, ab, inv).min() for p in points])


# ---------------------------------------------------------------------- the contract
@pytest.mark.parametrize("kind", KINDS)
@SETTINGS
@given(fraction=st.floats(-0.2, 1.2))
def test_targets_are_unit_dual_quaternions(kind: str, fraction: float) -> None:
    traj = FACTORIES[kind]()
    x = traj.target(fraction * traj.duration)
    assert x.shape == (8,)
    assert dq_is_unit(x, tol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
@SETTINGS
@given(fraction=st.floats(0.001, 0.999))
def test_target_derivative_matches_finite_differences(kind: str, fraction: float) -> None:
    traj = FACTORIES[kind]()
    sigma = fraction * traj.duration
    h = 1e-6 * traj.duration
    fd = (traj.target(sigma + h) - traj.target(sigma - h)) / (2.0 * h)
    d = traj.target_derivative(sigma)
    np.testing.assert_allclose(d, fd, atol=1e-7 * (1.0 + np.abs(fd).max()))


@pytest.mark.parametrize("kind", KINDS)
def test_batch_targets_equal_single_targets(kind: str) -> None:
    traj = FACTORIES[kind]()
    sigmas = np.concatenate(
        ([-0.5, 0.0], np.random.default_rng(0).uniform(0, traj.duration, 9), [traj.duration, 99])
    )
    poses, derivatives = traj.targets(sigmas)
    assert poses.shape == derivatives.shape == (sigmas.size, 8)
    for sigma, x, dx in zip(sigmas, poses, derivatives, strict=True):
        np.testing.assert_allclose(x, traj.target(sigma), rtol=0, atol=1e-14)
        np.testing.assert_allclose(dx, traj.target_derivative(sigma), rtol=0, atol=1e-13)
    inside = sigmas[(sigmas > 0) & (sigmas < traj.duration)]
    local_x, local_dx = traj.local_poses(inside)
    for sigma, x, dx in zip(inside, local_x, local_dx, strict=True):
        np.testing.assert_allclose(x, traj.local_pose(sigma), rtol=0, atol=1e-15)
        np.testing.assert_allclose(dx, traj.local_derivative(sigma), rtol=0, atol=1e-13)


@pytest.mark.parametrize("kind", KINDS)
def test_target_is_clipped_and_derivative_zero_outside(kind: str) -> None:
    traj = FACTORIES[kind]()
    T = traj.duration
    np.testing.assert_array_equal(traj.target(T + 1.0), traj.target(T))
    np.testing.assert_array_equal(traj.target(-1.0), traj.target(0.0))
    for sigma in (T, T + 1e-9, T + 5.0, -1e-3):
        np.testing.assert_array_equal(traj.target_derivative(sigma), np.zeros(8))
    assert np.any(traj.target_derivative(0.01 * T) != 0.0)
    poses, derivatives = traj.targets(np.array([T - 0.1, T, T + 2.0]))
    np.testing.assert_allclose(poses[2], traj.target(T), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(derivatives[1:], np.zeros((2, 8)))


@pytest.mark.parametrize("kind", KINDS)
def test_anchored_at_starts_at_x0(kind: str) -> None:
    traj = FACTORIES[kind]()
    rng = np.random.default_rng(11)
    for _ in range(5):
        x0 = random_pose(rng)
        anchored = traj.anchored_at(x0)
        np.testing.assert_allclose(anchored.target(0.0), x0, rtol=0, atol=2e-16 * 8)
        np.testing.assert_allclose(
            anchored.reference, dq_mul(x0, dq_conj(traj.local_pose(0.0))), atol=1e-15
        )
        assert dq_is_unit(anchored.reference, tol=1e-14)
    # The original is unchanged.
    np.testing.assert_allclose(traj.reference, REF, rtol=0, atol=1e-16)


def test_unanchored_trajectory_asks_for_anchored_at() -> None:
    traj = Circle(2.0)
    assert traj.reference is None
    for call in (
        lambda: traj.target(0.0),
        lambda: traj.target_derivative(0.0),
        lambda: traj.targets(np.zeros(3)),
        lambda: traj.path_positions(),
    ):
        with pytest.raises(ParameterError, match=r"anchored_at\(x0\)"):
            call()
    np.testing.assert_array_equal(traj.local_pose(0.0)[5:7], [0.05, 0.0])


def test_reference_is_read_only_and_with_reference_copies() -> None:
    traj = Circle(2.0).with_reference(REF)
    with pytest.raises(ValueError):
        traj.reference[0] = 0.0
    other = traj.with_reference(np.array([1.0, 0, 0, 0, 0, 0, 0, 0]))
    np.testing.assert_allclose(traj.reference, REF, rtol=0, atol=1e-16)
    np.testing.assert_allclose(translation(other.target(0.0)), [0.1, 0.0, 0.0], atol=1e-16)


def test_reference_is_renormalised_within_tolerance() -> None:
    slightly_off = REF * (1.0 + 1e-8)
    traj = Circle(2.0, reference=slightly_off)
    assert dq_is_unit(traj.reference, tol=1e-15)
    np.testing.assert_allclose(traj.reference, REF, atol=1e-15)


def test_targets_of_no_sigmas_is_empty() -> None:
    poses, derivatives = FACTORIES["circle"]().targets(np.array([]))
    assert poses.shape == derivatives.shape == (0, 8)


# ---------------------------------------------------------------------- circle and sinusoid
def test_circle_geometry() -> None:
    R = 0.1
    circle = Circle(4.0, R, reference=REF)
    local = translation(circle.local_poses(np.linspace(0, 4.0, 101))[0])
    np.testing.assert_allclose(local[0], [R, 0.0, 0.0], atol=1e-17)
    np.testing.assert_allclose(np.linalg.norm(local[:, :2], axis=1), R, rtol=1e-15)
    np.testing.assert_array_equal(local[:, 2], 0.0)
    np.testing.assert_allclose(local[-1], local[0], atol=1e-16)  # one full turn
    # World: every point at R from the centre (the reference origin), in the plane ⟂ its z.
    world = circle.path_positions(500)
    centre = translation(REF)
    normal = qto_matrix(REF[:4])[:, 2]
    np.testing.assert_allclose(np.linalg.norm(world - centre, axis=1), R, rtol=1e-14)
    np.testing.assert_allclose((world - centre) @ normal, 0.0, atol=1e-15)
    # Identity rotation relative to ref.
    np.testing.assert_allclose(circle.target(1.3)[:4], REF[:4], atol=1e-15)


def test_anchored_circle_lies_in_the_start_tool_xy_plane() -> None:
    x0 = random_pose(np.random.default_rng(2))
    circle = Circle(3.0, 0.1).anchored_at(x0)
    rot = qto_matrix(x0[:4])
    centre = translation(x0) - 0.1 * rot[:, 0]
    world = circle.path_positions(300)
    np.testing.assert_allclose(np.linalg.norm(world - centre, axis=1), 0.1, rtol=1e-13)
    np.testing.assert_allclose((world - centre) @ rot[:, 2], 0.0, atol=1e-15)
    for sigma in (0.0, 1.0, 2.5):  # tool orientation held at the start orientation
        np.testing.assert_allclose(circle.target(sigma)[:4], x0[:4], atol=1e-15)


@pytest.mark.parametrize("cls", [Circle, Sinusoid])
def test_path_does_not_depend_on_duration(cls: type) -> None:
    slow = cls(8.0, reference=REF)
    fast = cls(1.0, reference=REF)
    np.testing.assert_allclose(slow.path_positions(1000), fast.path_positions(1000), atol=1e-14)
    resampled = fast.path_positions(777)
    assert slow.path_deviation(resampled).max() < 5e-8
    # Speed scales with 1/T_tot: dx_d/dσ of the fast one is 8 times that of the slow one.
    np.testing.assert_allclose(
        fast.target_derivative(0.25), 8.0 * slow.target_derivative(2.0), atol=1e-13
    )


def test_sinusoid_spans_four_periods() -> None:
    T = 5.0
    sinus = Sinusoid(T, amplitude_m=0.1, omega_x_rad_per_m=60.0)
    t = translation(sinus.local_poses(np.linspace(0.0, T, 40001))[0])
    np.testing.assert_allclose(t[0], 0.0, atol=1e-17)
    np.testing.assert_allclose(t[-1], [2 * math.pi / 15, 0.0, 0.0], atol=1e-15)
    assert np.all(np.diff(t[:, 0]) > 0)
    np.testing.assert_array_equal(t[:, 1], 0.0)
    z = t[:, 2]
    maxima = np.flatnonzero((z[1:-1] > z[:-2]) & (z[1:-1] > z[2:]))
    assert maxima.size == 4
    np.testing.assert_allclose(z[maxima + 1], 0.1, rtol=1e-6)
    np.testing.assert_allclose(np.diff(t[maxima + 1, 0]), 2 * math.pi / 15 / 4, rtol=1e-3)


# ---------------------------------------------------------------------- waypoints
def test_waypoints_pass_through_keyframes_at_their_times() -> None:
    traj = make_waypoints(reference=None)
    for k, sigma in enumerate(traj.times_s):
        x = traj.local_pose(sigma)
        np.testing.assert_allclose(translation(x), traj.positions_m[k], atol=1e-15)
        q = traj.orientations[k]
        assert min(np.abs(x[:4] - q).max(), np.abs(x[:4] + q).max()) < 1e-14
    # The given (unnormalised-sign) inputs are matched up to ±q.
    rng = np.random.default_rng(3)
    rng.normal(size=(5, 3))
    given_q = random_quaternions(rng, 5)
    for k in range(5):
        assert abs(abs(np.dot(traj.local_pose(traj.times_s[k])[:4], given_q[k])) - 1.0) < 1e-14


def test_waypoints_start_and_stop_at_rest_and_orientation_varies() -> None:
    traj = make_waypoints()
    for sigma in (0.0, traj.duration * (1 - 1e-15)):
        x, dx = traj.local_pose(sigma), traj.local_derivative(sigma)
        np.testing.assert_allclose(translation_velocity(x, dx), 0.0, atol=1e-12)
        np.testing.assert_allclose(angular_velocity(x, dx), 0.0, atol=1e-12)
    angles = [
        rotation_angle(qmul(qconj(traj.local_pose(0.0)[:4]), traj.local_pose(s)[:4]))
        for s in np.linspace(0, traj.duration, 20)
    ]
    assert max(angles) > 0.5
    assert np.all(np.abs(np.diff(angles)) < 1.0)  # smooth, no jumps


def test_waypoints_are_c2_across_knots() -> None:
    traj = make_waypoints(reference=None)
    h = 1e-5

    def rates(sigma: float) -> tuple[np.ndarray, np.ndarray]:
        x, dx = traj.local_pose(sigma), traj.local_derivative(sigma)
        return translation_velocity(x, dx), angular_velocity(x, dx)

    for knot in traj.times_s[1:-1]:
        v_minus, w_minus = rates(knot - h)
        v0, w0 = rates(knot)
        v_plus, w_plus = rates(knot + h)
        acc_left, acc_right = (v0 - v_minus) / h, (v_plus - v0) / h
        alpha_left, alpha_right = (w0 - w_minus) / h, (w_plus - w0) / h
        assert np.abs(acc_right - acc_left).max() < 1e-3 * (1 + np.abs(acc_left).max())
        assert np.abs(alpha_right - alpha_left).max() < 1e-3 * (1 + np.abs(alpha_left).max())
        assert np.abs(w0).max() > 1e-3  # the rotation does not stop at the keyframes


def test_single_axis_rotation_is_the_clamped_spline_of_the_angle() -> None:
    axis = np.array([1.0, 2.0, -1.0])
    angles = np.array([0.0, 1.0, 2.5, 2.0, 4.0])  # accumulated: steps < π
    times = np.array([0.0, 1.0, 1.5, 3.0, 4.0])
    quats = np.array([qfrom_axis_angle(axis, a) for a in angles])
    traj = WaypointTrajectory(np.zeros((5, 3)), quats, times_s=times)
    expected = CubicSpline(times, angles, bc_type="clamped")
    for sigma in np.linspace(0, 4.0, 37):
        r = traj.local_pose(sigma)[:4]
        q = qfrom_axis_angle(axis, float(expected(sigma)))
        assert min(np.abs(r - q).max(), np.abs(r + q).max()) < 1e-14


def test_waypoint_times_follow_chord_length() -> None:
    positions = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.1, 0.3, 0], [0.1, 0.3, 0.1]])
    traj = WaypointTrajectory(positions, duration_s=5.0)
    np.testing.assert_allclose(traj.times_s, [0.0, 1.0, 4.0, 5.0], atol=1e-15)
    for k, sigma in enumerate(traj.times_s):
        np.testing.assert_allclose(translation(traj.local_pose(sigma)), positions[k], atol=1e-16)
        np.testing.assert_array_equal(traj.local_pose(sigma)[:4], [1.0, 0, 0, 0])


# ---------------------------------------------------------------------- function trajectory
def test_function_trajectory_finite_difference_matches_analytic() -> None:
    traj = FunctionTrajectory(helix_pose, None, _HELIX_T)
    for sigma in (0.0, 1e-7, 0.4, 1.7, _HELIX_T - 1e-7, _HELIX_T):
        np.testing.assert_allclose(
            traj.local_derivative(sigma), helix_derivative(sigma), rtol=0, atol=1e-9
        )


def test_function_trajectory_finite_difference_survives_sign_flips() -> None:
    def flipping(sigma: float) -> np.ndarray:  # -x on a grid of sigmas: the same poses
        return helix_pose(sigma) * (-1.0 if int(sigma * 1e6) % 2 else 1.0)

    traj = FunctionTrajectory(flipping, None, _HELIX_T)
    for sigma in (0.3, 1.1, 2.9):
        x = traj.local_pose(sigma)
        sign = np.sign(np.dot(x, helix_pose(sigma)))
        np.testing.assert_allclose(
            traj.local_derivative(sigma), sign * helix_derivative(sigma), atol=1e-9
        )


def test_function_trajectory_calls_pose_fn_only_inside_the_interval() -> None:
    seen: list[float] = []

    def pose(sigma: float) -> np.ndarray:
        seen.append(sigma)
        return helix_pose(sigma)

    traj = FunctionTrajectory(pose, None, _HELIX_T, REF)
    traj.targets(np.array([-1.0, 0.0, 1.0, _HELIX_T, 10.0]))
    assert min(seen) >= 0.0 and max(seen) <= _HELIX_T


# ---------------------------------------------------------------------- path deviation
def test_path_deviation_is_zero_on_the_path() -> None:
    rng = np.random.default_rng(5)
    for kind in KINDS:
        traj = FACTORIES[kind]()
        on_path, _ = traj.targets(rng.uniform(0, traj.duration, 300))
        assert traj.path_deviation(translation(on_path)).max() < 5e-8, kind
    circle = FACTORIES["circle"]()
    on_circle = translation(circle.targets(rng.uniform(0, 4.0, 300))[0])
    # Bound h²/8 max‖p''‖ = (T/S)²/8 · RΩ² for the circle.
    bound = (4.0 / 20000) ** 2 / 8 * 0.1 * (2 * math.pi / 4.0) ** 2
    assert circle.path_deviation(on_circle).max() <= bound * 1.01


@SETTINGS
@given(
    fraction=st.floats(0.0, 1.0),
    radial=st.floats(-0.05, 0.05),
    normal=st.floats(-0.05, 0.05),
)
def test_path_deviation_along_circle_normals(fraction: float, radial: float, normal: float) -> None:
    R = 0.1
    circle = Circle(4.0, R, reference=REF)
    phi = 2.0 * math.pi * fraction
    local = np.array([(R + radial) * math.cos(phi), (R + radial) * math.sin(phi), normal])
    point = translation(dq_mul(REF, dq_from_rt(np.array([1.0, 0, 0, 0]), local)))
    expected = math.hypot(radial, normal)
    assert abs(circle.path_deviation(point) - expected) < 5e-9


@pytest.mark.parametrize("kind", ["circle", "sinusoid", "waypoints"])
def test_path_deviation_agrees_with_brute_force(kind: str) -> None:
    traj = FACTORIES[kind]()
    rng = np.random.default_rng(8)
    base = traj.path_positions(200)
    centre = base.mean(axis=0)
    points = np.concatenate(
        (
            base + rng.normal(size=base.shape) * 1e-4,
            base + rng.normal(size=base.shape) * 0.03,
            centre + rng.normal(size=(50, 3)) * 1e-3,  # equidistant from much of a circle
            centre + rng.normal(size=(20, 3)) * 1.0,  # far away
        )
    )
    segments = 3000
    got = traj.path_deviation(points, segments=segments)
    np.testing.assert_allclose(got, brute_force_deviation(traj, points, segments), atol=1e-12)


def test_path_deviation_of_the_circle_centre_is_the_radius() -> None:
    circle = Circle(4.0, 0.1, reference=REF)
    d = circle.path_deviation(np.tile(translation(REF), (3, 1)))
    # Vertices are at R, chord midpoints at R cos(π/S).
    np.testing.assert_allclose(d, 0.1 * math.cos(math.pi / 20000), rtol=1e-12)


# ---------------------------------------------------------------------- validation and repr
@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: Circle(0.0), "duration_s"),
        (lambda: Circle(float("nan")), "duration_s"),
        (lambda: Circle(-1.0), "> 0"),
        (lambda: Circle(1.0, radius_m=0.0), "radius_m"),
        (lambda: Circle(1.0, reference=np.ones(8)), "reference"),
        (lambda: Circle(1.0, reference=np.ones(7)), "shape"),
        (lambda: Sinusoid(1.0, amplitude_m=-0.1), "amplitude_m"),
        (lambda: Sinusoid(1.0, omega_x_rad_per_m=float("inf")), "omega_x_rad_per_m"),
        (lambda: Sinusoid("fast"), "duration_s"),
        (lambda: WaypointTrajectory(np.zeros((1, 3)), duration_s=1.0), "N ≥ 2"),
        (lambda: WaypointTrajectory(np.zeros((3, 2)), duration_s=1.0), r"\(N, 3\)"),
        (lambda: WaypointTrajectory([[0, 0, 0], [np.nan, 0, 0]], duration_s=1.0), "finite"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]]), "duration_s"),
        (lambda: WaypointTrajectory([[0, 0, 0], [0, 0, 0]], duration_s=1.0), "pass times_s"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[0, 0]), "increasing"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[1, 2]), "start at 0"),
        (lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[0, 1, 2]), "shape"),
        (
            lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], times_s=[0, 1], duration_s=2),
            "times_s\\[-1\\]",
        ),
        (
            lambda: WaypointTrajectory(
                [[0, 0, 0], [1, 0, 0]], [[1, 0, 0, 0], [2, 0, 0, 0]], duration_s=1
            ),
            "unit quaternions",
        ),
        (
            lambda: WaypointTrajectory([[0, 0, 0], [1, 0, 0]], [[1, 0, 0, 0]], duration_s=1),
            r"\(2, 4\)",
        ),
        (lambda: FunctionTrajectory(lambda s: np.ones(8), None, 1.0), "pose_fn\\(0\\)"),
        (lambda: FunctionTrajectory(lambda s: np.ones(4), None, 1.0), "shape"),
        (lambda: FunctionTrajectory("pose", None, 1.0), "callable"),
        (lambda: FunctionTrajectory(helix_pose, lambda s: np.zeros(3), 1.0), "shape"),
        (lambda: FACTORIES["circle"]().targets(np.array([0.0, np.nan])), "finite"),
        (lambda: FACTORIES["circle"]().targets(np.zeros((2, 2))), "1-D"),
        (lambda: FACTORIES["circle"]().target(float("nan")), "finite"),
        (lambda: FACTORIES["circle"]().path_positions(1), "num"),
        (lambda: FACTORIES["circle"]().path_deviation(np.zeros((3, 2))), "points_m"),
        (lambda: FACTORIES["circle"]().path_deviation(np.zeros(3), segments=0), "segments"),
        (lambda: Circle(1.0).anchored_at(np.zeros(8)), "x0"),
    ],
)
def test_bad_input_raises_parameter_error(build, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        build()


def test_repr_shows_parameters() -> None:
    text = repr(Sinusoid(4.0, amplitude_m=0.05))
    assert "Sinusoid(duration_s=4.0" in text and "amplitude_m=0.05" in text
    assert "reference=None" in text
    assert "radius_m=0.1" in repr(FACTORIES["circle"]())
    assert "times_s=[0. , 0.7" in repr(make_waypoints())
    assert "finite difference" in repr(FACTORIES["function_fd"]())

"""The contract of ``dqcontrol.trajectories.base.Trajectory`` (docs/theory.md §3) over every
kind of trajectory (its fused ``target_pair`` equal to the target and its derivative), and
its path deviation (§9) against brute force and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from trajectories.trajectory_cases import (
    FACTORIES,
    KINDS,
    REF,
    SETTINGS,
    make_waypoints,
    random_pose,
)

from dqcontrol.dq import dq_conj, dq_from_rt, dq_is_unit, dq_mul, translation
from dqcontrol.errors import ParameterError
from dqcontrol.trajectories import (
    Circle,
    FunctionTrajectory,
    Sinusoid,
    Trajectory,
    WaypointTrajectory,
)
from dqcontrol.trajectories.base import _segment_distances


def brute_force_deviation(traj: Trajectory, points: np.ndarray, segments: int) -> np.ndarray:
    v = traj.path_positions(segments + 1)
    a = v[:-1]
    ab = v[1:] - a
    inv = 1.0 / np.sum(ab * ab, axis=1)
    return np.array([_segment_distances(p, a, ab, inv).min() for p in points])


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


def _trajectories():
    ref = np.array([1.0, 0, 0, 0, 0, 0.05, -0.1, 0.2])
    yield Circle(2.0, reference=ref)
    yield Sinusoid(4.0, reference=ref)
    yield WaypointTrajectory(
        np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0.05]]), duration_s=3.0, reference=ref
    )
    circle = Circle(2.0)
    yield FunctionTrajectory(circle.local_pose, None, 2.0, reference=ref)


@pytest.mark.parametrize("traj", list(_trajectories()), ids=lambda t: type(t).__name__)
def test_target_pair_equals_target_and_derivative(traj):
    duration = traj.duration
    for sigma in (-0.3, 0.0, 0.1234, 0.5 * duration, duration - 1e-9, duration, duration + 1):
        pair = traj.target_pair(sigma)
        np.testing.assert_allclose(pair[0], traj.target(sigma), rtol=0, atol=1e-15)
        np.testing.assert_allclose(pair[1], traj.target_derivative(sigma), rtol=0, atol=1e-15)


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


def test_repr_shows_parameters() -> None:
    text = repr(Sinusoid(4.0, amplitude_m=0.05))
    assert "Sinusoid(duration_s=4.0" in text and "amplitude_m=0.05" in text
    assert "reference=None" in text
    assert "radius_m=0.1" in repr(FACTORIES["circle"]())
    assert "times_s=[0. , 0.7" in repr(make_waypoints())
    assert "finite difference" in repr(FACTORIES["function_fd"]())


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: Circle(0.0), "duration_s"),
        (lambda: Circle(float("nan")), "duration_s"),
        (lambda: Circle(-1.0), "> 0"),
        (lambda: Circle(1.0, reference=np.ones(8)), "reference"),
        (lambda: Circle(1.0, reference=np.ones(7)), "shape"),
        (lambda: Sinusoid("fast"), "duration_s"),
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

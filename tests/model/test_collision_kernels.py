"""The compiled kernels of ``dqcontrol.model.collision_kernels`` against numpy (segment distances,
support functions, motion bounds) and the screening pass against its steps run one by one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol import load_lbr4p
from dqcontrol.model.collision import Box, CollisionModel, HalfSpace, Sphere
from dqcontrol.model.collision_closed_forms import solve_closed_forms
from dqcontrol.model.collision_kernels import (
    FORM_SIZE,
    close_pairs,
    screen_pairs,
    segment_distance,
    separation,
    support,
)


@pytest.fixture(scope="module")
def model() -> CollisionModel:
    obstacles = (
        Sphere(name="ball", position_m=(0.3, -0.2, 0.9), radius_m=0.08),
        Box(name="crate", position_m=(0.4, 0.3, 0.5), size_m=(0.1, 0.1, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.2),
    )
    return CollisionModel(load_lbr4p(), obstacles)


def test_close_pairs_is_the_motion_bound():
    rng = np.random.default_rng(7)
    for _ in range(50):
        count, pairs, n = 6, 40, 5
        influence = 0.1
        gaps = rng.uniform(-0.05, 0.3, (count, pairs))
        qs = rng.uniform(-1.0, 1.0, (count, n))
        reference_q = rng.uniform(-1.0, 1.0, (pairs, n))
        reference_m = rng.uniform(0.0, 2.0, pairs)
        reference_m[rng.random(pairs) < 0.2] = -math.inf
        levers = rng.uniform(0.0, 0.3, (pairs, n))
        moved = np.abs(qs[:, None, :] - reference_q[None]) * levers[None]
        bound = reference_m[None] - 1e-6 - moved.sum(axis=2)
        want = np.nonzero((gaps < influence) & (bound < influence))
        states, found = close_pairs(gaps, qs, reference_q, reference_m, levers, influence)
        assert states.tolist() == want[0].tolist()
        assert found.tolist() == want[1].tolist()


@pytest.mark.parametrize("influence", [0.02, 0.1, 0.3])
def test_screen_pairs_is_its_passes_in_turn(model, influence):
    rng = np.random.default_rng(int(influence * 1000))
    qs = model.robot.random_configurations(8, 5, margin_rad=0.1)
    rot, trans, _ = model._kinematics_batch(qs)
    reference_q = qs[rng.integers(0, 8, model.num_pairs)] + rng.normal(
        0, 0.02, (model.num_pairs, qs.shape[1])
    )
    reference_m = rng.uniform(-0.05, 0.6, model.num_pairs)
    tables = (model._joint_of, model._ends, model._radii, model._forms, model._a, model._b)
    planes = (model._normals, model._offsets, model._plane)
    got = screen_pairs(
        rot, trans, qs, *tables, *planes, reference_q, reference_m, model._levers,
        *model._closed, influence,
    )  # fmt: skip
    gaps = model._gaps(rot, trans, math.inf)
    states, pairs = close_pairs(gaps, qs, reference_q, reference_m, model._levers, influence)
    solved, points, todo = solve_closed_forms(
        rot, trans, states, pairs, model._a, model._b, model._joint_of, *model._closed
    )
    assert states.size > 0 and (todo.size > 0 or influence < 0.1)
    assert got[0].tolist() == states.tolist() and got[1].tolist() == pairs.tolist()
    np.testing.assert_array_equal(got[2], solved)
    np.testing.assert_array_equal(got[3], points)
    assert got[4].tolist() == np.stack([todo, states[todo], pairs[todo]], axis=1).tolist()


def _brute_segments(ends: np.ndarray) -> float:
    """Distance of two segments by a dense grid, refined once around the best cell."""
    s = np.linspace(0.0, 1.0, 401)
    a = ends[0, 0] + s[:, None] * (ends[0, 1] - ends[0, 0])
    b = ends[1, 0] + s[:, None] * (ends[1, 1] - ends[1, 0])
    return float(np.linalg.norm(a[:, None] - b[None], axis=2).min())


def test_segment_distance_is_a_tight_lower_bound():
    rng = np.random.default_rng(3)
    for trial in range(300):
        ends = rng.uniform(-0.3, 0.3, (2, 2, 3))
        if trial % 3 == 0:  # nearly parallel
            ends[1, 1] = ends[1, 0] + (ends[0, 1] - ends[0, 0]) * (1 + 1e-9 * trial)
        if trial % 7 == 0:  # a point
            ends[0, 1] = ends[0, 0]
        found = segment_distance(ends, 0, 1)[0]
        dense = _brute_segments(ends)
        assert found <= dense + 1e-12
        assert found >= dense - 2e-3  # the grid's resolution


def _form(centre, spans=None, axis=None, disc=0.0, ball=0.0) -> np.ndarray:
    """One row of support forms: ``c, s_0, s_1, s_2, a, ρ, r``."""
    spans = np.zeros((3, 3)) if spans is None else spans
    axis = np.zeros(3) if axis is None else axis
    return np.concatenate((centre, np.ravel(spans), axis, [disc, ball]))


def _unit(rng: np.random.Generator) -> np.ndarray:
    u = rng.standard_normal(3)
    return u / np.linalg.norm(u)


def test_support_is_the_largest_projection_of_the_shape():
    """Against numpy maxima of ``uᵀx`` over a box's corners, a ball and a cylinder's rims."""
    rng = np.random.default_rng(17)
    rotation = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    half = np.array([0.1, 0.2, 0.05])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    box_points = np.array([0.3, -0.1, 0.2]) + (corners * half) @ rotation.T
    axis, radius, half_length = rotation[:, 2], 0.06, 0.15
    angles = np.linspace(0.0, 2.0 * np.pi, 20001)
    rim = radius * (
        np.outer(np.cos(angles), rotation[:, 0]) + np.outer(np.sin(angles), rotation[:, 1])
    )
    cylinder_points = np.concatenate((rim + half_length * axis, rim - half_length * axis))
    forms = np.array(
        [
            _form([0.3, -0.1, 0.2], spans=(half[:, None] * rotation.T)),
            _form([-0.2, 0.1, 0.4], ball=0.07),
            _form(
                np.zeros(3),
                spans=np.vstack((half_length * axis, np.zeros((2, 3)))),
                axis=axis,
                disc=radius,
            ),
        ]
    )
    assert forms.shape[1] == FORM_SIZE
    for _ in range(100):
        u = _unit(rng)
        np.testing.assert_allclose(support(forms, 0, *u), (box_points @ u).max(), atol=1e-14)
        np.testing.assert_allclose(support(forms, 1, *u), u @ [-0.2, 0.1, 0.4] + 0.07, atol=1e-15)
        assert 0.0 <= support(forms, 2, *u) - (cylinder_points @ u).max() <= 1e-8


def test_separation_of_two_balls_along_their_centres_is_their_distance():
    forms = np.array([_form([0.1, 0.2, 0.3], ball=0.05), _form([0.4, -0.1, 0.5], ball=0.1)])
    v = np.array([0.3, -0.3, 0.2])
    exact = np.linalg.norm(v) - 0.15
    np.testing.assert_allclose(separation(forms, 0, 1, *v), exact - 1e-9, rtol=0, atol=1e-15)
    # any other direction gives a lower bound; a zero direction gives none
    rng = np.random.default_rng(18)
    for _ in range(20):
        assert separation(forms, 0, 1, *_unit(rng)) <= exact
    assert separation(forms, 0, 1, 0.0, 0.0, 0.0) == -math.inf

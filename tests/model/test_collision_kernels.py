"""The screening pass of the collision queries: the motion bounds' selection against its
formula in numpy, and the one compiled pass against the bounds, the selection and the
closed forms run one by one, on seeded random states of the LBR4p with obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dqcontrol import load_lbr4p
from dqcontrol.model.collision import Box, CollisionModel, HalfSpace, Sphere
from dqcontrol.model.collision_closed_forms import solve_closed_forms
from dqcontrol.model.collision_kernels import close_pairs, screen_pairs


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

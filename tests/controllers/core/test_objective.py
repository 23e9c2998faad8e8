"""The first level's objective with changing dense rows in one compiled call, against
:func:`~dqcontrol.controllers.core.problem.objective` on seeded random draws (docs/theory.md
§7.4)."""

import numpy as np
import pytest

from dqcontrol.controllers.core.objective import level_objective
from dqcontrol.controllers.core.problem import DecisionLayout, Residual, objective
from dqcontrol.controllers.linalg.gram import frozen


def _layout(joints, blocks):
    return DecisionLayout(joints, np.arange(blocks) * 0.1, np.full(blocks, 0.1))


def _draw(rng, layout, weighted, frozen_blocks):
    p, m, nv = layout.num_blocks, layout.block_size, layout.num_vars
    rows = rng.normal(size=(5, nv))
    rows[rng.random(size=rows.shape) < 0.4] = 0.0
    damping = np.tile(np.eye(m), (p, 1, 1))
    if frozen_blocks:
        frozen(damping)
    return (
        Residual(
            "path", 3.0, rng.normal(size=5), A=rows, row_weights=rng.random(5) if weighted else None
        ),  # fmt: skip
        Residual("damping", 1e-3, rng.normal(size=p * m), blocks=damping, held=False),
        Residual("off", 0.0, rng.normal(size=p), blocks=rng.normal(size=(p, 1, m)), held=False),
        Residual("blocks", 0.5, rng.normal(size=2 * p), blocks=rng.normal(size=(p, 2, m))),
    )


@pytest.mark.parametrize("weighted", [False, True])
@pytest.mark.parametrize("frozen_blocks", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_the_level_objective_is_objectives(seed, weighted, frozen_blocks):
    rng = np.random.default_rng(seed)
    layout = _layout(int(rng.integers(1, 4)), int(rng.integers(1, 4)))
    residuals = _draw(rng, layout, weighted, frozen_blocks)
    p_mat, c = level_objective(layout, residuals)
    p_ref, c_ref = objective(layout, residuals)
    assert p_mat.shape == p_ref.shape and c.shape == c_ref.shape
    assert np.allclose(p_mat, p_ref, rtol=1e-14, atol=1e-14)
    assert np.allclose(c, c_ref, rtol=1e-14, atol=1e-14)


def test_read_only_or_other_rows_are_left_to_objective():
    rng = np.random.default_rng(5)
    layout = _layout(2, 3)
    residuals = _draw(rng, layout, True, True)
    path = residuals[0]
    path = path._replace(A=frozen(path.A.copy()), row_weights=frozen(path.row_weights.copy()))
    kept = (path, residuals[1])
    p_mat, _ = level_objective(layout, kept)
    assert not p_mat.flags.writeable  # objective's kept product of read-only rows
    assert np.array_equal(p_mat, objective(layout, kept)[0])

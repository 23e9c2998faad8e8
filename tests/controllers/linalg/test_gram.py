"""Products of constant rows: kept for read-only arrays, the same numbers as recomputed."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers.core.problem import DecisionLayout, Residual, objective
from dqcontrol.controllers.linalg.gram import frozen, kept


def _layout() -> DecisionLayout:
    return DecisionLayout(3, np.array([0.0, 0.1, 0.3]), np.array([0.1, 0.2, 0.2]))


def _residuals(rng: np.random.Generator, freeze: bool) -> tuple[Residual, ...]:
    layout = _layout()
    mark = frozen if freeze else (lambda a: a)
    blocks = mark(rng.normal(size=(3, 2, layout.block_size)))
    b = mark(rng.normal(size=6))
    a = mark(rng.normal(size=(5, layout.num_vars)))
    rows = rng.normal(size=(4, layout.num_vars))
    return (
        Residual("blocks", 0.7, b, blocks=blocks),
        Residual("dense", 1.3, rng.normal(size=5), A=a),
        Residual("weighted", 2.0, rng.normal(size=4), A=rows, row_weights=rng.uniform(size=4)),
    )


def test_objective_of_frozen_rows_is_bit_identical_and_repeatable():
    layout = _layout()
    plain = objective(layout, _residuals(np.random.default_rng(3), False))
    res = _residuals(np.random.default_rng(3), True)
    for _ in range(2):  # computed, then kept
        p_mat, c = objective(layout, res)
        assert np.array_equal(p_mat, plain[0]) and np.array_equal(c, plain[1])


def test_kept_only_for_read_only_operands():
    a = np.arange(6.0).reshape(2, 3)
    first = kept((a,), lambda x: x.T @ x)
    assert first is not kept((a,), lambda x: x.T @ x)  # writable: recomputed
    frozen(a)
    twice = kept((a,), np.transpose)
    assert twice is kept((a,), np.transpose) and not twice.flags.writeable
    assert np.array_equal(twice, a.T)


def test_dense_of_frozen_blocks_is_read_only_and_equal():
    layout = _layout()
    blocks = np.random.default_rng(1).normal(size=(3, 2, layout.block_size))
    ref = Residual("r", 1.0, np.zeros(6), blocks=blocks.copy()).dense(layout)
    dense = Residual("r", 1.0, np.zeros(6), blocks=frozen(blocks)).dense(layout)
    assert np.array_equal(dense, ref) and not dense.flags.writeable


def test_a_kept_product_holds_its_operands_so_no_other_array_takes_their_address():
    import weakref

    def double(*xs):
        return 2.0 * xs[0]

    for count in (1, 2):
        operands = tuple(frozen(np.arange(3.0) + k) for k in range(count))
        refs = [weakref.ref(a) for a in operands]
        first = kept(operands, double)
        del operands
        # the entry keeps them alive: an array made now cannot take one of their ids
        assert all(r() is not None for r in refs)
        again = tuple(frozen(np.arange(3.0) + 10 + k) for k in range(count))
        assert all(id(a) != id(r()) for a in again for r in refs)
        assert np.array_equal(kept(again, double), [20.0, 22.0, 24.0])
        assert kept(tuple(r() for r in refs), double) is first


def test_block_rows_on_the_first_blocks_only_give_the_dense_objective():
    """Block rows that cover fewer blocks than the layout (rows on the first instants):
    the objective equals the one of their dense rows, zero on the later blocks."""
    layout = _layout()
    rng = np.random.default_rng(11)
    for freeze in (False, True):
        mark = frozen if freeze else (lambda a: a)
        blocks = mark(rng.normal(size=(2, 2, layout.block_size)))  # 2 of the 3 blocks
        b = mark(rng.normal(size=4))
        partial = Residual("first blocks", 0.9, b, blocks=blocks)
        dense = Residual("dense", 0.9, b, A=partial.dense(layout))
        p_mat, c = objective(layout, (partial,))
        p_ref, c_ref = objective(layout, (dense,))
        np.testing.assert_allclose(p_mat, p_ref, atol=1e-12)
        np.testing.assert_allclose(c, c_ref, atol=1e-12)
        assert np.all(c[2 * layout.block_size :] == 0.0)

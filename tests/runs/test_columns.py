"""dqcontrol/runs/columns.py: a block of samples against the in-memory recorder given the same
samples, its bytes decoded back equal, blocks concatenated, and bad bytes refused."""

from __future__ import annotations

import numpy as np
import pytest
from runs.test_log import N, _result

from dqcontrol.errors import ParameterError
from dqcontrol.runs.columns import (
    SampleBlock,
    concat_arrays,
    decode_block,
    encode_block,
    field_layout,
)
from dqcontrol.runs.log import LogRecorder


def _fill(rng, blocks: list[SampleBlock], rec: LogRecorder, count: int, plan_from=None):
    """Record ``count`` samples in both the blocks (one after the other, as they fill) and
    ``rec``; from sample ``plan_from`` on they come from a streamed controller."""
    statuses = ("solved", "closed_form", "primal_infeasible")
    current = 0
    for k in range(count):
        if blocks[current].full:
            current += 1
        plan = None if plan_from is None or k < plan_from else 100 + k
        result = _result(rng, k, statuses[k % 3], plan_id=plan)
        q, qd = rng.standard_normal(N), rng.standard_normal(N)
        torque = None if k % 4 == 1 else rng.standard_normal(N)
        args = (0.01 * k, q, qd, result, torque, torque, k >= count - 2)
        blocks[current].record(*args)
        rec.record(*args)


def _assert_equal_arrays(got: dict, want: dict) -> None:
    assert got.keys() == want.keys()
    for name, values in want.items():
        np.testing.assert_array_equal(got[name], values, err_msg=name)
        assert got[name].dtype.kind == values.dtype.kind, name


def test_a_block_holds_what_the_recorder_holds():
    rng = np.random.default_rng(4)
    block, rec = SampleBlock(N, 8), LogRecorder(N)
    _fill(rng, [block], rec, 6)
    assert block.count == 6 and not block.full
    _assert_equal_arrays(block.arrays(), rec.finish().arrays())
    tail = block.arrays(start=4)
    np.testing.assert_array_equal(tail["t_s"], [0.04, 0.05])


def test_encoded_bytes_decode_to_the_same_arrays():
    rng = np.random.default_rng(5)
    block, rec = SampleBlock(N, 5), LogRecorder(N)
    _fill(rng, [block], rec, 5, plan_from=2)
    assert block.full
    decoded = decode_block(encode_block(block))
    _assert_equal_arrays(decoded, block.arrays())
    np.testing.assert_array_equal(decoded["plan_id"], [-1, -1, 102, 103, 104])
    assert decoded["solver_status"].tolist() == [
        "solved", "closed_form", "primal_infeasible", "solved", "closed_form",
    ]  # fmt: skip


def test_the_layout_names_every_field_and_its_columns():
    layout = {name: (dtype, cols) for name, dtype, cols in field_layout(4)}
    assert layout["q"] == ("<f8", 4) and layout["pose"] == ("<f8", 8)
    assert layout["t_s"] == ("<f8", 0) and layout["stopping"] == ("|b1", 0)
    empty = {f.name for f in LogRecorder(4).finish().__dataclass_fields__.values()}
    assert set(layout) == empty - {"meta", "plan_id", "plan_age_s", "lateness_s"}


def test_blocks_concatenate_into_the_recorders_log():
    rng = np.random.default_rng(6)
    blocks, rec = [SampleBlock(N, 4) for _ in range(3)], LogRecorder(N)
    _fill(rng, blocks, rec, 10, plan_from=6)  # the first block has no stream columns
    parts = [decode_block(encode_block(b)) for b in blocks]
    assert "plan_id" not in parts[0] and "plan_id" in parts[2]
    _assert_equal_arrays(concat_arrays(parts, N).arrays(), rec.finish().arrays())


def test_no_block_is_an_empty_log():
    log = concat_arrays([], N)
    assert len(log) == 0 and log.q.shape == (0, N)


def test_a_cleared_block_is_filled_again_from_its_first_row():
    rng = np.random.default_rng(7)
    block = SampleBlock(N, 3)
    _fill(rng, [block], LogRecorder(N), 3)
    block.clear()
    assert block.count == 0 and not block.full and block.status_names() == []
    rec = LogRecorder(N)
    _fill(rng, [block], rec, 2)
    _assert_equal_arrays(block.arrays(), rec.finish().arrays())


def test_bad_blocks_are_refused():
    with pytest.raises(ParameterError, match="at least 1 sample, got 0"):
        SampleBlock(N, 0)
    block = SampleBlock(N, 1)
    _fill(np.random.default_rng(8), [block], LogRecorder(N), 1)
    data = encode_block(block)
    other_layout = data.replace(b"dqcontrol.columns.v1", b"dqcontrol.columns.v9")
    for bad in (b"", data[:-1], other_layout):
        with pytest.raises(ParameterError, match="not a dqcontrol sample block"):
            decode_block(bad)

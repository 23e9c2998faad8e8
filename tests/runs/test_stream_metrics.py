"""dqcontrol/runs/stream_metrics.py: the metrics of a streamed run, block by block, against
``compute_metrics`` over the whole loaded log, and the exact selection behind its medians."""

from __future__ import annotations

import numpy as np

from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs import stream_metrics
from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.metrics import compute_metrics
from dqcontrol.runs.storage import load_run
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle


def _streamed(lbr4p, path, duration_s=1.0, **kwargs):
    controller = LocalController(lbr4p, Circle(duration_s), 0.01)
    return controller, run_kinematic(controller, LBR4P_Q0, log_file=path, **kwargs)


def _assert_metrics_close(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key, x in a.items():
        if isinstance(x, float):  # a JSON record holds NaN as None
            y = float("nan") if b[key] is None else b[key]
            np.testing.assert_allclose(y, x, rtol=1e-12, atol=1e-12, err_msg=key)
        else:
            assert b[key] == x, key


def test_metrics_from_the_file_equal_the_in_memory_ones(lbr4p, tmp_path):
    controller, streamed = _streamed(lbr4p, tmp_path / "run.mcap")
    log, record = load_run(streamed.log_file)
    direct = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), 0.01)
    _assert_metrics_close(direct.as_dict(), streamed.metrics.as_dict())
    _assert_metrics_close(direct.as_dict(), record["metrics"])


def test_exact_medians_without_keeping_the_values(lbr4p, tmp_path, monkeypatch):
    """Beyond MEDIAN_KEEP samples the medians come from a selection over the bit patterns."""
    monkeypatch.setattr(stream_metrics, "MEDIAN_KEEP", 7)
    controller, streamed = _streamed(lbr4p, tmp_path / "run.mcap")
    log, _ = load_run(streamed.log_file)
    direct = compute_metrics(log, controller.trajectory, bounds_of(controller, log.q), 0.01)
    assert streamed.metrics.step_time_median_s == direct.step_time_median_s
    assert streamed.metrics.solve_time_median_s == direct.solve_time_median_s


def test_selection_finds_every_rank_with_negative_values():
    rng = np.random.default_rng(7)
    values = np.concatenate((rng.normal(size=300), [0.0, -0.0, 1e-300, -5.0, 5.0, 5.0]))
    blocks = [{"v": part, "w": -part} for part in np.array_split(values, 7)]
    ranks = (0, 1, 150, 305)
    wanted = [(name, rank) for name in ("v", "w") for rank in ranks]
    found = stream_metrics._select(lambda: iter(blocks), wanted)
    assert found == [*np.sort(values)[list(ranks)], *np.sort(-values)[list(ranks)]]

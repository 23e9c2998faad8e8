"""``dqcontrol.experiments.sweep``: results in case order whatever the submission order, records
saved as they arrive, finished cases kept on Ctrl-C, against hand-made jobs in this process."""

from __future__ import annotations

import json

import pytest

from dqcontrol.experiments.executor import Executor
from dqcontrol.experiments.sweep import run_indexed, sweep


def _square(case: int) -> int:
    return case * case


def test_run_indexed_keeps_the_index():
    assert run_indexed((4, 3), _square) == (4, 9)


def test_results_come_back_in_case_order_whatever_the_order_of_submission():
    seen = []
    outcome = sweep(
        _square, [1, 2, 3, 4], Executor(1), order=[3, 0, 2, 1],
        on_result=lambda i, r: seen.append((i, r)),
    )  # fmt: skip
    assert seen == [(3, 16), (0, 1), (2, 9), (1, 4)]  # as they finished
    assert outcome.results == [1, 4, 9, 16] and outcome.indices == [0, 1, 2, 3]
    assert not outcome.interrupted and outcome.wall_time_s >= 0.0


def test_each_record_is_saved_as_plain_json_under_the_case_s_name(tmp_path):
    folder = tmp_path / "records"
    outcome = sweep(
        _square, [2, 5], Executor(1), name=lambda c: f"case_{c}",
        record=lambda r: {"value": r, "half": r / 2}, record_dir=folder,
    )  # fmt: skip
    assert outcome.results == [4, 25]
    assert sorted(p.name for p in folder.iterdir()) == ["case_2.json", "case_5.json"]
    assert json.loads((folder / "case_5.json").read_text()) == {"value": 25, "half": 12.5}


def test_without_a_folder_nothing_is_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sweep(_square, [1], Executor(1), record=lambda r: {"value": r})
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_keeps_the_finished_cases():
    def stop_at_the_third(index, result):
        if index == 2:
            raise KeyboardInterrupt

    outcome = sweep(_square, [1, 2, 3, 4], Executor(1), on_result=stop_at_the_third)
    assert outcome.interrupted and outcome.results == [1, 4, 9] and outcome.indices == [0, 1, 2]


def test_other_errors_propagate():
    def failing(case):
        raise ValueError(f"case {case} failed")

    with pytest.raises(ValueError, match="case 1 failed"):
        sweep(failing, [1, 2], Executor(1))

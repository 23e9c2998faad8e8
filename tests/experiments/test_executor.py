"""``dqcontrol.experiments.executor``: the executor for a number of cases, its labels and errors,
jobs run in this process, and one BLAS thread per worker of the pool and of a local Dask cluster."""

from __future__ import annotations

import os

import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.experiments.executor import (
    LOCAL_SCHEDULER,
    THREAD_VARIABLES,
    Executor,
    progress_bar,
    resolve_executor,
    run_jobs,
    single_threaded_children,
)


@pytest.mark.parametrize("scheduler", [None, "local"])
def test_workers_run_one_blas_thread_each(monkeypatch, scheduler):
    """The pool's and the local Dask cluster's workers see one BLAS/OpenMP thread (the
    variables are set for the workers only, and restored here)."""
    import functools

    from dqcontrol.experiments.executor import THREAD_VARIABLES, Executor, run_jobs

    if scheduler:
        pytest.importorskip("dask.distributed")
    for variable in THREAD_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    seen = []
    job = functools.partial(os.getenv, default="unset")
    run_jobs(job, list(THREAD_VARIABLES), Executor(2, scheduler), seen.append)
    assert seen == ["1"] * len(THREAD_VARIABLES)
    assert all(v not in os.environ for v in THREAD_VARIABLES)


@pytest.mark.parametrize("workers", [0, -2, 1.5, True, "4"], ids=repr)
def test_workers_must_be_a_positive_integer(workers):
    with pytest.raises(ParameterError, match="workers must be an integer ≥ 1"):
        resolve_executor(workers, None, 10)


def test_workers_are_capped_at_the_cases_and_a_scheduler_must_be_an_address():
    assert resolve_executor(8, None, 3) == Executor(workers=3)
    assert resolve_executor(8, None, 0) == Executor(workers=1)
    assert resolve_executor(2, "tcp://h:8786", 5) == Executor(2, "tcp://h:8786")
    with pytest.raises(ParameterError, match="scheduler must be an address"):
        resolve_executor(2, "  ", 5)


def test_labels():
    assert Executor().label == "in-process (1 worker)"
    assert Executor(4).label == "process pool, 4 workers"
    assert Executor(3, LOCAL_SCHEDULER).label == (
        "Dask distributed, local cluster of 3 worker processes"
    )
    assert Executor(3, "tcp://h:8786").label == "Dask distributed at tcp://h:8786"


def test_one_worker_runs_the_jobs_here_in_order():
    seen = []
    run_jobs(lambda case: case * case, [3, 1, 2], Executor(1), seen.append)
    assert seen == [9, 1, 4]


def test_the_children_s_thread_variables_leave_the_user_s_alone(monkeypatch):
    first, *others = THREAD_VARIABLES
    monkeypatch.setenv(first, "4")
    for variable in others:
        monkeypatch.delenv(variable, raising=False)
    with single_threaded_children():
        assert os.environ[first] == "4"
        assert all(os.environ[v] == "1" for v in others)
    assert os.environ[first] == "4" and not any(v in os.environ for v in others)


def test_the_progress_bar_writes_to_stderr_only_when_enabled(capsys):
    for enabled in (False, True):
        bar = progress_bar(3, "cases", enabled=enabled)
        bar.update(2)
        bar.set_postfix_str("circle_T1s_local", refresh=False)
        bar.close()
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("cases") >= 1
    assert "2/3" in captured.err


def test_disabled_the_progress_bar_is_silent(capsys):
    bar = progress_bar(3, "cases", enabled=False)
    bar.update(3)
    bar.close()
    assert capsys.readouterr().err == ""

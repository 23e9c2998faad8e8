"""A sweep: every case of an experiment through one job on an executor, the results put back
in case order, each one optionally saved the moment it arrives.

Table 1 (:func:`~dqcontrol.experiments.table1.run_table1`), the fault campaign
(:func:`~dqcontrol.faults.campaign.run_cases`) and studies
(:func:`~dqcontrol.studies.run_study`) run their cases through :func:`sweep`; where the
cases run is the :class:`~dqcontrol.experiments.executor.Executor`'s business.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dqcontrol.experiments.executor import Executor, progress_bar, run_jobs

__all__ = ["SweepOutcome", "run_indexed", "sweep"]


@dataclass(frozen=True)
class SweepOutcome:
    """The finished cases of a sweep.

    Attributes:
        results: the results of the cases that finished, in case order.
        indices: their indices in the case list.
        interrupted: whether Ctrl-C (a ``KeyboardInterrupt``, also one raised by a
            callback) stopped the sweep before every case finished.
        wall_time_s: wall time of the sweep [s].
    """

    results: list[Any]
    indices: list[int]
    interrupted: bool
    wall_time_s: float


def run_indexed(item: tuple[int, Any], job: Callable[[Any], Any]) -> tuple[int, Any]:
    """``(i, job(case))`` for ``item = (i, case)``: the job an executor runs, so that results
    arriving in completion order go back to their place."""
    index, case = item
    return index, job(case)


def sweep(
    job: Callable[[Any], Any],
    cases: Sequence[Any],
    executor: Executor,
    *,
    order: Sequence[int] | None = None,
    on_result: Callable[[int, Any], None] | None = None,
    name: Callable[[Any], str] = str,
    progress: str | None = None,
    record: Callable[[Any], dict] | None = None,
    record_dir: str | Path | None = None,
) -> SweepOutcome:
    """Run ``job(case)`` for every case on ``executor``.

    Args:
        job: a picklable callable of one case (see :mod:`dqcontrol.experiments.executor`).
        cases: the cases, each given to ``job``.
        executor: where the cases run.
        order: the order in which the cases are submitted (indices; default: as given).
        on_result: called as ``on_result(index, result)`` in this process as each case
            finishes (after its record is saved).
        name: a case's file-name friendly name (progress bar, record files).
        progress: the progress bar's description, or ``None`` for no bar.
        record: with ``record_dir``, each finished case's ``record(result)`` (plain JSON
            data) is written at once, atomically, to ``record_dir/<name(case)>.json``.
        record_dir: the folder of those files.

    A ``KeyboardInterrupt`` stops the sweep: the finished cases are kept and returned with
    ``interrupted`` set; any other exception propagates.
    """
    results: dict[int, Any] = {}
    folder = _record_folder(record, record_dir)
    bar = progress_bar(len(cases), progress or "", progress is not None)

    def on_done(item: tuple[int, Any]) -> None:
        index, result = item
        results[index] = result
        label = name(cases[index])
        if folder is not None and record is not None:
            _save_record(folder / f"{label}.json", record(result))
        bar.set_postfix_str(label, refresh=False)
        bar.update(1)
        if on_result is not None:
            on_result(index, result)

    indices = range(len(cases)) if order is None else order
    items = [(i, cases[i]) for i in indices]
    start = time.perf_counter()
    interrupted = False
    try:
        run_jobs(_bind(job), items, executor, on_done)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
    done = sorted(results)
    return SweepOutcome([results[i] for i in done], done, interrupted, time.perf_counter() - start)


def _record_folder(record, record_dir: str | Path | None) -> Path | None:
    """The folder of the cases' records (made if missing), or ``None`` without records."""
    if record is None or record_dir is None:
        return None
    folder = Path(record_dir)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _save_record(path: Path, data: dict) -> None:
    """``data`` (plain JSON data) written to ``path`` at once, atomically."""
    from dqcontrol.runs.storage import atomic_write_text, jsonable

    text = json.dumps(jsonable(data), indent=1, allow_nan=False)
    atomic_write_text(path, text + "\n")


def _bind(job: Callable[[Any], Any]) -> Callable[[tuple[int, Any]], tuple[int, Any]]:
    import functools

    return functools.partial(run_indexed, job=job)

"""Streamed runs as a whole: ending one (metrics from its file, then the end record) and
loading one back, in full or decimated for display.

A run's ``.mcap`` (:mod:`dqcontrol.runs.mcap_log`) loads as a
:class:`~dqcontrol.runs.log.RunLog` and a record shaped as the ``.json`` of
:func:`~dqcontrol.runs.storage.save_run` (``meta``, ``metrics``, ``interrupted``, ``note``),
plus ``complete``: ``False`` for a file cut short (no end record), whose record then says
so in ``note`` and has ``interrupted = True`` and no metrics.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable

import numpy as np

from dqcontrol.runs.columns import concat_arrays
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.mcap_log import RUN_FORMAT, RunLogWriteError, StreamedRun, read_streamed
from dqcontrol.runs.metrics import BoundSpec, Metrics, run_figures
from dqcontrol.runs.stream import StreamRecorder
from dqcontrol.runs.stream_metrics import streamed_metrics
from dqcontrol.trajectories import Trajectory

__all__ = ["end_streamed", "load_streamed"]


def end_streamed(
    rec: StreamRecorder,
    trajectory: Trajectory,
    bounds_for: Callable[[np.ndarray], BoundSpec],
    period_s: float,
    status: tuple[bool, str],
) -> tuple[RunLog, Metrics | None, str]:
    """Write the last samples, compute the metrics from the file, write the end record.

    Args:
        rec: the run's recorder (its ``meta`` complete: stop record, driver report, note).
        trajectory: the anchored trajectory the controller used.
        bounds_for: the bounds for a block's joint positions (as
            :func:`~dqcontrol.runs.stream_metrics.streamed_metrics`).
        period_s: the control period T [s].
        status: ``(interrupted, note)`` of the run.

    Returns:
        The window of recent samples (with ``meta``), the metrics (``None`` if the file
        could not be written or read back) and ``""`` or why the log is incomplete.
    """
    interrupted, note = status
    window = rec.window()
    try:
        rec.drain()
        run = read_streamed_for_metrics(rec)
        metrics = streamed_metrics(run.blocks, trajectory, bounds_for, period_s)
        metrics = dataclasses.replace(metrics, **run_figures(rec.meta))
        end = {
            "meta": rec.meta,
            "metrics": metrics.as_dict(),
            "interrupted": bool(interrupted),
            "note": str(note),
            "samples": len(rec),
        }
        rec.close(end)
    except RunLogWriteError as exc:
        _close_quietly(rec)
        return window, None, str(exc)
    return window, metrics, ""


def read_streamed_for_metrics(rec: StreamRecorder) -> StreamedRun:
    """The file being written, scanned up to its last block (all drained)."""
    try:
        return read_streamed(rec.path)
    except OSError as exc:
        raise RunLogWriteError(f"cannot read back the run log {rec.path}: {exc}") from None


def _close_quietly(rec: StreamRecorder) -> None:
    try:
        rec.close(None)
    except RunLogWriteError:
        pass


def _stride(samples: int, max_samples: int | None) -> int:
    if max_samples is None or samples <= max_samples:
        return 1
    return int(math.ceil(samples / max_samples))


def load_streamed(path: str | os.PathLike, max_samples: int | None = None) -> tuple[RunLog, dict]:
    """A streamed run's log and record (see the module docstring).

    Args:
        path: the run's ``.mcap``.
        max_samples: keep every k-th sample so that at most this many are loaded (the
            last sample is always kept); ``None``: all of them.
    """
    run = read_streamed(path)
    stride = _stride(run.samples, max_samples)
    parts, seen = [], 0
    for block in run.blocks():
        count = len(block["t_s"])
        if stride > 1:
            rows = np.arange((-seen) % stride, count, stride)
            if seen + count == run.samples and (not rows.size or rows[-1] != count - 1):
                rows = np.append(rows, count - 1)
            block = {k: v[rows] for k, v in block.items()}
        parts.append(block)
        seen += count
    log = concat_arrays(parts, run.num_joints)
    return log, _record(run, log, stride)


def _record(run: StreamedRun, log: RunLog, stride: int) -> dict:
    """The run's record, shaped as a ``.json`` run record (see the module docstring)."""
    end = run.end or {}
    meta = dict(end.get("meta") or run.meta)
    log.meta = meta
    record = {
        "format": RUN_FORMAT,
        "name": run.path.stem,
        "log": run.path.name,
        "meta": meta,
        "metrics": end.get("metrics"),
        "interrupted": bool(end.get("interrupted", True)),
        "note": str(end.get("note", "")),
        "complete": run.complete,
        "samples": run.samples,
        "stride": stride,
    }
    if not run.complete:
        cut = (
            f"the run log was cut short: {run.samples} samples up to its last complete "
            "chunk (the process ended before the run did)"
        )
        record["note"] = f"{cut}; {record['note']}" if record["note"] else cut
        record["interrupted"] = True
    return record

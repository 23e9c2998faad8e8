"""The streamed recorder: the run log goes to disk block by block while the run goes on.

:class:`StreamRecorder` records like :class:`~dqcontrol.runs.log.LogRecorder` but keeps
only two blocks of samples in memory (the one being filled and the one before it: the
window the live view and the end of the run see). A full block is encoded on the control
thread (a copy of its columns) and handed to the writer thread of
:class:`~dqcontrol.runs.mcap_log.McapRunWriter`, which compresses, writes, flushes and
syncs it off the control step. A block is at most ``chunk_s`` of samples (1 s by
default), so a crash loses at most that much.
"""

from __future__ import annotations

import math
import os

import numpy as np

from dqcontrol.controllers.base import StepResult
from dqcontrol.errors import ParameterError
from dqcontrol.runs.columns import SampleBlock, concat_arrays, encode_block
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.mcap_log import McapRunWriter
from dqcontrol.runs.preview import preview_stride

__all__ = ["DEFAULT_CHUNK_S", "StreamRecorder"]

#: Longest stretch of samples [s] in one chunk (what a crash can lose).
DEFAULT_CHUNK_S = 1.0


def block_capacity(period_s: float, chunk_s: float) -> int:
    """Samples per block: ``chunk_s / period_s`` rounded down, at least 1."""
    if not (chunk_s > 0.0 and math.isfinite(chunk_s)):
        raise ParameterError(f"chunk_s must be a finite duration > 0 [s], got {chunk_s!r}")
    return max(1, int(math.floor(chunk_s / period_s + 1e-9)))


class StreamRecorder:
    """Records samples to ``path`` (an MCAP run log) in blocks of ≤ ``chunk_s`` [s].

    Args:
        path: the ``.mcap`` file to write (its folder is created).
        num_joints: n.
        period_s: the control period T [s].
        meta: the run's description, written at the start of the file.
        chunk_s: longest stretch of samples in one block [s].
        fsync: sync the file after every block (survives a power cut, not only a crash).
        preview: also publish about 50 samples a second as JSON for viewers such as
            Foxglove (:mod:`dqcontrol.runs.preview`), written by the writer thread.

    Raises:
        RunLogWriteError: the file cannot be created.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        num_joints: int,
        period_s: float,
        meta: dict | None = None,
        *,
        chunk_s: float = DEFAULT_CHUNK_S,
        fsync: bool = True,
        preview: bool = True,
    ) -> None:
        capacity = block_capacity(period_s, chunk_s)
        self.n = num_joints
        self.meta = dict(meta or {})
        self._current = SampleBlock(num_joints, capacity)
        self._previous = SampleBlock(num_joints, capacity)
        self._done = 0  # samples handed to the writer
        stride = preview_stride(period_s) if preview else 0
        self.writer = McapRunWriter(path, self.meta, fsync=fsync, preview_stride=stride)
        self.path = self.writer.path

    def __len__(self) -> int:
        return self._done + self._current.count

    def record(
        self,
        t_s: float,
        q: np.ndarray,
        qd_measured: np.ndarray,
        result: StepResult,
        torque: np.ndarray | None = None,
        torque_peak: np.ndarray | None = None,
        stopping: bool = False,
    ) -> None:
        """Append one sample (as :meth:`~dqcontrol.runs.log.LogRecorder.record`).

        Raises:
            RunLogWriteError: an earlier block could not be written.
        """
        block = self._current
        block.record(t_s, q, qd_measured, result, torque, torque_peak, stopping)
        if block.full:
            self._hand_off()

    def _hand_off(self) -> None:
        """Encode the current block for the writer thread and start the next one."""
        block = self._current
        if not block.count:
            return
        first_ns = max(0, int(round(float(block.columns["t_s"][0]) * 1e9)))
        data = encode_block(block)
        self._done += block.count
        self._current, self._previous = self._previous, block
        self._current.clear()
        self.writer.put_block(first_ns, data)

    def window(self) -> RunLog:
        """The recent samples still in memory (between one and two blocks), with ``meta``."""
        parts = [b.arrays() for b in (self._previous, self._current) if b.count]
        log = concat_arrays(parts, self.n)
        log.meta = self.meta
        return log

    def drain(self) -> None:
        """Hand the last samples to the writer and wait until all are on disk.

        Raises:
            RunLogWriteError: something could not be written.
        """
        self._hand_off()
        self.writer.drain()

    def close(self, end: dict | None) -> None:
        """Write the last samples and (``end`` not ``None``) the end record; close the file.

        Raises:
            RunLogWriteError: something could not be written.
        """
        try:
            self._hand_off()
        finally:
            self.writer.close(end)

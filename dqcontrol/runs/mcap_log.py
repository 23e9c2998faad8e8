"""The streamed run log on disk: an MCAP file written block by block, read back tolerantly.

Layout of a run's ``.mcap`` (docs/run_logs.md):

* a Metadata record ``dqcontrol.run`` (``format``, ``version``, ``meta`` as JSON text);
* channel ``/dqcontrol/run`` (JSON messages): ``{"kind": "start", "meta": ...}`` first and,
  when the run ends normally, ``{"kind": "end", "meta", "metrics", "interrupted", "note",
  "samples"}`` last;
* channel ``/dqcontrol/samples``: one message per block of samples
  (:func:`~dqcontrol.runs.columns.encode_block`), each flushed as its own MCAP chunk;
* channel ``/dqcontrol/preview`` (JSON, optional): every k-th sample, for viewers
  (:mod:`dqcontrol.runs.preview`), in the chunk of its block.

A file cut short (SIGKILL, power cut) has no end record and no MCAP footer; the reader
keeps every complete chunk before the cut and flags the run incomplete.
"""

from __future__ import annotations

import json
import os
import queue
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from dqcontrol import __version__
from dqcontrol.errors import DQControlError, ParameterError
from dqcontrol.runs.columns import BLOCK_LAYOUT, decode_block
from dqcontrol.runs.preview import PREVIEW_SCHEMA, preview_messages

__all__ = ["McapRunWriter", "RunLogWriteError", "StreamedRun", "read_streamed"]

#: Value of the metadata's ``format`` (shared with the ``.json`` run record).
RUN_FORMAT = "dqcontrol-run"
STREAM_VERSION = "2"
SAMPLES_TOPIC = "/dqcontrol/samples"
PREVIEW_TOPIC = "/dqcontrol/preview"
RUN_TOPIC = "/dqcontrol/run"


class RunLogWriteError(DQControlError):
    """The run log could not be written (full disk, unwritable folder, …)."""


def _json_bytes(record: dict) -> bytes:
    from dqcontrol.runs.storage import jsonable

    return json.dumps(jsonable(record), allow_nan=False).encode("utf-8")


def _write_failure(path: Path, exc: BaseException) -> RunLogWriteError:
    return RunLogWriteError(
        f"cannot write the run log {path}: {exc.__class__.__name__}: {exc} (free disk space "
        "or choose a writable folder)"
    )


class McapRunWriter:
    """Writes a run's ``.mcap``: blocks go through a queue to a writer thread, which adds
    each as one message, flushes it as a complete chunk and (``fsync``) syncs the file.

    With ``preview_stride`` k > 0 it also publishes every k-th sample as JSON
    (:mod:`dqcontrol.runs.preview`). The first failed write is kept in :attr:`error`;
    :meth:`put_block` raises it.
    """

    def __init__(
        self, path: str | os.PathLike, meta: dict, *, fsync: bool = True, preview_stride: int = 0
    ) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self.fsync = fsync
        self.preview_stride = preview_stride
        self._sequence = self._written = 0
        self.error: RunLogWriteError | None = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: IO[bytes] = open(self.path, "wb")  # noqa: SIM115 - closed in close()
            self._writer = Writer(self._file, compression=CompressionType.ZSTD)
            self._writer.start(profile="", library=f"dqcontrol {__version__}")
            self._writer.add_metadata(
                "dqcontrol.run",
                {
                    "format": RUN_FORMAT,
                    "version": STREAM_VERSION,
                    "meta": _json_bytes(meta).decode(),
                },
            )
            run_schema = self._writer.register_schema(
                "dqcontrol.RunRecord", "jsonschema", b'{"type": "object"}'
            )
            self._run_channel = self._writer.register_channel(RUN_TOPIC, "json", run_schema)
            self._sample_channel = self._writer.register_channel(
                SAMPLES_TOPIC, BLOCK_LAYOUT, 0, {"layout": BLOCK_LAYOUT}
            )
            preview_schema = self._writer.register_schema(
                "dqcontrol.Sample", "jsonschema", json.dumps(PREVIEW_SCHEMA).encode("utf-8")
            )
            self._preview_channel = self._writer.register_channel(
                PREVIEW_TOPIC, "json", preview_schema
            )
            self._add(self._run_channel, 0, _json_bytes({"kind": "start", "meta": meta}))
            self._sync()
        except OSError as exc:
            if hasattr(self, "_file"):
                self._file.close()
            raise _write_failure(self.path, exc) from None
        self._queue: queue.Queue[tuple[int, bytes] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._drain, name="dqcontrol-runlog", daemon=True)
        self._thread.start()

    def _add(self, channel: int, time_ns: int, data: bytes, flush: bool = True) -> None:
        self._sequence += 1
        self._writer.add_message(channel, time_ns, data, time_ns, self._sequence)
        if flush:
            self._writer.flush()

    def _add_block(self, time_ns: int, data: bytes) -> None:
        """The block's preview messages (if any) and the block, as one flushed chunk."""
        arrays = decode_block(data) if self.preview_stride else None
        if arrays is not None:
            for preview_ns, message in preview_messages(arrays, self._written, self.preview_stride):
                self._add(self._preview_channel, preview_ns, message, flush=False)
            self._written += len(arrays["t_s"])
        self._add(self._sample_channel, time_ns, data)

    def _sync(self) -> None:
        self._file.flush()
        if self.fsync:
            os.fsync(self._file.fileno())

    def _drain(self) -> None:
        """The writer thread: each queued block becomes one flushed chunk, until ``None``."""
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self.error is not None:
                continue
            try:
                self._add_block(*item)
                self._sync()
            except (OSError, ValueError) as exc:
                self.error = _write_failure(self.path, exc)

    def put_block(self, time_ns: int, data: bytes) -> None:
        """Queue one encoded block (stamped ``time_ns``, its first sample's time [ns]).

        Raises:
            RunLogWriteError: an earlier block could not be written.
        """
        if self.error is not None:
            raise self.error
        self._queue.put((time_ns, data))

    def drain(self) -> None:
        """Wait until every queued block is written (the writer thread then ends).

        Raises:
            RunLogWriteError: a block could not be written.
        """
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        if self.error is not None:
            raise self.error

    def close(self, end: dict | None) -> None:
        """Write the queued blocks, then (``end`` not ``None``) the end record and the MCAP
        summary; close the file.

        Raises:
            RunLogWriteError: a block, the end record or the summary could not be written.
        """
        try:
            self.drain()
            if end is not None:
                self._add(self._run_channel, 0, _json_bytes({"kind": "end", **end}))
                self._writer.finish()
                self._sync()
        except (OSError, ValueError) as exc:
            self.error = self.error or _write_failure(self.path, exc)
        finally:
            try:
                self._file.close()
            except OSError as exc:
                self.error = self.error or _write_failure(self.path, exc)
        if self.error is not None:
            raise self.error


@dataclass
class StreamedRun:
    """What a streamed run's file holds: its start ``meta``, the end record (``None`` when
    the file was cut short), whether it is complete, and where its blocks are."""

    path: Path
    meta: dict
    end: dict | None
    complete: bool
    samples: int
    num_joints: int
    problems: list[str] = field(default_factory=list)

    def blocks(self) -> Iterator[dict[str, np.ndarray]]:
        """The sample blocks in order, each as arrays by field (one pass over the file)."""
        for kind, payload in _records(self.path, self.problems):
            if kind == "block":
                yield decode_block(payload)


def _records(path: Path, problems: list[str]) -> Iterator[tuple[str, bytes]]:
    """``("run" | "block" | "footer", payload)`` in file order, stopping quietly at a cut;
    what stopped it is appended to ``problems``."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Footer, Message
    from mcap.stream_reader import StreamReader

    topics: dict[int, str] = {}
    with open(path, "rb") as fh:
        reader = StreamReader(fh, validate_crcs=True)
        try:
            for record in reader.records:
                if isinstance(record, Channel):
                    topics[record.id] = record.topic
                elif isinstance(record, Message):
                    topic = topics.get(record.channel_id)
                    if topic == SAMPLES_TOPIC:
                        yield "block", record.data
                    elif topic == RUN_TOPIC:
                        yield "run", record.data
                elif isinstance(record, Footer):
                    yield "footer", b""
        except (McapError, ValueError, OSError, EOFError) as exc:
            problems.append(f"{type(exc).__name__}: {exc}".rstrip(": "))


def read_streamed(path: str | os.PathLike) -> StreamedRun:
    """Scan a run's ``.mcap`` once: its meta, end record, sample count and completeness.

    Raises:
        ParameterError: the file is not a dqcontrol streamed run (or holds no start record).
    """
    p = Path(path)
    problems: list[str] = []
    start, end, footer, samples, num_joints = None, None, False, 0, 0
    for kind, payload in _records(p, problems):
        if kind == "run":
            record = json.loads(bytes(payload).decode("utf-8"))
            if record.get("kind") == "start":
                start = record
            elif record.get("kind") == "end":
                end = record
        elif kind == "block":
            header = _block_header(payload)
            samples += int(header["count"])
            num_joints = int(header["num_joints"])
        else:
            footer = True
    if start is None:
        why = f" ({problems[0]})" if problems else ""
        raise ParameterError(f"{p} is not a dqcontrol run log (no start record){why}")
    meta = dict(start.get("meta") or {})
    num_joints = num_joints or len(meta.get("joint_names") or [])
    complete = end is not None and footer and not problems
    return StreamedRun(p, meta, end, complete, samples, num_joints, problems)


def _block_header(payload: bytes) -> dict:
    view = memoryview(payload)
    size = int.from_bytes(view[:4], "little")
    return json.loads(bytes(view[4 : 4 + size]).decode("utf-8"))

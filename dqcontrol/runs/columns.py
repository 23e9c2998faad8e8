"""A block of run-log samples in preallocated columns, and its bytes on disk.

A :class:`SampleBlock` holds up to ``capacity`` consecutive samples, one preallocated
array per :class:`~dqcontrol.runs.log.RunLog` field, so that recording a sample is a few
row copies and no allocation (the streamed log's hot path, docs/run_logs.md). A full block
is turned into bytes by :func:`encode_block` and back by :func:`decode_block`:

* a little-endian ``uint32``: the length ``H`` of the header;
* the header, ``H`` bytes of UTF-8 JSON: ``{"count": K, "num_joints": n, "status": [...],
  "fields": [[name, dtype, columns], ...]}``;
* each field's ``K × columns`` values, C order, little-endian, in the header's order.

The solver status strings are stored as ``uint16`` indices into the header's ``status``
list (the distinct statuses of the block).
"""

from __future__ import annotations

import json
import struct

import numpy as np

from dqcontrol.controllers.base import StepResult
from dqcontrol.errors import ParameterError
from dqcontrol.runs.log import NO_PLAN, STREAM_FIELDS, RunLog, stream_values

__all__ = ["SampleBlock", "decode_block", "encode_block", "field_layout"]

#: Name of the block layout (stored in the file, checked when reading).
BLOCK_LAYOUT = "dqcontrol.columns.v1"
_STATUS_FIELD = "solver_status"


def field_layout(num_joints: int) -> list[tuple[str, str, int]]:
    """``(name, dtype, columns)`` of every stored field (``columns`` 0: one value a sample)."""
    n = num_joints
    return [
        ("t_s", "<f8", 0),
        ("sigma", "<f8", 0),
        ("s", "<f8", 0),
        ("q", "<f8", n),
        ("qd_measured", "<f8", n),
        ("qd_command", "<f8", n),
        ("torque", "<f8", n),
        ("torque_peak", "<f8", n),
        ("pose", "<f8", 8),
        ("target", "<f8", 8),
        (_STATUS_FIELD, "<u2", 0),
        ("iterations", "<i8", 0),
        ("solve_time_s", "<f8", 0),
        ("step_time_s", "<f8", 0),
        ("fallback", "|b1", 0),
        ("relaxed", "|b1", 0),
        ("saturated", "|b1", 0),
        ("stopping", "|b1", 0),
    ]


def _empty(dtype: str, columns: int, rows: int) -> np.ndarray:
    return np.zeros((rows, columns) if columns else rows, dtype=np.dtype(dtype))


class SampleBlock:
    """Up to ``capacity`` samples in preallocated columns (see the module docstring)."""

    def __init__(self, num_joints: int, capacity: int) -> None:
        if capacity < 1:
            raise ParameterError(f"a sample block holds at least 1 sample, got {capacity}")
        self.num_joints, self.capacity = num_joints, capacity
        self.layout = field_layout(num_joints)
        self.columns = {name: _empty(dt, cols, capacity) for name, dt, cols in self.layout}
        self.count = 0
        self.statuses: dict[str, int] = {}
        self._nan_row = np.full(num_joints, np.nan)

    @property
    def full(self) -> bool:
        """Whether every row holds a sample."""
        return self.count >= self.capacity

    def clear(self) -> None:
        """Forget the samples (the arrays are kept for the next ones)."""
        self.count = 0
        self.statuses = {}

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
        """Write one sample in the next row (as :meth:`~dqcontrol.runs.log.LogRecorder.record`)."""
        k, c, d = self.count, self.columns, result.diagnostics
        c["t_s"][k] = t_s
        c["sigma"][k] = result.sigma
        c["s"][k] = result.s
        c["q"][k] = q
        c["qd_measured"][k] = qd_measured
        c["qd_command"][k] = result.qd_command
        c["torque"][k] = self._nan_row if torque is None else torque
        c["torque_peak"][k] = self._nan_row if torque_peak is None else torque_peak
        c["pose"][k] = result.pose
        c["target"][k] = result.target
        code = self.statuses.get(d.status)
        if code is None:
            code = self.statuses[d.status] = len(self.statuses)
        c[_STATUS_FIELD][k] = code
        c["iterations"][k] = d.iterations
        c["solve_time_s"][k] = d.solve_time_s
        c["step_time_s"][k] = d.step_time_s
        c["fallback"][k] = d.fallback
        c["relaxed"][k] = d.relaxed
        c["saturated"][k] = d.saturated
        stream = stream_values(result)
        if stream is not None or "plan_id" in c:
            self._record_stream(k, stream or NO_PLAN)
        c["stopping"][k] = stopping
        self.count = k + 1

    def _record_stream(self, k: int, values: tuple[int, float, float]) -> None:
        """A streamed controller's plan id, plan age and lateness: their columns are made
        at its first sample (the samples before it :data:`NO_PLAN`'s)."""
        c = self.columns
        if "plan_id" not in c:
            for name, dt in (("plan_id", "<i8"), ("plan_age_s", "<f8"), ("lateness_s", "<f8")):
                self.layout.append((name, dt, 0))
                c[name] = _empty(dt, 0, self.capacity)
            for name, missing in zip(STREAM_FIELDS, NO_PLAN, strict=True):
                c[name][:k] = missing
        c["plan_id"][k], c["plan_age_s"][k], c["lateness_s"][k] = values

    def status_names(self) -> list[str]:
        """The block's distinct solver statuses, in the order of their codes."""
        return sorted(self.statuses, key=self.statuses.__getitem__)

    def arrays(self, start: int = 0) -> dict[str, np.ndarray]:
        """Copies of samples ``start..count`` as :meth:`RunLog.arrays` (statuses as text)."""
        out = {name: arr[start : self.count].copy() for name, arr in self.columns.items()}
        names = np.array(self.status_names() or [""], dtype="U32")
        out[_STATUS_FIELD] = names[out[_STATUS_FIELD]]
        return out


def encode_block(block: SampleBlock) -> bytes:
    """The bytes of ``block``'s samples (layout in the module docstring)."""
    k = block.count
    header = {
        "layout": BLOCK_LAYOUT,
        "count": k,
        "num_joints": block.num_joints,
        "status": block.status_names(),
        "fields": [[name, dt, cols] for name, dt, cols in block.layout],
    }
    head = json.dumps(header, separators=(",", ":")).encode("utf-8")
    parts = [struct.pack("<I", len(head)), head]
    parts += [
        np.ascontiguousarray(block.columns[name][:k]).tobytes() for name, _, _ in block.layout
    ]
    return b"".join(parts)


def decode_block(data: bytes | memoryview) -> dict[str, np.ndarray]:
    """The arrays of one encoded block, by field (statuses as text, ``U32``).

    Raises:
        ParameterError: the bytes are not a block of this layout (or are cut short).
    """
    view = memoryview(data)
    try:
        (size,) = struct.unpack_from("<I", view, 0)
        header = json.loads(bytes(view[4 : 4 + size]).decode("utf-8"))
        if header.get("layout") != BLOCK_LAYOUT:
            raise ValueError(f"layout {header.get('layout')!r}, expected {BLOCK_LAYOUT!r}")
        count, offset = int(header["count"]), 4 + size
        out: dict[str, np.ndarray] = {}
        for name, dt, cols in header["fields"]:
            dtype = np.dtype(dt)
            num = count * max(int(cols), 1)
            arr = np.frombuffer(view, dtype=dtype, count=num, offset=offset)
            out[name] = arr.reshape((count, int(cols)) if cols else count).astype(
                dtype.newbyteorder("=")
            )
            offset += num * dtype.itemsize
    except (ValueError, KeyError, TypeError, struct.error) as exc:
        raise ParameterError(f"not a dqcontrol sample block: {exc}") from None
    names = np.array(header["status"] or [""], dtype="U32")
    out[_STATUS_FIELD] = names[out[_STATUS_FIELD]]
    return out


def concat_arrays(parts: list[dict[str, np.ndarray]], num_joints: int) -> RunLog:
    """One :class:`RunLog` of consecutive blocks' arrays (an empty log if there are none)."""
    if not parts:
        empty = {name: _empty(dt, cols, 0) for name, dt, cols in field_layout(num_joints)}
        empty[_STATUS_FIELD] = np.zeros(0, dtype="U32")
        return RunLog.from_arrays(empty)
    names = list(dict.fromkeys(name for part in parts for name in part))
    merged = {name: np.concatenate([_column(p, name) for p in parts]) for name in names}
    merged[_STATUS_FIELD] = merged[_STATUS_FIELD].astype("U32")
    return RunLog.from_arrays(merged)


def _column(part: dict[str, np.ndarray], name: str) -> np.ndarray:
    """``part[name]``; a stream field a block does not have (no plan gave its samples) as
    :data:`NO_PLAN`'s value."""
    if name in part:
        return part[name]
    count = len(part["t_s"])
    value = NO_PLAN[STREAM_FIELDS.index(name)]
    return np.full(count, value, dtype=np.int64 if name == "plan_id" else float)

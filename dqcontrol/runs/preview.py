"""The display-rate preview of a streamed run log: one JSON message per k-th sample.

The samples themselves are stored in columnar blocks (:mod:`dqcontrol.runs.columns`),
which general MCAP viewers cannot decode. The writer thread also publishes every k-th
sample (about 50 per second) on ``/dqcontrol/preview`` as a JSON message with a JSON
schema, so that Foxglove can plot the joints, commands, scaling and errors of a run
directly (docs/run_logs.md). The preview is for viewing only; the readers never use it.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np

__all__ = ["PREVIEW_RATE_HZ", "PREVIEW_SCHEMA", "preview_messages", "preview_stride"]

#: About this many preview messages per second of run.
PREVIEW_RATE_HZ = 50.0

#: The JSON schema of a preview message (Foxglove offers its fields in plots).
PREVIEW_SCHEMA = {
    "type": "object",
    "properties": {
        "t_s": {"type": "number"},
        "sigma": {"type": "number"},
        "s": {"type": "number"},
        "q": {"type": "array", "items": {"type": "number"}},
        "qd_measured": {"type": "array", "items": {"type": "number"}},
        "qd_command": {"type": "array", "items": {"type": "number"}},
        "torque": {"type": "array", "items": {"type": ["number", "null"]}},
        "error": {"type": "number"},
        "solver_status": {"type": "string"},
        "step_time_s": {"type": "number"},
    },
}


def preview_stride(period_s: float) -> int:
    """Samples between two preview messages: about :data:`PREVIEW_RATE_HZ` a second."""
    return max(1, int(round(1.0 / (PREVIEW_RATE_HZ * period_s))))


def _finite_or_none(values: np.ndarray) -> list:
    return [float(v) if np.isfinite(v) else None for v in values]


def preview_messages(
    arrays: dict[str, np.ndarray], first_index: int, stride: int
) -> Iterator[tuple[int, bytes]]:
    """``(log time [ns], JSON bytes)`` of the block's samples whose run index is a multiple
    of ``stride`` (the block starts at run index ``first_index``)."""
    count = len(arrays["t_s"])
    rows = np.arange((-first_index) % stride, count, stride)
    error = np.linalg.norm(arrays["target"][rows] - arrays["pose"][rows], axis=1)
    for i, k in enumerate(rows):
        message = {
            "t_s": float(arrays["t_s"][k]),
            "sigma": float(arrays["sigma"][k]),
            "s": float(arrays["s"][k]),
            "q": arrays["q"][k].tolist(),
            "qd_measured": arrays["qd_measured"][k].tolist(),
            "qd_command": arrays["qd_command"][k].tolist(),
            "torque": _finite_or_none(arrays["torque"][k]),
            "error": float(error[i]),
            "solver_status": str(arrays["solver_status"][k]),
            "step_time_s": float(arrays["step_time_s"][k]),
        }
        time_ns = max(0, int(round(message["t_s"] * 1e9)))
        yield time_ns, json.dumps(message, allow_nan=True).encode("utf-8")

"""Run logs, metrics and the bounds a run is judged against (shared by every loop)."""

from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import LogRecorder, RunLog
from dqcontrol.runs.metrics import BoundSpec, Metrics, compute_metrics
from dqcontrol.runs.storage import atomic_write_bytes, atomic_write_text, load_run, save_run

__all__ = [
    "BoundSpec",
    "LogRecorder",
    "Metrics",
    "RunLog",
    "atomic_write_bytes",
    "atomic_write_text",
    "bounds_of",
    "compute_metrics",
    "load_run",
    "save_run",
]

"""Run logs, metrics and the bounds a run is judged against (shared by every loop)."""

from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.log import LogRecorder, RunLog
from dqcontrol.runs.metrics import BoundSpec, Metrics, compute_metrics

__all__ = ["BoundSpec", "LogRecorder", "Metrics", "RunLog", "bounds_of", "compute_metrics"]

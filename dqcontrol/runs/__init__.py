"""Run logs, metrics and the bounds a run is judged against (shared by every loop).

A log is kept in memory (:class:`LogRecorder`, saved as ``.npz`` + ``.json``) or streamed
to an MCAP file as the run goes (:class:`StreamRecorder`; docs/run_logs.md).
"""

from dqcontrol.runs.bounds import bounds_of
from dqcontrol.runs.check import check_run
from dqcontrol.runs.contacts import ContactKind, RunContacts, contacts_text, loaded_contacts
from dqcontrol.runs.log import LogRecorder, RunLog
from dqcontrol.runs.mcap_log import RunLogWriteError
from dqcontrol.runs.metrics import BoundSpec, Metrics, compute_metrics
from dqcontrol.runs.reflexes import CommandMonitor, Violation
from dqcontrol.runs.storage import atomic_write_bytes, atomic_write_text, load_run, save_run
from dqcontrol.runs.stream import StreamRecorder
from dqcontrol.runs.stream_metrics import streamed_metrics
from dqcontrol.runs.streamed_run import load_streamed

__all__ = [
    "BoundSpec",
    "ContactKind",
    "CommandMonitor",
    "LogRecorder",
    "Metrics",
    "RunContacts",
    "RunLog",
    "RunLogWriteError",
    "StreamRecorder",
    "Violation",
    "atomic_write_bytes",
    "atomic_write_text",
    "bounds_of",
    "check_run",
    "compute_metrics",
    "contacts_text",
    "load_run",
    "load_streamed",
    "loaded_contacts",
    "save_run",
    "streamed_metrics",
]

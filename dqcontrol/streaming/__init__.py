"""Plan at the rate the solve allows, stream the plan at the robot's rate (docs/theory.md
§12): :func:`streamed` wraps a path-following controller into a controller of period ``T``
whose commands come from plans solved every ``T_p``."""

from dqcontrol.streaming.plan import Plan
from dqcontrol.streaming.streamed import StreamDiagnostics, StreamedController, streamed
from dqcontrol.streaming.streamer import Streamer
from dqcontrol.streaming.tracker import JerkLimitedTracker

__all__ = [
    "JerkLimitedTracker",
    "Plan",
    "StreamDiagnostics",
    "StreamedController",
    "Streamer",
    "streamed",
]

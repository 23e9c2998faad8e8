"""What a closed loop does for a streamed controller (docs/theory.md §12.4): tell it the
clock (stepped or wall clock) before the first sample, stop its planner after the last, and
put its figures in the log's ``meta["stream"]``. Any other controller is left alone."""

from __future__ import annotations

__all__ = ["StreamHook", "stream_hook"]


class StreamHook:
    """The hook of one run (a no-op for a controller that is not streamed)."""

    def __init__(self, controller: object) -> None:
        self.controller = controller

    def close(self) -> None:
        """Stop the controller's planner thread, if it has one."""
        close = getattr(self.controller, "close", None)
        if callable(close):
            close()

    def meta(self) -> dict:
        """``{"stream": …}`` (:meth:`StreamedController.report`), or nothing."""
        report = getattr(self.controller, "report", None)
        return {"stream": report()} if callable(report) else {}


def stream_hook(controller: object, realtime: bool) -> StreamHook:
    """The hook of a run of ``controller``; a streamed one is switched to the wall clock
    (``realtime``: a planner thread) or to stepped planning."""
    from dqcontrol.streaming.streamed import StreamedController

    if isinstance(controller, StreamedController):
        controller.use_wall_clock(realtime)
        return StreamHook(controller)
    return StreamHook(None)

"""The end at rest of a task that ends at speed, streamed (docs/theory.md §8.10).

On the wall clock the rest-to-rest path-following controller that ends such a task cannot
take its first step within a period at 1 kHz (it linearises from scratch, several
milliseconds); stepped in the loop it would hold the arm's last command meanwhile. Here it
is prepared before the clock as a streamed controller (its planner process forked and
warmed up) and takes over at the handover without a synchronous solve: the task's own
controller keeps commanding until the first plan starts, and the plan's switch blends from
its last command (§12.3).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.controllers.stop_delegate import path_following_like
from dqcontrol.streaming.planner import choose_plan_period
from dqcontrol.streaming.streamed import StreamedController

if TYPE_CHECKING:  # pragma: no cover
    from dqcontrol.controllers.base import Controller

__all__ = ["end_plan_period_s", "end_stream"]


def end_plan_period_s(first_step_s: float, period_s: float) -> float:
    """The plan period [s] of a streamed end whose first step, timed in the caller's
    process, took ``first_step_s`` [s] (:func:`~dqcontrol.streaming.planner.
    choose_plan_period`'s margin and floor); ``inf`` where it was not measured."""
    if not math.isfinite(first_step_s):
        return math.inf
    return choose_plan_period([first_step_s], period_s)


def end_stream(
    controller: Controller, q0: np.ndarray, plan_period_s: float, wall_clock: bool = True
) -> StreamedController:
    """The streamed rest-to-rest end of ``controller``'s task (reset, at ``q0`` [rad]),
    planning every ``plan_period_s`` [s]: reset at ``q0`` (its first plan solved here, which
    loads its kernels) and, with ``wall_clock``, its planner process started and warmed up
    — all before the clock. Stepped (``wall_clock=False``) each plan starts one plan period
    after its measurement, as on the wall clock, and is solved in the caller's thread
    (deterministic). :meth:`~dqcontrol.controllers.base.Controller.finish_at_rest` hands
    over to it once it is ``controller.end_stream``; close it after the run."""
    planner = path_following_like(controller, plan_period_s, at_end=True)
    num = round(plan_period_s / controller.period_s)
    ender = StreamedController(planner, controller.period_s, lead_periods=num)
    ender.reset(np.asarray(q0, dtype=float))
    ender.use_wall_clock(wall_clock)
    ender.warm_up_stop()
    return ender

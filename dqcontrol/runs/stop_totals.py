"""The ``stop_*`` metrics of a run taken block by block (docs/theory.md §8.10): the same
figures as :func:`~dqcontrol.runs.metrics.compute_metrics` gives, from the samples flagged
``stopping``, for logs of any length."""

from __future__ import annotations

import numpy as np

from dqcontrol.dq.algebra import translation
from dqcontrol.runs.metrics import VIOLATION_TOL, BoundSpec
from dqcontrol.trajectories import Trajectory

__all__ = ["StopTotals"]


class StopTotals:
    """Running figures of the stop's samples; :meth:`add` every block in order."""

    def __init__(self, trajectory: Trajectory, bounds_for, period_s: float) -> None:
        self.trajectory, self.bounds_for, self.period_s = trajectory, bounds_for, period_s
        self.count, self.violations = 0, 0
        self.first_sigma = self.last_sigma_next = 0.0
        self.travel_m = self.deviation_m = self.last_command = 0.0
        self.prev_command: np.ndarray | None = None
        self.prev_tool: np.ndarray | None = None

    def add(self, block: dict[str, np.ndarray]) -> None:
        """The block's stop samples (the previous command is kept across blocks)."""
        qd = block["qd_command"]
        prev = np.zeros((1, qd.shape[1])) if self.prev_command is None else self.prev_command
        if len(qd):
            self.prev_command = qd[-1:].copy()
        flags = block.get("stopping")
        idx = np.flatnonzero(flags) if flags is not None else np.zeros(0, dtype=int)
        if not idx.size:
            return
        if not self.count:
            self.first_sigma = float(block["sigma"][idx[0]])
        self.count += idx.size
        last = idx[-1]
        self.last_sigma_next = float(block["sigma"][last] + self.period_s * block["s"][last])
        self.last_command = float(np.max(np.abs(qd[last])))
        tool = translation(block["pose"][idx])
        self._add_path(tool)
        self._add_bounds(block["q"], qd, prev, idx)

    def _add_path(self, tool: np.ndarray) -> None:
        path = tool if self.prev_tool is None else np.vstack((self.prev_tool, tool))
        self.travel_m += float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
        self.prev_tool = tool[-1:].copy()
        dev = np.asarray(self.trajectory.path_deviation(tool))
        self.deviation_m = max(self.deviation_m, float(np.max(dev)))

    def _add_bounds(self, q, qd, prev, idx) -> None:
        bounds: BoundSpec = self.bounds_for(q)
        acc = np.abs(qd - np.vstack((prev, qd[:-1]))) / self.period_s
        if bounds.a_max is not None:
            acc = acc - np.broadcast_to(bounds.a_max, acc.shape)
        elif bounds.a_max_per_sample is not None:
            acc = acc - bounds.a_max_per_sample
        else:
            acc = acc - np.inf
        vel = np.abs(qd) - bounds.qd_max
        acc_tol = VIOLATION_TOL * max(1.0, 1.0 / self.period_s)
        beyond = np.any(vel > VIOLATION_TOL, axis=1) | np.any(acc > acc_tol, axis=1)
        self.violations += int(np.count_nonzero(beyond[idx]))

    def figures(self) -> dict:
        """The ``stop_*`` fields of :class:`~dqcontrol.runs.metrics.Metrics` (none: {})."""
        if not self.count:
            return {}
        return {
            "stop_samples": self.count,
            "stop_duration_s": self.count * self.period_s,
            "stop_phase_advance_s": self.last_sigma_next - self.first_sigma,
            "stop_tool_travel_m": self.travel_m,
            "stop_path_deviation_max_m": self.deviation_m,
            "stop_limit_violations": self.violations,
            "stop_last_command_rad_s": self.last_command,
        }

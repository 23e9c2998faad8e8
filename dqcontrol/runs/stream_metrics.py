"""The metrics of a run computed block by block (docs/theory.md §9), for logs of any length.

:func:`streamed_metrics` gives the figures of
:func:`~dqcontrol.runs.metrics.compute_metrics` from a re-iterable source of sample blocks
without holding the whole log: sums, counts and maxima in one pass; the two medians (solve
and step time) from the values kept in that pass up to :data:`MEDIAN_KEEP` samples, else by
an exact selection over the bit patterns of the values (four more passes over the blocks,
16 bits each, for both medians at once). Sums are taken block by block, so the means may
differ from the in-memory ones by rounding (far below 1e-12 relative).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator

import numpy as np

from dqcontrol.dq.algebra import pose_error, translation
from dqcontrol.runs.metrics import VIOLATION_TOL, BoundSpec, Metrics
from dqcontrol.runs.stop_totals import StopTotals
from dqcontrol.trajectories import Trajectory

__all__ = ["MEDIAN_KEEP", "streamed_metrics"]

#: Up to this many task samples the timing values are kept for the medians [samples].
MEDIAN_KEEP = 1_000_000
_TIMING = ("solve_time_s", "step_time_s")
Blocks = Callable[[], Iterable[dict[str, np.ndarray]]]


class _Totals:
    """Running sums, counts and maxima over the task's samples."""

    def __init__(self) -> None:
        self.sums = dict.fromkeys(("err", "terr", "rerr", "dev", "u", "s"), 0.0)
        self.maxima = dict.fromkeys(("err", "terr", "rerr", "dev", "pos", "vel", "acc"), None)
        self.counts = dict.fromkeys(("pos", "vel", "acc", "fallback", "relaxed"), 0)
        self.torque_sq, self.torque_values, self.torque_peak = 0.0, 0, 0.0
        self.torque_finite = True
        self.task = 0

    def add_sum(self, name: str, values: np.ndarray) -> None:
        self.sums[name] += float(np.sum(values))

    def add_max(self, name: str, values: np.ndarray) -> None:
        if values.size:
            top = np.max(values)
            old = self.maxima[name]
            self.maxima[name] = top if old is None else np.maximum(old, top)

    def maximum(self, name: str) -> float:
        value = self.maxima[name]
        return 0.0 if value is None else float(value)

    def mean(self, name: str) -> float:
        return self.sums[name] / self.task if self.task else float("nan")


class _Pass:
    """One pass over the blocks: the task's end, and everything but the medians."""

    def __init__(self, trajectory: Trajectory, bounds_for, period_s: float) -> None:
        self.trajectory, self.bounds_for, self.period_s = trajectory, bounds_for, period_s
        self.totals = _Totals()
        self.samples = 0
        self.end: int | None = None
        self.prev_command: np.ndarray | None = None
        self.nan_seen = False
        self.last_sigma_next = 0.0
        self.exec_time = float("nan")
        self.kept: dict[str, list[np.ndarray]] | None = {name: [] for name in _TIMING}
        self.timing_nan = dict.fromkeys(_TIMING, False)
        self.stopped = False
        self.stop = StopTotals(trajectory, bounds_for, period_s)

    def add(self, block: dict[str, np.ndarray]) -> None:
        count = len(block["t_s"])
        if not count:
            return
        self.nan_seen = self.nan_seen or not (
            np.all(np.isfinite(block["q"]))
            and np.all(np.isfinite(block["qd_command"]))
            and np.all(np.isfinite(block["pose"]))
        )
        self.last_sigma_next = float(block["sigma"][-1] + self.period_s * block["s"][-1])
        self.stop.add(block)
        if self.end is None:
            task = self._task_part(block, count)
            if task:
                self._add_task({k: v[:task] for k, v in block.items()})
        self.samples += count

    def _task_part(self, block: dict[str, np.ndarray], count: int) -> int:
        """How many of the block's samples belong to the task (sets ``end`` when it ends)."""
        duration = self.trajectory.duration
        reached = np.flatnonzero(block["sigma"] + self.period_s * block["s"] >= duration - 1e-12)
        stops = np.flatnonzero(block.get("stopping", np.zeros(count, dtype=bool)))
        if stops.size and (not reached.size or stops[0] <= reached[0]):
            self.end, self.stopped = self.samples + int(stops[0]), True
            return int(stops[0])
        if not reached.size:
            return count
        task = int(reached[0]) + 1
        self.end = self.samples + task
        self.exec_time = float(block["t_s"][task - 1] + self.period_s)
        return task

    def _add_task(self, b: dict[str, np.ndarray]) -> None:
        t, count = self.totals, len(b["t_s"])
        t.task += count
        pose, target = b["pose"], b["target"]
        errors = {
            "err": np.linalg.norm(target - pose, axis=1),
            **dict(
                zip(
                    ("terr", "rerr"), (np.asarray(e) for e in pose_error(pose, target)), strict=True
                )
            ),
            "dev": np.asarray(self.trajectory.path_deviation(translation(pose))),
        }
        for name, values in errors.items():
            t.add_sum(name, values)
            t.add_max(name, values)
        t.add_sum("u", np.linalg.norm(b["qd_command"], axis=1))
        t.add_sum("s", b["s"])
        self._add_bounds(b)
        self._add_torque(b)
        t.counts["fallback"] += int(np.count_nonzero(b["fallback"]))
        t.counts["relaxed"] += int(np.count_nonzero(b["relaxed"]))
        self._keep_timing(b)

    def _add_bounds(self, b: dict[str, np.ndarray]) -> None:
        t, q, qd = self.totals, b["q"], b["qd_command"]
        bounds: BoundSpec = self.bounds_for(q)
        pos = np.maximum(q - bounds.q_max, bounds.q_min - q)
        vel = np.abs(qd) - bounds.qd_max
        prev = np.zeros((1, qd.shape[1])) if self.prev_command is None else self.prev_command
        acc = np.abs(qd - np.vstack((prev, qd[:-1]))) / self.period_s
        if bounds.a_max is not None:
            acc = acc - np.broadcast_to(bounds.a_max, acc.shape)
        elif bounds.a_max_per_sample is not None:
            acc = acc - bounds.a_max_per_sample
        else:
            acc = acc - np.inf
        self.prev_command = qd[-1:].copy()
        acc_tol = VIOLATION_TOL * max(1.0, 1.0 / self.period_s)
        for name, excess, tol in (("pos", pos, VIOLATION_TOL), ("vel", vel, VIOLATION_TOL),
                                  ("acc", acc, acc_tol)):  # fmt: skip
            t.counts[name] += int(np.count_nonzero(excess > tol))
            t.add_max(name, excess)

    def _add_torque(self, b: dict[str, np.ndarray]) -> None:
        t, torque = self.totals, b["torque"]
        if not torque.size:
            return
        t.torque_finite = t.torque_finite and bool(np.all(np.isfinite(torque)))
        t.torque_sq += float(np.sum(torque**2))
        t.torque_values += torque.size
        t.torque_peak = float(np.maximum(t.torque_peak, np.max(np.abs(b["torque_peak"]))))

    def _keep_timing(self, b: dict[str, np.ndarray]) -> None:
        for name in _TIMING:
            self.timing_nan[name] = self.timing_nan[name] or bool(np.isnan(b[name]).any())
        if self.kept is None:
            return
        if self.totals.task > MEDIAN_KEEP:
            self.kept = None
            return
        for name in _TIMING:
            self.kept[name].append(np.array(b[name], dtype=float))


def _order_keys(values: np.ndarray) -> np.ndarray:
    """Unsigned keys ordered as the float64 ``values`` (negative: all bits flipped)."""
    bits = np.ascontiguousarray(values, dtype=np.float64).view(np.uint64)
    negative = (bits >> np.uint64(63)).astype(bool)
    return np.where(negative, ~bits, bits | np.uint64(1 << 63))


def _from_key(key: int) -> float:
    bits = key ^ (1 << 63) if key >> 63 else ~key & ((1 << 64) - 1)
    return float(np.array([bits], dtype=np.uint64).view(np.float64)[0])


def _select(
    columns: Callable[[], Iterator[dict[str, np.ndarray]]], wanted: list[tuple[str, int]]
) -> list[float]:
    """For each ``(name, rank)`` of ``wanted``, the ``rank``-th smallest value (0-based) of
    column ``name`` over the blocks of ``columns()``, exactly: all of them together in four
    passes, each fixing 16 more bits of the order keys."""
    prefixes, left = [0] * len(wanted), [rank for _, rank in wanted]
    for shift in (48, 32, 16, 0):
        counts = np.zeros((len(wanted), 1 << 16), dtype=np.int64)
        for block in columns():
            keys_of = {name: _order_keys(block[name]) for name in {n for n, _ in wanted}}
            for i, (name, _) in enumerate(wanted):
                keys = keys_of[name]
                if shift < 48:
                    keys = keys[(keys >> np.uint64(shift + 16)) == np.uint64(prefixes[i])]
                digits = ((keys >> np.uint64(shift)) & np.uint64(0xFFFF)).astype(np.int64)
                counts[i] += np.bincount(digits, minlength=1 << 16)
        for i in range(len(wanted)):
            cumulative = np.cumsum(counts[i])
            digit = int(np.searchsorted(cumulative, left[i], side="right"))
            left[i] -= int(cumulative[digit - 1]) if digit else 0
            prefixes[i] = (prefixes[i] << 16) | digit
    return [_from_key(p) for p in prefixes]


def _medians(one_pass: _Pass, blocks: Blocks) -> dict[str, float]:
    """The medians of the timing columns over the task's samples (NaN if there are none,
    or if one is NaN), from the values kept or by :func:`_select`."""
    count = one_pass.totals.task
    if not count:
        return dict.fromkeys(_TIMING, float("nan"))
    if one_pass.kept is not None:
        return {name: float(np.median(np.concatenate(one_pass.kept[name]))) for name in _TIMING}

    def columns() -> Iterator[dict[str, np.ndarray]]:
        seen = 0
        for block in blocks():
            take = min(len(block["t_s"]), count - seen)
            if take > 0:
                yield {name: np.asarray(block[name][:take], dtype=float) for name in _TIMING}
            seen += take

    names = [name for name in _TIMING if not one_pass.timing_nan[name]]
    wanted = [(name, rank) for name in names for rank in ((count - 1) // 2, count // 2)]
    values = _select(columns, wanted) if wanted else []
    out = dict.fromkeys(_TIMING, float("nan"))
    for i, name in enumerate(names):
        out[name] = float(np.mean(values[2 * i : 2 * i + 2]))
    return out


def streamed_metrics(
    blocks: Blocks,
    trajectory: Trajectory,
    bounds_for: Callable[[np.ndarray], BoundSpec],
    period_s: float,
) -> Metrics:
    """The metrics of a run whose samples come in blocks (see the module docstring).

    Args:
        blocks: returns a fresh iterable of the run's blocks, in order, each as arrays by
            :class:`~dqcontrol.runs.log.RunLog` field (called once, or five times for runs
            longer than :data:`MEDIAN_KEEP` samples).
        trajectory: the anchored trajectory the controller used.
        bounds_for: the bounds for a block's joint positions ``(K, n)`` [rad] (e.g.
            ``lambda q: bounds_of(controller, q)``).
        period_s: the control period T [s].
    """
    one = _Pass(trajectory, bounds_for, period_s)
    for block in blocks():
        one.add(block)
    t, duration = one.totals, trajectory.duration
    completed = one.end is not None and not one.stopped
    medians = _medians(one, blocks)
    torque_ok = t.torque_values > 0 and t.torque_finite
    return Metrics(
        completed=completed,
        sigma_reached_s=float(min(duration, one.last_sigma_next)) if one.samples else 0.0,
        duration_s=float(duration),
        execution_time_s=one.exec_time,
        execution_ratio=one.exec_time / duration if completed else float("nan"),
        samples=int(t.task),
        e_mean=t.mean("err"),
        e_max=t.maximum("err"),
        translation_error_mean_m=t.mean("terr"),
        translation_error_max_m=t.maximum("terr"),
        rotation_error_mean_rad=t.mean("rerr"),
        rotation_error_max_rad=t.maximum("rerr"),
        path_deviation_mean_m=t.mean("dev"),
        path_deviation_max_m=t.maximum("dev"),
        u_mean_rad_s=t.mean("u"),
        s_mean=t.mean("s"),
        torque_peak_nm=t.torque_peak if torque_ok else float("nan"),
        torque_rms_nm=float(np.sqrt(t.torque_sq / t.torque_values)) if torque_ok else float("nan"),
        position_violations=t.counts["pos"],
        position_violation_max_rad=max(0.0, t.maximum("pos")),
        velocity_violations=t.counts["vel"],
        velocity_violation_max_rad_s=max(0.0, t.maximum("vel")),
        acceleration_violations=t.counts["acc"],
        acceleration_violation_max_rad_s2=max(0.0, t.maximum("acc")),
        fallbacks=t.counts["fallback"],
        relaxed_steps=t.counts["relaxed"],
        nan_seen=one.nan_seen,
        solve_time_median_s=medians["solve_time_s"],
        step_time_median_s=medians["step_time_s"],
        **one.stop.figures(),
    )

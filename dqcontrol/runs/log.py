"""The run log: everything a closed loop records per control sample.

Both closed loops (kinematic and MuJoCo) fill the same :class:`LogRecorder` and produce the
same :class:`RunLog`, so the metrics, figures and files never depend on the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from dqcontrol.controllers.base import StepResult

__all__ = ["NO_PLAN", "LogRecorder", "RunLog", "STREAM_FIELDS", "stream_values"]

#: The fields only a streamed controller's samples have.
STREAM_FIELDS = ("plan_id", "plan_age_s", "lateness_s")
#: The stream fields of a sample no plan gave (a stop another controller stepped).
NO_PLAN = (-1, float("nan"), float("nan"))


def stream_values(result: StepResult) -> tuple[int, float, float] | None:
    """``(plan_id, plan_age_s, lateness_s)`` of a streamed controller's step, else ``None``."""
    d = result.diagnostics
    plan_id = getattr(d, "plan_id", None)
    if plan_id is None:
        return None
    return plan_id, d.plan_age_s, d.lateness_s  # type: ignore[attr-defined]


@dataclass
class RunLog:
    """Arrays over the K control samples of a run (row k = sample k).

    Attributes:
        t_s: time of sample k [s]. sigma: phase σ_k [s]. s: scaling applied.
        q: measured joint positions [rad] (K, n). qd_measured, qd_command: [rad/s] (K, n).
        torque: joint torques applied at the end of period k [N·m] (K, n); NaN in the
            kinematic loop. torque_peak: largest |torque| during period k [N·m] (K, n).
        pose, target: measured end-effector pose x_k and target x_d(σ_k), vec8 (K, 8).
        solver_status: status string per sample. iterations, solve_time_s, step_time_s.
        fallback, relaxed, saturated: per-sample flags.
        meta: free-form description (robot, trajectory, controller, parameters, simulator).
        plan_id, plan_age_s, lateness_s: a streamed controller's samples only (``None``
            otherwise): the plan each command came from, the time since that plan's
            measurement [s] and, on the wall clock, how long after its place on the grid the
            command was ready [s] (NaN in stepped runs); docs/theory.md §12.4. A sample no
            plan gave (a stop another controller stepped) has ``-1``, NaN, NaN.
        stopping: per-sample flag: the sample belongs to a stop (the controller's stop was
            requested: the end of the task, Ctrl-C, the watchdog, a driver error or the
            caller); all False when not given.
    """

    t_s: np.ndarray
    sigma: np.ndarray
    s: np.ndarray
    q: np.ndarray
    qd_measured: np.ndarray
    qd_command: np.ndarray
    torque: np.ndarray
    torque_peak: np.ndarray
    pose: np.ndarray
    target: np.ndarray
    solver_status: np.ndarray
    iterations: np.ndarray
    solve_time_s: np.ndarray
    step_time_s: np.ndarray
    fallback: np.ndarray
    relaxed: np.ndarray
    saturated: np.ndarray
    meta: dict = field(default_factory=dict)
    plan_id: np.ndarray | None = None
    plan_age_s: np.ndarray | None = None
    lateness_s: np.ndarray | None = None
    stopping: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.stopping is None:
            self.stopping = np.zeros(self.t_s.shape, dtype=bool)

    def __len__(self) -> int:
        return int(self.t_s.size)

    def arrays(self) -> dict[str, np.ndarray]:
        """The array fields by name (for ``np.savez``; the stream's only where present)."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "meta"}
        return {name: value for name, value in out.items() if value is not None}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], meta: dict | None = None) -> RunLog:
        """Rebuild a log from :meth:`arrays` (e.g. a loaded ``.npz``)."""
        names = [f.name for f in fields(cls) if f.name not in ("meta", "stopping", *STREAM_FIELDS)]
        stream = {k: np.asarray(arrays[k]) for k in STREAM_FIELDS if k in arrays}
        stopping = arrays.get("stopping")
        return cls(
            **{k: np.asarray(arrays[k]) for k in names},
            meta=dict(meta or {}),
            stopping=None if stopping is None else np.asarray(stopping, dtype=bool),
            **stream,
        )


class LogRecorder:
    """Collects one row per control step; :meth:`finish` turns the rows into a RunLog."""

    def __init__(self, num_joints: int, meta: dict | None = None) -> None:
        self.n = num_joints
        self.meta = dict(meta or {})
        self._rows: list[tuple] = []
        self._stream: list[tuple[int, float, float]] = []

    def __len__(self) -> int:
        return len(self._rows)

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
        """Append sample k: the measurement it was computed from and the controller output
        (``stopping``: the sample belongs to a stop)."""
        d = result.diagnostics
        self._stream.append(stream_values(result) or NO_PLAN)
        self._rows.append(
            (
                t_s,
                result.sigma,
                result.s,
                np.array(q, dtype=float),
                np.array(qd_measured, dtype=float),
                np.array(result.qd_command, dtype=float),
                np.full(self.n, np.nan) if torque is None else np.array(torque, dtype=float),
                np.full(self.n, np.nan)
                if torque_peak is None
                else np.array(torque_peak, dtype=float),
                np.array(result.pose, dtype=float),
                np.array(result.target, dtype=float),
                d.status,
                d.iterations,
                d.solve_time_s,
                d.step_time_s,
                d.fallback,
                d.relaxed,
                d.saturated,
                bool(stopping),
            )
        )

    def finish(self) -> RunLog:
        """The collected samples as a :class:`RunLog` (empty arrays if nothing recorded)."""
        n = self.n
        if not self._rows:
            empty = np.zeros(0)
            return RunLog(
                t_s=empty, sigma=empty, s=empty, q=np.zeros((0, n)),
                qd_measured=np.zeros((0, n)), qd_command=np.zeros((0, n)),
                torque=np.zeros((0, n)), torque_peak=np.zeros((0, n)),
                pose=np.zeros((0, 8)), target=np.zeros((0, 8)),
                solver_status=np.zeros(0, dtype="U32"), iterations=np.zeros(0, dtype=int),
                solve_time_s=empty, step_time_s=empty, fallback=np.zeros(0, dtype=bool),
                relaxed=np.zeros(0, dtype=bool), saturated=np.zeros(0, dtype=bool),
                meta=self.meta, stopping=np.zeros(0, dtype=bool),
            )  # fmt: skip
        cols = list(zip(*self._rows, strict=True))
        stream = {}
        if any(values[0] != NO_PLAN[0] for values in self._stream):
            ids, ages, late = zip(*self._stream, strict=True)
            stream = {
                "plan_id": np.array(ids, dtype=np.int64),
                "plan_age_s": np.array(ages, dtype=float),
                "lateness_s": np.array(late, dtype=float),
            }
        return RunLog(
            t_s=np.array(cols[0], dtype=float),
            sigma=np.array(cols[1], dtype=float),
            s=np.array(cols[2], dtype=float),
            q=np.array(cols[3]),
            qd_measured=np.array(cols[4]),
            qd_command=np.array(cols[5]),
            torque=np.array(cols[6]),
            torque_peak=np.array(cols[7]),
            pose=np.array(cols[8]),
            target=np.array(cols[9]),
            solver_status=np.array(cols[10], dtype="U32"),
            iterations=np.array(cols[11], dtype=int),
            solve_time_s=np.array(cols[12], dtype=float),
            step_time_s=np.array(cols[13], dtype=float),
            fallback=np.array(cols[14], dtype=bool),
            relaxed=np.array(cols[15], dtype=bool),
            saturated=np.array(cols[16], dtype=bool),
            meta=self.meta,
            stopping=np.array(cols[17], dtype=bool),
            **stream,
        )

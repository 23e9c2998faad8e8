"""The fault campaign: every controller on every task under every fault, and its report.

One case is one closed-loop run (:func:`~dqcontrol.sim.run_loop`, the loop of every run)
against the driver of :func:`~dqcontrol.faults.simulation.fault_driver`: a MuJoCo or a
kinematic arm, the model faults (payload, torque limits) and the measurement faults (noise,
delay) as wrappers around it, the outermost recording the *true* state. What is judged:

- **status**: ``completed`` (σ reached ``T_tot``), ``stopped`` (not completed, but the arm
  is at rest at the end: every true joint speed and every command below
  :data:`STOP_SPEED_RAD_S`), ``advancing`` (not at rest, but σ still advanced by at least
  :data:`ADVANCE_FRACTION` of ``T_tot`` over the last :data:`END_SAMPLES` samples: slowed
  down, e.g. by solver failures, yet progressing along the path), ``moving`` (none of these
  at the time limit: the arm moves while the task does not) or ``error`` (the loop raised,
  or the physics became unstable);
- **σ reached**, ``e_mean`` and the path deviation — from the *true* state (noise-free,
  undelayed), so that a noisy sensor does not make the arm look worse or better;
- **bound violations**: commanded velocity and acceleration (the loop's metrics,
  docs/theory.md §9), and joint positions, of the true state (``q_true``) and of what the
  controller measured (``q_meas``, which includes the noise);
- fallbacks and relaxed steps, NaN anywhere, σ monotone, ``0 ≤ s ≤ 1``;
- for contradictory QPs, how often the solver claimed to have solved a QP that has no
  feasible point (``false_successes``).

The QP controllers must have no violation and no NaN; the proportional controller, whose
bounds are only a clip of its command, is reported separately.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from dqcontrol.controllers.base import Controller
from dqcontrol.dq.algebra import dq_from_rt, dq_mul, translation
from dqcontrol.errors import ParameterError
from dqcontrol.experiments.executor import Executor, resolve_executor
from dqcontrol.experiments.runner import lbr4p
from dqcontrol.experiments.sweep import sweep
from dqcontrol.experiments.thesis import THESIS_PERIOD_S
from dqcontrol.faults.qp_faults import ContradictoryBoundsQP, contradictory
from dqcontrol.faults.scenarios import (
    CONTROLLERS,
    FAULTS,
    QUICK_CONTROLLERS,
    QUICK_FAULTS,
    TRAJECTORIES,
    ControllerSpec,
    Fault,
    TrajectorySpec,
    fault_by_name,
)
from dqcontrol.faults.simulation import fault_driver
from dqcontrol.model.robot import RobotModel
from dqcontrol.runs.metrics import VIOLATION_TOL
from dqcontrol.sim.kinematic import RunResult
from dqcontrol.sim.loop import run_loop

__all__ = [
    "PERIOD_S",
    "STOP_SPEED_RAD_S",
    "CampaignResult",
    "CaseResult",
    "CaseSpec",
    "campaign_cases",
    "render_csv",
    "render_markdown",
    "run_campaign",
    "run_case",
    "run_cases",
]

#: Control period of the campaign [s] (the thesis's).
PERIOD_S = THESIS_PERIOD_S
#: Below this speed [rad/s] (every joint, true state and command) the arm is at rest.
STOP_SPEED_RAD_S = 0.05
#: Samples at the end of a run over which ``s_end`` is averaged (1 s at T = 50 ms).
END_SAMPLES = 20
#: σ must advance by this fraction of ``T_tot`` over the last END_SAMPLES for ``advancing``.
ADVANCE_FRACTION = 0.01
SIMULATORS = ("mujoco", "kinematic")


# ----------------------------------------------------------------------------- cases
@dataclass(frozen=True)
class CaseSpec:
    """One run of the campaign (picklable: sent to worker processes)."""

    controller: ControllerSpec
    trajectory: TrajectorySpec
    fault: Fault
    simulator: str
    duration_s: float
    period_s: float = PERIOD_S
    seed: int = 0

    @property
    def max_time_s(self) -> float:
        """Time limit [s]: ``3 T_tot + 2 s``, or ``T_tot + 3 s`` when the fault makes the
        task impossible (the run must then stop safely)."""
        if self.fault.expect_completion:
            return 3.0 * self.duration_s + 2.0
        return self.duration_s + 3.0

    @property
    def label(self) -> str:
        """``fault/trajectory/controller/simulator``."""
        return f"{self.fault.name}/{self.trajectory.name}/{self.controller.name}/{self.simulator}"


@dataclass
class CaseResult:
    """The judged outcome of one case (one row of the table)."""

    fault: str
    group: str
    trajectory: str
    controller: str
    qp: bool
    simulator: str
    status: str
    completed: bool
    sigma_reached_s: float
    duration_s: float
    time_s: float
    s_mean: float
    s_end: float
    e_mean: float
    path_dev_mean_m: float
    path_dev_max_m: float
    path_dev_end_m: float
    speed_end_rad_s: float
    velocity_violations: int
    acceleration_violations: int
    q_violations_true: int
    q_excess_true_rad: float
    q_violations_measured: int
    q_excess_measured_rad: float
    fallbacks: int
    relaxed_steps: int
    false_successes: int
    nan_seen: bool
    sigma_monotone: bool
    s_in_range: bool
    raised: str
    note: str
    wall_time_s: float
    log: object = field(default=None, repr=False, compare=False)
    true_q: object = field(default=None, repr=False, compare=False)
    path_dev: object = field(default=None, repr=False, compare=False)
    anchored_trajectory: object = field(default=None, repr=False, compare=False)

    @property
    def safe(self) -> bool:
        """No exception, no NaN, no bound violation (commands and true positions), σ never
        decreasing, ``s`` in ``[0, 1]``."""
        return (
            not self.raised
            and not self.nan_seen
            and self.velocity_violations == 0
            and self.acceleration_violations == 0
            and self.q_violations_true == 0
            and self.sigma_monotone
            and self.s_in_range
        )

    def row(self) -> dict:
        """The table fields (no arrays)."""
        out = {}
        for f in fields(self):
            if f.name in ("log", "true_q", "path_dev", "anchored_trajectory"):
                continue
            out[f.name] = getattr(self, f.name)
        out["safe"] = self.safe
        return out


@contextlib.contextmanager
def _quiet_c_stdout(enabled: bool):
    """Send C-level stdout to /dev/null (OSQP prints an ERROR line for every rejected
    update of contradictory bounds)."""
    if not enabled:
        yield
        return
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        yield
        return
    sys.stdout.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                sys.stdout.flush()
                os.dup2(saved, fd)
    finally:
        os.close(saved)


def _build_controller(spec: CaseSpec, robot: RobotModel, trajectory) -> Controller:
    """The case's controller, told of the fault as :meth:`Fault.controller_options` says;
    solver faults in OSQP's settings, contradictory bounds through
    :func:`~dqcontrol.faults.qp_faults.contradictory`."""
    f, ctrl_spec = spec.fault, spec.controller
    extra: dict = f.controller_options()
    if ctrl_spec.qp and f.solver_settings:
        extra["solver"] = "osqp"  # the solver faults are written in OSQP's settings
        extra["solver_settings"] = dict(f.solver_settings)
    if ctrl_spec.qp and f.contradiction is not None:
        extra["contradiction"] = f.contradiction
    if "contradiction" in extra or any(k == "contradiction" for k, _ in ctrl_spec.kwargs):
        ctrl_spec = replace(ctrl_spec, cls=contradictory(ctrl_spec.cls))
    return ctrl_spec.build(robot, trajectory, spec.period_s, **extra)


def _build_trajectory(spec: CaseSpec, robot: RobotModel, q0: np.ndarray):
    traj = spec.trajectory.build(spec.duration_s, unreachable=spec.fault.unreachable)
    offset = spec.fault.reference_offset_m
    if offset is not None:
        reference = traj.anchored_at(robot.pose(q0)).reference
        assert reference is not None, "an anchored trajectory has its reference"
        shift = dq_from_rt(np.array([1.0, 0.0, 0.0, 0.0]), np.asarray(offset, dtype=float))
        traj = traj.with_reference(dq_mul(shift, reference))
    return traj


def _position_excess(q: np.ndarray, robot: RobotModel) -> tuple[int, float]:
    if q.size == 0:
        return 0, 0.0
    lim = robot.limits
    excess = np.maximum(q - lim.q_max, lim.q_min - q)
    return int(np.count_nonzero(excess > VIOLATION_TOL)), float(max(0.0, excess.max()))


def run_case(
    spec: CaseSpec,
    *,
    keep_log: bool = False,
    hook: Callable[[Controller], object] | None = None,
) -> CaseResult:
    """Run one case and judge it. Never raises for what happens inside the run: an exception
    is caught and reported in ``raised`` (with ``status = "error"``).

    ``keep_log`` attaches the run log, the true joint positions, the true path deviation
    and the anchored trajectory (for figures). ``hook(controller)`` is called on the
    controller before the run (the what-if experiments of :mod:`dqcontrol.faults.analysis`).
    """
    start_wall = time.perf_counter()
    robot = lbr4p()
    f, ctrl_spec = spec.fault, spec.controller
    nan = float("nan")
    base: dict[str, Any] = {
        "fault": f.name,
        "group": f.group,
        "trajectory": spec.trajectory.name,
        "controller": ctrl_spec.name,
        "qp": ctrl_spec.qp,
        "simulator": spec.simulator,
        "duration_s": spec.duration_s,
    }
    controller = None
    try:
        q0 = f.start_configuration(robot)
        traj = _build_trajectory(spec, robot, q0)
        controller = _build_controller(spec, robot, traj)
        if hook is not None:
            hook(controller)
        driver = fault_driver(f, spec.simulator, robot, spec.period_s, spec.seed)
        with _quiet_c_stdout(f.contradiction is not None):
            # no brake after the run: a case is judged in the state its last command led to
            result: RunResult = run_loop(
                controller,
                driver,
                q0=q0,
                max_time_s=spec.max_time_s,
                meta={"simulator": spec.simulator, "fault": f.name},
                brake=False,
            )
    except Exception as exc:  # noqa: BLE001 - the campaign reports, it does not stop
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return CaseResult(
            **base, status="error", completed=False, sigma_reached_s=nan, time_s=nan,
            s_mean=nan, s_end=nan, e_mean=nan, path_dev_mean_m=nan, path_dev_max_m=nan,
            path_dev_end_m=nan, speed_end_rad_s=nan, velocity_violations=0,
            acceleration_violations=0, q_violations_true=0, q_excess_true_rad=0.0,
            q_violations_measured=0, q_excess_measured_rad=0.0, fallbacks=0, relaxed_steps=0,
            false_successes=0, nan_seen=False, sigma_monotone=True, s_in_range=True,
            raised=tb, note="", wall_time_s=time.perf_counter() - start_wall,
        )  # fmt: skip

    if result.interrupted and result.note.startswith("interrupted by the user"):
        # run_mujoco turns Ctrl-C into a partial run; the campaign must stop, not go on
        raise KeyboardInterrupt
    log, m = result.log, result.metrics
    k = len(log)
    end = m.samples  # samples counted by the metrics (until σ reached T_tot)
    true_q = driver.true_q  # (k + 1, n): after reset and after every held command
    true_qd = driver.true_qd
    anchored = controller.trajectory
    # judged on the true state: samples 0..end-1, and the state the last command led to
    states = true_q[: end + 1]
    q_true_count, q_true_excess = _position_excess(states, robot)
    q_meas_count, q_meas_excess = _position_excess(log.q[:end], robot)
    nan_seen = bool(m.nan_seen or not np.isfinite(true_q).all())
    if end and np.isfinite(true_q[:end]).all():
        poses = robot.poses(true_q[:end])
        target = log.target[:end]
        flip = (poses * target).sum(axis=1) < 0.0
        poses[flip] *= -1.0
        err = np.linalg.norm(target - poses, axis=1)
        dev = anchored.path_deviation(translation(poses))
        e_mean = float(err.mean())
        dev_end = float(anchored.path_deviation(translation(robot.pose(true_q[k]))))
    else:
        e_mean, dev, dev_end = nan, np.zeros(0), nan
    speed_end = (
        float(max(np.abs(true_qd[-1]).max(), np.abs(log.qd_command[-1]).max())) if k else 0.0
    )
    completed = bool(m.completed)
    if result.interrupted:
        status = "error"
    elif completed:
        status = "completed"
    elif speed_end < STOP_SPEED_RAD_S:
        status = "stopped"
    elif k > END_SAMPLES and (
        log.sigma[-1] - log.sigma[-1 - END_SAMPLES] >= ADVANCE_FRACTION * anchored.duration
    ):
        status = "advancing"
    else:
        status = "moving"
    qp = getattr(controller, "qp", None)
    false_successes = qp.false_successes if isinstance(qp, ContradictoryBoundsQP) else 0
    notes = []
    if result.note:
        notes.append(result.note)
    if false_successes:
        notes.append(f"solver reported 'solved' on {false_successes} infeasible QPs")
    row = CaseResult(
        **base,
        status=status,
        completed=completed,
        sigma_reached_s=float(m.sigma_reached_s),
        time_s=float(k * spec.period_s),
        s_mean=float(log.s.mean()) if k else nan,
        s_end=float(log.s[-END_SAMPLES:].mean()) if k else nan,
        e_mean=e_mean,
        path_dev_mean_m=float(dev.mean()) if dev.size else nan,
        path_dev_max_m=float(dev.max()) if dev.size else nan,
        path_dev_end_m=dev_end,
        speed_end_rad_s=speed_end,
        velocity_violations=int(m.velocity_violations),
        acceleration_violations=int(m.acceleration_violations),
        q_violations_true=q_true_count,
        q_excess_true_rad=q_true_excess,
        q_violations_measured=q_meas_count,
        q_excess_measured_rad=q_meas_excess,
        fallbacks=int(np.count_nonzero(log.fallback)),
        relaxed_steps=int(np.count_nonzero(log.relaxed)),
        false_successes=int(false_successes),
        nan_seen=nan_seen,
        sigma_monotone=bool(np.all(np.diff(log.sigma) >= 0.0)),
        s_in_range=bool(np.all((log.s >= 0.0) & (log.s <= 1.0))),
        raised="",
        note="; ".join(notes),
        wall_time_s=time.perf_counter() - start_wall,
    )
    if keep_log:
        row.log, row.true_q, row.path_dev, row.anchored_trajectory = log, true_q, dev, anchored
    return row


def _names(given, default: Iterable[str], known: dict | None, what: str) -> list:
    names = list(default) if given is None else list(given)
    if known is not None:
        bad = [n for n in names if isinstance(n, str) and n not in known]
        if bad:
            raise ParameterError(f"unknown {what} {bad}; known: {sorted(known)}")
    return names


def campaign_cases(
    controllers: Sequence[str | ControllerSpec] | None = None,
    trajectories: Sequence[str | TrajectorySpec] | None = None,
    faults: Sequence[str | Fault] | None = None,
    simulator: str = "mujoco",
    quick: bool = False,
    seed: int = 0,
) -> list[CaseSpec]:
    """The cases of a campaign, in table order (fault, trajectory, controller).

    ``None`` selects everything (``quick``: :data:`~dqcontrol.faults.scenarios.QUICK_CONTROLLERS`,
    :data:`~dqcontrol.faults.scenarios.QUICK_FAULTS` and the circle only). Faults that do not
    apply (a payload in the kinematic simulator, a solver fault for the proportional
    controller, coupled bounds for ``p = 1``) are left out.
    """
    if simulator not in SIMULATORS:
        raise ParameterError(f"simulator must be one of {SIMULATORS}, got {simulator!r}")
    ctrl_names = _names(
        controllers, QUICK_CONTROLLERS if quick else CONTROLLERS, CONTROLLERS, "controllers"
    )
    traj_names = _names(
        trajectories, ["circle"] if quick else TRAJECTORIES, TRAJECTORIES, "trajectories"
    )
    fault_list = _names(faults, QUICK_FAULTS if quick else [f.name for f in FAULTS], None, "")
    ctrls = [CONTROLLERS[c] if isinstance(c, str) else c for c in ctrl_names]
    trajs = [TRAJECTORIES[t] if isinstance(t, str) else t for t in traj_names]
    flts = [fault_by_name(f) if isinstance(f, str) else f for f in fault_list]
    cases = []
    for fault in flts:
        for traj in trajs:
            duration = traj.quick_duration_s if quick else traj.duration_s
            for ctrl in ctrls:
                if fault.applies_to(ctrl, simulator):
                    cases.append(CaseSpec(ctrl, traj, fault, simulator, duration, seed=seed))
    return cases


@dataclass
class CampaignResult:
    """The rows of a campaign, in case order, and whether it was cut short."""

    rows: list[CaseResult]
    simulator: str
    quick: bool
    total_cases: int
    interrupted: bool = False
    note: str = ""
    wall_time_s: float = 0.0

    @property
    def qp_rows(self) -> list[CaseResult]:
        """Rows of the QP controllers (the hard bounds are theirs to keep)."""
        return [r for r in self.rows if r.qp]

    @property
    def proportional_rows(self) -> list[CaseResult]:
        """Rows of the proportional controller (bounds by clipping only)."""
        return [r for r in self.rows if not r.qp]


def run_campaign(
    controllers: Sequence[str | ControllerSpec] | None = None,
    trajectories: Sequence[str | TrajectorySpec] | None = None,
    faults: Sequence[str | Fault] | None = None,
    simulator: str = "mujoco",
    quick: bool = False,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    seed: int = 0,
    on_result: Callable[[CaseResult, int, int], None] | None = None,
) -> CampaignResult:
    """Run the fault campaign; see :func:`campaign_cases` for the selection.

    Args:
        controllers: the selection of :func:`campaign_cases`, as are ``trajectories``,
            ``faults``, ``simulator`` and ``quick``.
        trajectories: see ``controllers``.
        faults: see ``controllers``.
        simulator: see ``controllers``.
        quick: see ``controllers``.
        workers: processes of the local pool (default: every core; 1 runs in this
            process), or of the local Dask cluster.
        scheduler: a Dask scheduler address, ``"local"`` for a local Dask cluster, or
            ``None`` for the local pool (:mod:`dqcontrol.experiments.executor`).
        seed: seed of the measurement noise.
        on_result: called as ``on_result(row, done, total)`` after each case (progress).

    Ctrl-C stops the campaign: the completed rows are kept and ``interrupted`` is set (the
    note says how many cases ran).
    """
    cases = campaign_cases(controllers, trajectories, faults, simulator, quick, seed)
    executor = resolve_executor(workers, scheduler, len(cases))
    return run_cases(cases, executor, simulator=simulator, quick=quick, on_result=on_result)


def run_cases(
    cases: Sequence[CaseSpec],
    executor: Executor,
    *,
    simulator: str,
    quick: bool = False,
    on_result: Callable[[CaseResult, int, int], None] | None = None,
) -> CampaignResult:
    """Run ``cases`` on ``executor`` (:mod:`dqcontrol.experiments.executor`: this process,
    the local process pool or a Dask cluster) and collect the rows in case order.

    ``simulator`` and ``quick`` label the result. Ctrl-C (or a ``KeyboardInterrupt`` raised
    by ``on_result``) stops the campaign: the completed rows are kept and ``interrupted``
    is set.
    """
    finished = 0

    def progress(index: int, row: CaseResult) -> None:
        nonlocal finished
        finished += 1
        if on_result is not None:
            on_result(row, finished, len(cases))

    outcome = sweep(run_case, cases, executor, on_result=progress)
    rows, interrupted = outcome.results, outcome.interrupted
    note = f"interrupted after {len(rows)} of {len(cases)} cases" if interrupted else ""
    return CampaignResult(
        rows=rows,
        simulator=simulator,
        quick=quick,
        total_cases=len(cases),
        interrupted=interrupted,
        note=note,
        wall_time_s=outcome.wall_time_s,
    )


# ----------------------------------------------------------------------------- reports
def render_csv(result: CampaignResult) -> str:
    """Every row and field as CSV text."""
    buf = io.StringIO()
    rows = [r.row() for r in result.rows]
    if not rows:
        return ""
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: _csv_value(v) for k, v in r.items()})
    return buf.getvalue()


def _csv_value(v):
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return v


def _mm(v: float) -> str:
    return "–" if not math.isfinite(v) else f"{1000.0 * v:.1f}"


def _sci(v: float) -> str:
    return "–" if not math.isfinite(v) else f"{v:.2e}"


def _fixed(v: float, digits: int = 2) -> str:
    return "–" if not math.isfinite(v) else f"{v:.{digits}f}"


def _q_viol(count: int, excess_rad: float) -> str:
    return "0" if count == 0 else f"**{count}** [{1000.0 * excess_rad:.2f}]"


def _status(r: CaseResult) -> str:
    if r.status == "error":
        return f"**error**: {r.raised or r.note}"
    return r.status


def _table(rows: list[CaseResult], with_solver: bool) -> list[str]:
    head = (
        "| fault | traj | controller | status | σ/T_tot | s mean | e_mean | dev mean/max "
        "[mm] | viol v/a | viol q true [max mrad] | viol q meas | fallback/relaxed | NaN |"
    )
    cols = head.count("|") - 1
    lines = [head, "|" + "---|" * cols]
    for r in rows:
        lines.append(
            "| "
            + " | ".join(
                [
                    r.fault,
                    r.trajectory,
                    r.controller,
                    _status(r),
                    f"{_fixed(r.sigma_reached_s)}/{r.duration_s:g}",
                    _fixed(r.s_mean),
                    _sci(r.e_mean),
                    f"{_mm(r.path_dev_mean_m)}/{_mm(r.path_dev_max_m)}",
                    f"{r.velocity_violations}/{r.acceleration_violations}",
                    _q_viol(r.q_violations_true, r.q_excess_true_rad),
                    str(r.q_violations_measured),
                    f"{r.fallbacks}/{r.relaxed_steps}" if with_solver else "–",
                    "**yes**" if r.nan_seen else "no",
                ]
            )
            + " |"
        )
    return lines


def _check(ok: bool) -> str:
    return "PASS" if ok else "**FAIL**"


def render_markdown(result: CampaignResult, *, command: str = "dqcontrol faults") -> str:
    """The report: the checks, the QP controllers' table, the proportional controller's
    table, the graceful-degradation table and notes."""
    qp, prop = result.qp_rows, result.proportional_rows
    lines = [
        "# Fault campaign",
        "",
        f"Generated by `{command}` — simulator **{result.simulator}**, "
        f"{'quick (reduced)' if result.quick else 'full'} campaign, control period "
        f"T = {PERIOD_S * 1000:g} ms, robot LBR4p, {len(result.rows)} of "
        f"{result.total_cases} cases, {result.wall_time_s:.0f} s.",
        "",
    ]
    if result.interrupted:
        lines += [f"> **Incomplete**: {result.note}. The rows below are the completed cases.", ""]
    lines += [
        "e_mean, path deviation and `viol q true` (joint positions beyond a limit: count "
        "[largest excess in mrad]) are computed from the *true* state (noise-free, "
        "undelayed); `viol q meas` counts the positions the controller measured (noise "
        "and delay included). `viol v/a`: commanded velocity / acceleration samples beyond "
        "the bounds. Status: `completed` (σ reached T_tot), `stopped` (arm at rest below "
        f"{STOP_SPEED_RAD_S} rad/s at the time limit), `advancing` (still moving, σ still "
        f"advancing by ≥ {ADVANCE_FRACTION:.0%} of T_tot in the last {END_SAMPLES} samples), "
        "`moving` (the arm moves, the task does not), `error`.",
        "",
        "## Checks (QP controllers)",
        "",
    ]
    checks = [
        ("no exception from inside the loop", all(not r.raised for r in qp)),
        ("no NaN", all(not r.nan_seen for r in qp)),
        (
            "no commanded velocity/acceleration violation",
            all(r.velocity_violations == 0 and r.acceleration_violations == 0 for r in qp),
        ),
        ("no true joint-position violation", all(r.q_violations_true == 0 for r in qp)),
        ("σ never decreases, 0 ≤ s ≤ 1", all(r.sigma_monotone and r.s_in_range for r in qp)),
        (
            "every case completed, stopped at rest, or still advancing along the path",
            all(r.status in ("completed", "stopped", "advancing") for r in qp),
        ),
    ]
    for text, ok in checks:
        lines.append(f"- {_check(ok)} — {text} ({len(qp)} cases)")
    true_bad = [r for r in qp if r.q_violations_true]
    if true_bad:
        worst = max(true_bad, key=lambda r: r.q_excess_true_rad)
        lines.append(
            f"- true joint positions beyond a limit in {len(true_bad)} cases, at most "
            f"{1000.0 * worst.q_excess_true_rad:.2f} mrad ({worst.fault}/{worst.trajectory}/"
            f"{worst.controller}); the commands themselves never crossed a bound"
        )
    moving = [r for r in qp if r.status == "moving"]
    if moving:
        lines.append(
            "- cases still moving at the time limit: "
            + ", ".join(f"{r.fault}/{r.trajectory}/{r.controller}" for r in moving)
        )
    false = [r for r in qp if r.false_successes]
    if false:
        lines.append(
            "- the solver reported 'solved' on QPs with no feasible point (a stale solution, "
            "see docs/faults.md): "
            + ", ".join(
                f"{r.fault}/{r.trajectory}/{r.controller} ×{r.false_successes}" for r in false
            )
        )
    lines += ["", "## QP controllers", ""]
    lines += _table(qp, with_solver=True)
    if prop:
        lines += [
            "",
            "## Proportional controller (reported separately)",
            "",
            "Its command is the damped pseudo-inverse solution clipped to the same box: the "
            "bounds hold by clipping, at the price of the path.",
            "",
        ]
        lines += _table(prop, with_solver=False)
    unreach = [r for r in result.rows if r.fault == "unreachable"]
    if unreach:
        lines += [
            "",
            "## Graceful degradation: unreachable path",
            "",
            "A path partly outside the workspace should drive s towards 0 and leave the arm "
            "at rest near the path, not deform the path or diverge. `s end`: mean s over "
            "the last second; `dev end`: distance of the final tool position to the path; "
            "`speed end`: largest joint speed (true or commanded) at the end.",
            "",
            "| traj | controller | status | σ reached [s] | s end | dev max [mm] | "
            "dev end [mm] | speed end [rad/s] | viol q true [max mrad] |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in unreach:
            lines.append(
                f"| {r.trajectory} | {r.controller} | {_status(r)} | "
                f"{_fixed(r.sigma_reached_s)} | {_fixed(r.s_end, 3)} | {_mm(r.path_dev_max_m)}"
                f" | {_mm(r.path_dev_end_m)} | {_fixed(r.speed_end_rad_s)} | "
                f"{_q_viol(r.q_violations_true, r.q_excess_true_rad)} |"
            )
    notes = [r for r in result.rows if r.raised or r.status == "error"]
    if notes:
        lines += ["", "## Errors", ""]
        for r in notes:
            lines.append(f"- {r.fault}/{r.trajectory}/{r.controller}: {r.raised or r.note}")
    lines += ["", "## Faults", "", "| fault | group | what |", "|---|---|---|"]
    seen = []
    for r in result.rows:
        if r.fault not in seen:
            seen.append(r.fault)
    for name in seen:
        f = fault_by_name(name) if name in [x.name for x in FAULTS] else None
        desc = f.description if f else ""
        group = f.group if f else ""
        lines.append(f"| {name} | {group} | {desc} |")
    return "\n".join(lines) + "\n"

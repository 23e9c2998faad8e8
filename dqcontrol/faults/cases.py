"""The cases of the fault campaign and their outcomes, as data.

- :class:`CaseSpec` — one case: a controller on a trajectory under a fault, in a simulator;
- :func:`campaign_cases` — the cases a campaign runs, in table order;
- :class:`CaseResult` — the judged outcome of one case (one row of the report);
- :class:`CampaignResult` — the rows of a campaign.

The constants here are the campaign's control period and the thresholds that set a case's
status (:mod:`dqcontrol.faults.campaign` judges, :mod:`dqcontrol.faults.report` explains).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields

from dqcontrol.errors import ParameterError
from dqcontrol.experiments.thesis import THESIS_PERIOD_S
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

__all__ = [
    "ADVANCE_FRACTION",
    "END_SAMPLES",
    "PERIOD_S",
    "SIMULATORS",
    "STOP_SPEED_RAD_S",
    "CampaignResult",
    "CaseResult",
    "CaseSpec",
    "campaign_cases",
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


def _names(given, default: Iterable[str], known: dict | None, what: str) -> list:
    """The names ``given`` (``None``: ``default``), checked against ``known`` if given.

    Raises:
        ParameterError: a name that ``known`` does not have.
    """
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

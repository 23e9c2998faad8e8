"""The fault campaign's ingredients: controllers, trajectories and faults, by name.

Every fault is a plain, picklable description (:class:`Fault`); turning it into a driver
(:func:`~dqcontrol.faults.simulation.fault_driver`), a start configuration, a trajectory or
a controller happens in :mod:`dqcontrol.faults.campaign`. The controllers are
:mod:`dqcontrol.registry`'s, the trajectories are described by their metadata. Faults are
grouped by what they corrupt:

- *measurement*: noise on ``q`` and ``qd``, a delay of one or two control periods
  (:class:`~dqcontrol.sim.FaultyDriver`);
- *model* (MuJoCo only): an unknown payload at the flange, torque limits halved
  (:class:`~dqcontrol.sim.PayloadDriver`, :class:`~dqcontrol.sim.TorqueLimitDriver`);
- *task*: a path partly outside the workspace, a start far from the path, a start at a
  singular configuration, a start within a degree of the joint limits;
- *solver* (QP controllers only): contradictory bounds
  (:mod:`dqcontrol.faults.qp_faults`), a solver that fails (``max_iter``), one that times out
  (``time_limit``), both started cold (a warm start kept across failures lets even one
  iteration per step converge after ~100 steps), and one that fails now and then.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.experiments.runner import build_trajectory
from dqcontrol.experiments.thesis import THESIS_Q0
from dqcontrol.model.robot import RobotModel
from dqcontrol.registry import ControllerSpec, controller_spec
from dqcontrol.trajectories import Trajectory

__all__ = [
    "CONTROLLERS",
    "FAULTS",
    "QUICK_CONTROLLERS",
    "QUICK_FAULTS",
    "TRAJECTORIES",
    "ControllerSpec",
    "Fault",
    "TrajectorySpec",
    "fault_by_name",
    "near_limit_configuration",
]

#: Start "within a degree of the joint limits": every joint this far inside [rad].
NEAR_LIMIT_MARGIN_RAD = math.radians(0.8)


# ----------------------------------------------------------------------------- controllers
#: The campaign's controllers (:mod:`dqcontrol.registry` specs under the controllers' own
#: names, which the campaign's tables use): the thesis's, the proportional one and the
#: path-following controller (p = 10 intervals, its defaults).
CONTROLLERS: dict[str, ControllerSpec] = {
    name: controller_spec(name).renamed(name)
    for name in (
        "local",
        "predictive_p6",
        "predictive_p10",
        "predictive_noscale_p6",
        "proportional",
        "path_following",
    )
}
#: Controllers of the reduced (CI) campaign.
QUICK_CONTROLLERS = (
    "local",
    "predictive_p6",
    "predictive_noscale_p6",
    "proportional",
    "path_following",
)


# ----------------------------------------------------------------------------- trajectories
@dataclass(frozen=True)
class TrajectorySpec:
    """A task of the campaign: its nominal duration and its unreachable variant.

    Attributes:
        name: its name in the tables.
        duration_s: ``T_tot`` of the full campaign [s].
        quick_duration_s: ``T_tot`` of the reduced campaign [s].
    """

    name: str
    duration_s: float
    quick_duration_s: float

    def metadata(self, duration_s: float, *, unreachable: bool = False) -> dict:
        """The task as trajectory metadata; ``unreachable`` gives the variant partly
        outside the LBR4p's workspace from :data:`~dqcontrol.model.LBR4P_Q0`."""
        meta = {"trajectory": self.name, "duration_s": duration_s}
        if self.name == "circle":
            # R = 0.4 m: the far side of the circle is 0.8 m from the start, beyond reach
            meta["radius_m"] = 0.4 if unreachable else 0.1
        elif self.name == "sinusoid":
            if unreachable:
                # one period of ±0.6 m along the tool z (world vertical): the top is out of
                # reach
                meta.update(amplitude_m=0.6, omega_x_rad_per_m=15.0)
        else:
            raise ParameterError(f"unknown trajectory {self.name!r}; known: circle, sinusoid")
        return meta

    def build(self, duration_s: float, *, unreachable: bool = False) -> Trajectory:
        """The (unanchored) trajectory of :meth:`metadata`."""
        return build_trajectory(self.metadata(duration_s, unreachable=unreachable))


TRAJECTORIES: dict[str, TrajectorySpec] = {
    "circle": TrajectorySpec("circle", 2.0, 2.0),
    "sinusoid": TrajectorySpec("sinusoid", 4.0, 4.0),
}


# ----------------------------------------------------------------------------- faults
@dataclass(frozen=True)
class Fault:
    """One fault (or none): how the run differs from a nominal one.

    Attributes:
        name: its name in the tables.
        group: ``"none"``, ``"measurement"``, ``"model"``, ``"task"`` or ``"solver"``.
        description: one line for the report.
        q_noise_rad, qd_noise_rad_s: measurement noise (standard deviations) [rad], [rad/s].
        delay_periods: measurement delay [control periods].
        payload_kg: mass at the flange unknown to the controller (MuJoCo only) [kg].
        payload_offset_m: its centre in the flange frame [m].
        effort_scale: factor on the URDF's torque limits (MuJoCo only).
        start: ``"default"`` (:data:`~dqcontrol.model.LBR4P_Q0`), ``"singular"`` (``q = 0``,
            the stretched arm) or ``"near_limits"`` (:func:`near_limit_configuration`).
        reference_offset_m: world translation of the path's reference frame from the
            default anchoring [m] (the arm starts that far from the path), or ``None``.
        unreachable: use the trajectory's variant partly outside the workspace.
        solver_settings: OSQP settings for the QP controllers (items).
        contradiction: ``"crossed"`` / ``"coupled"`` contradictory bounds, or ``None``.
        expect_completion: the task can be completed despite the fault (if ``False``, the
            run is given ``T_tot + 3 s`` and must stop safely instead).
        compensated: the controller is told of the measurement faults, as a user who has
            characterised their sensors would configure it: ``measurement_delay_periods =
            delay_periods`` and ``position_margin_rad = max(5 mrad, 3 q_noise_rad)``.
            ``False`` runs it unaware (the findings of docs/faults.md).
    """

    name: str
    group: str
    description: str
    q_noise_rad: float = 0.0
    qd_noise_rad_s: float = 0.0
    delay_periods: int = 0
    payload_kg: float = 0.0
    payload_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.05)
    effort_scale: float = 1.0
    start: str = "default"
    reference_offset_m: tuple[float, float, float] | None = None
    unreachable: bool = False
    solver_settings: tuple[tuple[str, object], ...] = field(default=())
    contradiction: str | None = None
    expect_completion: bool = True
    compensated: bool = True

    def controller_options(self) -> dict:
        """Keyword arguments of the controller for this fault (see ``compensated``)."""
        if not self.compensated:
            return {}
        options: dict = {}
        if self.delay_periods:
            options["measurement_delay_periods"] = self.delay_periods
        if self.q_noise_rad > 0.0:
            options["position_margin_rad"] = max(5e-3, 3.0 * self.q_noise_rad)
        return options

    @property
    def mujoco_only(self) -> bool:
        """A model fault: only a dynamic simulation can have it."""
        return self.payload_kg > 0.0 or self.effort_scale != 1.0

    @property
    def qp_only(self) -> bool:
        """A solver fault: only the QP controllers have a solver."""
        return bool(self.solver_settings) or self.contradiction is not None

    @property
    def measurement(self) -> bool:
        """Whether the measurements are corrupted."""
        return self.q_noise_rad > 0.0 or self.qd_noise_rad_s > 0.0 or self.delay_periods > 0

    def applies_to(self, controller: ControllerSpec, simulator: str) -> bool:
        """Whether this fault makes sense for ``controller`` in ``simulator``."""
        if self.mujoco_only and simulator != "mujoco":
            return False
        if self.qp_only and not controller.qp:
            return False
        if self.contradiction == "coupled" and controller.num_instants < 2:
            return False
        return True

    def start_configuration(self, robot: RobotModel) -> np.ndarray:
        """The start configuration ``q0`` [rad]."""
        if self.start == "default":
            return THESIS_Q0.copy()
        if self.start == "singular":
            return np.zeros(robot.nq)
        if self.start == "near_limits":
            return near_limit_configuration(robot)
        raise ParameterError(
            f"start must be 'default', 'singular' or 'near_limits', got {self.start!r}"
        )


def near_limit_configuration(
    robot: RobotModel, margin_rad: float = NEAR_LIMIT_MARGIN_RAD
) -> np.ndarray:
    """Every joint ``margin_rad`` inside the limit on the side of :data:`LBR4P_Q0`'s sign
    (the thesis's start, :data:`~dqcontrol.experiments.thesis.THESIS_Q0`).

    For the LBR4p this is ``[-2.953, -2.080, -2.953, -2.080, 2.953, -2.080, 2.953]`` rad: a
    folded arm, clear of the pedestal and of itself (no MuJoCo contact).
    """
    lim = robot.limits
    side = np.sign(THESIS_Q0) if robot.nq == THESIS_Q0.size else np.ones(robot.nq)
    return np.where(side > 0, lim.q_max - margin_rad, lim.q_min + margin_rad)


_MRAD = 1e-3
FAULTS: tuple[Fault, ...] = (
    Fault("nominal", "none", "no fault"),
    # --- measurement
    Fault(
        "noise",
        "measurement",
        "Gaussian noise on q (σ = 2 mrad) and qd (σ = 0.02 rad/s)",
        q_noise_rad=2 * _MRAD,
        qd_noise_rad_s=0.02,
    ),
    Fault("delay_1", "measurement", "measurement delayed by 1 period", delay_periods=1),
    Fault("delay_2", "measurement", "measurement delayed by 2 periods", delay_periods=2),
    Fault(
        "noise_delay_2",
        "measurement",
        "noise (2 mrad, 0.02 rad/s) and a 2-period delay",
        q_noise_rad=2 * _MRAD,
        qd_noise_rad_s=0.02,
        delay_periods=2,
    ),
    # --- model (MuJoCo only)
    Fault("payload_1kg", "model", "1 kg at 5 cm from the flange, unknown", payload_kg=1.0),
    Fault("payload_3kg", "model", "3 kg at 5 cm from the flange, unknown", payload_kg=3.0),
    Fault("torque_half", "model", "every torque limit halved", effort_scale=0.5),
    Fault(
        "payload_3kg_torque_half",
        "model",
        "3 kg payload and torque limits halved",
        payload_kg=3.0,
        effort_scale=0.5,
    ),
    # --- task
    Fault(
        "unreachable",
        "task",
        "path partly outside the workspace (circle R = 0.4 m; sinusoid A = 0.6 m)",
        unreachable=True,
        expect_completion=False,
    ),
    Fault(
        "far_start",
        "task",
        "reference frame moved 10 cm: the arm starts 10 cm from the path",
        reference_offset_m=(0.05, 0.05, -0.07),
    ),
    Fault("singular_start", "task", "start at q = 0 (stretched arm, singular)", start="singular"),
    Fault(
        "near_limits",
        "task",
        "start with every joint 0.8° from a limit",
        start="near_limits",
    ),
    Fault(
        "near_limits_noise",
        "task",
        "near the limits, with noise on q (2 mrad) and qd (0.02 rad/s)",
        start="near_limits",
        q_noise_rad=2 * _MRAD,
        qd_noise_rad_s=0.02,
    ),
    Fault(
        "near_limits_delay_2",
        "task",
        "near the limits, with a 2-period measurement delay",
        start="near_limits",
        delay_periods=2,
    ),
    # --- solver (QP controllers only)
    Fault(
        "qp_crossed",
        "solver",
        "steps 10-29: joint 1's command box has lower > upper (contradictory bounds)",
        contradiction="crossed",
    ),
    Fault(
        "qp_coupled",
        "solver",
        "steps 10-29: instant 2's box contradicts the acceleration coupling (p ≥ 2)",
        contradiction="coupled",
    ),
    Fault(
        "solver_fails",
        "solver",
        "OSQP max_iter = 1, cold starts: every solve fails",
        solver_settings=(("max_iter", 1), ("warm_starting", False)),
        expect_completion=False,
    ),
    Fault(
        "solver_timeout",
        "solver",
        "OSQP time_limit = 1 ns, cold starts: every solve times out",
        solver_settings=(("time_limit", 1e-9), ("warm_starting", False)),
        expect_completion=False,
    ),
    Fault(
        "solver_flaky",
        "solver",
        "OSQP max_iter = 100: a solve fails now and then (hard active-set changes)",
        solver_settings=(("max_iter", 100),),
    ),
)
#: Faults of the reduced (CI) campaign: one of each kind.
QUICK_FAULTS = (
    "nominal",
    "noise_delay_2",
    "unreachable",
    "far_start",
    "singular_start",
    "near_limits",
    "qp_crossed",
    "qp_coupled",
    "solver_fails",
    "solver_timeout",
    "solver_flaky",
)


def fault_by_name(name: str) -> Fault:
    """The fault of :data:`FAULTS` called ``name`` (ParameterError listing them if none)."""
    for f in FAULTS:
        if f.name == name:
            return f
    raise ParameterError(f"unknown fault {name!r}; known: {[f.name for f in FAULTS]}")

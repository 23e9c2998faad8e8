"""Closed-loop dynamic simulation in MuJoCo: the robot's joints are torque-limited velocity
servos, the way the thesis ran its CoppeliaSim LBR4p (joints in dynamic mode, velocity
control, torque limits).

The model is built from the same URDF as the Pinocchio model (:mod:`dqcontrol.sim.mjcf_builder`):
same kinematics, same link inertias, the same base placement and locked joints. What the
controller's model does *not* have is what makes it a simulation: rotor inertia (armature),
joint damping, a servo that needs time to reach a commanded velocity, torque limits, contacts,
and optionally an unknown payload.

The velocity servo
------------------
The drives hold the commanded joint velocity ``u`` with a PI loop written in joint
accelerations and turned into torques with the *nominal* model (the controller's Pinocchio
model plus the rotor inertia; it knows neither the payload nor the joint damping)::

    a = (u - qd) / τ_v + w                        commanded joint acceleration [rad/s²]
    τ = sat_τmax( M_nom(q) a + g_nom(q) )          one Pinocchio RNEA call per physics step
    ẇ = (u_m - qd) / (τ_v τ_i)                     integral action (conditional, below)
    u̇_m = (u - u_m) / τ_v                          reference model of the nominal response

* With the nominal model the loop is decoupled: every joint answers a velocity step like a
  first-order lag of time constant ``τ_v`` in every configuration, until the torque limit
  caps the acceleration. Fixed per-joint gains cannot do that: the inertia joint 1 of the
  LBR4p sees varies 15-fold over the workspace, and an explicit loop with gains scheduled on
  the diagonal of ``M`` alone is unstable on the Panda at ``dt/τ_v = 0.2`` (the coupling
  ``M⁻¹ diag(M)`` has eigenvalues up to 15). MuJoCo's implicit ``velocity`` actuators would
  be stable, but they integrate a *clamped* torque explicitly: a saturated step overshoots
  and the torque chatters between its limits.
* The integral term ``w`` removes what the nominal model does not know (payload, damping,
  Coriolis forces). It integrates the error against the reference model ``u_m`` (what a
  nominal joint would do), not against ``u``: a command step then does not wind it up, so
  the velocity does not overshoot (a plain PI with these gains overshoots by 14 %).
* Anti-windup: while a joint's torque is saturated its ``w`` is frozen and its reference
  model is reset to the measured velocity.
* ``sat_τmax``: each torque is clipped to ``±effort_scale · effort`` of the URDF (the
  ``motor`` actuators' ``ctrlrange``/``forcerange`` and the joints' ``actuatorfrcrange`` hold
  the same limit).
* Pushing against a joint limit or an obstacle winds the integral up until the torque
  saturates (as a drive without following-error monitoring would); after the command
  reverses it takes about 0.1 s to unwind. The controllers keep away from joint limits.
* The loop is explicit (torques computed from the state at the start of each physics step),
  so ``τ_v ≥ 2 · physics_dt_s`` is required (it is checked); the defaults have
  ``dt / τ_v = 0.2``.

Defaults: ``τ_v = 5 ms`` — a velocity step reaches 95 % in ``3 τ_v ≈ 15 ms`` unless the
torque limit caps the acceleration, well within one period of the thesis's T = 0.05 s, and a
T = 1 ms controller sees a first-order lag of a few periods (industrial velocity loops have
30–100 Hz of bandwidth, τ = 1.6–5 ms). ``τ_i = 50 ms`` — a constant disturbance torque
(e.g. an unknown payload) is rejected with poles at about -22 and -178 rad/s. As gains:
``kv(q) = (M_nom(q) + diag(armature)) / τ_v`` [N·m·s/rad] and ``ki(q) = kv(q) / τ_i``
[N·m/rad] (:meth:`MujocoSimulation.servo_gains`). ``tests/sim/test_mujoco_sim.py`` measures the
step response and the holding drift.

Computed torque (``motor="torque"``)
------------------------------------
The drives compute the torque from the full rigid-body model (docs/drivers.md)::

    a = K_v (u_ref - qd) + q̈_ff,   K_v = 1 / τ_v
    τ = sat_τmax( M(q) a + C(q, qd) qd + g(q) + D qd )     one Pinocchio RNEA call

with the nominal model (the controller's Pinocchio model plus the rotor inertia and the joint
damping ``D``; not the payload). A new command ``u`` is reached along a ramp: ``u_ref`` goes
linearly from the previous reference to ``u`` over ``command_ramp_s`` (default: the duration
of the :meth:`MujocoSimulation.step` that brings it, i.e. one control period) and
``q̈_ff = Δu / command_ramp_s`` is its slope, so that with a perfect model the joint velocity
follows ``u_ref`` exactly and reaches ``u`` at the end of the period. No integral action: what
the model does not know (a payload) shows as a velocity error ``τ_v M⁻¹ τ_unknown``.

Physical defaults (documented choices, not identified values)
--------------------------------------------------------------
* armature (reflected rotor inertia) ``= 1e-3 s² × effort_max`` [kg·m²]: a drive's
  reflected inertia grows with its gear ratio as its torque does. LBR4p: 0.176 (joints 1–2),
  0.10 (3–5), 0.038 (6–7) kg·m², the order of an LWR-class harmonic drive (rotor
  ~4e-6 kg·m², ratio 160 → 0.1 kg·m²).
* joint damping: the URDF's ``<dynamics damping>`` (LBR4p: 0.5 N·m·s/rad on joints 1–4,
  0.2 on 5–7, see ``robots/lbr4p/README.md``), unless ``joint_damping`` is given.
* physics step 1 ms (at most 2 ms), ``implicitfast`` integrator (joint damping is
  integrated implicitly), gravity 9.81 m/s², contacts on (collision geoms of the URDF),
  MuJoCo's default joint-limit constraints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pinocchio as pin

from dqcontrol.dq.algebra import dq_from_rt, qfrom_matrix
from dqcontrol.errors import DQControlError, ParameterError, URDFError
from dqcontrol.extras import lazy_module
from dqcontrol.model.robot import RobotModel
from dqcontrol.model.urdf_source import URDFSource
from dqcontrol.sim.mjcf_builder import (
    PAYLOAD_BODY,
    SpecOptions,
    build_spec,
    prepare_urdf_xml,
)

if TYPE_CHECKING:
    import mujoco
else:  # imported on first use: the package works without the sim extra
    mujoco = lazy_module("mujoco", extra="sim", purpose="the MuJoCo simulation")

__all__ = [
    "ARMATURE_PER_NM",
    "MAX_PHYSICS_DT_S",
    "Measurement",
    "MujocoSimulation",
    "ServoGains",
]

#: Default time constant ``τ_v`` of the velocity servos [s] (module docstring).
SERVO_TIME_CONSTANT_S = 0.005

#: Largest accepted physics step [s].
MAX_PHYSICS_DT_S = 0.002
#: Default armature per N·m of effort limit [kg·m² / (N·m)] (module docstring).
ARMATURE_PER_NM = 1e-3
_MOTORS = ("velocity", "torque")


@dataclass(frozen=True, slots=True)
class Measurement:
    """What the robot's sensors report after a held command (all in ``robot.joint_names``
    order).

    Attributes:
        t_s: simulated time [s].
        q: joint positions [rad].
        qd: joint velocities [rad/s].
        torque: total actuator torque applied during the last physics step [N·m]
            (servo + gravity feed-forward, after the torque limit; joint damping excluded).
        torque_peak: largest ``|torque|`` over the physics steps of the last held interval
            [N·m] (after :meth:`MujocoSimulation.reset`: ``|torque|``).
    """

    t_s: float
    q: np.ndarray
    qd: np.ndarray
    torque: np.ndarray
    torque_peak: np.ndarray


class ServoGains(NamedTuple):
    """Equivalent gains of the velocity servos at one configuration (n×n, coupled).

    Attributes:
        kv: proportional gain [N·m·s/rad]: torque per rad/s of velocity error,
            ``(M_nom(q) + diag(armature)) / τ_v``.
        ki: integral gain [N·m/rad]: torque per rad of integrated velocity error,
            ``kv / τ_i``.
    """

    kv: np.ndarray
    ki: np.ndarray


def _positive(name: str, value: float, unit: str, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [{unit}], got {value!r}") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        bound = "≥ 0" if allow_zero else "> 0"
        raise ParameterError(f"{name} must be finite and {bound} [{unit}], got {value!r}")
    return v


def _per_joint(name: str, value, n: int, unit: str) -> np.ndarray:
    """A scalar or an (n,) array of finite values ≥ 0."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number or {n} numbers [{unit}]") from None
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ParameterError(
            f"{name} must be a scalar or have shape ({n},) [{unit}], got shape {arr.shape}"
        )
    if not np.isfinite(arr).all() or (arr < 0.0).any():
        raise ParameterError(f"{name} must be finite and ≥ 0 [{unit}], got {arr}")
    return arr


def _payload_offset(value) -> np.ndarray:
    """The payload's centre in the end-effector frame [m]: 3 finite numbers (``None``: 0)."""
    try:
        offset = np.zeros(3) if value is None else np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        offset = np.full(1, np.nan)
    if offset.shape != (3,) or not np.isfinite(offset).all():
        raise ParameterError(f"payload_offset_m must be 3 finite numbers [m], got {value!r}")
    return offset.copy()


def _effort_limits(robot: RobotModel) -> np.ndarray:
    """The URDF's effort limit of every controlled joint [N·m] (each must be > 0)."""
    effort = np.asarray(robot.limits.effort_max, dtype=float)
    if not (np.isfinite(effort).all() and (effort > 0.0).all()):
        raise ParameterError(
            f"every controlled joint needs a positive URDF effort limit, got {effort} for "
            f"{robot.joint_names}"
        )
    return effort


def _urdf_source(robot: RobotModel) -> URDFSource:
    """The URDF ``robot`` was built from.

    Raises:
        ParameterError: ``robot`` is not a :class:`RobotModel` or has no URDF source.
    """
    if not isinstance(robot, RobotModel):
        raise ParameterError(f"robot must be a RobotModel, got {type(robot).__name__}")
    if robot.source is None:
        raise ParameterError(
            "robot has no URDF source (build it with RobotModel.from_urdf or a loader)"
        )
    return robot.source


def _time_constants(
    physics_dt_s: float, servo_time_constant_s: float, integral_time_constant_s: float
) -> tuple[float, float, float]:
    """The physics step, ``τ_v`` and ``τ_i`` [s], checked (``math.inf``: no ``τ_i``).

    Raises:
        ParameterError: ``physics_dt_s`` is not in ``(0, MAX_PHYSICS_DT_S]``, ``τ_v`` is
            below ``2 physics_dt_s`` (the servo is explicit in time) or ``τ_i`` is not > 0.
    """
    dt = _positive("physics_dt_s", physics_dt_s, "s")
    if dt > MAX_PHYSICS_DT_S:
        raise ParameterError(f"physics_dt_s must be ≤ {MAX_PHYSICS_DT_S} s, got {dt}")
    tau_v = _positive("servo_time_constant_s", servo_time_constant_s, "s")
    if tau_v < 2.0 * dt:
        raise ParameterError(
            f"servo_time_constant_s must be ≥ 2 physics_dt_s = {2.0 * dt} s (the servo is "
            f"explicit in time), got {tau_v}"
        )
    tau_i = float(integral_time_constant_s)
    if not (tau_i > 0.0) or math.isnan(tau_i):  # inf allowed: no integral action
        raise ParameterError(
            f"integral_time_constant_s must be > 0 [s] (math.inf: no integral action), "
            f"got {integral_time_constant_s!r}"
        )
    return dt, tau_v, tau_i


class _Drives(NamedTuple):
    """The checked physical settings of the drives and the payload (per joint in
    ``robot.joint_names`` order).

    Attributes:
        effort_scale: factor on the URDF's effort limits.
        effort_limit_nm: torque limit of each drive [N·m] (``effort_scale`` × URDF effort).
        armature: reflected rotor inertia [kg·m²].
        damping: viscous joint damping [N·m·s/rad]; ``None`` keeps the URDF's.
        payload_kg: payload mass [kg].
        payload_offset_m: payload centre in the end-effector frame [m].
    """

    effort_scale: float
    effort_limit_nm: np.ndarray
    armature: np.ndarray
    damping: np.ndarray | None
    payload_kg: float
    payload_offset_m: np.ndarray


def _drives(
    robot: RobotModel,
    *,
    effort_scale: float,
    payload_kg: float,
    payload_offset_m: np.ndarray | None,
    armature: float | np.ndarray | None,
    joint_damping: float | np.ndarray | None,
) -> _Drives:
    """The drives' and the payload's settings of :class:`MujocoSimulation`'s arguments of
    the same names, checked, with the defaults filled in (module docstring).

    Raises:
        ParameterError: an argument is outside its range, or a controlled joint has no
            positive URDF effort limit.
    """
    n = robot.nq
    scale = _positive("effort_scale", effort_scale, "-")
    payload = _positive("payload_kg", payload_kg, "kg", allow_zero=True)
    offset = _payload_offset(payload_offset_m)
    effort = _effort_limits(robot)
    arm = (
        ARMATURE_PER_NM * effort
        if armature is None
        else _per_joint("armature", armature, n, "kg·m²")
    )
    damping = (
        None
        if joint_damping is None
        else _per_joint("joint_damping", joint_damping, n, "N·m·s/rad")
    )
    return _Drives(scale, scale * effort, arm, damping, payload, offset)


class MujocoSimulation:
    """A robot in MuJoCo whose joints track velocity commands through torque-limited servos.

    Args:
        robot: the controller's robot model; the simulator reads its URDF (``robot.source``),
            base placement, locked joints and end-effector frame.
        physics_dt_s: MuJoCo time step [s], ``0 < dt ≤ 0.002``.
        gravity: gravity on (-9.81 m/s² along world z).
        motor: joint drive model: ``"velocity"`` (the velocity servo of the module
            docstring) or ``"torque"`` (computed torque, the module docstring).
        servo_time_constant_s: ``τ_v`` [s], the servo's velocity time constant
            (``≥ 2 physics_dt_s``); with ``motor="torque"`` the gain is ``K_v = 1/τ_v``.
        command_ramp_s: ``motor="torque"`` only: time [s] over which a new command is
            ramped in (``None``: the duration of the ``step`` that brings it); a whole
            number of physics steps.
        integral_time_constant_s: ``τ_i`` [s] of the integral action; ``math.inf`` turns it
            off (pure proportional servo).
        gravity_feedforward: the drives add the nominal model's gravity torque ``g_nom(q)``.
        armature: reflected rotor inertia [kg·m²] (scalar or per joint); default
            ``ARMATURE_PER_NM × effort_max``.
        joint_damping: viscous joint damping [N·m·s/rad] (scalar or per joint); default the
            URDF's.
        payload_kg: extra mass at the end-effector that the controller's model (and the
            drives' nominal model) does not know [kg]; its centre is at
            ``payload_offset_m`` [m] in the end-effector frame.
        effort_scale: multiplies the URDF's effort limits (torque-saturation faults), > 0.
        obstacles: static obstacles of :mod:`dqcontrol.model.collision` (sphere, box,
            capsule, cylinder, half-space) added to the world as geoms the robot collides
            with.

    Raises:
        ParameterError: an argument is outside its range (the message says which).
        URDFError: MuJoCo cannot build the robot from its URDF.
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        physics_dt_s: float = 0.001,
        gravity: bool = True,
        motor: str = "velocity",
        servo_time_constant_s: float = SERVO_TIME_CONSTANT_S,
        command_ramp_s: float | None = None,
        integral_time_constant_s: float = 0.05,
        gravity_feedforward: bool = True,
        armature: float | np.ndarray | None = None,
        joint_damping: float | np.ndarray | None = None,
        payload_kg: float = 0.0,
        payload_offset_m: np.ndarray | None = None,
        effort_scale: float = 1.0,
        obstacles: tuple = (),
    ) -> None:
        source = _urdf_source(robot)
        if motor not in _MOTORS:
            raise ParameterError(f"motor must be one of {_MOTORS}, got {motor!r}")
        dt, tau_v, tau_i = _time_constants(
            physics_dt_s, servo_time_constant_s, integral_time_constant_s
        )
        drives = _drives(
            robot,
            effort_scale=effort_scale,
            payload_kg=payload_kg,
            payload_offset_m=payload_offset_m,
            armature=armature,
            joint_damping=joint_damping,
        )

        self.robot = robot
        self.physics_dt_s = dt
        #: The joint drive model (``"velocity"`` or ``"torque"``).
        self.motor = motor
        self.command_ramp_s = (
            None if command_ramp_s is None else _positive("command_ramp_s", command_ramp_s, "s")
        )
        self.servo_time_constant_s = tau_v
        self.integral_time_constant_s = tau_i
        self.gravity_feedforward = bool(gravity_feedforward)
        #: Reflected rotor inertia of each joint [kg·m²].
        self.armature = drives.armature.copy()

        self._build_model(source, bool(gravity), drives, obstacles)
        self._build_nominal_model(bool(gravity))
        self._allocate_buffers(robot.nq)
        self.reset(np.clip(np.zeros(robot.nq), robot.limits.q_min, robot.limits.q_max))

    # ------------------------------------------------------------------ construction
    def _build_model(
        self, source: URDFSource, gravity: bool, drives: _Drives, obstacles: tuple
    ) -> None:
        """Prepare the URDF and compile the first MuJoCo model, with ``gravity`` on or off,
        the drives' settings and the static ``obstacles``."""
        self._prepared = prepare_urdf_xml(source)
        #: Visual meshes MuJoCo could not read and that were left out (path and reason).
        self.dropped_visuals = self._prepared.dropped_visuals
        #: Static obstacles in the world (they collide with the robot's geometry).
        self.obstacles = tuple(obstacles)
        w = mujoco.mjtWarning
        self._bad = np.array(
            [
                int(w.mjWARN_BADQPOS),
                int(w.mjWARN_BADQVEL),
                int(w.mjWARN_BADQACC),
                int(w.mjWARN_BADCTRL),
            ]
        )
        self._compile(
            SpecOptions(
                physics_dt_s=self.physics_dt_s,
                gravity=gravity,
                armature_kg_m2=drives.armature,
                damping_nms_rad=drives.damping,
                effort_limit_nm=drives.effort_limit_nm,
                payload_kg=drives.payload_kg,
                payload_offset_m=drives.payload_offset_m,
                obstacles=self.obstacles,
            )
        )
        self.effort_scale = drives.effort_scale

    def _build_nominal_model(self, gravity: bool) -> None:
        """The drives' nominal Pinocchio model: the controller's plus the rotor inertia, with
        gravity only when it is on and fed forward."""
        self._pin_model = pin.Model(self.robot.model)
        self._pin_model.armature = self.armature.copy()
        if not (gravity and self.gravity_feedforward):
            self._pin_model.gravity = pin.Motion.Zero()
        self._pin_data = self._pin_model.createData()

    def _allocate_buffers(self, n: int) -> None:
        """The drives' state and the work arrays of the hot loop for ``n`` joints, allocated
        once (no numpy allocation per physics step)."""
        self._u = np.zeros(n)  # velocity command [rad/s]
        self._um = np.zeros(n)  # reference model's velocity [rad/s]
        self._w = np.zeros(n)  # integral action [rad/s²]
        self._q = np.zeros(n)
        self._qd = np.zeros(n)
        self._zero = np.zeros(n)
        self._a = np.zeros(n)
        self._tmp = np.zeros(n)
        self._tau = np.zeros(n)
        self._peak = np.zeros(n)
        self._sat = np.zeros(n, dtype=bool)
        self._free = np.zeros(n, dtype=bool)
        # computed torque: the ramp from u0 to u over ramp_steps physics steps
        self._u0 = np.zeros(n)
        self._du = np.zeros(n)  # (u - u0) / ramp time [rad/s²]
        self._ramp_steps = 0
        self._ramp_done = 0
        self._warnings = 0

    # ------------------------------------------------------------------ the model
    def _compile(self, options: SpecOptions) -> None:
        """Build and compile the MuJoCo model of ``options``. A simulation that is already
        running keeps its joint state and time (and the drives theirs)."""
        robot = self.robot
        spec = build_spec(robot, self._prepared, options)
        try:
            model = spec.compile()
        except ValueError as exc:
            raise URDFError(f"MuJoCo could not compile the robot model: {exc}") from None
        data = mujoco.MjData(model)
        old = getattr(self, "_data", None)
        if old is not None:  # a payload has no joint: qpos and qvel keep their layout
            data.qpos[:], data.qvel[:], data.time = old.qpos, old.qvel, old.time
            mujoco.mj_forward(model, data)
        #: The edited :class:`mujoco.MjSpec` the model was compiled from.
        self.spec = spec
        self._options, self._model, self._data = options, model, data
        #: Torque limit of each joint's drive [N·m] (``effort_scale`` × URDF effort).
        self.torque_limit = np.array(options.effort_limit_nm, dtype=float)
        #: Viscous damping of each joint in the simulation [N·m·s/rad].
        self.joint_damping = np.array([model.joint(j).damping[0] for j in robot.joint_names])
        self._qpos_idx = np.array([model.joint(j).qposadr[0] for j in robot.joint_names])
        self._dof_idx = np.array([model.joint(j).dofadr[0] for j in robot.joint_names])
        self._site = model.site(robot.ee_frame).id
        self._payload_body = model.body(PAYLOAD_BODY).id if options.payload_kg > 0.0 else -1
        self._warnings = self._bad_count()

    @property
    def payload_kg(self) -> float:
        """Mass at the end-effector that the drives' and the controller's models do not
        know [kg] (0: none)."""
        return float(self._options.payload_kg)

    @property
    def payload_offset_m(self) -> np.ndarray:
        """The payload's centre in the end-effector frame [m] (a copy)."""
        return np.array(self._options.payload_offset_m, dtype=float)

    def set_payload(self, mass_kg: float, offset_m: np.ndarray | None = None) -> None:
        """Carry ``mass_kg`` [kg] (0: none) centred at ``offset_m`` [m] in the end-effector
        frame, unknown to the drives' model. The model is rebuilt; the joint state, the
        time and the drives' state are kept, and :attr:`model` and :attr:`data` are new
        objects (a viewer of the old ones must take them again).

        Raises:
            ParameterError: a negative or non-finite mass, an offset that is not 3 finite
                numbers.
        """
        mass = _positive("payload_kg", mass_kg, "kg", allow_zero=True)
        offset = _payload_offset(offset_m)
        self._compile(replace(self._options, payload_kg=mass, payload_offset_m=offset))

    def set_effort_scale(self, scale: float) -> None:
        """Limit every drive's torque to ``scale`` × the URDF's effort limit (``scale`` > 0;
        0.5 halves them). The model is rebuilt; the state is kept (as :meth:`set_payload`).

        Raises:
            ParameterError: ``scale`` is not finite and > 0.
        """
        value = _positive("effort_scale", scale, "-")
        limits = value * _effort_limits(self.robot)
        self._compile(replace(self._options, effort_limit_nm=limits))
        self.effort_scale = value

    # ------------------------------------------------------------------ properties
    @property
    def model(self) -> mujoco.MjModel:
        """The compiled :class:`mujoco.MjModel` (e.g. for a viewer)."""
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        """The :class:`mujoco.MjData` being stepped (read it; change it only via this class)."""
        return self._data

    @property
    def joint_qpos_adr(self) -> dict[str, int]:
        """``qpos`` address of each controlled joint, by name (``robot.joint_names`` order)."""
        return {j: int(a) for j, a in zip(self.robot.joint_names, self._qpos_idx, strict=True)}

    @property
    def joint_dof_adr(self) -> dict[str, int]:
        """``qvel``/``qfrc`` address of each controlled joint, by name."""
        return {j: int(a) for j, a in zip(self.robot.joint_names, self._dof_idx, strict=True)}

    @property
    def ee_site(self) -> str:
        """Name of the MuJoCo site at the end-effector frame (``robot.ee_frame``)."""
        return self.robot.ee_frame

    @property
    def time_s(self) -> float:
        """Simulated time since the last :meth:`reset` [s]."""
        return float(self._data.time)

    @property
    def command(self) -> np.ndarray:
        """The velocity command being held [rad/s] (a copy)."""
        return self._u.copy()

    @property
    def integral_action(self) -> np.ndarray:
        """The servos' integral terms ``w`` [rad/s²] (a copy)."""
        return self._w.copy()

    def servo_gains(self, q: np.ndarray) -> ServoGains:
        """Equivalent proportional and integral gain matrices of the servos at ``q`` [rad]."""
        q = self.robot.check_q(q)
        m = pin.crba(self._pin_model, self._pin_model.createData(), q)
        m = np.triu(m) + np.triu(m, 1).T
        kv = m / self.servo_time_constant_s
        return ServoGains(kv=kv, ki=kv / self.integral_time_constant_s)

    # ------------------------------------------------------------------ control
    def reset(self, q0: np.ndarray, qd0: np.ndarray | None = None) -> Measurement:
        """Put the robot at ``q0`` [rad] with velocity ``qd0`` [rad/s] (default 0), time 0.

        The servos' command becomes ``qd0`` and their integral terms 0. Returns the
        measurement at the new state (``torque``: what the drives would apply now).

        Raises:
            ConfigurationError: ``q0``/``qd0`` has the wrong shape or is not finite.
        """
        q0 = self.robot.check_q(q0, "q0")
        qd0 = np.zeros(self.robot.nq) if qd0 is None else self.robot.check_q(qd0, "qd0")
        m, d = self._model, self._data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qpos_idx] = q0
        d.qvel[self._dof_idx] = qd0
        self._u[:] = qd0
        self._um[:] = qd0
        self._w[:] = 0.0
        self._u0[:] = qd0
        self._du[:] = 0.0
        self._ramp_steps = self._ramp_done = 0
        self._drive_torque()
        d.ctrl[:] = self._tau
        mujoco.mj_forward(m, d)
        np.abs(self._tau, out=self._peak)
        self._warnings = self._bad_count()
        return self.measure()

    def steps_for(self, duration_s: float) -> int:
        """Number of physics steps in ``duration_s`` [s]; it must be a whole number of them.

        Raises:
            ParameterError: not finite, not positive, or not a multiple of ``physics_dt_s``
                within 1e-9 s.
        """
        try:
            duration = float(duration_s)
        except (TypeError, ValueError):
            raise ParameterError(f"duration_s must be a number [s], got {duration_s!r}") from None
        if not math.isfinite(duration) or duration <= 0.0:
            raise ParameterError(f"duration_s must be finite and > 0 [s], got {duration_s!r}")
        steps = round(duration / self.physics_dt_s)
        if steps < 1 or abs(duration - steps * self.physics_dt_s) > 1e-9:
            raise ParameterError(
                f"duration_s={duration!r} is not a whole number of physics steps of "
                f"{self.physics_dt_s} s (within 1e-9 s); use a multiple such as "
                f"{max(steps, 1) * self.physics_dt_s!r}"
            )
        return steps

    def step(self, qd_command: np.ndarray, duration_s: float) -> Measurement:
        """Hold the velocity command ``qd_command`` [rad/s] for ``duration_s`` [s].

        ``duration_s`` must be a whole number of physics steps (e.g. the control period).
        Returns the measurement at the end of the interval.

        Raises:
            ConfigurationError: ``qd_command`` has the wrong shape or is not finite.
            ParameterError: ``duration_s`` is not a positive multiple of ``physics_dt_s``.
            DQControlError: the physics became unstable (MuJoCo reported bad accelerations
                or the state is not finite); call :meth:`reset` before stepping again.
        """
        u = self.robot.check_q(qd_command, "qd_command")
        steps = self.steps_for(duration_s)
        if self.motor == "torque" and not np.array_equal(u, self._u):
            ramp = steps if self.command_ramp_s is None else self.steps_for(self.command_ramp_s)
            self._u0[:] = self._reference()
            np.subtract(u, self._u0, out=self._du)
            self._du /= ramp * self.physics_dt_s
            self._ramp_steps, self._ramp_done = ramp, 0
        self._u[:] = u
        self._advance(steps)
        return self.measure()

    def _reference(self) -> np.ndarray:
        """Computed torque: the velocity reference ``u_ref`` [rad/s] of the present step."""
        if self._ramp_done >= self._ramp_steps:
            return self._u.copy()
        return self._u0 + (self._ramp_done * self.physics_dt_s) * self._du

    def _drive_torque(self) -> None:
        """The drives' torque ``self._tau`` (clipped) for the present state and command."""
        if self.motor == "velocity":
            self._servo_torque()
        else:
            self._computed_torque()

    def _computed_torque(self) -> None:
        """``τ = M a + C qd + g + D qd``, ``a = (u_ref - qd)/τ_v + q̈_ff``, clipped; advances
        the ramp by one physics step."""
        d = self._data
        q, qd, a, tau = self._q, self._qd, self._a, self._tau
        np.take(d.qpos, self._qpos_idx, out=q)
        np.take(d.qvel, self._dof_idx, out=qd)
        ramping = self._ramp_done < self._ramp_steps
        np.subtract(self._reference(), qd, out=a)
        np.multiply(a, 1.0 / self.servo_time_constant_s, out=a)
        if ramping:
            np.add(a, self._du, out=a)
            self._ramp_done += 1
        tau[:] = pin.rnea(self._pin_model, self._pin_data, q, qd, a)
        tau += self.joint_damping * qd
        np.clip(tau, -self.torque_limit, self.torque_limit, out=tau)

    def _servo_torque(self) -> None:
        """Servo torques ``self._tau`` (clipped) for the current state and command; updates
        the integral term and the reference model (module docstring). No allocation beyond
        the one RNEA result."""
        d = self._data
        q, qd, u, um, w, a, tmp, tau = (
            self._q,
            self._qd,
            self._u,
            self._um,
            self._w,
            self._a,
            self._tmp,
            self._tau,
        )
        np.take(d.qpos, self._qpos_idx, out=q)
        np.take(d.qvel, self._dof_idx, out=qd)
        dt, tau_v, tau_i = (
            self.physics_dt_s,
            self.servo_time_constant_s,
            self.integral_time_constant_s,
        )
        # a = (u - qd)/τ_v + w ;  τ = M_nom a + g_nom
        np.subtract(u, qd, out=a)
        np.multiply(a, 1.0 / tau_v, out=a)
        np.add(a, w, out=a)
        tau[:] = pin.rnea(self._pin_model, self._pin_data, q, self._zero, a)
        # anti-windup: a saturated joint freezes w and resyncs its reference model
        np.abs(tau, out=tmp)
        np.greater_equal(tmp, self.torque_limit, out=self._sat)
        np.logical_not(self._sat, out=self._free)
        np.copyto(um, qd, where=self._sat)
        # w += dt (u_m - qd) / (τ_v τ_i)  on free joints
        np.subtract(um, qd, out=tmp)
        np.multiply(tmp, dt / (tau_v * tau_i), out=tmp)
        np.add(w, tmp, out=w, where=self._free)
        # u_m += (dt/τ_v) (u - u_m): the nominal explicit response to the held command
        np.subtract(u, um, out=tmp)
        np.multiply(tmp, dt / tau_v, out=tmp)
        np.add(um, tmp, out=um)
        np.clip(tau, -self.torque_limit, self.torque_limit, out=tau)

    def _advance(self, steps: int) -> None:
        """``steps`` physics steps of the servo loop."""
        m, d = self._model, self._data
        ctrl, qfrc, dof = d.ctrl, d.qfrc_actuator, self._dof_idx
        tau, tmp, peak = self._tau, self._tmp, self._peak
        servo, mj_step = self._drive_torque, mujoco.mj_step
        peak[:] = 0.0
        for _ in range(steps):
            servo()
            ctrl[:] = tau
            mj_step(m, d)
            np.take(qfrc, dof, out=tau)  # the torque MuJoCo applied (= the clipped command)
            np.abs(tau, out=tmp)
            np.maximum(peak, tmp, out=peak)
        self._check_state()

    def _bad_count(self) -> int:
        """How many bad-state warnings (qpos, qvel, qacc, ctrl) MuJoCo has issued."""
        return int(self._data.warning.number[self._bad].sum())

    def _check_state(self) -> None:
        d = self._data
        count = self._bad_count()
        if count != self._warnings:
            self._warnings = count
            raise DQControlError(
                f"MuJoCo physics became unstable at t = {d.time:.4f} s (it reported a "
                "non-finite or huge position, velocity, acceleration or control and reset "
                "its state). Check the commands, gains and physics_dt_s, then call reset()."
            )
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            raise DQControlError(
                f"MuJoCo state is not finite at t = {d.time:.4f} s: qpos={d.qpos}, "
                f"qvel={d.qvel}. Call reset()."
            )

    def measure(self) -> Measurement:
        """The current measurement, without stepping."""
        d = self._data
        return Measurement(
            t_s=float(d.time),
            q=d.qpos[self._qpos_idx],
            qd=d.qvel[self._dof_idx],
            torque=self._tau.copy(),
            torque_peak=self._peak.copy(),
        )

    # ------------------------------------------------------------------ kinematics
    def ee_pose(self) -> np.ndarray:
        """End-effector pose ``vec8`` in the world, from MuJoCo (rotation with ``r_w ≥ 0``)."""
        m, d = self._model, self._data
        mujoco.mj_kinematics(m, d)
        rot = qfrom_matrix(d.site_xmat[self._site].reshape(3, 3))
        return dq_from_rt(rot, d.site_xpos[self._site].copy())

    def payload_position(self) -> np.ndarray | None:
        """World position of the payload's centre [m], or ``None`` without payload."""
        if self._payload_body < 0:
            return None
        mujoco.mj_kinematics(self._model, self._data)
        return self._data.xpos[self._payload_body].copy()

    def __repr__(self) -> str:
        return (
            f"MujocoSimulation('{self.robot.model.name}', n={self.robot.nq}, "
            f"dt={self.physics_dt_s} s, motor={self.motor!r}, payload={self.payload_kg} kg, "
            f"effort_scale={self.effort_scale})"
        )

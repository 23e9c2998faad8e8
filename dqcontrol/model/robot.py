"""The robot model: a URDF loaded by Pinocchio, with kinematics in dual-quaternion form.

docs/theory.md §2: the end-effector pose ``x`` (``vec8``) comes from Pinocchio's placement
``oMf`` and the 8×n pose Jacobian from Pinocchio's 6×n frame Jacobian in
``LOCAL_WORLD_ALIGNED`` (rows ``[Jv; Jw]``)::

    J_r = ½ H-4(r)[:, 1:4] Jw
    J_d = ½ ( H-4(r)[:, 1:4] Jv + H+4(t) J_r )

written out on floats in :mod:`dqcontrol.dq.kernels` (compiled with Numba), so one call
costs one Pinocchio call, one conversion of the placement and one compiled call.

A batch of configurations (:meth:`RobotModel.poses_and_jacobians`) of a chain of at most
eight revolute joints is computed in closed form without Pinocchio
(:mod:`dqcontrol.model.chain_batch`: a fixed handful of numpy calls for the whole batch);
other models loop over Pinocchio and convert the batch in one compiled call. The choice is
made at load time.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from dqcontrol.dq.kernels import (
    pose_from_xyzquat,
    pose_jacobian_batch,
    pose_jacobian_from_xyzquat,
    pose_jacobian_into,
)
from dqcontrol.errors import ConfigurationError, FrameError, ParameterError, URDFError
from dqcontrol.model.chain_batch import ChainBatch
from dqcontrol.model.chain_dynamics import ChainDynamics, acceleration_bounds
from dqcontrol.model.fast import UncheckedModel
from dqcontrol.model.limit_profile import LimitProfile, fitted_limits, load_profile
from dqcontrol.model.pinocchio_model import angle_model, build_angle_model, lock_joints
from dqcontrol.model.urdf_source import URDFSource, read_urdf

__all__ = ["JointLimits", "RobotModel"]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class JointLimits:
    """Joint limits of a robot, one entry per joint (radians for revolute joints).

    Attributes:
        q_min, q_max: position limits [rad] (or [m] for prismatic joints); ``-inf`` and
            ``inf`` for a continuous joint.
        qd_max: symmetric velocity limit [rad/s].
        effort_max: symmetric torque limit [N·m].
        qdd_max: symmetric acceleration limit [rad/s²]; ``inf`` where none is given (a
            URDF gives none).
        qddd_max: symmetric jerk limit of the commanded velocity [rad/s³]; ``inf`` where
            none is given (a URDF gives none).
    """

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    effort_max: np.ndarray
    qdd_max: np.ndarray | None = None
    qddd_max: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = np.shape(self.q_min)[0]
        for name in ("qdd_max", "qddd_max"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.full(n, np.inf))


class RobotModel:
    """A fixed-base robot from a URDF, with its end-effector pose as a unit dual quaternion.

    Build with :meth:`from_urdf`. All quantities are in the world frame of the model (the
    URDF's root link, moved by ``base`` if one is given). A Pinocchio model given directly
    may hold unbounded revolute joints (``(cos θ, sin θ)``); they become angle-coordinate
    joints (:func:`~dqcontrol.model.pinocchio_model.angle_model`).

    Attributes:
        model, data: the Pinocchio model and its workspace (the model may be reduced).
            Treat ``model`` as read-only: tables for the batched kinematics are built from
            it once, at construction; to change the robot, build a new ``RobotModel``.
        ee_frame: name of the end-effector frame (a ``tool`` offset adds ``<ee>_tool``).
        nq: number of controlled joints ``n``.
        joint_names: names of the controlled joints, in ``q`` order.
        limits: :class:`JointLimits`: the URDF's, or those of a limit profile
            (:meth:`with_limits`).
        limit_profile: the name of the profile :attr:`limits` come from (``"urdf"``: the
            URDF's own).
        source: the URDF text and path (the simulator and the viewer read the same file).
        base_placement: pose of the URDF root in the world [``pin.SE3``].
        locked_joints: joints held fixed, name → position.
    """

    def __init__(
        self,
        model: pin.Model,
        ee_frame: str,
        *,
        source: URDFSource | None = None,
        base_placement: pin.SE3 | None = None,
        locked_joints: dict[str, float] | None = None,
        tool_placement: pin.SE3 | None = None,
    ) -> None:
        model = angle_model(model)  # continuous joints: one angle each
        if model.nq != model.nv:
            bad = [
                model.names[j]
                for j in range(1, model.njoints)
                if model.joints[j].nq != model.joints[j].nv
            ]
            raise URDFError(
                "only 1-DoF revolute, continuous and prismatic joints are supported (q holds "
                f"one number per joint); joints with more: {bad}. Lock them or make them fixed."
            )
        if model.nq == 0:
            raise URDFError("the robot has no movable joint")
        self.model = model
        self.source = source
        self.base_placement = base_placement if base_placement is not None else pin.SE3.Identity()
        self.tool_placement = tool_placement if tool_placement is not None else pin.SE3.Identity()
        self.locked_joints = dict(locked_joints or {})
        self.frame_names = [f.name for f in model.frames]
        if ee_frame not in self.frame_names:
            raise FrameError(
                f"unknown end-effector frame '{ee_frame}'; frames of this robot: "
                f"{sorted(set(self.frame_names))}"
            )
        self.ee_frame = ee_frame
        self._fid = model.getFrameId(ee_frame)
        self.data = model.createData()
        self._omf = self.data.oMf  # cached proxy: saves an attribute lookup per call
        # a reference into data.oMf that Pinocchio updates in place at every call
        self._ee_placement = self.data.oMf[self._fid]
        self.nq = int(model.nq)
        self.joint_names = [model.names[j] for j in range(1, model.njoints)]
        self.limits = JointLimits(
            q_min=np.array(model.lowerPositionLimit, dtype=float),
            q_max=np.array(model.upperPositionLimit, dtype=float),
            qd_max=np.array(model.velocityLimit, dtype=float),
            effort_max=np.array(model.effortLimit, dtype=float),
        )
        self.limit_profile = "urdf"
        self._qdd_cap: np.ndarray | None = None  # the profile's acceleration, where finite
        self._one_dof = model.nv == 1
        # closed-form batched kinematics (None: loop on Pinocchio). Its tables are read from
        # the model here, once: a model edited in place afterwards needs a new RobotModel.
        self._chain = self._build_chain()
        # the same for the mass matrix's diagonal and the gravity torques (None: Pinocchio)
        self._dynamics = self._build_dynamics()
        #: the unchecked hot-path API (:class:`~dqcontrol.model.fast.UncheckedModel`)
        self.fast = UncheckedModel(self)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_urdf(
        cls,
        urdf: str | os.PathLike,
        ee_frame: str,
        *,
        base: pin.SE3 | np.ndarray | None = None,
        tool: pin.SE3 | np.ndarray | None = None,
        locked_joints: dict[str, float] | None = None,
        package_dirs: Sequence[str | os.PathLike] | None = None,
        limits: str | os.PathLike | LimitProfile | None = None,
    ) -> RobotModel:
        """Load a robot from a URDF file path or XML string.

        Args:
            urdf: path to a ``.urdf`` file, or the XML text itself.
            ee_frame: name of the end-effector frame (a link or joint name of the URDF).
            base: pose of the URDF's root link in the world (``pin.SE3``, 4×4 matrix or
                ``vec8``); identity by default.
            tool: fixed offset from ``ee_frame`` to the controlled tool frame; the model then
                controls a new frame ``<ee_frame>_tool``.
            locked_joints: joints to hold fixed (e.g. gripper fingers), name → position
                [rad or m].
            package_dirs: folders where ``package://`` mesh URIs resolve.
            limits: a limit profile (a shipped name, a ``FILE.toml`` or a
                :class:`~dqcontrol.model.limit_profile.LimitProfile`) that replaces the
                URDF's limits (:meth:`with_limits`); ``None``: the URDF's.

        A ``continuous`` joint is a revolute joint without position limit; its coordinate in
        ``q`` is its angle [rad] (:mod:`dqcontrol.model.pinocchio_model`).

        Raises:
            URDFError: missing file, malformed XML, invalid values, unsupported joints.
            FrameError: ``ee_frame`` or a locked joint does not exist (the message lists
                what exists).
        """
        source = read_urdf(urdf, package_dirs)
        model = lock_joints(build_angle_model(source.xml), locked_joints or {})
        base_se3 = _to_se3(base, "base") if base is not None else None
        if base_se3 is not None:
            _move_base(model, base_se3)
        names = [f.name for f in model.frames]
        if ee_frame not in names:
            raise FrameError(
                f"unknown end-effector frame '{ee_frame}'; frames of this robot: "
                f"{sorted(set(names))}"
            )
        tool_se3 = _to_se3(tool, "tool") if tool is not None else None
        if tool_se3 is not None:
            ee_frame = _add_tool_frame(model, ee_frame, tool_se3)
        robot = cls(
            model,
            ee_frame,
            source=source,
            base_placement=base_se3,
            locked_joints=locked_joints,
            tool_placement=tool_se3,
        )
        return robot if limits is None else robot.with_limits(limits)

    def with_limits(self, profile: str | os.PathLike | LimitProfile) -> RobotModel:
        """The same robot with the joint limits of a limit profile (a new model; this one
        is unchanged).

        The profile is put on the robot, not on each controller, because one robot
        description feeds the controllers, the simulator's reflexes, the checker and the
        viewer: a controller built on the returned model takes its position, velocity and
        acceleration bounds from the profile unless given others, and no part of a run can
        use other limits than another (docs/user_guide.md, "Robot limit profiles"). The
        dynamics-aware acceleration bound (:meth:`acceleration_limits`) is capped by the
        profile's acceleration limit.

        Args:
            profile: a shipped profile's name
                (:func:`~dqcontrol.model.limit_profile.profile_names`), the path of a
                ``FILE.toml`` or a loaded :class:`~dqcontrol.model.limit_profile.LimitProfile`;
                ``"urdf"`` keeps the URDF's limits.

        Raises:
            ProfileError: an unknown name or a bad file; a profile for other joints (both
                lists in the message) or looser than the URDF in any entry (the joint, the
                entry and both values).
        """
        if not isinstance(profile, LimitProfile):
            profile = load_profile(profile)
        urdf = (
            np.array(self.model.lowerPositionLimit, dtype=float),
            np.array(self.model.upperPositionLimit, dtype=float),
            np.array(self.model.velocityLimit, dtype=float),
        )
        q_min, q_max, qd_max, qdd_max, qddd_max = fitted_limits(profile, self.joint_names, urdf)
        robot = RobotModel(
            self.model,
            self.ee_frame,
            source=self.source,
            base_placement=self.base_placement,
            locked_joints=self.locked_joints,
            tool_placement=self.tool_placement,
        )
        robot.limits = JointLimits(
            q_min, q_max, qd_max, self.limits.effort_max.copy(), qdd_max, qddd_max
        )
        robot.limit_profile = profile.name
        robot._qdd_cap = qdd_max if np.isfinite(qdd_max).any() else None
        return robot

    # ------------------------------------------------------------------ input checks
    def check_q(self, q: np.ndarray, name: str = "q") -> np.ndarray:
        """Return ``q`` as a float array of shape ``(n,)``; raise on wrong size or NaN/inf."""
        try:
            arr = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise ConfigurationError(
                f"{name} must be an array of {self.nq} numbers [rad], got {q!r}"
            ) from None
        if arr.shape != (self.nq,):
            raise ConfigurationError(
                f"{name} must have shape ({self.nq},) for this robot's joints "
                f"{self.joint_names}, got shape {arr.shape}"
            )
        # a dot product is NaN/inf iff some entry is (or it overflows): cheap first test
        if not math.isfinite(arr.dot(arr)) and not np.isfinite(arr).all():
            raise ConfigurationError(f"{name} must be finite, got {arr}")
        return arr

    def check_batch(self, qs: np.ndarray, name: str = "qs") -> np.ndarray:
        """Return a batch of configurations as a float ``(N, n)`` array, checked."""
        try:
            arr = np.asarray(qs, dtype=float)
        except (TypeError, ValueError):
            raise ConfigurationError(
                f"{name} must be an (N, {self.nq}) array of numbers, got {qs!r}"
            ) from None
        if arr.ndim != 2 or arr.shape[1] != self.nq:
            raise ConfigurationError(
                f"{name} must have shape (N, {self.nq}), got shape {arr.shape}"
            )
        # as in check_q: the dot product is finite unless some entry is not (or it overflows)
        flat = arr.ravel()
        if not math.isfinite(flat.dot(flat)) and not np.isfinite(arr).all():
            raise ConfigurationError(f"{name} must be finite")
        return arr

    # ------------------------------------------------------------------ kinematics
    def pose(self, q: np.ndarray) -> np.ndarray:
        """End-effector pose ``vec8`` in the world frame (rotation with ``r_w ≥ 0``)."""
        return self._pose(self.check_q(q))

    def placement(self, q: np.ndarray, frame: str | None = None) -> pin.SE3:
        """World placement of ``frame`` (default: the end-effector) as a ``pin.SE3``."""
        q = self.check_q(q)
        fid = self._fid if frame is None else self.frame_id(frame)
        pin.framesForwardKinematics(self.model, self.data, q)
        return pin.SE3(self.data.oMf[fid])

    def frame_id(self, frame: str) -> int:
        """Pinocchio index of a frame; :class:`FrameError` listing the frames if unknown."""
        if frame not in self.frame_names:
            raise FrameError(
                f"unknown frame '{frame}'; frames of this robot: {sorted(set(self.frame_names))}"
            )
        return self.model.getFrameId(frame)

    def pose_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """End-effector pose ``vec8`` (8,) and pose Jacobian ``∂vec8(x)/∂q`` (8×n)."""
        return self._pose_and_jacobian(self.check_q(q))

    def pose_jacobian(self, q: np.ndarray) -> np.ndarray:
        """Pose Jacobian ``∂vec8(x)/∂q`` (8×n) of the end-effector (docs/theory.md §2)."""
        return self._pose_and_jacobian(self.check_q(q))[1]

    def _pose(self, q: np.ndarray) -> np.ndarray:
        """Unchecked :meth:`pose` (the kinematics alone, no Jacobian; the same numbers as
        :meth:`pose_and_jacobian`'s pose)."""
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacement(self.model, self.data, self._fid)
        return pose_from_xyzquat(pin.SE3ToXYZQUAT(self._ee_placement))

    def _pose_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unchecked hot-path version of :meth:`pose_and_jacobian` (``q`` already valid)."""
        return pose_jacobian_from_xyzquat(*self._frame_jacobian(q))

    def _pose_and_jacobian_into(self, q: np.ndarray, x: np.ndarray, jac: np.ndarray) -> None:
        """:meth:`_pose_and_jacobian` written into ``x`` (8,) and ``jac`` (8, n)."""
        pose_jacobian_into(*self._frame_jacobian(q), x, jac)

    def _frame_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The end-effector's XYZQUAT (7,) and (6, n) ``LOCAL_WORLD_ALIGNED`` Jacobian."""
        j6 = pin.computeFrameJacobian(self.model, self.data, q, self._fid, _LWA)
        if self._one_dof:  # Pinocchio returns a (6,) Jacobian for a one-joint model
            j6 = j6.reshape(6, 1)
        return pin.SE3ToXYZQUAT(self._ee_placement), j6

    def poses_and_jacobians(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched pose and Jacobian for N configurations: ``(N, 8)`` and ``(N, 8, n)``.

        The predictive controller calls this with its p predicted configurations every
        step. A chain of at most eight revolute joints is computed in closed form for the
        whole batch (:mod:`dqcontrol.model.chain_batch`); any other model loops over
        Pinocchio. Both give the single-configuration result (to rounding), ``r_w ≥ 0``.
        """
        return self._poses_and_jacobians(self.check_batch(qs))

    def _poses_and_jacobians(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if qs.shape[0] == 0:
            return np.empty((0, 8)), np.empty((0, 8, self.nq))
        if self._chain is not None:
            return self._chain(qs)
        return self._poses_and_jacobians_pinocchio(qs)

    def _build_chain(self) -> ChainBatch | None:
        """The closed-form batch of this model, if it applies and agrees with Pinocchio."""
        chain = ChainBatch.build(self.model, self._fid)
        if chain is None:
            return None
        # a safety net against a joint convention the tables got wrong: never trust them
        # without checking them against Pinocchio on a few configurations
        qs = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(4, self.nq))
        xs, jacs = chain(qs)
        xs_ref, jacs_ref = self._poses_and_jacobians_pinocchio(qs)
        if not (
            np.allclose(xs, xs_ref, rtol=0, atol=1e-12)
            and np.allclose(jacs, jacs_ref, rtol=0, atol=1e-12)
        ):
            return None
        return chain

    def _build_dynamics(self) -> ChainDynamics | None:
        """The compiled ``diag M`` and ``g`` of this model, if it applies and agrees with
        Pinocchio's on a few configurations."""
        dynamics = ChainDynamics.build(self.model)
        if dynamics is None:
            return None
        qs = np.random.default_rng(1).uniform(-np.pi, np.pi, size=(4, self.nq))
        diag, g = dynamics.diagonal_and_gravity(qs)
        diag_ref, g_ref = self._diagonal_and_gravity_pinocchio(qs)
        if not (
            np.allclose(diag, diag_ref, rtol=1e-12, atol=1e-12)
            and np.allclose(g, g_ref, rtol=1e-12, atol=1e-10)
        ):
            return None
        return dynamics

    def _diagonal_and_gravity_pinocchio(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``diag M`` and ``g`` at each row of ``qs`` by two Pinocchio calls a row."""
        model, data = self.model, self.data
        crba, gravity = pin.crba, pin.computeGeneralizedGravity
        diag, g = np.empty(qs.shape), np.empty(qs.shape)
        for i, qi in enumerate(qs):
            diag[i] = np.diagonal(crba(model, data, qi))
            g[i] = gravity(model, data, qi)
        return diag, g

    def _poses_and_jacobians_pinocchio(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The batch by one Pinocchio call per configuration (any model; ``N ≥ 1``)."""
        count = qs.shape[0]
        # one Pinocchio call per configuration (≈1 µs each) is the floor; everything else is
        # done once for the batch
        model, data, fid, placement = self.model, self.data, self._fid, self._ee_placement
        jacobian, to_xyzquat = pin.computeFrameJacobian, pin.SE3ToXYZQUAT
        j6s, xqs = [], []
        for qi in qs:
            j6s.append(jacobian(model, data, qi, fid, _LWA))
            xqs.append(to_xyzquat(placement))
        # reshape: for n = 1 Pinocchio returns each Jacobian as a (6,) vector
        return pose_jacobian_batch(np.array(xqs), np.array(j6s).reshape(count, 6, self.nq))

    def poses(self, qs: np.ndarray) -> np.ndarray:
        """Batched end-effector poses ``(N, 8)``."""
        return self._poses_and_jacobians(self.check_batch(qs))[0]

    # ------------------------------------------------------------------ dynamics
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space mass matrix ``M(q)`` (n×n) [kg·m²] from Pinocchio's CRBA."""
        q = self.check_q(q)
        m = pin.crba(self.model, self.data, q)
        return np.triu(m) + np.triu(m, 1).T

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Generalised gravity torques ``g(q)`` [N·m]."""
        return np.array(pin.computeGeneralizedGravity(self.model, self.data, self.check_q(q)))

    def acceleration_limits(
        self,
        q: np.ndarray,
        *,
        effort_fraction: float = 1.0,
        floor_rad_s2: float = 0.5,
        cap_rad_s2: float = 50.0,
    ) -> np.ndarray:
        """Dynamics-aware joint acceleration bound ``a_max(q)`` [rad/s²] (docs/theory.md §5).

        ``a_max_j = (effort_fraction·τ_max_j - |g_j(q)|) / M_jj(q)``, clipped to
        ``[floor_rad_s2, cap_rad_s2]``: the acceleration joint j can reach alone with the
        torque left after holding gravity. It replaces the thesis's estimate (eq. 4.14).
        With a limit profile (:meth:`with_limits`) it is then capped by the profile's
        acceleration limit ``limits.qdd_max``.
        """
        q = self.check_q(q)
        return self._acceleration_limits(q, effort_fraction, floor_rad_s2, cap_rad_s2)

    def _acceleration_limits(
        self, q: np.ndarray, effort_fraction: float, floor: float, cap: float
    ) -> np.ndarray:
        return self._acceleration_limits_batch(q[None, :], effort_fraction, floor, cap)[0]

    def _acceleration_limits_batch(
        self, qs: np.ndarray, effort_fraction: float, floor: float, cap: float
    ) -> np.ndarray:
        """:meth:`_acceleration_limits` at each row of ``qs``: ``diag M`` and ``g`` in one
        compiled pass where the model is a chain of revolute joints
        (:mod:`~dqcontrol.model.chain_dynamics`), else by two Pinocchio calls a row; the
        arithmetic once for the batch."""
        self._check_acceleration_settings(effort_fraction, floor, cap)
        if self._dynamics is not None:
            diag, g = self._dynamics.diagonal_and_gravity(qs)
        else:
            diag, g = self._diagonal_and_gravity_pinocchio(qs)
        bounds, positive = acceleration_bounds(
            diag, g, effort_fraction, self.limits.effort_max, floor, cap
        )
        if not positive:
            for row in diag:  # the first configuration with a massless joint
                self._check_inertias(row)
        if self._qdd_cap is not None:  # never above the profile's acceleration limit
            np.minimum(bounds, self._qdd_cap, out=bounds)
        return bounds

    @staticmethod
    def _check_acceleration_settings(effort_fraction: float, floor: float, cap: float) -> None:
        if not 0.0 < effort_fraction <= 1.0:
            raise ParameterError(f"effort_fraction must be in (0, 1], got {effort_fraction}")
        if not 0.0 < floor <= cap:
            raise ParameterError(
                f"need 0 < floor_rad_s2 ≤ cap_rad_s2 [rad/s²], got {floor} and {cap}"
            )

    def _check_inertias(self, diag: np.ndarray) -> None:
        """:class:`ParameterError` naming the first joint with ``M_jj ≤ 0`` (or NaN)."""
        if not np.all(diag > 0.0):
            j = int(np.flatnonzero(~(diag > 0.0))[0])
            name = self.joint_names[j] if len(self.joint_names) == diag.size else f"#{j}"
            raise ParameterError(
                f"joint '{name}' moves no mass or inertia (M_jj = {diag[j]}): "
                "dynamics-aware acceleration limits need the URDF's inertias; pass a constant "
                "acceleration_limit [rad/s²] instead"
            )

    def random_configurations(self, count: int, seed: int, margin_rad: float = 0.0) -> np.ndarray:
        """``count`` uniformly drawn configurations within the limits (shrunk by a margin).

        A joint without position limit (continuous) is drawn in ``[-π, π]``.
        """
        rng = np.random.default_rng(seed)
        lo = np.where(np.isfinite(self.limits.q_min), self.limits.q_min + margin_rad, -np.pi)
        hi = np.where(np.isfinite(self.limits.q_max), self.limits.q_max - margin_rad, np.pi)
        return rng.uniform(lo, hi, size=(count, self.nq))

    def __repr__(self) -> str:
        return (
            f"RobotModel('{self.model.name}', n={self.nq}, ee_frame='{self.ee_frame}', "
            f"joints={self.joint_names})"
        )


def _move_base(model: pin.Model, base: pin.SE3) -> None:
    """Place the root link at ``base`` in the world: the joints and frames on the root."""
    for j in range(1, model.njoints):
        if model.parents[j] == 0:
            model.jointPlacements[j] = base * model.jointPlacements[j]
    for f in range(1, len(model.frames)):
        frame = model.frames[f]
        if frame.parentJoint == 0:
            frame.placement = base * frame.placement
            model.frames[f] = frame


def _add_tool_frame(model: pin.Model, ee_frame: str, tool: pin.SE3) -> str:
    """Add the frame ``<ee_frame>_tool`` at ``tool`` from ``ee_frame``; its name."""
    parent = model.frames[model.getFrameId(ee_frame)]
    tool_name = f"{ee_frame}_tool"
    model.addFrame(
        pin.Frame(
            tool_name,
            parent.parentJoint,
            model.getFrameId(ee_frame),
            parent.placement * tool,
            pin.FrameType.OP_FRAME,
        )
    )
    return tool_name


def _to_se3(value: pin.SE3 | np.ndarray, name: str) -> pin.SE3:
    from dqcontrol.dq.algebra import dq_is_unit, dq_to_se3

    if isinstance(value, pin.SE3):
        return pin.SE3(value)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.shape == (4, 4) and np.isfinite(arr).all():
        rot = arr[:3, :3]
        if np.allclose(rot.T @ rot, np.eye(3), atol=1e-9) and np.linalg.det(rot) > 0:
            return pin.SE3(rot, arr[:3, 3])
    if arr.shape == (8,) and np.isfinite(arr).all() and dq_is_unit(arr, 1e-9):
        return dq_to_se3(arr)
    raise ParameterError(
        f"{name} must be a pin.SE3, a 4×4 homogeneous transform or a unit vec8, got {value!r}"
    )

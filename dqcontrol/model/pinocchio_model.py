"""The Pinocchio model of a URDF with one angle per joint, and its reduction by locked joints.

Pinocchio models a URDF ``continuous`` joint as an *unbounded* revolute joint whose
configuration is the pair ``(cos θ, sin θ)`` (``nq = 2``, ``nv = 1``). dqcontrol's joint
vector ``q`` holds one number per joint, so :func:`angle_model` replaces each such joint
by the revolute joint about the same axis whose coordinate is the angle ``θ`` itself
[rad], with no position limit (``-inf ≤ θ ≤ inf``). The two are the same kinematics: the
placement of the revolute joint at ``θ`` is the placement of the unbounded one at
``(cos θ, sin θ)``. Joint indices, frames, inertias and the velocity, effort, friction and
damping limits are kept, so a geometry model built on the original model's frames fits the
new one.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from dqcontrol.errors import FrameError, URDFError

__all__ = ["angle_model", "build_angle_model", "has_unbounded_joints", "lock_joints"]

_ALIGNED = {
    "JointModelRUBX": pin.JointModelRX,
    "JointModelRUBY": pin.JointModelRY,
    "JointModelRUBZ": pin.JointModelRZ,
}
_UNALIGNED = "JointModelRevoluteUnboundedUnaligned"


def _is_unbounded(joint) -> bool:
    return joint.shortname() in _ALIGNED or joint.shortname() == _UNALIGNED


def has_unbounded_joints(model: pin.Model) -> bool:
    """Whether ``model`` has a ``(cos θ, sin θ)`` revolute joint (a URDF ``continuous``)."""
    return any(_is_unbounded(model.joints[j]) for j in range(1, model.njoints))


def _revolute_like(joint) -> pin.JointModel:
    """The bounded revolute joint model about the axis of the unbounded ``joint``."""
    name = joint.shortname()
    if name in _ALIGNED:
        return _ALIGNED[name]()
    # the axis is the angular part of the motion subspace (the same at every angle)
    data = joint.createData()
    joint.calc(data, np.array([1.0, 0.0]))
    axis = np.array(data.S, dtype=float).reshape(6)[3:]
    return pin.JointModelRevoluteUnaligned(axis / np.linalg.norm(axis))


def angle_model(model: pin.Model) -> pin.Model:
    """``model`` with every unbounded revolute joint replaced by an angle-coordinate revolute
    joint without position limit; ``model`` itself when it has none (module docstring)."""
    if not has_unbounded_joints(model):
        return model
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    lower, upper = [], []
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if _is_unbounded(joint):
            replacement = _revolute_like(joint)
            lower.append(np.array([-np.inf]))
            upper.append(np.array([np.inf]))
        else:
            replacement = joint
            span = slice(joint.idx_q, joint.idx_q + joint.nq)
            lower.append(np.array(model.lowerPositionLimit[span]))
            upper.append(np.array(model.upperPositionLimit[span]))
        new.addJoint(int(model.parents[j]), replacement, model.jointPlacements[j], model.names[j])
    for f in range(1, model.nframes):
        new.addFrame(pin.Frame(model.frames[f]), False)
    for j in range(model.njoints):
        new.inertias[j] = model.inertias[j]
    new.lowerPositionLimit = np.concatenate(lower) if lower else np.zeros(0)
    new.upperPositionLimit = np.concatenate(upper) if upper else np.zeros(0)
    # tangent-space vectors have the same layout in both models (nv and idx_v unchanged)
    for name in (
        "velocityLimit", "effortLimit", "friction", "damping", "armature", "rotorInertia",
        "rotorGearRatio", "lowerEffortLimit", "upperEffortLimit", "lowerVelocityLimit",
        "upperVelocityLimit", "lowerDryFrictionLimit", "upperDryFrictionLimit",
    ):  # fmt: skip
        setattr(new, name, np.array(getattr(model, name)))
    return new


def build_angle_model(xml: str) -> pin.Model:
    """The fixed-base Pinocchio model of a URDF text, one angle per revolute joint.

    Raises:
        URDFError: Pinocchio cannot build a model from the text.
    """
    try:
        model = pin.buildModelFromXML(xml)
    except (ValueError, RuntimeError) as exc:
        raise URDFError(f"Pinocchio could not build a model from the URDF: {exc}") from None
    return angle_model(model)


def lock_joints(
    model: pin.Model,
    locked_joints: Mapping[str, float],
    geometry: pin.GeometryModel | None = None,
):
    """``model`` (and ``geometry``, if given) reduced by holding joints at fixed positions.

    Args:
        model: a model with one coordinate per joint (:func:`angle_model`).
        locked_joints: joint name → position [rad or m].
        geometry: a geometry model on ``model``'s frames, reduced with it.

    Returns:
        The reduced model, or ``(model, geometry)`` when ``geometry`` is given.

    Raises:
        FrameError: a name is not a joint of ``model`` (the message lists the joints).
    """
    if not locked_joints:
        return model if geometry is None else (model, geometry)
    ids, q_reference = [], pin.neutral(model)
    for name, value in locked_joints.items():
        if not model.existJointName(name):
            raise FrameError(
                f"cannot lock unknown joint '{name}'; joints of this robot: {list(model.names)[1:]}"
            )
        jid = model.getJointId(name)
        ids.append(jid)
        q_reference[model.idx_qs[jid]] = float(value)
    if geometry is None:
        return pin.buildReducedModel(model, ids, q_reference)
    return pin.buildReducedModel(model, geometry, ids, q_reference)

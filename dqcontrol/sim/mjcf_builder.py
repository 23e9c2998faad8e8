"""Build the MuJoCo model of a :class:`~dqcontrol.model.robot.RobotModel` from its own URDF.

One description of the robot (STYLE: "never three"): the simulator reads the very URDF text
Pinocchio read (``robot.source``), then edits it as an :class:`mujoco.MjSpec`:

1. :func:`prepare_urdf_xml` rewrites the XML for MuJoCo's URDF importer: ``package://``,
   ``file://`` and relative mesh paths become absolute files; visual meshes MuJoCo cannot
   read (``.dae`` ...) are dropped (they only matter for drawing); the ``<mujoco><compiler>``
   block is set so that every link stays a body (``fusestatic="false"``), visuals are kept,
   paths are not stripped, and a link without ``<inertial>`` has no mass (as in Pinocchio;
   MuJoCo's default would give it the mass of its collision geoms).
2. :func:`build_spec` splits each concave collision mesh into convex parts
   (:mod:`dqcontrol.sim.convex_parts`: MuJoCo collides a mesh as its hull), moves the root
   to ``robot.base_placement``, welds locked joints at their lock value, sets armature,
   damping and the torque limits of the controlled joints, adds a site named
   ``robot.ee_frame`` at the Pinocchio end-effector frame, an optional payload body at that
   frame, one torque actuator (``motor``, clamped to the torque limit) per
   controlled joint, and the obstacles (:func:`add_obstacles`: static geoms in the world).

:func:`count_contacts` sorts a state's contacts into robot–obstacle and self contacts.

Nothing here steps physics; :mod:`dqcontrol.sim.mujoco_sim` owns the servo loop.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from dqcontrol.dq.algebra import qfrom_axis_angle, qfrom_matrix, qmul, qto_matrix
from dqcontrol.errors import ConfigurationError, ParameterError, URDFError
from dqcontrol.extras import lazy_module
from dqcontrol.model.collision import Box, Capsule, Cylinder, HalfSpace, Obstacle, Sphere
from dqcontrol.model.meshes import find_mesh
from dqcontrol.model.robot import RobotModel
from dqcontrol.model.urdf_source import URDFSource
from dqcontrol.sim.convex_parts import convex_parts

if TYPE_CHECKING:
    import mujoco
else:  # imported on first use: the package works without the sim extra
    mujoco = lazy_module("mujoco", extra="sim", purpose="the MuJoCo model")

__all__ = [
    "MESH_EXTENSIONS",
    "PAYLOAD_BODY",
    "ACTUATOR_SUFFIX",
    "OBSTACLE_PREFIX",
    "ContactCount",
    "PreparedURDF",
    "SpecOptions",
    "add_obstacles",
    "build_spec",
    "contact_model",
    "count_contacts",
    "replay_contacts",
    "prepare_urdf_xml",
    "resolve_mesh_path",
]

#: Mesh file types MuJoCo's compiler reads (others, e.g. COLLADA ``.dae``, are refused).
MESH_EXTENSIONS = frozenset({".stl", ".obj", ".msh"})
#: Name of the payload body added at the end-effector frame when ``payload_kg > 0``.
PAYLOAD_BODY = "dqcontrol_payload"
#: Actuator of joint ``j`` is named ``j + ACTUATOR_SUFFIX``.
ACTUATOR_SUFFIX = "_servo"
#: Radius [m] of the payload's solid-sphere inertia (and of its visual marker).
PAYLOAD_RADIUS_M = 0.02
#: Obstacle ``name`` is the geom ``OBSTACLE_PREFIX + name``.
OBSTACLE_PREFIX = "obstacle_"

# Compiler settings the simulator relies on; they override the URDF's own <mujoco> block.
_FORCED_COMPILER = {
    "fusestatic": "false",  # every link stays a body (frames, EE, payload need them)
    "discardvisual": "false",  # keep visuals for a viewer (group 1, no contact, no mass)
    "strippath": "false",  # mesh paths are absolute after prepare_urdf_xml
    "inertiafromgeom": "false",  # a link without <inertial> is massless, as in Pinocchio
}
# Defaults that a URDF's <mujoco><compiler> may override.
_DEFAULT_COMPILER = {"balanceinertia": "true"}


@dataclass(frozen=True)
class PreparedURDF:
    """URDF text ready for ``mujoco.MjSpec.from_string`` and what was changed to get it.

    Attributes:
        xml: the rewritten URDF.
        dropped_visuals: visual meshes removed (path and reason), for the record.
    """

    xml: str
    dropped_visuals: tuple[str, ...]


@dataclass(frozen=True)
class SpecOptions:
    """What :func:`build_spec` adds to the imported URDF (all arrays in ``robot.joint_names``
    order; validated by the caller).

    Attributes:
        physics_dt_s: MuJoCo time step [s].
        gravity: gravity on (-9.81 m/s² along world z) or off.
        armature_kg_m2: rotor inertia reflected to each joint [kg·m²].
        damping_nms_rad: viscous joint damping [N·m·s/rad]; ``None`` keeps the URDF's.
        effort_limit_nm: torque limit of each joint's drive [N·m] (already scaled).
        payload_kg: extra mass at the end-effector [kg] (0: no payload body).
        payload_offset_m: payload centre in the end-effector frame [m].
        obstacles: static obstacles in the world (named, e.g. by
            :class:`~dqcontrol.model.collision.CollisionModel`).
    """

    physics_dt_s: float
    gravity: bool
    armature_kg_m2: np.ndarray
    damping_nms_rad: np.ndarray | None
    effort_limit_nm: np.ndarray
    payload_kg: float
    payload_offset_m: np.ndarray
    obstacles: tuple[Obstacle, ...] = ()


# ----------------------------------------------------------------------------- URDF text
def resolve_mesh_path(filename: str, source: URDFSource) -> Path | None:
    """Absolute path of a URDF mesh ``filename``, or ``None`` if no such file exists (or a
    ``package://`` path climbs out of its package folder); the search is
    :func:`dqcontrol.model.meshes.find_mesh`'s."""
    return find_mesh(filename, source.package_dirs, source.directory).path


def prepare_urdf_xml(source: URDFSource) -> PreparedURDF:
    """Rewrite a URDF for MuJoCo's importer (module docstring, step 1).

    Raises:
        URDFError: a collision mesh cannot be found or has a type MuJoCo cannot read (the
            simulation would silently lose that link's collision geometry). A source from
            :func:`~dqcontrol.model.urdf_source.read_urdf` was already checked for both
            (:mod:`dqcontrol.model.meshes`); this guards a hand-made one.
    """
    try:
        root = ET.fromstring(source.xml)
    except ET.ParseError as exc:  # read_urdf already checked it; keep the error typed
        raise URDFError(f"malformed URDF XML: {exc}") from None
    where = str(source.path) if source.path is not None else "<string>"
    dropped: list[str] = []
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for element in list(link.findall(tag)):
                mesh = element.find("geometry/mesh")
                if mesh is None:
                    continue
                filename = mesh.get("filename", "")
                path = resolve_mesh_path(filename, source)
                problem = None
                if path is None:
                    problem = (
                        f"file not found (package_dirs={[str(d) for d in source.package_dirs]}, "
                        f"URDF folder={source.directory})"
                    )
                elif path.suffix.lower() not in MESH_EXTENSIONS:
                    problem = (
                        f"MuJoCo cannot read '{path.suffix}' meshes (it reads "
                        f"{sorted(MESH_EXTENSIONS)})"
                    )
                if problem is None:
                    mesh.set("filename", str(path))
                elif tag == "visual":
                    link.remove(element)
                    dropped.append(f"{link.get('name')}: {filename}: {problem}")
                else:
                    raise URDFError(
                        f"{where}: collision mesh '{filename}' of link '{link.get('name')}': "
                        f"{problem}. Pass package_dirs to the robot loader, or convert the "
                        "mesh to STL/OBJ."
                    )
    block = root.find("mujoco")
    if block is None:
        block = ET.SubElement(root, "mujoco")
    compiler = block.find("compiler")
    if compiler is None:
        compiler = ET.SubElement(block, "compiler")
    for key, value in _DEFAULT_COMPILER.items():
        compiler.set(key, compiler.get(key, value))
    for key, value in _FORCED_COMPILER.items():
        compiler.set(key, value)
    return PreparedURDF(ET.tostring(root, encoding="unicode"), tuple(dropped))


# ----------------------------------------------------------------------------- spec edits
def _pos_quat(placement: pin.SE3) -> tuple[np.ndarray, np.ndarray]:
    return np.array(placement.translation, dtype=float), qfrom_matrix(placement.rotation)


def _body_quat(spec: mujoco.MjSpec, body: mujoco.MjsBody) -> np.ndarray:
    if body.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        return np.asarray(spec.resolve_orientation(False, None, body.alt), dtype=float)
    q = np.asarray(body.quat, dtype=float)
    return q / np.linalg.norm(q)


def _lock_joint(spec: mujoco.MjSpec, name: str, value: float) -> None:
    """Weld joint ``name`` at ``value`` [rad or m]: fold the motion into its body's pose."""
    joint = spec.joint(name)
    if joint is None:
        raise URDFError(f"locked joint '{name}' is not in the MuJoCo model of the URDF")
    body = joint.parent
    quat = _body_quat(spec, body)
    rot = qto_matrix(quat)
    axis = np.asarray(joint.axis, dtype=float)
    anchor = np.asarray(joint.pos, dtype=float)
    ref = float(joint.ref)
    if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
        dq = qfrom_axis_angle(axis, value - ref)
        # rotation about the axis through `anchor` (body frame): x -> a + R (x - a)
        offset = anchor - qto_matrix(dq) @ anchor
        body.pos = np.asarray(body.pos, dtype=float) + rot @ offset
        body.quat = qmul(quat, dq)
    elif joint.type == mujoco.mjtJoint.mjJNT_SLIDE:
        body.pos = np.asarray(body.pos, dtype=float) + rot @ (axis / np.linalg.norm(axis)) * (
            value - ref
        )
        body.quat = quat
    else:
        raise ConfigurationError(
            f"cannot lock joint '{name}' of MuJoCo type {joint.type}: only 1-DoF joints"
        )
    spec.delete(joint)


def build_spec(robot: RobotModel, prepared: PreparedURDF, options: SpecOptions) -> mujoco.MjSpec:
    """The edited :class:`mujoco.MjSpec` of ``robot`` (module docstring, step 2).

    Raises:
        URDFError: MuJoCo cannot import the URDF, or a controlled joint is missing from it.
    """
    spec = _import_urdf(prepared)
    _split_concave_meshes(spec)
    _set_physics(spec, options)
    _place_base(spec, robot)
    _lock_joints(spec, robot)
    _add_drives(spec, robot, options)
    ee_body, site_pos, site_quat = _add_ee_site(spec, robot)
    if options.payload_kg > 0.0:
        _add_payload(ee_body, site_pos, site_quat, options)
    add_obstacles(spec, options.obstacles)
    return spec


def _import_urdf(prepared: PreparedURDF) -> mujoco.MjSpec:
    """Import the prepared URDF text as a :class:`mujoco.MjSpec`.

    Raises:
        URDFError: MuJoCo cannot import the URDF.
    """
    try:
        return mujoco.MjSpec.from_string(prepared.xml)
    except ValueError as exc:
        raise URDFError(f"MuJoCo could not import the URDF: {exc}") from None


#: The placement and contact attributes a convex part takes from the geom it replaces.
_PART_ATTRIBUTES = (
    "pos", "quat", "alt", "contype", "conaffinity", "condim", "group", "priority", "friction",
    "solmix", "solref", "solimp", "margin", "gap", "rgba",
)  # fmt: skip


def _split_concave_meshes(spec: mujoco.MjSpec) -> None:
    """Replace each collision geom of a concave mesh by one geom per convex part of it
    (:func:`~dqcontrol.sim.convex_parts.convex_parts`), in the same body and place; the
    visual geoms keep the mesh as it is."""
    meshes = {mesh.name: mesh for mesh in spec.meshes}
    geoms = [
        geom
        for geom in spec.geoms
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH and (geom.contype or geom.conaffinity)
    ]
    used = sorted({geom.meshname for geom in geoms})
    found = convex_parts(
        [(Path(meshes[name].file), np.asarray(meshes[name].scale, dtype=float)) for name in used]
    )
    parts_of = dict(zip(used, found, strict=True))
    for geom in geoms:
        parts = parts_of[geom.meshname]
        if parts is None:
            continue
        for k, vertices in enumerate(parts):
            name = f"{geom.meshname}_part{k}"
            if name not in meshes:
                meshes[name] = spec.add_mesh(name=name, uservert=vertices.ravel().tolist())
            part = geom.parent.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name)
            for attribute in _PART_ATTRIBUTES:
                setattr(part, attribute, getattr(geom, attribute))
            if geom.frame is not None:
                part.set_frame(geom.frame)
            if geom.name:
                part.name = f"{geom.name}_part{k}"
        spec.delete(geom)


def _set_physics(spec: mujoco.MjSpec, options: SpecOptions) -> None:
    """Set the time step, the ``implicitfast`` integrator and the gravity of ``options``."""
    spec.option.timestep = options.physics_dt_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -9.81] if options.gravity else [0.0, 0.0, 0.0]


def _place_base(spec: mujoco.MjSpec, robot: RobotModel) -> None:
    """Hang every top-level body from a frame at ``robot.base_placement``."""
    base_pos, base_quat = _pos_quat(robot.base_placement)
    base = spec.worldbody.add_frame(name="dqcontrol_base", pos=base_pos, quat=base_quat)
    for body in list(spec.worldbody.bodies):
        body.set_frame(base)


def _lock_joints(spec: mujoco.MjSpec, robot: RobotModel) -> None:
    """Weld each of ``robot.locked_joints`` at its value and delete the joint couplings
    (a URDF ``<mimic>`` becomes a joint equality) that involve a locked joint."""
    for name, value in robot.locked_joints.items():
        _lock_joint(spec, name, float(value))
    locked = set(robot.locked_joints)
    for eq in list(spec.equalities):
        if eq.type == mujoco.mjtEq.mjEQ_JOINT and {eq.name1, eq.name2} & locked:
            spec.delete(eq)


def _add_drives(spec: mujoco.MjSpec, robot: RobotModel, options: SpecOptions) -> None:
    """Set armature, damping and torque limit of every controlled joint and give it a
    torque motor, in ``robot.joint_names`` order.

    Raises:
        URDFError: a controlled joint is missing from the imported URDF.
    """
    limited = mujoco.mjtLimited.mjLIMITED_TRUE
    for i, name in enumerate(robot.joint_names):
        joint = spec.joint(name)
        if joint is None:
            raise URDFError(f"controlled joint '{name}' is not in the MuJoCo model of the URDF")
        joint.armature = float(options.armature_kg_m2[i])
        if options.damping_nms_rad is not None:
            joint.damping = [float(options.damping_nms_rad[i]), 0.0, 0.0]
        limit = float(options.effort_limit_nm[i])
        joint.actfrclimited = limited
        joint.actfrcrange = [-limit, limit]
        _add_motor(spec, name, limit)


def _add_motor(spec: mujoco.MjSpec, joint: str, limit: float) -> None:
    """Add the torque motor of ``joint``, its control and force clamped to ``±limit``
    [N·m]; the servo law runs in :mod:`dqcontrol.sim.mujoco_sim`."""
    limited = mujoco.mjtLimited.mjLIMITED_TRUE
    act = spec.add_actuator(
        name=joint + ACTUATOR_SUFFIX, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT
    )
    act.set_to_motor()
    act.gear = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    act.ctrllimited = limited
    act.ctrlrange = [-limit, limit]
    act.forcelimited = limited
    act.forcerange = [-limit, limit]


def _add_ee_site(
    spec: mujoco.MjSpec, robot: RobotModel
) -> tuple[mujoco.MjsBody, np.ndarray, np.ndarray]:
    """Add the site ``robot.ee_frame`` at the Pinocchio end-effector frame, on the body of
    the frame's parent joint.

    Returns:
        The body carrying the site, and the site's position [m] and quaternion ``wxyz`` in
        that body.

    Raises:
        URDFError: the joint carrying the end-effector frame is missing from the URDF.
    """
    frame = robot.model.frames[robot.model.getFrameId(robot.ee_frame)]
    if frame.parentJoint == 0:
        ee_body = spec.worldbody
    else:
        joint = spec.joint(robot.model.names[frame.parentJoint])
        if joint is None:
            raise URDFError(
                f"joint '{robot.model.names[frame.parentJoint]}' carrying the end-effector "
                "frame is not in the MuJoCo model of the URDF"
            )
        ee_body = joint.parent
    site_pos, site_quat = _pos_quat(frame.placement)
    ee_body.add_site(
        name=robot.ee_frame,
        pos=site_pos,
        quat=site_quat,
        size=[0.01, 0.0, 0.0],
        rgba=[0.1, 0.8, 0.1, 0.6],
        group=2,
    )
    return ee_body, site_pos, site_quat


def _add_payload(
    ee_body: mujoco.MjsBody, site_pos: np.ndarray, site_quat: np.ndarray, options: SpecOptions
) -> None:
    """Add the payload body of ``options.payload_kg`` [kg] to ``ee_body``, centred at
    ``options.payload_offset_m`` [m] from the end-effector site (at ``site_pos`` [m], with
    quaternion ``site_quat`` in ``ee_body``): a small solid sphere, drawn but without
    contacts."""
    mass = float(options.payload_kg)
    inertia = 0.4 * mass * PAYLOAD_RADIUS_M**2  # solid sphere: "a point-ish mass"
    payload = ee_body.add_body(
        name=PAYLOAD_BODY,
        pos=site_pos + qto_matrix(site_quat) @ options.payload_offset_m,
        quat=[1.0, 0.0, 0.0, 0.0],
        mass=mass,
        inertia=[inertia, inertia, inertia],
        explicitinertial=True,
    )
    payload.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[PAYLOAD_RADIUS_M, 0.0, 0.0],
        contype=0,
        conaffinity=0,
        group=1,
        density=0.0,
        rgba=[0.8, 0.1, 0.1, 1.0],
    )


def add_obstacles(spec: mujoco.MjSpec, obstacles: tuple[Obstacle, ...]) -> None:
    """Add each obstacle as a static geom of the world body, named
    ``OBSTACLE_PREFIX + name`` (a :class:`HalfSpace` as a MuJoCo plane, which collides as the
    solid below it). Contacts with the robot's collision geoms are on."""
    for k, obs in enumerate(obstacles):
        name = OBSTACLE_PREFIX + (obs.name or str(k))
        rgba = [0.55, 0.35, 0.75, 0.6]
        if isinstance(obs, HalfSpace):
            normal = np.array(obs.normal)
            axis = np.cross([0.0, 0.0, 1.0], normal)
            angle = float(np.arctan2(np.linalg.norm(axis), normal[2]))
            axis = (
                axis / np.linalg.norm(axis)
                if np.linalg.norm(axis) > 1e-12
                else np.array([1.0, 0.0, 0.0])
            )
            spec.worldbody.add_geom(
                name=name,
                type=mujoco.mjtGeom.mjGEOM_PLANE,
                size=[0.0, 0.0, 0.05],
                pos=normal * obs.offset_m,
                quat=qfrom_axis_angle(axis, angle),
                rgba=rgba,
            )
            continue
        if isinstance(obs, Sphere):
            kind, size = mujoco.mjtGeom.mjGEOM_SPHERE, [obs.radius_m, 0.0, 0.0]
        elif isinstance(obs, Box):
            kind, size = mujoco.mjtGeom.mjGEOM_BOX, [0.5 * v for v in obs.size_m]
        elif isinstance(obs, Capsule):
            kind, size = mujoco.mjtGeom.mjGEOM_CAPSULE, [obs.radius_m, 0.5 * obs.length_m, 0.0]
        elif isinstance(obs, Cylinder):
            kind, size = mujoco.mjtGeom.mjGEOM_CYLINDER, [obs.radius_m, 0.5 * obs.length_m, 0.0]
        else:
            raise ConfigurationError(f"obstacle {name}: unsupported shape {type(obs).__name__}")
        spec.worldbody.add_geom(
            name=name,
            type=kind,
            size=size,
            pos=list(obs.position_m),
            quat=list(obs.quaternion_wxyz),
            rgba=rgba,
        )


@dataclass(frozen=True)
class ContactCount:
    """The contacts of one state.

    Attributes:
        obstacle: contacts between the robot and an obstacle.
        self_contact: contacts between two of the robot's geoms.
        deepest_m: the deepest penetration over them [m] (0 without contact).
    """

    obstacle: int
    self_contact: int
    deepest_m: float


def count_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> ContactCount:
    """Sort the contacts of ``data`` (after ``mj_forward`` or a step) into robot–obstacle and
    self contacts; contacts between two obstacles are not counted."""
    obstacle = self_contact = 0
    deepest = 0.0
    for i in range(data.ncon):
        con = data.contact[i]
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in con.geom]
        on_obstacle = [n.startswith(OBSTACLE_PREFIX) for n in names]
        if all(on_obstacle):
            continue
        if any(on_obstacle):
            obstacle += 1
        else:
            self_contact += 1
        deepest = max(deepest, -float(con.dist))
    return ContactCount(obstacle, self_contact, deepest)


def contact_model(
    robot: RobotModel, obstacles: tuple[Obstacle, ...]
) -> tuple[mujoco.MjModel, mujoco.MjData, list[int]]:
    """The robot's MuJoCo model with ``obstacles``, for contact queries at given
    configurations (no dynamics): the model, its data and the ``qpos`` address of each of
    ``robot.joint_names``."""
    n = robot.nq
    effort = np.asarray(robot.limits.effort_max, dtype=float)
    effort = np.where(np.isfinite(effort) & (effort > 0.0), effort, 1.0)  # unused: no dynamics
    options = SpecOptions(
        0.001, False, np.zeros(n), None, effort, 0.0, np.zeros(3), tuple(obstacles)
    )
    if robot.source is None:
        raise ParameterError(
            "robot has no URDF source (build it with RobotModel.from_urdf or a loader)"
        )
    model = build_spec(robot, prepare_urdf_xml(robot.source), options).compile()
    joint = mujoco.mjtObj.mjOBJ_JOINT
    adr = [int(model.jnt_qposadr[mujoco.mj_name2id(model, joint, j)]) for j in robot.joint_names]
    return model, mujoco.MjData(model), adr


def replay_contacts(
    robot: RobotModel, obstacles: tuple[Obstacle, ...], qs: np.ndarray
) -> ContactCount:
    """Contacts of a run's configurations ``qs`` ``(N, n)`` [rad] in the robot's MuJoCo model
    with ``obstacles`` (positions set, ``mj_forward``; no dynamics): the contacts summed over
    the samples and the deepest penetration [m]."""
    model, data, adr = contact_model(robot, obstacles)
    obstacle = self_contact = 0
    deepest = 0.0
    for q in np.atleast_2d(qs):
        data.qpos[adr] = q
        mujoco.mj_forward(model, data)
        found = count_contacts(model, data)
        obstacle += found.obstacle
        self_contact += found.self_contact
        deepest = max(deepest, found.deepest_m)
    return ContactCount(obstacle, self_contact, deepest)

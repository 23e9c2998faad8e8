"""Collision geometry: the robot's from its URDF, obstacles from the user, and the distances
between them with their gradients (docs/theory.md §10.1).

The robot's collision shapes are read from the same URDF as its kinematics, through
Pinocchio's ``GeometryModel``; distances come from coal (the distance library that ships
with Pinocchio). Meshes are replaced by their convex hulls (a conservative shape: the
distance to the hull is at most the distance to the mesh), so that every pair is convex,
solved by GJK/EPA, and the distance is continuous in ``q``. The pairs that have a closed
form (a sphere against a sphere, a cylinder, a box or a half-space, a cylinder against a
half-space) are solved without coal, with coal's results
(:mod:`~dqcontrol.model.collision_closed_forms`).

Obstacles are frozen values with units, fixed in the world: :class:`Sphere`, :class:`Box`,
:class:`Capsule`, :class:`Cylinder` at a pose, and :class:`HalfSpace` (a table or floor).

The pairs considered (:class:`CollisionModel`) are every shape on a moving link against
every obstacle and, for self-collision, every pair of shapes except those that cannot move
relative to each other (on the same rigid body), those on adjacent bodies (one joint between
them, touching by design) and those on link pairs the user allows (a list, or the
``<disable_collisions>`` of an SRDF file).

For a pair ``(a, b)`` at distance ``d`` with witness points ``p_a``, ``p_b`` and unit normal
``n`` from ``a`` to ``b`` (``n = (p_b - p_a)/d`` when separated), the distance changes as

    ḋ = nᵀ (J_b(p_b) - J_a(p_a)) q̇,

with ``J_x(p)`` the Jacobian of the body-fixed point at ``p`` (zero for an obstacle): the
gradient ``∇d = (J_b - J_a)ᵀ n`` [m/rad].
"""

from __future__ import annotations

import dataclasses
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import coal
import numpy as np
import pinocchio as pin

from dqcontrol.errors import ParameterError
from dqcontrol.model.collision_bounds import bounding_capsule, pair_levers, support_form
from dqcontrol.model.collision_closed_forms import closed_form_table
from dqcontrol.model.collision_kernels import (
    FORM_SIZE,
    SEPARATED_M,
    capsule_gaps,
    chain_kinematics,
    collect_pairs,
    screen_pairs,
)
from dqcontrol.model.pinocchio_model import build_angle_model, lock_joints
from dqcontrol.model.robot import RobotModel

__all__ = [
    "Box",
    "Capsule",
    "CollisionModel",
    "Cylinder",
    "DistanceBatch",
    "HalfSpace",
    "Obstacle",
    "OBSTACLE_KINDS",
    "PairDistance",
    "Sphere",
    "make_obstacle",
    "parse_obstacle",
    "read_srdf_pairs",
]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

#: Largest accepted obstacle coordinate or size [m] (as for a URDF's origins).
MAX_EXTENT_M = 1e4


def _finite_vector(name: str, value, size: int) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be {size} numbers, got {value!r}") from None
    if arr.shape != (size,):
        raise ParameterError(f"{name} must be {size} numbers, got shape {arr.shape}: {value!r}")
    if not np.isfinite(arr).all():
        raise ParameterError(f"{name} must be finite, got {arr.tolist()}")
    if np.any(np.abs(arr) > MAX_EXTENT_M):
        raise ParameterError(f"{name} must be within ±{MAX_EXTENT_M:g}, got {arr.tolist()}")
    return tuple(float(v) for v in arr)


def _positive_size(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number [m], got {value!r}") from None
    if not (math.isfinite(v) and 0.0 < v <= MAX_EXTENT_M):
        raise ParameterError(f"{name} must be > 0 and finite [m], got {value!r}")
    return v


@dataclass(frozen=True, kw_only=True)
class Obstacle:
    """A rigid obstacle fixed in the world.

    Attributes:
        name: label (unique within a :class:`CollisionModel`; ``""``: a name is given).
        position_m: position of the shape's centre in the world [m] ``(3,)``.
        quaternion_wxyz: orientation of the shape in the world (unit quaternion ``w, x, y,
            z``; normalised when within 1e-3 of unit length).
    """

    name: str = ""
    position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quaternion_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    kind = "obstacle"

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", str(self.name))
        object.__setattr__(self, "position_m", _finite_vector("position_m", self.position_m, 3))
        quat = np.array(_finite_vector("quaternion_wxyz", self.quaternion_wxyz, 4))
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > 1e-3:
            raise ParameterError(
                f"quaternion_wxyz must be a unit quaternion (w, x, y, z), got {quat.tolist()} "
                f"of norm {norm:.6g}"
            )
        object.__setattr__(self, "quaternion_wxyz", tuple(float(v) for v in quat / norm))
        self._check_sizes()

    def _check_sizes(self) -> None:  # pragma: no cover - every shape overrides it
        pass

    def placement(self) -> pin.SE3:
        """The shape's pose in the world."""
        w, x, y, z = self.quaternion_wxyz
        return pin.SE3(pin.Quaternion(w, x, y, z).matrix(), np.array(self.position_m))

    def shape(self) -> coal.ShapeBase:  # pragma: no cover - every shape overrides it
        """The coal shape in its own frame."""
        raise NotImplementedError


@dataclass(frozen=True, kw_only=True)
class Sphere(Obstacle):
    """A ball of radius ``radius_m`` [m] centred at ``position_m``."""

    radius_m: float
    kind = "sphere"

    def _check_sizes(self) -> None:
        object.__setattr__(self, "radius_m", _positive_size("radius_m", self.radius_m))

    def shape(self) -> coal.ShapeBase:
        """The coal geometry."""
        return coal.Sphere(self.radius_m)


@dataclass(frozen=True, kw_only=True)
class Box(Obstacle):
    """A box of side lengths ``size_m`` [m] ``(x, y, z)`` in its own frame."""

    size_m: tuple[float, float, float]
    kind = "box"

    def _check_sizes(self) -> None:
        sizes = _finite_vector("size_m", self.size_m, 3)
        for axis, v in zip("xyz", sizes, strict=True):
            _positive_size(f"size_m ({axis})", v)
        object.__setattr__(self, "size_m", sizes)

    def shape(self) -> coal.ShapeBase:
        """The coal geometry."""
        return coal.Box(*self.size_m)


@dataclass(frozen=True, kw_only=True)
class Capsule(Obstacle):
    """The points within ``radius_m`` [m] of a segment of ``length_m`` [m] along the
    shape's ``z`` axis, centred at ``position_m``."""

    radius_m: float
    length_m: float
    kind = "capsule"

    def _check_sizes(self) -> None:
        object.__setattr__(self, "radius_m", _positive_size("radius_m", self.radius_m))
        object.__setattr__(self, "length_m", _positive_size("length_m", self.length_m))

    def shape(self) -> coal.ShapeBase:
        """The coal geometry."""
        return coal.Capsule(self.radius_m, self.length_m)


@dataclass(frozen=True, kw_only=True)
class Cylinder(Obstacle):
    """A cylinder of ``radius_m`` [m] and ``length_m`` [m] along the shape's ``z`` axis,
    centred at ``position_m``."""

    radius_m: float
    length_m: float
    kind = "cylinder"

    def _check_sizes(self) -> None:
        object.__setattr__(self, "radius_m", _positive_size("radius_m", self.radius_m))
        object.__setattr__(self, "length_m", _positive_size("length_m", self.length_m))

    def shape(self) -> coal.ShapeBase:
        """The coal geometry."""
        return coal.Cylinder(self.radius_m, self.length_m)


@dataclass(frozen=True, kw_only=True)
class HalfSpace(Obstacle):
    """The solid ``{x : normalᵀ x ≤ offset_m}`` (a table top or the floor): ``normal``
    (normalised) points out of the solid into free space, ``offset_m`` [m] is the plane's
    signed distance from the world origin along it. ``position_m``/``quaternion_wxyz`` are
    not used (the plane is given in the world)."""

    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset_m: float = 0.0
    kind = "plane"

    def _check_sizes(self) -> None:
        normal = np.array(_finite_vector("normal", self.normal, 3))
        norm = float(np.linalg.norm(normal))
        if norm < 1e-9:
            raise ParameterError(f"normal must be a non-zero vector, got {normal.tolist()}")
        object.__setattr__(self, "normal", tuple(float(v) for v in normal / norm))
        object.__setattr__(self, "offset_m", _finite_vector("offset_m", [self.offset_m], 1)[0])

    def placement(self) -> pin.SE3:
        """The identity: the plane is given by ``normal`` and ``offset_m``."""
        return pin.SE3.Identity()

    def shape(self) -> coal.ShapeBase:
        """The coal geometry."""
        return coal.Halfspace(np.array(self.normal), self.offset_m)


#: Shape names accepted by :func:`make_obstacle` and :func:`parse_obstacle`, with the numbers
#: the text form takes (all in metres; a plane's normal is unitless).
OBSTACLE_KINDS: dict[str, tuple[type[Obstacle], tuple[str, ...]]] = {
    "sphere": (Sphere, ("x", "y", "z", "radius")),
    "box": (Box, ("x", "y", "z", "size_x", "size_y", "size_z")),
    "capsule": (Capsule, ("x", "y", "z", "radius", "length")),
    "cylinder": (Cylinder, ("x", "y", "z", "radius", "length")),
    "plane": (HalfSpace, ("normal_x", "normal_y", "normal_z", "offset")),
}


def make_obstacle(kind: str, **params) -> Obstacle:
    """An obstacle by shape name (``sphere``, ``box``, ``capsule``, ``cylinder``, ``plane``)
    and its fields; :class:`ParameterError` naming the shapes for an unknown one."""
    if kind not in OBSTACLE_KINDS:
        raise ParameterError(
            f"unknown obstacle shape {kind!r}; shapes: {', '.join(sorted(OBSTACLE_KINDS))}"
        )
    cls = OBSTACLE_KINDS[kind][0]
    try:
        return cls(**params)
    except TypeError as exc:
        raise ParameterError(f"{kind}: {exc}") from None


def parse_obstacle(text: str, name: str = "") -> Obstacle:
    """An obstacle from ``shape:a,b,c,…`` [m]: ``sphere:X,Y,Z,R``,
    ``box:X,Y,Z,SX,SY,SZ`` (centre and side lengths, axis-aligned),
    ``capsule:X,Y,Z,R,L`` and ``cylinder:X,Y,Z,R,L`` (vertical axis),
    ``plane:NX,NY,NZ,D`` (the solid ``n·x ≤ D``, ``n`` pointing into free space)."""
    kind, sep, rest = str(text).partition(":")
    kind = kind.strip().lower()
    if kind not in OBSTACLE_KINDS:
        raise ParameterError(
            f"unknown obstacle shape {kind!r} in {text!r}; shapes: "
            + ", ".join(f"{k}:{','.join(v[1])}" for k, v in OBSTACLE_KINDS.items())
        )
    fields = OBSTACLE_KINDS[kind][1]
    parts = [p.strip() for p in rest.split(",")] if sep else []
    if len(parts) != len(fields):
        raise ParameterError(
            f"obstacle {text!r}: {kind} takes {len(fields)} numbers "
            f"{kind}:{','.join(fields)} [m], got {len(parts)}"
        )
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ParameterError(f"obstacle {text!r}: every field must be a number [m]") from None
    if kind == "plane":
        return HalfSpace(name=name, normal=(values[0], values[1], values[2]), offset_m=values[3])
    position = (values[0], values[1], values[2])
    if kind == "sphere":
        return Sphere(name=name, position_m=position, radius_m=values[3])
    if kind == "box":
        return Box(name=name, position_m=position, size_m=(values[3], values[4], values[5]))
    cls = Capsule if kind == "capsule" else Cylinder
    return cls(name=name, position_m=position, radius_m=values[3], length_m=values[4])


def read_srdf_pairs(srdf: str | os.PathLike) -> tuple[tuple[str, str], ...]:
    """The ``(link1, link2)`` pairs of every ``<disable_collisions>`` of an SRDF (a path, or
    the XML text itself)."""
    text = str(srdf)
    if not text.lstrip().startswith("<"):
        path = Path(srdf)
        if not path.is_file():
            raise ParameterError(f"SRDF file not found: '{path}'")
        text = path.read_text("utf-8")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ParameterError(f"the SRDF is not well-formed XML: {exc}") from None
    pairs = []
    for elem in root.iter("disable_collisions"):
        a, b = elem.get("link1"), elem.get("link2")
        if not a or not b:
            raise ParameterError(
                f"<disable_collisions> needs link1 and link2 attributes, got {elem.attrib}"
            )
        pairs.append((a, b))
    return tuple(pairs)


class DistanceBatch(NamedTuple):
    """The pairs within an influence distance at several configurations (one row each).

    Attributes:
        state: index of the configuration ``(k,)``.
        pair: index of the pair in :attr:`CollisionModel.pairs` ``(k,)``.
        distance_m: signed distance [m] ``(k,)`` (``-inf``: the penetration solver failed;
            the gradient is then zero).
        gradient: ``∂d/∂q`` [m/rad] ``(k, n)``.
    """

    state: np.ndarray
    pair: np.ndarray
    distance_m: np.ndarray
    gradient: np.ndarray


class PairDistance(NamedTuple):
    """One pair's distance at one configuration.

    Attributes:
        pair: index of the pair in :attr:`CollisionModel.pairs`.
        distance_m: signed distance [m] (negative: penetration depth; ``-inf`` where the
            penetration solver failed, with NaN points and normal and a zero gradient).
        point_a_m, point_b_m: witness points on ``a`` and ``b`` in the world [m] ``(3,)``.
        normal: unit vector from ``a`` to ``b`` ``(3,)``: moving ``b`` along it increases
            the distance.
        gradient: ``∂d/∂q`` [m/rad] ``(n,)``.
    """

    pair: int
    distance_m: float
    point_a_m: np.ndarray
    point_b_m: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray


class CollisionModel:
    """The robot's collision geometry, the obstacles, the pairs, and distance queries.

    Args:
        robot: the robot (its URDF source gives the collision shapes; meshes are read from
            its ``package_dirs``).
        obstacles: obstacles fixed in the world.
        self_collision: include pairs of the robot's own links.
        allowed_pairs: link pairs never checked, ``(link1, link2)`` (SRDF-style).
        srdf: an SRDF file (or its text) whose ``<disable_collisions>`` are also allowed.
        closed_forms: solve the pairs that have a closed form (a sphere against a sphere, a
            cylinder, a box or a half-space, a cylinder against a half-space) without coal
            (:mod:`~dqcontrol.model.collision_closed_forms`; the same results).

    Attributes:
        geometry: Pinocchio's ``GeometryModel``: the robot's shapes (on their joints), then
            the obstacles (on the world).
        pairs: ``(name_a, name_b)`` of every geometry pair considered (``a`` on the robot,
            nearer the base for self pairs).
        pair_links: ``(link_a, link_b)`` of each pair (the obstacle's name for ``b``).
        obstacles: the obstacles, named.
        link_names: the robot's links that carry collision geometry.

    Raises:
        ParameterError: the URDF has no collision geometry, an allowed pair names a link that
            does not exist (the message lists the links), duplicate obstacle names.
    """

    def __init__(
        self,
        robot: RobotModel,
        obstacles: tuple[Obstacle, ...] | list[Obstacle] = (),
        *,
        self_collision: bool = True,
        allowed_pairs: tuple[tuple[str, str], ...] | list = (),
        srdf: str | os.PathLike | None = None,
        closed_forms: bool = True,
    ) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = self.model.createData()
        geometry = _robot_geometry(robot)
        if geometry.ngeoms == 0:
            raise ParameterError(
                f"the URDF of '{robot.model.name}' has no <collision> geometry: give its links "
                "collision shapes to check self-collision or obstacles"
            )
        self.num_robot_geometries = int(geometry.ngeoms)
        self.obstacles = _named_obstacles(obstacles)
        for obs in self.obstacles:
            geometry.addGeometryObject(
                pin.GeometryObject(obs.name, 0, 0, obs.placement(), obs.shape())
            )
        self.geometry = geometry
        frames = self.model.frames
        self._links = [
            frames[go.parentFrame].name
            for go in geometry.geometryObjects[: self.num_robot_geometries]
        ]
        self.link_names = tuple(dict.fromkeys(self._links))
        allowed_set = self._allowed(allowed_pairs, srdf)
        self.allowed_pairs = tuple(tuple(sorted(p)) for p in allowed_set)
        pairs = self._pairs(bool(self_collision), allowed_set)
        for a, b in pairs:
            geometry.addCollisionPair(pin.CollisionPair(a, b))
        self._a = np.array([a for a, _ in pairs], dtype=int)
        self._b = np.array([b for _, b in pairs], dtype=int)
        names = [go.name for go in geometry.geometryObjects]
        self.pairs = tuple((names[a], names[b]) for a, b in pairs)
        links = self._links + [o.name for o in self.obstacles]
        self.pair_links = tuple((links[a], links[b]) for a, b in pairs)
        self.geometry_data = pin.GeometryData(geometry)
        for k in range(len(pairs)):
            req = self.geometry_data.distanceRequests[k]
            req.gjk_tolerance = 1e-9
            req.epa_tolerance = 1e-9
        self._joint_of = np.array([go.parentJoint for go in geometry.geometryObjects], dtype=int)
        self._bounds()
        self._tables()
        self._references()
        self._closed = closed_form_table(geometry, self._a, self._b)
        if not closed_forms:
            self._closed.kind[:] = 0
        #: distance queries made since construction (pairs solved by coal)
        self.query_count = 0
        #: pairs solved in closed form since construction
        self.closed_form_count = 0

    # ------------------------------------------------------------------ construction
    def _allowed(self, allowed_pairs, srdf) -> set[frozenset]:
        """The allowed link pairs (the list and the SRDF's), each checked against the links."""
        body_names = {f.name for f in self.model.frames if f.type == pin.FrameType.BODY}
        allowed = list(allowed_pairs)
        if srdf is not None:
            allowed += list(read_srdf_pairs(srdf))
        out = set()
        for pair in allowed:
            if len(pair) != 2:
                raise ParameterError(f"an allowed pair must be two link names, got {pair!r}")
            for link in pair:
                if link not in body_names:
                    raise ParameterError(
                        f"allowed pair {tuple(pair)} names link '{link}', which this robot does "
                        f"not have; links: {sorted(body_names)}"
                    )
            out.add(frozenset(pair))
        return out

    def _pairs(self, self_collision: bool, allowed: set) -> list[tuple[int, int]]:
        geoms = self.geometry.geometryObjects
        nr = self.num_robot_geometries
        parents = self.model.parents
        out = []
        if self_collision:
            for a in range(nr):
                for b in range(a + 1, nr):
                    ja, jb = geoms[a].parentJoint, geoms[b].parentJoint
                    if ja == jb or parents[jb] == ja or parents[ja] == jb:
                        continue  # one rigid body, or adjacent bodies
                    if frozenset((self._links[a], self._links[b])) in allowed:
                        continue
                    out.append((a, b) if ja < jb else (b, a))
        for k in range(len(self.obstacles)):
            for a in range(nr):
                if geoms[a].parentJoint == 0:
                    continue  # fixed to the world like the obstacle
                if frozenset((self._links[a], self.obstacles[k].name)) in allowed:
                    continue
                out.append((a, nr + k))
        return out

    def _bounds(self) -> None:
        """Bounding capsules of the shapes in their joints' frames (segment ends ``(g, 2,
        3)`` and radii [m]), their support functions there (:func:`support_form`) and the
        half-spaces' planes."""
        count = self.geometry.ngeoms
        self._ends = np.zeros((count, 2, 3))
        self._radii = np.zeros(count)
        self._plane = np.zeros(count, dtype=bool)
        self._forms = np.zeros((count, FORM_SIZE))
        for k, go in enumerate(self.geometry.geometryObjects):
            shape = go.geometry
            if isinstance(shape, coal.Halfspace):
                self._plane[k] = True
                continue
            capsule = bounding_capsule(shape)
            start, end, self._radii[k] = capsule
            self._ends[k] = [go.placement.act(start), go.placement.act(end)]
            centre, spans, axis, disc, ball = support_form(shape, capsule)
            rotation = go.placement.rotation
            placed = [go.placement.act(centre), *(spans @ rotation.T), rotation @ axis]
            self._forms[k] = np.concatenate([*placed, [disc, ball]])
        self._normals = np.zeros((count, 3))
        self._offsets = np.zeros(count)
        for k, obs in enumerate(self.obstacles):
            if isinstance(obs, HalfSpace):
                self._normals[self.num_robot_geometries + k] = obs.normal
                self._offsets[self.num_robot_geometries + k] = obs.offset_m

    def _tables(self) -> None:
        """The joints that move shapes, the columns that move each joint's body (``support``
        ``(njoints, n)``, 1 where joint ``k`` carries joint ``j``'s body) and the revolute
        chain's constants."""
        model = self.model
        n = self.robot.nq
        self._support = np.zeros((model.njoints, n))
        for j in range(1, model.njoints):
            k = j
            while k > 0:
                self._support[j, model.idx_vs[k]] = 1.0
                k = model.parents[k]
        self._moving_joints = sorted({int(j) for j in self._joint_of if j > 0})
        self._revolute = self._revolute_tables()

    def _references(self) -> None:
        """The last distance solved of each pair and its configuration (none yet), and the
        joints' levers on each pair (:func:`pair_levers`; revolute chains only, where
        :meth:`_kinematics_batch` is compiled)."""
        self._remember = self._revolute is not None
        self._levers = np.zeros((self.num_pairs, self.robot.nq))  # every reference stays -inf
        if self._remember:
            self._levers = pair_levers(
                self.model, self._joint_of, self._ends, self._radii, self._a, self._b
            )
        self._reference_q = np.zeros((self.num_pairs, self.robot.nq))
        self._reference_m = np.full(self.num_pairs, -math.inf)

    # ------------------------------------------------------------------ queries
    @property
    def num_pairs(self) -> int:
        """Pairs considered."""
        return len(self.pairs)

    def distances(self, q: np.ndarray, influence_m: float = math.inf) -> tuple[PairDistance, ...]:
        """Every pair closer than ``influence_m`` [m] at ``q``, with witness points, normal
        and gradient (checked input)."""
        q = self.robot.check_q(q)
        if not (influence_m > 0.0):
            raise ParameterError(f"influence_m must be > 0 [m], got {influence_m!r}")
        return self.query(q, influence_m)

    def min_distance(self, q: np.ndarray) -> float:
        """The smallest distance over every pair at ``q`` [m] (``inf`` without pairs)."""
        found = self.distances(q)
        return min((p.distance_m for p in found), default=math.inf)

    def candidates(self, influence_m: float) -> np.ndarray:
        """Indices of the pairs whose bounding capsules are within ``influence_m`` at the
        configuration of the last :meth:`update` (a conservative filter)."""
        placements = self.data.oMi
        rot = np.empty((self.model.njoints, 3, 3))
        trans = np.empty((self.model.njoints, 3))
        for j in self._moving_joints:
            m = placements[j]
            rot[j] = m.rotation
            trans[j] = m.translation
        rot[0], trans[0] = np.eye(3), np.zeros(3)
        gap = self._gaps(rot[None], trans[None], influence_m)[0]
        return np.flatnonzero(gap < influence_m)

    def update(self, q: np.ndarray) -> None:
        """Kinematics, joint Jacobians and shape placements at ``q`` (unchecked)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateGeometryPlacements(self.model, self.data, self.geometry, self.geometry_data)

    def query(self, q: np.ndarray, influence_m: float) -> tuple[PairDistance, ...]:
        """Unchecked :meth:`distances`: ``q`` a valid ``(n,)`` float array."""
        self.update(q)
        _, pair, distance, points, grad = self._solve(q[None, :], influence_m, placed=0)
        return tuple(
            PairDistance(int(k), float(d), p[0], p[1], p[2], g)
            for k, d, p, g in zip(pair.tolist(), distance.tolist(), points, grad, strict=True)
        )

    def query_batch(self, qs: np.ndarray, influence_m: float) -> DistanceBatch:
        """Every pair closer than ``influence_m`` [m] at each configuration of ``qs``
        ``(N, n)`` (unchecked): the same distances and gradients as :meth:`query`, with one
        bounding-capsule filter for the whole batch (the path-following controller's
        predicted states)."""
        state, pair, distance, _, grad = self._solve(qs, influence_m)
        return DistanceBatch(state, pair, distance, grad)

    def _solve(self, qs: np.ndarray, influence_m: float, placed: int = -1) -> tuple:
        """The pairs within ``influence_m`` at each configuration of ``qs`` ``(N, n)``:
        configuration ``(k,)``, pair ``(k,)``, distance ``(k,)``, witness points ``a``,
        ``b`` and normal ``(k, 3, 3)``, gradients ``(k, n)``, ordered by configuration then
        pair.

        The capsules' lower bounds and the pairs' last solved distances choose the pairs
        solved, in closed form or by coal; ``placed``: the configuration whose shapes are
        already placed in :attr:`geometry_data`."""
        rot, trans, jac = self._kinematics_batch(qs)
        states, pairs, solved, points, jobs = screen_pairs(
            rot,
            trans,
            qs,
            self._joint_of,
            self._ends,
            self._radii,
            self._forms,
            self._a,
            self._b,
            self._normals,
            self._offsets,
            self._plane,
            self._reference_q,
            self._reference_m,
            self._levers,
            *self._closed,
            influence_m,
        )
        self.closed_form_count += states.size - len(jobs)
        self._narrow_phase(qs, jobs, solved, points, influence_m, placed)
        return collect_pairs(
            qs,
            states,
            pairs,
            solved,
            influence_m,
            points,
            jac,
            self._support,
            self._joint_of,
            self._a,
            self._b,
            self._reference_q,
            self._reference_m,
            self._remember,
        )

    def _narrow_phase(
        self,
        qs: np.ndarray,
        jobs: np.ndarray,
        solved: np.ndarray,
        points: np.ndarray,
        influence_m: float,
        placed: int,
    ) -> None:
        """Coal's distance ``solved[m]`` for each job ``(m, configuration, pair)`` of ``jobs``
        ``(k, 3)`` (grouped by configuration), and its witness points ``a``, ``b`` and normal
        ``points[m]`` ``(3, 3)`` where it is below ``influence_m`` (the normal only where the
        shapes touch or overlap: :func:`collect_pairs` takes it from the points otherwise).
        A configuration's shapes are placed only where coal solves one of its pairs."""
        if not len(jobs):
            return
        model, data, gm, gd = self.model, self.data, self.geometry, self.geometry_data
        compute, place = pin.computeDistance, pin.updateGeometryPlacements
        last = placed
        self.query_count += len(jobs)
        for m, i, k in jobs.tolist():
            if i != last:
                place(model, data, gm, gd, qs[i])  # the kinematics, then the shapes
                last = i
            res = compute(gm, gd, k)
            solved[m] = d = res.min_distance
            if d < influence_m:  # a failed query too: far below any distance
                out = points[m]
                out[0], out[1] = res.getNearestPoint1(), res.getNearestPoint2()
                if not d > SEPARATED_M:  # apart, the normal is the points' direction
                    out[2] = res.normal

    def _kinematics_batch(self, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint placements ``(N, njoints, 3, 3)``, ``(N, njoints, 3)`` and world Jacobians
        ``(N, 6, n)`` (as Pinocchio's ``data.J``) of a batch of configurations: a chain of
        1-DoF revolute joints in the compiled :func:`chain_kinematics`, other models
        through Pinocchio."""
        if self._revolute is not None:
            return chain_kinematics(qs, *self._revolute)
        count, nj = qs.shape[0], self.model.njoints
        rot = np.empty((count, nj, 3, 3))
        trans = np.empty((count, nj, 3))
        jac = np.zeros((count, 6, self.robot.nq))
        rot[:, 0], trans[:, 0] = np.eye(3), 0.0
        model, data = self.model, self.data
        for i in range(count):
            pin.computeJointJacobians(model, data, qs[i])
            jac[i] = data.J
            for j in range(1, nj):
                m = data.oMi[j]
                rot[i, j] = m.rotation
                trans[i, j] = m.translation
        return rot, trans, jac

    def _revolute_tables(self) -> tuple | None:
        """Constant tables of :func:`chain_kinematics` for a chain of 1-DoF revolute
        joints (``None`` otherwise): each joint's parent, placement ``(R_p, t_p)``,
        ``R_p K`` and ``R_p K²`` (``K`` the cross-product matrix of its unit axis ``a``),
        ``a`` and its index in ``q``."""
        from dqcontrol.model.chain_batch import revolute_axis

        model = self.model
        nj = model.njoints
        rotations, shifts = np.zeros((nj, 3, 3)), np.zeros((nj, 3))
        k1, k2, axes = np.zeros((nj, 3, 3)), np.zeros((nj, 3, 3)), np.zeros((nj, 3))
        iq = np.zeros(nj, dtype=np.int64)
        for j in range(1, nj):
            axis = revolute_axis(model.joints[j])
            if axis is None or model.joints[j].nq != 1:
                return None
            k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
            placement = model.jointPlacements[j]
            rotations[j], shifts[j] = placement.rotation, placement.translation
            k1[j], k2[j], axes[j] = rotations[j] @ k, rotations[j] @ k @ k, axis
            iq[j] = model.idx_qs[j]
        parents = np.array([int(model.parents[j]) for j in range(nj)], dtype=np.int64)
        return parents, rotations, shifts, k1, k2, axes, iq

    def _gaps(self, rot: np.ndarray, trans: np.ndarray, influence_m: float) -> np.ndarray:
        """Lower bounds of every pair's distance ``(N, pairs)`` [m] from the joint placements
        ``(N, njoints, 3, 3)``, ``(N, njoints, 3)``: the distances of the shapes' bounding
        capsules, tightened by their support functions below ``influence_m`` [m]
        (:func:`capsule_gaps`)."""
        return capsule_gaps(
            rot,
            trans,
            self._joint_of,
            self._ends,
            self._radii,
            self._forms,
            self._a,
            self._b,
            self._normals,
            self._offsets,
            self._plane,
            influence_m,
        )


def _robot_geometry(robot: RobotModel) -> pin.GeometryModel:
    """The collision ``GeometryModel`` of ``robot`` on its (possibly reduced, re-based)
    Pinocchio model; meshes replaced by their convex hulls."""
    source = robot.source
    if source is None:
        raise ParameterError("the robot has no URDF source to read collision geometry from")
    full = build_angle_model(source.xml)
    try:  # the meshes as the files found and checked at load
        geometry = pin.buildGeomFromUrdfString(
            full, source.xml_with_mesh_paths(), pin.GeometryType.COLLISION
        )
    except (ValueError, RuntimeError) as exc:
        raise ParameterError(f"could not read the URDF's collision geometry: {exc}") from None
    full, geometry = lock_joints(full, robot.locked_joints, geometry)
    if [full.names[j] for j in range(1, full.njoints)] != robot.joint_names:
        raise ParameterError("the collision geometry's joints do not match the robot's")
    base = robot.base_placement
    for go in geometry.geometryObjects:
        if go.parentJoint == 0:
            go.placement = base * go.placement
        shape = go.geometry
        if isinstance(shape, coal.BVHModelBase):
            # the hull itself (qhull): a convex representation of the mesh's own triangles
            # would leave GJK's support search at the local maxima of a concave mesh, and
            # the link would read smaller than its hull. False: the mesh is not convex.
            shape.buildConvexHull(False, "Qt")
            go.geometry = shape.convex
    return geometry


def _named_obstacles(obstacles) -> tuple[Obstacle, ...]:
    out, seen = [], set()
    for k, obs in enumerate(obstacles):
        if not isinstance(obs, Obstacle):
            raise ParameterError(
                f"obstacle {k} must be a Sphere, Box, Capsule, Cylinder or HalfSpace, got "
                f"{type(obs).__name__}"
            )
        name = obs.name or f"obstacle_{k}_{obs.kind}"
        if name in seen:
            raise ParameterError(f"two obstacles are named '{name}'; names must be unique")
        seen.add(name)
        if name != obs.name:
            obs = dataclasses.replace(obs, name=name)
        out.append(obs)
    return tuple(out)

"""Measure a run's contacts: the collision model's distances and MuJoCo's contacts at each
of its samples (:class:`~dqcontrol.runs.contacts.RunContacts`).

Each sample's joint positions are set in the robot's MuJoCo model with the obstacles
(``mj_forward``, no dynamics) and its contacts sorted as
:func:`~dqcontrol.sim.mjcf_builder.count_contacts` does; the same sample's smallest
distance over the collision model's pairs (docs/theory.md §10) gives the closest distance
and its pair. Both are needed for the run's summary anyway, so the per-sample columns cost
nothing more than keeping them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from dqcontrol.extras import lazy_module
from dqcontrol.model.collision import CollisionModel
from dqcontrol.model.robot import RobotModel
from dqcontrol.runs.contacts import CONTACT_COLUMNS, ContactKind, RunContacts
from dqcontrol.sim.mjcf_builder import OBSTACLE_PREFIX, contact_model

if TYPE_CHECKING:
    import mujoco
else:  # imported on first use: the package works without the sim extra
    mujoco = lazy_module("mujoco", extra="sim", purpose="the contacts of a run")

__all__ = ["measure_contacts"]


def measure_contacts(
    robot: RobotModel, collision: CollisionModel, q_rad: np.ndarray, t_s: np.ndarray
) -> RunContacts:
    """The contacts of a run whose samples have joint positions ``q_rad`` ``(K, n)`` [rad]
    at times ``t_s`` ``(K,)`` [s], with the obstacles and pairs of ``collision``."""
    qs = np.atleast_2d(np.asarray(q_rad, dtype=float))
    times = np.asarray(t_s, dtype=float).reshape(-1)
    closest_m, closest_pair = _closest(collision, qs)
    obstacle, self_count, depth_m = _mujoco_contacts(robot, collision, qs)
    deepest_m = np.maximum(depth_m[0], depth_m[1])
    columns = (closest_m, obstacle, self_count, deepest_m)
    k = int(np.argmin(closest_m)) if qs.shape[0] else 0
    found = qs.shape[0] > 0 and math.isfinite(closest_m[k])
    pair = collision.pairs[closest_pair[k]] if found else None
    links = collision.pair_links[closest_pair[k]] if found else None
    return RunContacts(
        obstacles=tuple(o.name for o in collision.obstacles),
        self_collision=_has_self_pairs(collision),
        samples=int(qs.shape[0]),
        obstacle=_kind(obstacle, depth_m[0]),
        self_contact=_kind(self_count, depth_m[1]),
        closest_m=float(closest_m[k]) if found else None,
        closest_pair=(str(pair[0]), str(pair[1])) if pair else None,
        closest_links=(str(links[0]), str(links[1])) if links else None,
        closest_t_s=float(times[k]) if found else None,
        per_sample=dict(zip(CONTACT_COLUMNS, columns, strict=True)),
    )


def _has_self_pairs(collision: CollisionModel) -> bool:
    obstacles = {o.name for o in collision.obstacles}
    return any(link_b not in obstacles for _, link_b in collision.pair_links)


def _kind(count: np.ndarray, depth_m: np.ndarray) -> ContactKind:
    return ContactKind(
        count=int(count.sum()),
        samples=int(np.count_nonzero(count)),
        deepest_m=float(depth_m.max(initial=0.0)),
    )


def _closest(collision: CollisionModel, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: the smallest distance over the pairs [m] (``inf`` without a pair) and
    the index of its pair (-1 without one)."""
    distance_m = np.full(qs.shape[0], np.inf)
    pair = np.full(qs.shape[0], -1, dtype=int)
    for k, q in enumerate(qs):
        for found in collision.distances(q):
            if found.distance_m < distance_m[k]:
                distance_m[k], pair[k] = found.distance_m, found.pair
    return distance_m, pair


def _mujoco_contacts(
    robot: RobotModel, collision: CollisionModel, qs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Per sample: robot–obstacle and self contacts and the deepest penetration of each
    kind [m] (contacts between two obstacles are not counted)."""
    model, data, adr = contact_model(robot, collision.obstacles)
    count = np.zeros((2, qs.shape[0]), dtype=int)
    depth_m = np.zeros((2, qs.shape[0]))
    for k, q in enumerate(qs):
        data.qpos[adr] = q
        mujoco.mj_forward(model, data)
        for i in range(data.ncon):
            con = data.contact[i]
            on_obstacle = [_is_obstacle(model, g) for g in con.geom]
            if all(on_obstacle):
                continue
            kind = 0 if any(on_obstacle) else 1
            count[kind, k] += 1
            depth_m[kind, k] = max(depth_m[kind, k], -float(con.dist))
    return count[0], count[1], (depth_m[0], depth_m[1])


def _is_obstacle(model: mujoco.MjModel, geom: int) -> bool:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(geom)) or ""
    return name.startswith(OBSTACLE_PREFIX)

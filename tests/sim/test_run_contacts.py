"""dqcontrol/sim/run_contacts.py: a run's contacts per sample against the collision model's
own distances and MuJoCo's contacts replayed one configuration at a time."""

from __future__ import annotations

import numpy as np

from dqcontrol.model.collision import CollisionModel, HalfSpace
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.sim.mjcf_builder import replay_contacts
from dqcontrol.sim.run_contacts import measure_contacts

#: The solid below z = 0.6 m: it cuts the LBR4p's upper arm at its start posture.
PLANE = HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.6)


def _samples(lbr4p, count: int = 5, seed: int = 3):
    rng = np.random.default_rng(seed)
    qs = LBR4P_Q0 + 0.1 * rng.standard_normal((count, lbr4p.nq))
    return qs, 0.01 * np.arange(count)


def test_each_sample_is_the_collision_models_distance_and_mujocos_contacts(lbr4p):
    collision = CollisionModel(lbr4p, [PLANE], self_collision=False)
    qs, t_s = _samples(lbr4p)
    contacts = measure_contacts(lbr4p, collision, qs, t_s)
    columns = contacts.per_sample
    distance_m = np.array([collision.min_distance(q) for q in qs])
    np.testing.assert_allclose(columns["contacts_closest_m"], distance_m, rtol=0, atol=1e-12)
    for k, q in enumerate(qs):
        counted = replay_contacts(lbr4p, collision.obstacles, q)
        assert columns["contacts_obstacle"][k] == counted.obstacle
        assert columns["contacts_self"][k] == counted.self_contact == 0
        assert columns["contacts_depth_m"][k] == counted.deepest_m
    obstacle = columns["contacts_obstacle"]
    assert contacts.obstacle.count == obstacle.sum() > 0
    assert contacts.obstacle.samples == np.count_nonzero(obstacle)
    assert contacts.samples == 5 and contacts.obstacles == ("table",)
    assert not contacts.self_collision and contacts.self_contact.count == 0


def test_the_closest_pair_is_that_of_the_closest_sample(lbr4p):
    collision = CollisionModel(lbr4p, [PLANE], self_collision=False)
    qs, t_s = _samples(lbr4p, seed=8)
    contacts = measure_contacts(lbr4p, collision, qs, t_s)
    distance_m = contacts.per_sample["contacts_closest_m"]
    k = int(np.argmin(distance_m))
    assert contacts.closest_m == distance_m[k] and contacts.closest_t_s == t_s[k]
    assert contacts.closest_links[1] == "table"
    assert contacts.closest_links[0] in collision.link_names
    assert contacts.deepest_m == max(contacts.obstacle.deepest_m, contacts.self_contact.deepest_m)


def test_a_run_without_samples_has_no_closest_pair(lbr4p):
    collision = CollisionModel(lbr4p, [PLANE], self_collision=False)
    contacts = measure_contacts(lbr4p, collision, np.zeros((0, lbr4p.nq)), np.zeros(0))
    assert contacts.samples == 0 and contacts.closest_m is None
    assert contacts.closest_pair is None and contacts.closest_t_s is None
    assert contacts.obstacle.count == 0 and contacts.deepest_m == 0.0

"""The collision limit (docs/theory.md §10) in every QP controller, through ``extra_limits``:
its rows against their definition, and the behaviours it must show in the kinematic loop —
an obstacle on the path stops the path-following controller before it (on the path, at
rest), an obstacle at the elbow is avoided in the null space while the tool keeps the path,
a task folding the arm into itself stops before self-contact — a seeded fuzz of obstacles
near the path, and, with MuJoCo as the oracle, no contact in the runs with the limit
replayed in MuJoCo."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dqcontrol import load_lbr4p
from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
)
from dqcontrol.controllers.limits.collision import CollisionLimit
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.dq.algebra import dq_to_se3
from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import CollisionModel, Sphere
from dqcontrol.trajectories import Circle, WaypointTrajectory

T = 0.01
THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
SAFETY_M = 0.02
#: How far below the safety distance a run may go [m]: the rows are linear in ``q̇`` (the
#: damper) or linearised at the predicted states, so each period leaves a second-order error
#: ``½ |∇²d| |Δq|²`` — about 1e-6 m measured; 0.5 mm is the stated bound.
TOLERANCE_M = 5e-4
#: The path-following controller's goal for the path deviation [m].
PATH_GOAL_M = 5e-4

CONTROLLERS = {
    "local": (LocalController, {}),
    "p6": (PredictiveController, {"num_instants": 6}),
    "noscale_p6": (PredictiveNoScalingController, {"num_instants": 6}),
    "path_following": (PathFollowingController, {"num_intervals": 6}),
}


@pytest.fixture(scope="module")
def robot():
    return load_lbr4p()


def make(robot, name, task, limits=()):
    cls, kw = CONTROLLERS[name]
    return cls(
        robot, task, T, velocity_limits=THESIS_VEL, acceleration_limit=10.0,
        extra_limits=tuple(limits), **kw,
    )  # fmt: skip


def closed_loop(robot, ctrl, collision, duration_s, q0=LBR4P_Q0):
    """The kinematic loop ``q ← q + T q̇``: per sample the configuration, ``s``, ``σ``, the
    smallest distance over every pair and the tool's path deviation."""
    ctrl.reset(q0)
    q = np.array(q0, dtype=float)
    out = {"q": [], "s": [], "sigma": [], "d_min": [], "fallbacks": 0}
    for _ in range(int(round(duration_s / T))):
        res = ctrl.step(q)
        out["fallbacks"] += int(res.diagnostics.fallback)
        q = q + T * res.qd_command
        out["q"].append(q.copy())
        out["s"].append(res.s)
        out["sigma"].append(res.sigma_next)
        out["d_min"].append(collision.min_distance(q))
    run = {k: np.asarray(v) for k, v in out.items()}
    tool = np.array([robot.placement(q).translation for q in run["q"]])
    run["deviation"] = ctrl.trajectory.path_deviation(tool)
    return run


def circle_point(robot, sigma):
    task = Circle(2.0).anchored_at(robot.pose(LBR4P_Q0))
    return dq_to_se3(task.target(sigma)).translation


# ---------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"influence_distance_m": 0.0}, "influence_distance_m"),
        ({"influence_distance_m": 2.0}, "influence_distance_m"),
        ({"safety_distance_m": -0.01}, "safety_distance_m"),
        ({"safety_distance_m": math.nan}, "safety_distance_m"),
        ({"safety_distance_m": 0.1, "influence_distance_m": 0.1}, "must be <"),
        ({"gain_m_per_s": 0.0}, "gain_m_per_s"),
        ({"gain_m_per_s": math.inf}, "gain_m_per_s"),
    ],
)
def test_bad_parameters_name_the_parameter(robot, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        CollisionLimit(CollisionModel(robot), **kwargs)


def test_it_needs_a_collision_model(robot):
    with pytest.raises(ParameterError, match="CollisionModel"):
        CollisionLimit(robot)


# ---------------------------------------------------------------------------- rows
def test_damper_rows_are_their_definition(robot):
    """Local controller: ``∇dᵀ q̇_0 ≥ -k (d - d_s)`` for the pairs within ``d_i``."""
    tool = robot.placement(LBR4P_Q0).translation
    ball = Sphere(name="ball", position_m=tuple(tool + [0.15, 0.0, 0.0]), radius_m=0.03)
    cm = CollisionModel(robot, (ball,))
    limit = CollisionLimit(cm, influence_distance_m=0.15)
    ctrl = make(robot, "local", Circle(2.0), (limit,))
    ctrl.reset(LBR4P_Q0)
    res = ctrl.step(LBR4P_Q0)
    rows = [g for g in ctrl.last_problem().inequalities if g.name == "collision"]
    assert len(rows) == 1
    near = cm.distances(LBR4P_Q0, influence_m=0.15)
    assert rows[0].lower.size == len(near) == limit.last_rows > 0
    assert not res.diagnostics.fallback
    rate = min(0.5 / (0.15 - SAFETY_M), 1.0 / T)
    qd0 = ctrl.layout.qd_index()[0]
    for row, low, p in zip(rows[0].C, rows[0].lower, near, strict=True):
        assert np.allclose(row[qd0], p.gradient) and np.count_nonzero(row) <= 7
        assert low == pytest.approx(-rate * (p.distance_m - SAFETY_M))
        assert p.gradient @ res.qd_command >= low - 1e-9
    keys = rows[0].keys  # each row named by its pair, once
    assert keys is not None and keys.size == rows[0].lower.size
    assert np.unique(keys).size == keys.size and keys.min() >= 0 and keys.max() < cm.num_pairs


def test_predicted_rows_linearise_the_distance(robot):
    """Path following: at the solution, each row's value is the distance at its predicted
    state linearised at ``q̄_i``; it holds, and the true distance is within second order."""
    ball = Sphere(name="ball", position_m=tuple(circle_point(robot, 0.3)), radius_m=0.03)
    cm = CollisionModel(robot, (ball,))
    limit = CollisionLimit(cm, influence_distance_m=0.3)
    ctrl = make(robot, "path_following", Circle(2.0), (limit,))
    ctrl.reset(LBR4P_Q0)
    q = LBR4P_Q0.copy()
    for _ in range(30):
        q = q + T * ctrl.step(q).qd_command
    problem = ctrl.last_problem()
    rows = [g for g in problem.inequalities if g.name == "collision"][0]
    # the solution of the last level (the plan the controller committed)
    pred = ctrl.prediction_model
    z = np.zeros(problem.layout.num_vars)
    qd_index, s_index = problem.layout.qd_index(), problem.layout.s_index()
    z[qd_index] = pred.plan_qd
    z[s_index] = pred.plan_s
    assert np.all(rows.C @ z >= rows.lower - 1e-7)
    assert rows.lower.size == limit.last_rows > 0
    # each row named by its predicted state and pair, once
    num_states = problem.layout.num_blocks
    assert rows.keys is not None and np.unique(rows.keys).size == rows.lower.size
    assert rows.keys.min() >= cm.num_pairs and rows.keys.max() < (num_states + 1) * cm.num_pairs


def test_closing_faster_than_braking_allows_keeps_the_qp_feasible(robot):
    """At 1 kHz under the thesis's 10 rad/s² the elbow closes on a ball faster than it can
    brake before the safety distance: the floors give way by the approach braking cannot
    avoid, so no step's QP fails (asking for ``d_s`` made 107 of 2500 steps fall back to
    braking blind, and the elbow came to 18.2 mm) and the pair stays within tolerance."""
    ball = Sphere(name="ball", position_m=(0.2245, -0.2559, 0.9519), radius_m=0.05)
    cm = CollisionModel(robot, (ball,))
    ctrl = PathFollowingController(
        robot, Circle(2.0), 0.001, velocity_limits=THESIS_VEL, acceleration_limit=10.0,
        extra_limits=(CollisionLimit(cm),),
    )  # fmt: skip
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    fallbacks, d_min = 0, np.inf
    for _ in range(1100):  # the first fall-back asking for d_s came at step 970
        res = ctrl.step(q)
        fallbacks += int(res.diagnostics.fallback)
        q = q + 0.001 * res.qd_command
        d_min = min(d_min, cm.min_distance(q))
    assert fallbacks == 0
    assert SAFETY_M - TOLERANCE_M <= d_min < SAFETY_M + 0.005  # the pair did come close


def test_pairs_that_come_and_go_keep_the_warm_start(robot):
    """At 1 kHz, as collision pairs enter and leave the influence distance, the levels'
    last active sets are carried to the rows that stay (by the rows' names): the steps
    where the collision rows change are solved on the carried sets, without a solver's
    iteration, where carrying them by index left DAQP 4–12 iterations on most of them."""
    from dqcontrol.model.collision import Box, HalfSpace

    tool = robot.placement(LBR4P_Q0).translation
    obstacles = (
        Sphere(name="ball", position_m=(0.2245, -0.2559, 0.9519), radius_m=0.05),
        Box(name="crate", position_m=tuple(tool + [0.0, 0.25, -0.1]), size_m=(0.1, 0.1, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=float(tool[2] - 0.3)),
    )
    limit = CollisionLimit(CollisionModel(robot, obstacles, self_collision=True))
    ctrl = PathFollowingController(
        robot, Circle(2.0), 1e-3, velocity_limits=THESIS_VEL, acceleration_limit=10.0,
        extra_limits=(limit,),
    )  # fmt: skip
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    last, changed = None, []
    for _ in range(600):
        res = ctrl.step(q)
        assert not res.diagnostics.fallback
        if last is not None and limit.last_rows != last:
            changed.append(res.diagnostics.iterations)
        last = limit.last_rows
        q = q + 1e-3 * res.qd_command
    assert len(changed) >= 10, "pairs entered and left the influence distance"
    assert max(changed) == 0, changed


# ---------------------------------------------------------------------------- behaviours
def test_an_obstacle_on_the_path_stops_the_path_following_controller(robot):
    ball = Sphere(name="ball", position_m=tuple(circle_point(robot, 1.0)), radius_m=0.03)
    cm = CollisionModel(robot, (ball,))
    free = closed_loop(robot, make(robot, "path_following", Circle(2.0)), cm, 2.5)
    assert free["d_min"].min() < -0.025  # the tool would go through it
    run = closed_loop(
        robot, make(robot, "path_following", Circle(2.0), (CollisionLimit(cm),)), cm, 4.0
    )
    assert run["d_min"].min() >= SAFETY_M - TOLERANCE_M  # no contact, the margin kept
    assert run["s"][-50:].max() < 0.01  # s → 0
    assert run["sigma"][-1] < 1.0  # stopped before the obstacle's phase
    speed = np.abs(np.diff(run["q"][-20:], axis=0)).max() / T
    assert speed < 0.01  # at rest [rad/s]
    assert run["deviation"].max() < PATH_GOAL_M  # on the path: it does not go around
    assert run["fallbacks"] == 0


def test_an_obstacle_at_the_elbow_is_avoided_in_the_null_space(robot):
    # a ball on the elbow's way (found from the task without the limit: the elbow's
    # null-space direction of motion at t = 1 s, the ball 5 mm in its way)
    ball = Sphere(name="ball", position_m=(0.22446, -0.25589, 0.95194), radius_m=0.05)
    cm = CollisionModel(robot, (ball,))
    free = closed_loop(robot, make(robot, "path_following", Circle(2.0)), cm, 2.5)
    assert free["d_min"].min() < 0.0  # the elbow would hit it
    run = closed_loop(
        robot, make(robot, "path_following", Circle(2.0), (CollisionLimit(cm),)), cm, 2.5
    )
    assert run["d_min"].min() >= SAFETY_M - TOLERANCE_M
    assert run["deviation"].max() < PATH_GOAL_M  # the tool keeps the path
    done = np.flatnonzero(run["sigma"] >= 2.0)
    done_free = np.flatnonzero(free["sigma"] >= 2.0)
    assert done.size and done[0] <= done_free[0] + 5  # as fast as without the ball
    elbow = [robot.placement(q, "lbr4p_link_4").translation for q in (free["q"], run["q"])[1]]
    elbow_free = [robot.placement(q, "lbr4p_link_4").translation for q in free["q"]]
    assert np.linalg.norm(np.array(elbow) - np.array(elbow_free), axis=1).max() > 0.01


def fold_task(robot):
    """The tool path of a joint-space line from the start to a configuration where the
    wrist is inside the pedestal (shoulder and elbow folded back)."""
    q_fold = np.array([-1.45, -1.81, -0.21, -1.97, 0.13, -1.53, 1.11])
    qs = LBR4P_Q0 + np.linspace(0.0, 1.0, 6)[:, None] * (q_fold - LBR4P_Q0)
    poses = [robot.placement(q) for q in qs]
    quats = [pin.Quaternion(m.rotation) for m in poses]
    return WaypointTrajectory(
        np.array([m.translation for m in poses]),
        np.array([[x.w, x.x, x.y, x.z] for x in quats]),
        duration_s=4.0,
        reference=np.array([1.0, 0, 0, 0, 0, 0, 0, 0]),
    )


@pytest.mark.parametrize("name", ["path_following", "local"])
def test_a_task_folding_the_arm_into_itself_stops_before_contact(robot, name):
    cm = CollisionModel(robot)
    task = fold_task(robot)
    if name == "path_following":
        free = closed_loop(robot, make(robot, name, task), cm, 5.0)
        assert free["d_min"].min() < 0.0  # the wrist would enter the pedestal
    run = closed_loop(robot, make(robot, name, task, (CollisionLimit(cm),)), cm, 6.0)
    assert run["d_min"].min() >= SAFETY_M - TOLERANCE_M
    assert run["sigma"][-1] < 4.0  # the task did not finish
    if name == "path_following":
        assert run["s"][-50:].max() < 0.01
        assert np.abs(np.diff(run["q"][-20:], axis=0)).max() / T < 0.01
        assert run["deviation"].max() < PATH_GOAL_M
    closest = min(cm.distances(run["q"][-1]), key=lambda p: p.distance_m)
    assert "lbr4p_pedestal" in cm.pair_links[closest.pair]


@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_every_controller_keeps_the_safety_distance(robot, name):
    ball = Sphere(name="ball", position_m=tuple(circle_point(robot, 1.0)), radius_m=0.03)
    cm = CollisionModel(robot, (ball,))
    run = closed_loop(robot, make(robot, name, Circle(2.0), (CollisionLimit(cm),)), cm, 3.0)
    assert run["d_min"].min() >= SAFETY_M - TOLERANCE_M
    assert run["fallbacks"] == 0


@settings(
    max_examples=6,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    phase=st.floats(0.3, 1.9),
    offset=st.lists(st.floats(-0.08, 0.08), min_size=3, max_size=3),
    radius=st.floats(0.02, 0.06),
    start=st.lists(st.floats(-0.05, 0.05), min_size=7, max_size=7),
)
def test_fuzz_obstacles_near_the_path(robot, phase, offset, radius, start):
    """Random balls near the path and random start states: the smallest distance over the
    run never goes below the safety distance minus the tolerance."""
    centre = circle_point(robot, phase) + np.array(offset)
    ball = Sphere(name="ball", position_m=tuple(centre), radius_m=radius)
    cm = CollisionModel(robot, (ball,))
    q0 = LBR4P_Q0 + np.array(start)
    if cm.min_distance(q0) < SAFETY_M + 0.01:
        return  # a start inside the margin is not this test's case
    ctrl = make(robot, "path_following", Circle(2.0), (CollisionLimit(cm),))
    run = closed_loop(robot, ctrl, cm, 2.5, q0=q0)
    assert run["d_min"].min() >= SAFETY_M - TOLERANCE_M


@pytest.mark.parametrize("name", ["path_following", "local"])
def test_a_mesh_robot_keeps_the_safety_distance(name):
    """The Panda (convex hulls of its meshes, the SRDF's allowed pairs) with a ball on its
    circle."""
    from dqcontrol import load_panda
    from dqcontrol.model import PANDA_Q0, panda_urdf_path

    panda = load_panda()
    srdf = panda_urdf_path()[0].parent.parent / "srdf" / "panda.srdf"
    point = dq_to_se3(Circle(2.0).anchored_at(panda.pose(PANDA_Q0)).target(1.0)).translation
    cm = CollisionModel(
        panda, (Sphere(name="ball", position_m=tuple(point), radius_m=0.03),), srdf=srdf
    )
    cls, kw = CONTROLLERS[name]
    ctrl = cls(
        panda, Circle(2.0), T, acceleration_limit=10.0, extra_limits=(CollisionLimit(cm),), **kw
    )
    run = closed_loop(panda, ctrl, cm, 3.0, q0=PANDA_Q0)
    assert run["d_min"].min() >= SAFETY_M - TOLERANCE_M
    assert run["sigma"][-1] < 1.0 and run["fallbacks"] == 0
    if name == "path_following":
        assert run["deviation"].max() < PATH_GOAL_M


@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_a_start_inside_the_safety_distance_comes_no_closer(robot, name):
    """A ball 10 mm from the wrist at the start (inside ``d_s``): no QP fails, and no pair
    comes closer than it started."""
    wrist = robot.placement(LBR4P_Q0, "lbr4p_link_6").translation
    centre = wrist + np.array([0.0, -1.0, 0.0]) * (0.06 + 0.04 + 0.01)
    cm = CollisionModel(robot, (Sphere(name="ball", position_m=tuple(centre), radius_m=0.04),))
    start = cm.min_distance(LBR4P_Q0)
    assert start == pytest.approx(0.01, abs=1e-6)
    run = closed_loop(robot, make(robot, name, Circle(2.0), (CollisionLimit(cm),)), cm, 1.0)
    assert run["fallbacks"] == 0
    assert run["d_min"].min() >= start - 1e-5


def test_moving_rows_refresh_the_backend_like_a_new_setup(robot):
    """Collision rows change values every step with the same shape: the backend refreshes
    its copy of them (no new setup); the commands equal those of a backend set up anew at
    every step."""
    ball = Sphere(name="ball", position_m=(0.22446, -0.25589, 0.95194), radius_m=0.05)
    cm = CollisionModel(robot, (ball,))
    a = make(robot, "local", Circle(2.0), (CollisionLimit(cm),))
    b = make(robot, "local", Circle(2.0), (CollisionLimit(cm),))
    q = LBR4P_Q0.copy()
    a.reset(q)
    b.reset(q)
    refreshed = 0
    for _ in range(150):
        before = a.backend._blocks._structure
        ra = a.step(q)
        refreshed += a.backend._blocks._structure == before and a.last_problem().C.shape[0] > 0
        b.backend._blocks._structure = None  # force a new setup
        rb = b.step(q)
        np.testing.assert_allclose(ra.qd_command, rb.qd_command, rtol=0, atol=1e-12)
        assert ra.s == pytest.approx(rb.s, abs=1e-12)
        q = q + T * ra.qd_command
    assert refreshed > 50  # the rows were there and the structure was kept


# ---------------------------------------------------------------------- MuJoCo as the oracle
# the runs with the limit replayed in MuJoCo's own collision detection
# (tests/sim/test_mjcf_builder.py's ``Replay``): no contact where the limit holds them apart
needs_mujoco = pytest.mark.skipif(
    importlib.util.find_spec("mujoco") is None, reason="MuJoCo is not installed (the 'sim' extra)"
)


@needs_mujoco
def test_runs_with_the_limit_make_no_contact(robot):
    from sim.test_mjcf_builder import Replay

    ball = Sphere(name="ball", position_m=tuple(circle_point(robot, 1.0)), radius_m=0.03)
    cm = CollisionModel(robot, (ball,))
    replay = Replay(robot, cm.obstacles)
    free = closed_loop(robot, make(robot, "path_following", Circle(2.0)), cm, 2.5)
    assert replay.contacts(free["q"])[0] > 0
    for name in ("path_following", "local"):
        run = closed_loop(robot, make(robot, name, Circle(2.0), (CollisionLimit(cm),)), cm, 3.0)
        assert replay.contacts(run["q"]) == (0, 0, 0.0)


@needs_mujoco
@settings(
    max_examples=4,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    phase=st.floats(0.3, 1.9),
    offset=st.lists(st.floats(-0.06, 0.06), min_size=3, max_size=3),
    radius=st.floats(0.02, 0.06),
)
def test_fuzz_no_contact_in_mujoco(robot, phase, offset, radius):
    from sim.test_mjcf_builder import Replay

    centre = circle_point(robot, phase) + np.array(offset)
    ball = Sphere(name="ball", position_m=tuple(centre), radius_m=radius)
    cm = CollisionModel(robot, (ball,))
    if cm.min_distance(LBR4P_Q0) < 0.03:
        return  # a start inside the margin is not this test's case
    run = closed_loop(
        robot, make(robot, "path_following", Circle(2.0), (CollisionLimit(cm),)), cm, 2.5
    )
    assert Replay(robot, cm.obstacles).contacts(run["q"])[:2] == (0, 0)
    assert not math.isnan(run["d_min"].min())


@needs_mujoco
def test_the_folding_task_has_no_self_contact_with_the_limit(robot):
    from sim.test_mjcf_builder import Replay

    cm = CollisionModel(robot)
    replay = Replay(robot, ())
    task = fold_task(robot)
    free = closed_loop(robot, make(robot, "path_following", task), cm, 5.0)
    assert replay.contacts(free["q"])[1] > 0  # MuJoCo sees the wrist in the pedestal
    run = closed_loop(robot, make(robot, "path_following", task, (CollisionLimit(cm),)), cm, 5.0)
    assert replay.contacts(run["q"]) == (0, 0, 0.0)

"""The compiled mass-matrix diagonal and gravity torques (``dqcontrol.model.chain_dynamics``)
against Pinocchio's composite rigid body algorithm and generalised gravity, and the gravity
against finite differences of the potential energy from Pinocchio's centre of mass.

``RobotModel`` takes the compiled pass for serial chains of revolute joints and Pinocchio
otherwise (the choice is made, and checked, when the model is built); the dynamics-aware
acceleration bound reads it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from model.test_pinocchio_model import _TILTED  # a tilted two-joint arm, first joint's kind open

import dqcontrol
from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.model import RobotModel
from dqcontrol.model import robot as robot_module
from dqcontrol.model.chain_dynamics import ChainDynamics

long_chain_urdf = load_bench().long_chain_urdf


def _general_chain_urdf(n: int, seed: int) -> str:
    """A chain of ``n`` revolute joints with tilted placements, unaligned axes, off-centre
    centres of mass in rotated inertial frames and full inertia tensors (seeded)."""
    rng = np.random.default_rng(seed)
    links, joints, parent = ['<link name="base"/>'], [], "base"
    for i in range(n):
        mass = rng.uniform(0.5, 4.0)
        root = rng.normal(size=(3, 3))
        inertia = 0.02 * (root @ root.T + 0.5 * np.eye(3))  # symmetric positive definite
        com, com_rpy = rng.uniform(-0.1, 0.1, 3), rng.uniform(-1.0, 1.0, 3)
        links.append(
            f'<link name="l{i}"><inertial><mass value="{mass}"/>'
            f'<origin xyz="{com[0]} {com[1]} {com[2]}" '
            f'rpy="{com_rpy[0]} {com_rpy[1]} {com_rpy[2]}"/>'
            f'<inertia ixx="{inertia[0, 0]}" iyy="{inertia[1, 1]}" izz="{inertia[2, 2]}" '
            f'ixy="{inertia[0, 1]}" ixz="{inertia[0, 2]}" iyz="{inertia[1, 2]}"/>'
            "</inertial></link>"
        )
        xyz, rpy = rng.uniform(-0.2, 0.2, 3), rng.uniform(-1.0, 1.0, 3)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        joints.append(
            f'<joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>'
            f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>'
            f'<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>'
            '<limit lower="-2.9" upper="2.9" effort="100" velocity="3"/></joint>'
        )
        parent = f"l{i}"
    return '<robot name="general">' + "".join(links + joints) + "</robot>"


def _with_armature(robot: RobotModel, seed: int) -> RobotModel:
    model = robot.model.copy()
    model.armature = np.random.default_rng(seed).uniform(0.01, 0.5, model.nv)
    return RobotModel(model, robot.ee_frame)


MODELS = {
    "lbr4p": dqcontrol.load_lbr4p,
    "panda": dqcontrol.load_panda,
    "lbr4p_on_a_tilted_base": lambda: dqcontrol.load_lbr4p(
        base=pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.4, 1.1), np.array([0.2, -0.1, 0.5]))
    ),
    "chain1": lambda: RobotModel.from_urdf(long_chain_urdf(1), "flange"),
    "tilted_continuous": lambda: RobotModel.from_urdf(_TILTED.format(kind="continuous"), "l2"),
    "chain14": lambda: RobotModel.from_urdf(long_chain_urdf(14), "flange"),
    "general7": lambda: RobotModel.from_urdf(_general_chain_urdf(7, seed=3), "l6"),
    "general10_armature": lambda: _with_armature(
        RobotModel.from_urdf(_general_chain_urdf(10, seed=4), "l9"), seed=5
    ),
}


def _reference(robot: RobotModel, qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    data = robot.model.createData()
    diag = np.array([np.diagonal(pin.crba(robot.model, data, q)) for q in qs])
    g = np.array([pin.computeGeneralizedGravity(robot.model, data, q) for q in qs])
    return diag, g


@pytest.mark.parametrize("name", list(MODELS))
def test_the_compiled_pass_equals_pinocchio(name):
    robot = MODELS[name]()
    assert isinstance(robot._dynamics, ChainDynamics), "expected the compiled pass"
    qs = np.random.default_rng(len(name)).uniform(-np.pi, np.pi, size=(60, robot.nq))
    diag, g = robot._dynamics.diagonal_and_gravity(qs)
    diag_ref, g_ref = _reference(robot, qs)
    np.testing.assert_allclose(diag, diag_ref, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(g, g_ref, rtol=1e-12, atol=1e-11)


@pytest.mark.parametrize("name", ["lbr4p", "general7"])
def test_gravity_is_the_gradient_of_the_potential(name):
    """``g = ∂V/∂q`` with ``V = -m g⃗ · c(q)`` from Pinocchio's centre of mass (central
    differences, step 1e-6 rad)."""
    robot = MODELS[name]()
    model, data = robot.model, robot.model.createData()
    total = sum(inertia.mass for inertia in model.inertias)

    def potential(q):
        return -total * float(model.gravity.linear @ pin.centerOfMass(model, data, q))

    h = 1e-6
    for q in np.random.default_rng(7).uniform(-np.pi, np.pi, size=(5, robot.nq)):
        _, g = robot._dynamics.diagonal_and_gravity(q[None, :])
        fd = [(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(robot.nq)]
        np.testing.assert_allclose(g[0], fd, rtol=1e-6, atol=1e-6)


def test_models_that_are_not_revolute_chains_stay_on_pinocchio():
    for robot in (
        RobotModel.from_urdf(_TILTED.format(kind="prismatic"), "l2"),
        dqcontrol.load_panda(locked_joints={}),  # the fingers branch off the hand
    ):
        assert robot._dynamics is None
        qs = robot.random_configurations(6, seed=1)
        a_max = robot.fast.acceleration_limits_batch(qs, 1.0, 0.5, 50.0)
        diag_ref, g_ref = _reference(robot, qs)
        expected = np.clip((robot.limits.effort_max - np.abs(g_ref)) / diag_ref, 0.5, 50.0)
        np.testing.assert_array_equal(a_max, expected)


def test_tables_that_disagree_with_pinocchio_are_not_used(monkeypatch):
    """The load-time check: a wrong table (here one mass off by 1e-9) leaves the model on
    Pinocchio."""
    build = ChainDynamics.build

    def wrong_build(model):
        dynamics = build(model)
        dynamics._bodies[2, 0] *= 1.0 + 1e-9
        return dynamics

    monkeypatch.setattr(robot_module.ChainDynamics, "build", staticmethod(wrong_build))
    assert dqcontrol.load_lbr4p()._dynamics is None


def test_acceleration_limits_read_the_compiled_pass(lbr4p):
    """The bound of one configuration and of a batch, against the formula on Pinocchio's
    ``M`` and ``g``; an empty batch gives an empty bound."""
    qs = lbr4p.random_configurations(8, seed=11)
    diag_ref, g_ref = _reference(lbr4p, qs)
    expected = np.clip((0.8 * lbr4p.limits.effort_max - np.abs(g_ref)) / diag_ref, 0.5, 50.0)
    batch = lbr4p.fast.acceleration_limits_batch(qs, 0.8, 0.5, 50.0)
    np.testing.assert_allclose(batch, expected, rtol=1e-12)
    for q, row in zip(qs, batch, strict=True):
        one = lbr4p.acceleration_limits(q, effort_fraction=0.8)
        np.testing.assert_array_equal(one, row)
    assert lbr4p.fast.acceleration_limits_batch(np.empty((0, 7)), 1.0, 0.5, 50.0).shape == (0, 7)


def test_the_bound_arithmetic_is_numpys():
    """``acceleration_bounds`` against numpy's ``clip((f τ - |g|) / diag, floor, cap)``
    bit for bit, through both clips; a non-positive inertia is reported."""
    from dqcontrol.model.chain_dynamics import acceleration_bounds

    rng = np.random.default_rng(21)
    diag = rng.uniform(0.01, 3.0, size=(12, 7))
    g = rng.normal(scale=40.0, size=(12, 7))
    effort = rng.uniform(20.0, 200.0, size=7)
    bounds, positive = acceleration_bounds(diag, g, 0.9, effort, 0.5, 50.0)
    expected = np.clip((0.9 * effort - np.abs(g)) / diag, 0.5, 50.0)
    assert positive and np.array_equal(bounds, expected)
    assert (bounds == 0.5).any() and (bounds == 50.0).any()  # both clips were reached
    diag[4, 2] = 0.0
    assert not acceleration_bounds(diag, g, 0.9, effort, 0.5, 50.0)[1]

"""The closed-form batched kinematics (``dqcontrol.model.chain_batch``) equals Pinocchio.

``RobotModel.poses_and_jacobians`` takes the closed form for chains of at most
``MAX_JOINTS`` revolute joints and loops over Pinocchio otherwise; the choice is made when
the model is built. Here both paths, and the single-configuration ``pose_and_jacobian``,
must agree to 1e-12 on hundreds of seeded configurations, and every model the closed form
cannot handle must fall back to Pinocchio (and still be right).
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

import dqcontrol
from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.dq.algebra import qfrom_axis_angle
from dqcontrol.errors import ConfigurationError
from dqcontrol.model import RobotModel, lbr4p_urdf_path
from dqcontrol.model import robot as robot_module
from dqcontrol.model.chain_batch import MAX_JOINTS, ChainBatch

#: the synthetic serial chains of the benchmark (benchmarks/bench.py)
long_chain_urdf = load_bench().long_chain_urdf

COUNT = 250
TOL = 1e-12


def _transform(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = np.eye(4)
    rotation = pin.Quaternion(*qfrom_axis_angle(rng.normal(size=3), rng.uniform(0.2, 3.0)))
    T[:3, :3] = rotation.toRotationMatrix()
    T[:3, 3] = rng.uniform(-0.5, 0.5, size=3)
    return T


PRISMATIC_URDF = """<robot name="slider">
  <link name="base"/><link name="l0"/><link name="l1"/><link name="tip"/>
  <joint name="j0" type="revolute"><parent link="base"/><child link="l0"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-2.9" upper="2.9" effort="10" velocity="1"/></joint>
  <joint name="j1" type="prismatic"><parent link="l0"/><child link="l1"/>
    <origin xyz="0.1 0 0.2" rpy="0.3 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-0.2" upper="0.2" effort="10" velocity="1"/></joint>
  <joint name="jt" type="fixed"><parent link="l1"/><child link="tip"/>
    <origin xyz="0 0 0.1"/></joint>
</robot>"""


def _models() -> dict:
    """Models the closed form must handle: name → factory."""
    return {
        "lbr4p": dqcontrol.load_lbr4p,
        "panda": dqcontrol.load_panda,
        f"chain{MAX_JOINTS}": lambda: RobotModel.from_urdf(long_chain_urdf(MAX_JOINTS), "flange"),
        "chain1": lambda: RobotModel.from_urdf(long_chain_urdf(1), "flange"),
        "lbr4p_base_tool": lambda: dqcontrol.load_lbr4p(base=_transform(41), tool=_transform(42)),
        "panda_base_tool": lambda: dqcontrol.load_panda(base=_transform(43), tool=_transform(44)),
        # a frame in the middle of the arm: the joints after it have zero columns
        "lbr4p_link_4": lambda: RobotModel.from_urdf(lbr4p_urdf_path(), "lbr4p_link_4"),
        # fingers unlocked: prismatic joints off the path to the hand, zero columns
        "panda_fingers_free": lambda: dqcontrol.load_panda(locked_joints={}),
    }


def _fallback_models() -> dict:
    """Models the closed form cannot handle: name → factory."""
    return {
        "chain14": lambda: RobotModel.from_urdf(long_chain_urdf(14), "flange"),
        f"chain{MAX_JOINTS + 1}": lambda: RobotModel.from_urdf(
            long_chain_urdf(MAX_JOINTS + 1), "flange"
        ),
        "prismatic_in_chain": lambda: RobotModel.from_urdf(PRISMATIC_URDF, "tip"),
        "panda_finger_frame": lambda: dqcontrol.load_panda("panda_leftfinger", locked_joints={}),
    }


MODELS = _models()
FALLBACKS = _fallback_models()


def _configurations(robot: RobotModel, seed: int) -> np.ndarray:
    qs = robot.random_configurations(COUNT, seed=seed)
    # and a few outside the limits and far from 0 (larger phases, more rounding)
    rng = np.random.default_rng(seed + 1)
    wide = rng.uniform(-4 * np.pi, 4 * np.pi, size=(20, robot.nq))
    return np.concatenate((qs, wide, np.zeros((1, robot.nq))))


def _assert_same(x, jac, x_ref, jac_ref) -> None:
    """Equal to TOL; where ``r_w`` is 0 to rounding (a half-turn, e.g. the Panda at q = 0)
    the convention ``r_w ≥ 0`` picks either sign, so there ``-x, -J`` count as equal too."""
    sign = np.where(np.abs(x_ref[..., :1]) <= TOL, np.sign(np.sum(x * x_ref, -1))[..., None], 1)
    np.testing.assert_allclose(x, sign * x_ref, rtol=0, atol=TOL)
    np.testing.assert_allclose(jac, sign[..., None] * jac_ref, rtol=0, atol=TOL)


def _assert_matches_single_and_pinocchio(robot: RobotModel, qs: np.ndarray) -> None:
    xs, jacs = robot.poses_and_jacobians(qs)
    assert xs.shape == (len(qs), 8)
    assert jacs.shape == (len(qs), 8, robot.nq)
    _assert_same(xs, jacs, *robot._poses_and_jacobians_pinocchio(qs))
    assert (xs[:, 0] >= 0.0).all()  # r_w ≥ 0, the Jacobian flipped with x
    for q, x, jac in zip(qs, xs, jacs, strict=True):
        x1, jac1 = robot.pose_and_jacobian(q)
        assert jac1.shape == (8, robot.nq)  # also for one joint (Pinocchio gives (6,) there)
        _assert_same(x, jac, x1, jac1)


@pytest.mark.parametrize("name", list(MODELS))
def test_closed_form_equals_pinocchio_and_single(name):
    robot = MODELS[name]()
    assert isinstance(robot._chain, ChainBatch), "expected the closed-form batch"
    _assert_matches_single_and_pinocchio(robot, _configurations(robot, seed=len(name)))


@pytest.mark.parametrize("name", list(MODELS))
def test_pose_alone_equals_the_batch_and_pinocchio(name):
    """``robot.fast.poses`` (the chain's pose columns alone) against the batch's poses and
    Pinocchio's forward kinematics."""
    robot = MODELS[name]()
    qs = _configurations(robot, seed=3 + len(name))
    xs, _ = robot.poses_and_jacobians(qs)
    alone = robot.fast.poses(qs)
    reference = np.array([robot._pose(q) for q in qs])
    np.testing.assert_array_equal(alone[:, 0] >= 0.0, True)
    for other in (xs, reference):  # the same pose; ±x where r_w is zero to rounding
        sign = np.copysign(1.0, np.einsum("ij,ij->i", alone, other))
        np.testing.assert_allclose(alone, sign[:, None] * other, rtol=0, atol=TOL)
        assert np.all((sign > 0) | (np.abs(alone[:, 0]) < TOL))


@pytest.mark.parametrize("name", list(FALLBACKS))
def test_unsupported_models_fall_back_to_pinocchio(name):
    robot = FALLBACKS[name]()
    assert robot._chain is None
    assert ChainBatch.build(robot.model, robot._fid) is None
    qs = robot.random_configurations(40, seed=5)
    xs, jacs = robot.poses_and_jacobians(qs)
    alone = robot.fast.poses(qs)
    assert alone.shape == (40, 8)
    for q, x, jac, x_alone in zip(qs, xs, jacs, alone, strict=True):
        assert np.array_equal(x_alone, robot.fast.pose(q))  # Pinocchio's, one by one
        x1, jac1 = robot.pose_and_jacobian(q)
        np.testing.assert_allclose(x, x1, rtol=0, atol=TOL)
        np.testing.assert_allclose(jac, jac1, rtol=0, atol=TOL)


def test_frame_on_the_universe_falls_back():
    robot = RobotModel.from_urdf(long_chain_urdf(3), "base")
    assert robot._chain is None
    xs, jacs = robot.poses_and_jacobians(np.zeros((2, 3)))
    np.testing.assert_allclose(xs, [[1.0, 0, 0, 0, 0, 0, 0, 0]] * 2, atol=1e-15)
    assert not jacs.any()


def test_tables_that_disagree_with_pinocchio_are_not_used(monkeypatch):
    """The load-time check: wrong tables (here perturbed) leave the model on Pinocchio."""
    build = ChainBatch.build

    def wrong_build(model, frame_id):
        chain = build(model, frame_id)
        chain._t = chain._t * (1.0 + 1e-9)
        return chain

    monkeypatch.setattr(robot_module.ChainBatch, "build", staticmethod(wrong_build))
    robot = dqcontrol.load_lbr4p()
    assert robot._chain is None
    qs = robot.random_configurations(5, seed=2)
    x1, jac1 = robot.pose_and_jacobian(qs[3])
    xs, jacs = robot.poses_and_jacobians(qs)
    np.testing.assert_allclose(xs[3], x1, rtol=0, atol=TOL)
    np.testing.assert_allclose(jacs[3], jac1, rtol=0, atol=TOL)


def test_batch_of_one_and_empty_batch(lbr4p):
    q = lbr4p.random_configurations(1, seed=9)
    xs, jacs = lbr4p.poses_and_jacobians(q)
    x1, jac1 = lbr4p.pose_and_jacobian(q[0])
    np.testing.assert_allclose(xs[0], x1, rtol=0, atol=TOL)
    np.testing.assert_allclose(jacs[0], jac1, rtol=0, atol=TOL)
    xs, jacs = lbr4p.poses_and_jacobians(np.zeros((0, 7)))
    assert xs.shape == (0, 8) and jacs.shape == (0, 8, 7)


def test_results_are_fresh_arrays(lbr4p):
    """A later call must not overwrite what an earlier one returned."""
    qs = lbr4p.random_configurations(3, seed=4)
    xs, jacs = lbr4p.poses_and_jacobians(qs)
    xs_copy, jacs_copy = xs.copy(), jacs.copy()
    lbr4p.poses_and_jacobians(qs[::-1] + 0.1)
    np.testing.assert_array_equal(xs, xs_copy)
    np.testing.assert_array_equal(jacs, jacs_copy)


def test_batch_check_after_the_cheaper_finiteness_test(lbr4p):
    """check_batch's dot-product test: huge finite angles pass, NaN/inf are rejected."""
    huge = np.full((3, 7), 1e200)  # the dot product overflows, the entries are finite
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy may report the overflow
        np.testing.assert_array_equal(lbr4p.check_batch(huge), huge)
    for bad in (np.nan, np.inf, -np.inf):
        qs = np.zeros((3, 7))
        qs[1, 4] = bad
        with pytest.raises(ConfigurationError, match="must be finite"):
            lbr4p.poses_and_jacobians(qs)


def test_the_compiled_loops_equal_numpys_broadcasts():
    from dqcontrol.model.chain_batch import outer_rows_into, positive_scalar_rows

    rng = np.random.default_rng(12)
    v = rng.normal(size=(5, 11))
    k = np.empty((5, 4 * 7))
    outer_rows_into(v, 4, k)
    assert np.array_equal(k, (v[:, :4, None] * v[:, None, 4:]).reshape(5, -1))
    out = rng.normal(size=(6, 9))
    out[2, 0] = -0.0
    expected = out * np.copysign(np.ones((1, 1)), out[:, :1])
    positive_scalar_rows(out)
    assert np.array_equal(out, expected) and np.all(np.signbit(out[:, 0]) == [0, 0, 0, 0, 0, 0])

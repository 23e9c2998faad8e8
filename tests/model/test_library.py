"""The ready-made robots of ``dqcontrol.model.library``: the package's LBR4p file, the Panda of
example-robot-data, and the documented start configurations, against the URDFs and a hand check."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import dqcontrol
from dqcontrol.errors import URDFError
from dqcontrol.model import library
from dqcontrol.model.library import LBR4P_Q0, PANDA_Q0, lbr4p_urdf_path, panda_urdf_path


def random_q(model: dqcontrol.RobotModel, count: int, seed: int) -> np.ndarray:
    """``count`` configurations drawn uniformly within the model's joint limits."""
    rng = np.random.default_rng(seed)
    return rng.uniform(model.limits.q_min, model.limits.q_max, size=(count, model.nq))


def test_the_lbr4p_file_is_package_data():
    path = lbr4p_urdf_path()
    assert path.is_file() and path.suffix == ".urdf"
    assert path.parent == Path(dqcontrol.__file__).parent / "robots" / "lbr4p"
    assert "<robot" in path.read_text(encoding="utf-8")


def test_a_missing_package_file_is_a_urdf_error_naming_it():
    with pytest.raises(URDFError, match=r"dqcontrol/robots/lbr4p/nothing\.urdf is missing"):
        library._package_file("lbr4p", "nothing.urdf")


def test_the_lbr4p_start_is_the_documented_one(lbr4p):
    """The comment on ``LBR4P_Q0``: flange near (0.55, -0.21, 0.70) m pointing down, its x
    axis along world +y, every joint ≥ 0.64 rad from its limits, far from singular."""
    placement = lbr4p.placement(LBR4P_Q0)
    np.testing.assert_allclose(placement.translation, [0.55, -0.21, 0.70], atol=0.01)
    np.testing.assert_allclose(placement.rotation[:, 2], [0.0, 0.0, -1.0], atol=0.01)
    np.testing.assert_allclose(placement.rotation[:, 0], [0.0, 1.0, 0.0], atol=0.02)
    margin = np.minimum(LBR4P_Q0 - lbr4p.limits.q_min, lbr4p.limits.q_max - LBR4P_Q0)
    assert margin.min() >= 0.64
    singular = np.linalg.svd(lbr4p.pose_jacobian(LBR4P_Q0), compute_uv=False)
    assert singular[-2] > 0.09  # the smallest non-zero one (a pose Jacobian has rank ≤ 6)


def test_the_panda_start_is_inside_its_limits(panda):
    assert PANDA_Q0.shape == (panda.nq,)
    assert np.all(PANDA_Q0 > panda.limits.q_min) and np.all(PANDA_Q0 < panda.limits.q_max)


def test_the_panda_file_and_its_package_folder():
    path, package_dir = panda_urdf_path()
    assert path.is_file() and path.name == "panda.urdf"
    # every package:// URI of the URDF names a file under the package folder
    uris = re.findall(r'package://([^"]+)', path.read_text(encoding="utf-8"))
    assert len(uris) >= 2
    for uri in uris:
        assert (package_dir / uri).is_file(), uri


def test_panda_loads_from_its_urdf(panda):
    path, package_dir = panda_urdf_path()
    assert panda.source is not None and panda.source.path == path
    assert panda.nq == 7
    assert panda.joint_names == [f"panda_joint{i}" for i in range(1, 8)]
    assert panda.ee_frame == "panda_hand_tcp"
    for frame in ("panda_hand", "panda_hand_tcp"):
        assert frame in panda.frame_names
        panda.frame_id(frame)
    # the same model as a direct RobotModel.from_urdf call
    direct = dqcontrol.RobotModel.from_urdf(
        path,
        "panda_hand",
        locked_joints={"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0},
        package_dirs=[package_dir],
    )
    hand = dqcontrol.load_panda("panda_hand")
    for q in random_q(panda, 5, seed=8):
        np.testing.assert_array_equal(direct.pose(q), hand.pose(q))
        # the TCP sits 0.1034 m along the hand's z axis
        offset = np.linalg.inv(hand.placement(q).homogeneous) @ panda.placement(q).homogeneous
        np.testing.assert_allclose(offset[:3, 3], [0.0, 0.0, 0.1034], rtol=0, atol=1e-12)

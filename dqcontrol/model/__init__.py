"""Robot models: URDF → Pinocchio → end-effector pose and pose Jacobian in ``vec8`` form;
collision geometry and distances (:mod:`dqcontrol.model.collision`)."""

from dqcontrol.model.collision import (
    Box,
    Capsule,
    CollisionModel,
    Cylinder,
    DistanceBatch,
    HalfSpace,
    Obstacle,
    PairDistance,
    Sphere,
    make_obstacle,
    parse_obstacle,
    read_srdf_pairs,
)
from dqcontrol.model.library import (
    LBR4P_Q0,
    PANDA_Q0,
    lbr4p_urdf_path,
    load_lbr4p,
    load_panda,
    panda_urdf_path,
)
from dqcontrol.model.robot import JointLimits, RobotModel
from dqcontrol.model.urdf_source import URDFSource, check_urdf_xml, read_urdf

__all__ = [
    "LBR4P_Q0",
    "PANDA_Q0",
    "Box",
    "Capsule",
    "CollisionModel",
    "Cylinder",
    "DistanceBatch",
    "HalfSpace",
    "JointLimits",
    "Obstacle",
    "PairDistance",
    "RobotModel",
    "Sphere",
    "URDFSource",
    "check_urdf_xml",
    "lbr4p_urdf_path",
    "load_lbr4p",
    "load_panda",
    "make_obstacle",
    "panda_urdf_path",
    "parse_obstacle",
    "read_srdf_pairs",
    "read_urdf",
]

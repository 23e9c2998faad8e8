"""Robot models: URDF → Pinocchio → end-effector pose and pose Jacobian in ``vec8`` form."""

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
    "JointLimits",
    "RobotModel",
    "URDFSource",
    "check_urdf_xml",
    "lbr4p_urdf_path",
    "load_lbr4p",
    "load_panda",
    "panda_urdf_path",
    "read_urdf",
]

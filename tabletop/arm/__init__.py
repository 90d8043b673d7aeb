"""The arm: Panda kinematics, inverse kinematics, collision checking, reaching, drivers."""

from tabletop.arm.errors import ArmError, DriverError, FrameError, SafetyError
from tabletop.arm.ik import IKResult, pose_error, solve_ik
from tabletop.arm.model import (
    ARM_JOINT_NAMES,
    FINGER_JOINT_NAMES,
    HOME_Q,
    TCP_FRAME,
    PandaModel,
    as_arm_q,
)

__all__ = [
    "ARM_JOINT_NAMES",
    "FINGER_JOINT_NAMES",
    "HOME_Q",
    "TCP_FRAME",
    "ArmError",
    "DriverError",
    "FrameError",
    "IKResult",
    "PandaModel",
    "SafetyError",
    "as_arm_q",
    "pose_error",
    "solve_ik",
]

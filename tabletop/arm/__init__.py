"""The arm: Panda kinematics, inverse kinematics, collision checking, reaching, drivers.

Typical use::

    from tabletop.arm import PandaModel, PyBulletDriver, ReachController, table_box

    model = PandaModel()
    ctrl = ReachController(model, PyBulletDriver(client_id, robot_id), [table_box(), *boxes])
    result = ctrl.move_to([0.5, 0.1, 0.05])   # a ReachResult; failures are reasons, not raises
"""

from tabletop.arm.collision import (
    SELF_COLLISION_DISABLED,
    Clearance,
    CollisionChecker,
    MotionCheck,
)
from tabletop.arm.diffik import DiffIKConfig, DiffIKStep, MinkDiffIK, top_down_rotation
from tabletop.arm.driver import ArmDriver, JointState, KinematicDriver, PyBulletDriver
from tabletop.arm.errors import (
    ArmError,
    ConnectionLost,
    ConnectionRefused,
    DriverError,
    FrameError,
    MotionStoppedShort,
    ReflexError,
    SafetyError,
)
from tabletop.arm.franky_driver import FR3_LIMITS, ROBOT_LIMITS, FrankyDriver, TrackingReport
from tabletop.arm.ik import IKResult, pose_error, solve_ik
from tabletop.arm.mjcf import build_mujoco_model, urdf_for_mujoco
from tabletop.arm.model import (
    ARM_JOINT_NAMES,
    FINGER_JOINT_NAMES,
    HOME_Q,
    TCP_FRAME,
    PandaModel,
    as_arm_q,
)
from tabletop.arm.obstacles import (
    Box,
    ConvexObstacle,
    Cylinder,
    Obstacle,
    boxes_from_voxels,
    obstacle_aabb,
    table_box,
)
from tabletop.arm.panda_py_driver import PandaPyDriver
from tabletop.arm.planner import JointPlanner, PlannerConfig, PlanReason, PlanResult
from tabletop.arm.reach import (
    GoalChoice,
    ReachConfig,
    ReachController,
    ReachReason,
    ReachResult,
    ReachRoute,
)
from tabletop.arm.self_filter import RobotSelfFilter
from tabletop.arm.success import SUCCESS_RADIUS_M, ReachSuccess, distance_to_box, reach_success
from tabletop.arm.trajectory import (
    PANDA_LIMITS,
    JointLimits,
    JointTrajectory,
    TrajectoryCheck,
    TrajectoryConfig,
    check_trajectory,
    time_parametrize,
)
from tabletop.arm.workspace import Workspace

__all__ = [
    "ARM_JOINT_NAMES",
    "FINGER_JOINT_NAMES",
    "FR3_LIMITS",
    "HOME_Q",
    "PANDA_LIMITS",
    "ROBOT_LIMITS",
    "SELF_COLLISION_DISABLED",
    "SUCCESS_RADIUS_M",
    "TCP_FRAME",
    "ArmDriver",
    "ArmError",
    "Box",
    "Clearance",
    "CollisionChecker",
    "ConnectionLost",
    "ConnectionRefused",
    "ConvexObstacle",
    "Cylinder",
    "DiffIKConfig",
    "DiffIKStep",
    "DriverError",
    "FrameError",
    "FrankyDriver",
    "GoalChoice",
    "IKResult",
    "JointLimits",
    "JointPlanner",
    "JointState",
    "JointTrajectory",
    "KinematicDriver",
    "MinkDiffIK",
    "MotionCheck",
    "MotionStoppedShort",
    "Obstacle",
    "PandaModel",
    "PandaPyDriver",
    "PlanReason",
    "PlanResult",
    "PlannerConfig",
    "PyBulletDriver",
    "ReachConfig",
    "ReachController",
    "ReachReason",
    "ReachResult",
    "ReachRoute",
    "ReachSuccess",
    "ReflexError",
    "RobotSelfFilter",
    "SafetyError",
    "TrackingReport",
    "TrajectoryCheck",
    "TrajectoryConfig",
    "Workspace",
    "as_arm_q",
    "boxes_from_voxels",
    "build_mujoco_model",
    "check_trajectory",
    "distance_to_box",
    "obstacle_aabb",
    "pose_error",
    "reach_success",
    "solve_ik",
    "table_box",
    "time_parametrize",
    "top_down_rotation",
    "urdf_for_mujoco",
]

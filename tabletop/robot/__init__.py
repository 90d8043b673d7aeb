"""The robot API shared by every embodiment, on top of an AVLMap.

Typical use::

    from tabletop.mapping.avlmap import AVLMap
    from tabletop.robot import SimArm

    robot = SimArm(AVLMap.load("map.npz"), "default")
    robot.move_to_left("red mug")                       # a ReachResult
    obj_map = robot.get_major_map(obj="mug")
    sound_map = robot.get_map(sound="a trumpet playing")
    robot.move_to(robot.get_max_pos_3d(obj_map * sound_map))   # approached from above
"""

from tabletop.errors import GoalNotFound
from tabletop.robot.api import (
    ImageGoalUnavailable,
    RobotAPI,
    RobotError,
    SpatialConfig,
)
from tabletop.robot.arm import ArmRobot, SimArm
from tabletop.robot.mobile import BaseMoveResult, MobileBase, MobileConfig
from tabletop.robot.obstacles import (
    ARM,
    MOBILE_BASE,
    Embodiment,
    ObstacleVoxels,
    OccupancyGrid,
    arm_obstacles,
    label_voxels,
    merge_boxes,
    obstacle_voxels,
    occupancy_grid,
)
from tabletop.robot.primitives import (
    EXCLUDED,
    PRIMITIVES,
    Primitive,
    motion_to,
    primitive,
    signature_mismatches,
    undeclared_methods,
)
from tabletop.robot.wheeled import (
    FLYER,
    GROUND_BASE,
    DriveResult,
    MobileRobot,
    RoomMoveConfig,
    plan_path,
)

__all__ = [
    "ARM",
    "EXCLUDED",
    "FLYER",
    "GROUND_BASE",
    "MOBILE_BASE",
    "PRIMITIVES",
    "ArmRobot",
    "BaseMoveResult",
    "DriveResult",
    "Embodiment",
    "GoalNotFound",
    "ImageGoalUnavailable",
    "MobileBase",
    "MobileConfig",
    "MobileRobot",
    "ObstacleVoxels",
    "OccupancyGrid",
    "Primitive",
    "RobotAPI",
    "RobotError",
    "RoomMoveConfig",
    "SimArm",
    "SpatialConfig",
    "arm_obstacles",
    "label_voxels",
    "merge_boxes",
    "motion_to",
    "obstacle_voxels",
    "occupancy_grid",
    "plan_path",
    "primitive",
    "signature_mismatches",
    "undeclared_methods",
]

"""The wheeled base: differential-drive kinematics, odometry, drivers and a path follower.

No simulator here (a real base implements :class:`BaseDriver`); the PyBullet driver lives in
:mod:`tabletop.sim.room_world`. Typical use::

    from tabletop.base import KinematicBaseDriver, TABLETOP_BASE, follow_path

    driver = KinematicBaseDriver(TABLETOP_BASE)
    result = follow_path(driver, [[0, 0], [1, 0], [1, 1]], final_yaw=1.57)
"""

from tabletop.base.description import (
    TABLETOP_BASE,
    BaseDescription,
    base_urdf_path,
    load_base_description,
)
from tabletop.base.driver import BaseDriver, KinematicBaseDriver, check_command
from tabletop.base.errors import BaseDriverError, BaseError, PathError
from tabletop.base.follower import FollowConfig, FollowResult, follow_path, turn_to
from tabletop.base.kinematics import (
    DiffDriveParams,
    integrate,
    limit_wheels,
    twist_from_wheels,
    wheels_from_twist,
)
from tabletop.base.odometry import OdometryDrift, WheelOdometry
from tabletop.base.planner import grid_path, line_is_free
from tabletop.base.pose import BasePose, wrap_angle

__all__ = [
    "TABLETOP_BASE",
    "BaseDescription",
    "BaseDriver",
    "BaseDriverError",
    "BaseError",
    "BasePose",
    "DiffDriveParams",
    "FollowConfig",
    "FollowResult",
    "KinematicBaseDriver",
    "OdometryDrift",
    "PathError",
    "WheelOdometry",
    "base_urdf_path",
    "check_command",
    "follow_path",
    "grid_path",
    "integrate",
    "limit_wheels",
    "line_is_free",
    "load_base_description",
    "turn_to",
    "twist_from_wheels",
    "wheels_from_twist",
    "wrap_angle",
]

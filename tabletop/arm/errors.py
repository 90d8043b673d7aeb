"""Errors raised by the arm package, all under :class:`tabletop.errors.TabletopError`."""

from __future__ import annotations

from tabletop.errors import TabletopError

__all__ = [
    "ArmError",
    "ConnectionLost",
    "ConnectionRefused",
    "DriverError",
    "FrameError",
    "MotionStoppedShort",
    "ReflexError",
    "SafetyError",
]


class ArmError(TabletopError):
    """Base class of every error raised on purpose by :mod:`tabletop.arm`."""


class FrameError(ArmError, ValueError):
    """A frame or joint name is not in the robot model; the message lists the valid ones."""


class DriverError(ArmError, RuntimeError):
    """A driver could not read the robot state or execute a command."""


class SafetyError(ArmError, RuntimeError):
    """A command was refused because it breaks a limit enforced on our side.

    Raised by drivers for commands beyond the velocity or workspace limits; the reach
    controller never raises it for a blocked motion (it returns a result with a reason).
    """


class ConnectionRefused(DriverError):
    """Nothing at the robot's address accepted the connection (wrong address, robot off, FCI
    not enabled); nothing was sent."""


class ConnectionLost(DriverError):
    """The connection to the robot broke (mid-motion or between commands); the driver is closed
    and every later command raises this again."""


class ReflexError(DriverError):
    """The robot aborted a motion with a reflex (a limit, a discontinuity, a collision).

    Attributes:
        errors: the names of the robot's error flags of the aborted motion.
        recovered: whether the automatic error recovery that followed succeeded (the robot
            accepts motions again).
    """

    def __init__(self, message: str, errors: tuple[str, ...] = (), recovered: bool = False):
        super().__init__(message)
        self.errors = tuple(errors)
        self.recovered = bool(recovered)


class MotionStoppedShort(DriverError):
    """A motion ended without error but away from its goal (stopped from elsewhere, blocked).

    Attributes:
        distance: the largest joint distance [rad] from the goal where the arm stopped.
    """

    def __init__(self, message: str, distance: float):
        super().__init__(message)
        self.distance = float(distance)

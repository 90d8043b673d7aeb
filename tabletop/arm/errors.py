"""Errors raised by the arm package, all under :class:`tabletop.errors.TabletopError`."""

from __future__ import annotations

from tabletop.errors import TabletopError

__all__ = ["ArmError", "DriverError", "FrameError", "SafetyError"]


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

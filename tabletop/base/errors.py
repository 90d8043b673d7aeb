"""Errors raised by the base package, all under :class:`tabletop.errors.TabletopError`."""

from __future__ import annotations

from tabletop.errors import ConfigError, TabletopError

__all__ = ["BaseDriverError", "BaseError", "PathError"]


class BaseError(TabletopError):
    """Base class of every error raised on purpose by :mod:`tabletop.base`."""


class PathError(BaseError, ConfigError):
    """A path handed to the follower is malformed (shape, non-finite points); the message
    names the bad value."""


class BaseDriverError(BaseError, RuntimeError):
    """A driver could not read the base's state or execute a command."""

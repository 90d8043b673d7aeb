"""The mapping package's errors."""

from __future__ import annotations

from tabletop.errors import TabletopError

__all__ = ["MapFormatError"]


class MapFormatError(TabletopError, ValueError):
    """A map file is missing, truncated, of another version, or inconsistent."""

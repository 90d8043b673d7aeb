"""The project's exception hierarchy: one base class, one subclass per kind of failure.

Messages name the problem and, where there is a choice, the valid options.
"""

from __future__ import annotations

__all__ = [
    "AssetError",
    "ConfigError",
    "GoalNotFound",
    "RecordingError",
    "SceneError",
    "SimulationError",
    "TabletopError",
    "check_bool",
    "count_problem",
]


class TabletopError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(TabletopError, ValueError):
    """A configuration value or argument is invalid."""


class SceneError(TabletopError, ValueError):
    """A scene spec is malformed or cannot be built."""


class AssetError(TabletopError, FileNotFoundError):
    """A shipped asset (URDF, mesh, sound clip) is missing or unreadable."""


class RecordingError(TabletopError, ValueError):
    """A recording on disk is missing a file, truncated, or inconsistent."""


class SimulationError(TabletopError, RuntimeError):
    """The simulator could not do what was asked (render, reach a pose, ...)."""


class GoalNotFound(TabletopError, LookupError):
    """A query (object, sound, image, area, or their product) matches nothing in the map, so
    there is no target; nothing moved."""

    def __init__(self, query: str, reason: str) -> None:
        super().__init__(f"{query}: not found ({reason})")
        self.query = query
        self.reason = reason


def check_bool(call: str, name: str, value: object) -> bool:
    """``value`` of the boolean parameter ``name`` of ``call``: True or False only (numpy's
    booleans included). ``"no"`` or ``0`` would be taken by truth, which is how a wrong value
    goes unnoticed: :class:`ConfigError` naming the parameter instead."""
    if isinstance(value, bool) or (
        type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")
    ):
        return bool(value)
    raise ConfigError(f"{call}({name}=...): {name} takes True or False, got {value!r}")


def count_problem(value: object) -> str:
    """Why ``value`` is no count of things (a whole number >= 0), "" where it is one: it names
    text that holds a number as text ("the text '60'"), which a file edited by hand may."""
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return ""
    if isinstance(value, str):
        got = f"the text {value!r}" + (" (a number in quotes)" if value.strip().isdigit() else "")
    elif isinstance(value, bool) or not isinstance(value, int | float):
        got = f"{value!r} ({type(value).__name__})"
    else:
        got = repr(value)
    return f"must be a count (a whole number >= 0), got {got}"

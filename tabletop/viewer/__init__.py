"""A local web viewer of a map: its voxels, queries, sounds, reaches, evaluation goals and a
room's obstacle grids, in 3D in a browser (``tabletop view``; docs/viewer.md).

It is the optional ``viewer`` extra (``pip install 'tabletop[viewer]'``: viser, and
viser-audio for positional sound): nothing here is imported by the rest of the package, and
:func:`require_viewer` names the extra when it is missing.
"""

from __future__ import annotations

from tabletop.errors import ConfigError

__all__ = ["EXTRA", "require_viewer"]

#: The optional dependency group that holds what the viewer needs.
EXTRA = "viewer"


def require_viewer() -> None:
    """Raise :class:`ConfigError` naming the ``viewer`` extra when viser is not installed."""
    try:
        import viser  # noqa: F401
    except ImportError as e:
        raise ConfigError(
            f"the viewer needs the optional '{EXTRA}' extra ({e.name or 'viser'} is not "
            f"installed): pip install -e '.[{EXTRA}]' (or scripts/bootstrap with "
            "TABLETOP_BACKENDS=1)"
        ) from None

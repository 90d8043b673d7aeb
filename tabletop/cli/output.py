"""Output helpers of the commands."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

from tabletop.errors import ConfigError

__all__ = ["check_parents_are_directories", "stdout_to_stderr"]


def check_parents_are_directories(flag: str, path: str | Path, hint: str = "") -> None:
    """The nearest existing ancestor of ``path`` must be a directory (a path through a file can
    never be created): :class:`ConfigError` naming the flag, the path and that ancestor, with
    ``hint`` appended, checked before any work."""
    for parent in Path(path).parents:
        if parent.exists():
            if not parent.is_dir():
                raise ConfigError(f"{flag} {str(path)!r}: {str(parent)!r} is not a directory{hint}")
            return


@contextlib.contextmanager
def stdout_to_stderr():
    """Send everything written to file descriptor 1 (native libraries' banners included) to
    stderr, so that ``--json`` prints nothing but the JSON on stdout."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)

"""Output helpers of the commands."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

from tabletop.atomic import check_writable
from tabletop.errors import ConfigError

__all__ = ["check_output_flag", "check_parents_are_directories", "stdout_to_stderr"]


def check_output_flag(
    flag: str, path: str | Path, *, directory: bool = False, hint: str = ""
) -> Path:
    """The one check of every command's output option, before any work: ``path`` (a file, or
    a directory with ``directory``) can be written (:func:`tabletop.atomic.check_writable`:
    a valid name, no file where a directory must be, a parent that takes new files).
    :class:`ConfigError` names ``flag``, the path and why, with ``hint`` appended."""
    try:
        return check_writable(path, directory=directory, what=flag)
    except ConfigError as e:
        raise ConfigError(f"{e}{hint}") from None


def check_parents_are_directories(flag: str, path: str | Path, hint: str = "") -> None:
    """The nearest existing ancestor of ``path`` must be a directory (a path through a file can
    never be created): :class:`ConfigError` naming the flag, the path and that ancestor, with
    ``hint`` appended, checked before any work; and that it takes new files
    (:func:`check_output_flag`)."""
    check_output_flag(flag, path, directory=Path(path).is_dir(), hint=hint)


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

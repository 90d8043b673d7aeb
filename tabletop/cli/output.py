"""Output helpers of the commands."""

from __future__ import annotations

import contextlib
import os
import sys

__all__ = ["stdout_to_stderr"]


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

"""Writes that are whole or absent: a temporary sibling, renamed over the target on success and
removed on any failure, an interrupt included.

The CLI turns SIGTERM and SIGHUP into :class:`SystemExit` (:func:`exit_on_signals`), so a
``kill`` or a closed terminal unwinds through the same clean-up as Ctrl-C: no hidden temporary
file or directory is left beside the output.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "exclusive", "exit_on_signals"]


@contextlib.contextmanager
def atomic_path(path: str | Path, *, directory: bool = False) -> Iterator[Path]:
    """A temporary sibling of ``path`` (a file, or an empty directory with ``directory``) to
    write into; on success it replaces ``path`` (a file atomically; a directory replaces only a
    missing ``path``), on any exception it is removed and the exception goes on."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if directory:
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    else:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        os.close(fd)
        tmp = Path(name)
    try:
        yield tmp
        os.replace(tmp, path) if not directory else tmp.rename(path)
    except BaseException:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            tmp.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def exclusive(path: str | Path) -> Iterator[None]:
    """Within the block this process alone holds the lock of ``path`` (an advisory lock on the
    sibling file ``.<name>.lock``); another process entering it for the same ``path`` waits.
    For a cache: two processes that need the same missing entry make it once, the second
    takes the first's (the lock file stays, empty)."""
    import fcntl

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(f".{path.name}.lock"), "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _raise_exit(signum, _frame) -> None:
    raise SystemExit(128 + signum)


@contextlib.contextmanager
def exit_on_signals() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise ``SystemExit(128 + signal)`` in the main
    thread, so writes in progress clean up; the previous handlers come back after it (a no-op
    outside the main thread, where signals cannot be handled)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    sigs = [s for s in (signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s is not None]
    before = {s: signal.signal(s, _raise_exit) for s in sigs}
    try:
        yield
    finally:
        for s, h in before.items():
            signal.signal(s, h)

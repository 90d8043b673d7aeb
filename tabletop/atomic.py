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

from tabletop.errors import ConfigError

__all__ = ["atomic_path", "check_writable", "exclusive", "exit_on_signals"]

#: The longest file name (one path component) most file systems take [bytes].
NAME_MAX = 255
#: The longest path the system takes (bytes, Linux's PATH_MAX).
PATH_MAX = 4096


def check_writable(path: str | Path, *, directory: bool = False, what: str = "output") -> Path:
    """Check, before any work, that ``path`` can be written: a valid name, no file where a
    directory must be (its existing ancestors are directories; ``path`` itself a directory when
    ``directory``, else not one), and the nearest existing ancestor takes new entries (a file
    is created there and removed, which is the only reliable test: permissions, read-only and
    virtual file systems such as /proc). :class:`ConfigError` names ``what``, the path and why.
    Returns ``path`` as a :class:`Path`."""
    shown = repr(str(path)) if len(str(path)) <= 80 else repr(str(path)[:77] + "...")
    if not isinstance(path, (str, Path)):
        raise ConfigError(f"{what} path must be a str or Path, got {type(path).__name__}")
    if str(path) == "" or str(path).strip() == "":
        raise ConfigError(f"{what} path is empty: give a {'directory' if directory else 'file'}")
    if "\0" in str(path):
        raise ConfigError(f"{what} path {shown} contains a NUL character")
    p = Path(path)
    if p.name in ("", ".", "..") and not directory:
        raise ConfigError(f"{what} path {shown} names a directory; give a file name")
    for part in p.parts:
        if len(os.fsencode(part)) > NAME_MAX:
            raise ConfigError(f"{what} path {shown}: a name in it is longer than {NAME_MAX} bytes")
    if len(os.fsencode(str(p.absolute()))) >= PATH_MAX:
        raise ConfigError(f"{what} path {shown} is longer than the system's {PATH_MAX} bytes")
    try:
        p.exists()
    except OSError as e:  # what the file system refuses to look up
        raise ConfigError(f"{what} path {shown} cannot be used: {e.strerror or e}") from None
    if p.exists():
        if directory and not p.is_dir():
            raise ConfigError(f"{what} {shown} exists and is not a directory")
        if not directory and p.is_dir():
            raise ConfigError(f"{what} {shown} is a directory; give a file path")
    if directory and p.is_dir():
        probe_in = p  # new entries go into it
    else:  # the nearest existing ancestor: where the path (and its missing parents) is made
        probe_in = next((a for a in p.parents if a.exists()), Path("."))
        if not probe_in.is_dir():
            raise ConfigError(
                f"{what} {shown} cannot be written: {str(probe_in)!r} is a file, not a directory"
            )
    try:
        fd, name = tempfile.mkstemp(prefix=".tabletop-write-check-", dir=probe_in)
    except OSError as e:
        raise ConfigError(
            f"{what} {shown} cannot be written: {str(probe_in)!r} does not take new files "
            f"({e.strerror or e})"
        ) from None
    os.close(fd)
    os.unlink(name)
    return p


@contextlib.contextmanager
def atomic_path(path: str | Path, *, directory: bool = False) -> Iterator[Path]:
    """A temporary sibling of ``path`` (a file, or an empty directory with ``directory``) to
    write into; on success it replaces ``path`` (a file atomically; a directory replaces only a
    missing ``path``), on any exception it is removed and the exception goes on."""
    path = check_writable(path, directory=directory)  # a clear error, not one from deep inside
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

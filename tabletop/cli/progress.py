"""Progress display of the commands: tqdm bars on a terminal, one line per stage otherwise.

Library functions report progress through callbacks (``progress(done, total)`` or
``progress(stage, done, total)``); this module is the only place that turns them into bars.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import TextIO

__all__ = ["ProgressBars", "interactive", "no_library_bars"]

#: Environment switches that turn off the progress bars of libraries the commands use (tqdm
#: itself; Hugging Face's hub, transformers and sentence-transformers, e.g. "Loading weights").
LIBRARY_BAR_SWITCHES = {"TQDM_DISABLE": "1", "HF_HUB_DISABLE_PROGRESS_BARS": "1"}


def interactive() -> bool:
    """Whether bars may be drawn: stdout and stderr are both terminals (not a log file, a pipe
    or a test's capture)."""
    return _isatty(sys.stdout) and _isatty(sys.stderr)


@contextlib.contextmanager
def no_library_bars() -> Iterator[None]:
    """Within the block, libraries draw no progress bars of their own (the switches of
    :data:`LIBRARY_BAR_SWITCHES`, restored afterwards; a switch the user set is kept). They are
    read when a library is first imported, so this acts on what a command imports inside it."""
    saved = {k: os.environ.get(k) for k in LIBRARY_BAR_SWITCHES}
    for k, v in LIBRARY_BAR_SWITCHES.items():
        os.environ.setdefault(k, v)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # replaced by an object without it, or closed
        return False


def _default_unit(stage: str) -> str:
    if stage.startswith("units"):
        return "unit"  # a unit of work run by a worker (tabletop.parallel)
    return "goal" if stage.startswith("goals") else "frame"


class ProgressBars:
    """``progress(stage, done, total)`` as one tqdm bar per stage, on stderr.

    When ``bars`` is False (the default where :func:`interactive` is false) nothing is drawn
    while a stage runs; when it ends one summary line ("scan default: 744 frames in 49.9 s")
    is written instead. Use as a context manager, or call :meth:`close` when done.
    """

    def __init__(
        self,
        *,
        bars: bool | None = None,
        file: TextIO | None = None,
        unit: Callable[[str], str] = _default_unit,
    ) -> None:
        self.bars = interactive() if bars is None else bool(bars)
        self._file = file
        self._unit = unit
        self._bar = None
        self._stage: str | None = None
        self._done = 0
        self._total = 0
        self._t0 = 0.0

    @property
    def file(self) -> TextIO:
        """Where bars and summary lines go (stderr unless given)."""
        return self._file if self._file is not None else sys.stderr

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self._stage:
            self.close()
            self._stage = stage
            self._t0 = time.perf_counter()
            if self.bars:
                from tqdm import tqdm

                self._bar = tqdm(
                    total=total,
                    desc=stage,
                    unit=self._unit(stage),
                    dynamic_ncols=True,
                    file=self.file,
                    disable=False,  # ours: drawn even where the libraries' are switched off
                )
        self._done, self._total = int(done), int(total)
        if self._bar is not None:
            self._bar.total = total
            self._bar.update(done - self._bar.n)

    def note(self, text: str) -> None:
        """Write one line (a unit of work that finished, ...) above the bar, or as it is."""
        if self._bar is not None:
            self._bar.write(text, file=self.file)
        else:
            print(text, file=self.file, flush=True)

    def stage(self, name: str) -> Callable[[int, int], None]:
        """A ``progress(done, total)`` callback that reports as the stage ``name``."""
        return lambda done, total: self(name, done, total)

    def close(self) -> None:
        """End the current stage (close its bar, or write its summary line)."""
        if self._stage is None:
            return
        if self._bar is not None:
            self._bar.close()
        else:
            dt = time.perf_counter() - self._t0
            n = f"{self._done}" if self._done == self._total else f"{self._done}/{self._total}"
            print(f"{self._stage}: {n} {self._unit(self._stage)}s in {dt:.1f} s", file=self.file)
        self._bar = None
        self._stage = None

    def __enter__(self) -> ProgressBars:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

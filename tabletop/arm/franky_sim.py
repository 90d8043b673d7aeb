"""franky-sim on this machine: a server that speaks libfranka's network protocol and simulates
an FR3 in MuJoCo (``pip install 'tabletop[frankysim]'``).

libfranka's ports are fixed (1337 for commands), so a server is told its own loopback address
(``127.x.y.z``) instead of a port: :func:`free_loopback` picks one nothing listens on, and
:class:`FrankySimServer` starts ``franky_sim.run_server`` there, waits until it accepts
connections, keeps reading its output (the server must never block on a full pipe), and kills
it on :meth:`~FrankySimServer.close`. :class:`~tabletop.arm.franky_driver.FrankyDriver`
connects to :attr:`~FrankySimServer.host` with ``realtime=False``.

The simulator's clock is the robot's: on a busy machine it runs slower than real time, so
motions take their robot-time duration or longer in wall time.
"""

from __future__ import annotations

import importlib.util
import random
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Sequence

from tabletop.arm.errors import DriverError

__all__ = ["FCI_PORT", "FrankySimServer", "free_loopback", "listening"]

#: libfranka's command port (fixed by the protocol).
FCI_PORT = 1337
#: What the server prints once it accepts connections.
_READY = "Connect to the server"


def listening(host: str) -> bool:
    """Whether something accepts connections on ``host``'s libfranka command port."""
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex((host, FCI_PORT)) == 0


def free_loopback(tries: int = 50, rng: random.Random | None = None) -> str:
    """A loopback address (``127.x.y.z``) whose libfranka command port is free.

    Raises:
        DriverError: none of ``tries`` random addresses was free.
    """
    rng = rng or random.Random()
    for _ in range(tries):
        host = f"127.{rng.randrange(1, 250)}.{rng.randrange(0, 250)}.{rng.randrange(2, 250)}"
        if listening(host):
            continue
        try:
            with socket.socket() as s:
                s.bind((host, FCI_PORT))
        except OSError:
            continue
        return host
    raise DriverError(f"no free loopback address for franky-sim (tried {tries})")


class FrankySimServer:
    """A franky-sim server process on its own loopback address (a context manager).

    Args:
        timeout: wall time [s] to wait for the server to accept connections.
        command: the server's command line without ``--hostname`` (default: franky-sim's
            MuJoCo server, ``python -m franky_sim.run_server -s mujoco``).

    Raises:
        DriverError: franky-sim is not installed (naming the extra), or the server exited or
            did not accept connections within ``timeout`` (with the end of its output).
    """

    def __init__(self, timeout: float = 60.0, command: Sequence[str] | None = None) -> None:
        if command is None:
            missing = [m for m in ("franky", "franky_sim") if importlib.util.find_spec(m) is None]
            if missing:
                raise DriverError(
                    f"{' and '.join(missing)} not installed: pip install 'tabletop[frankysim]' "
                    "(franky-control and franky-sim)"
                )
            command = [sys.executable, "-u", "-m", "franky_sim.run_server", "-s", "mujoco"]
        self.host = free_loopback()
        """The loopback address the server listens on."""
        self.output: list[str] = []
        """The server's output lines so far."""
        self.proc = subprocess.Popen(
            [*command, "--hostname", self.host],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        ready = threading.Event()

        def pump() -> None:
            for line in self.proc.stdout:
                self.output.append(line)
                if _READY in line:
                    ready.set()

        threading.Thread(target=pump, daemon=True).start()
        t_end = time.monotonic() + float(timeout)
        while not ready.wait(0.2):
            if self.proc.poll() is not None or time.monotonic() > t_end:
                why = "exited" if self.proc.poll() is not None else f"did not start in {timeout} s"
                self.close()
                tail = "".join(self.output)[-800:]
                raise DriverError(f"franky-sim {why}: {tail or '(no output)'}")

    @property
    def running(self) -> bool:
        return self.proc.poll() is None

    def close(self) -> None:
        """Kill the server (a second call does nothing)."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)

    def __enter__(self) -> FrankySimServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

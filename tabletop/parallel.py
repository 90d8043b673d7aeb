"""Units of work run in parallel: worker processes on this machine, or Ray tasks on a cluster.

The evaluation (one unit per encoder set x task file) and the vision training's renders (one
unit per slice of layouts) hand their units to :func:`run_units`, which returns the results in
the order of the units, whatever order they finished in, so a parallel run merges exactly like
a serial one.

```python
from tabletop.parallel import Backend, run_units

squares = run_units(pow, [(2, 2), (3, 2)], Backend(workers=2))  # [4, 9]
```

- ``Backend()`` runs the units one after another in this process.
- ``Backend(workers=N)`` runs them in N worker processes (``spawn``: nothing is inherited but
  the environment, so it is safe with threads, PyBullet and torch). Each worker is limited to
  ``threads`` math threads (``OMP_NUM_THREADS`` and the like, torch's and OpenCV's pools), so
  N workers on N cores do not oversubscribe them.
- ``Backend(ray="auto")`` (or a cluster's address, ``HOST:PORT``) sends them as Ray tasks of
  ``threads`` CPUs each to a running Ray cluster (``ray start``; Ray is the optional extra
  ``ray``: ``pip install -e '.[ray]'``). ``workers`` then caps how many run at once (default: as
  many as the cluster takes). A task runs in the driver's working directory, which must exist
  on every node (a shared file system mounted at the same path), so relative paths (the cache,
  the report) mean the same there.

The function and its arguments are pickled (by reference: the function must be importable, and
every worker must have the same tabletop installed; a Ray worker whose tabletop source differs
from the driver's is refused, since it would compute other results). An exception in a unit is
raised again here with the worker's traceback as a note, after the other units are stopped.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import pickle
import sys
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from tabletop.errors import ConfigError, TabletopError

__all__ = [
    "RAY_EXTRA",
    "THREAD_VARS",
    "Backend",
    "UnitError",
    "import_ray",
    "limit_threads",
    "run_units",
]

log = logging.getLogger(__name__)

#: The optional extra that installs Ray (pyproject.toml), named in the error when it is missing.
RAY_EXTRA = "ray"

#: Environment variables that size the math libraries' thread pools (OpenMP, MKL, OpenBLAS,
#: numexpr, Accelerate), set in every worker before it imports them.
THREAD_VARS = (
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)

OnDone = Callable[[int, object, float], None]
"""``on_done(index, result, seconds)``: called here as each unit finishes (in the order they
finish); ``seconds`` is the unit's own wall time in its worker."""


class UnitError(TabletopError):
    """A unit failed in a worker with an exception that cannot travel back as it is (one that
    does not survive pickling): its type, message and the worker's traceback."""


@dataclass(frozen=True)
class Backend:
    """Where units run: this process (the default), ``workers`` processes, or a Ray cluster."""

    workers: int | None = None
    """Worker processes on this machine; with ``ray``, the most units running at once."""
    ray: str | None = None
    """A Ray cluster's address (``HOST:PORT``, ``ray://HOST:PORT``) or ``auto`` (the cluster
    ``ray start`` started on this node)."""
    threads: int = 1
    """Math threads per worker (and CPUs a Ray task asks for)."""

    def __post_init__(self) -> None:
        if self.workers is not None and (
            isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1
        ):
            raise ConfigError(f"workers must be a whole number >= 1, got {self.workers!r}")
        if self.ray is not None and (not isinstance(self.ray, str) or not self.ray.strip()):
            raise ConfigError(
                f"ray must be a cluster address (HOST:PORT) or 'auto', got {self.ray!r}"
            )
        if isinstance(self.threads, bool) or not isinstance(self.threads, int) or self.threads < 1:
            raise ConfigError(f"threads must be a whole number >= 1, got {self.threads!r}")

    @property
    def serial(self) -> bool:
        """Whether the units run one after another in this process."""
        return self.workers is None and self.ray is None

    def describe(self) -> str:
        if self.ray is not None:
            cap = f", at most {self.workers} at once" if self.workers else ""
            return f"Ray tasks on the cluster at {self.ray}{cap}"
        if self.workers is not None:
            n = self.workers
            return f"{n} worker process{'es' if n > 1 else ''}"
        return "this process"


def run_units(
    fn: Callable,
    units: Sequence[tuple],
    backend: Backend | None = None,
    *,
    labels: Sequence[str] | None = None,
    on_done: OnDone | None = None,
) -> list:
    """``[fn(*args) for args in units]``, run by ``backend``, in the order of ``units``.

    ``labels`` name the units in errors; ``on_done`` reports each as it finishes."""
    backend = backend or Backend()
    units = [tuple(u) for u in units]
    labels = list(labels) if labels is not None else [f"unit {i + 1}" for i in range(len(units))]
    if len(labels) != len(units):
        raise ConfigError(f"{len(labels)} labels for {len(units)} units")
    if not units:
        return []
    if backend.ray is not None:
        return _run_ray(fn, units, labels, backend, on_done)
    if backend.workers is not None:
        return _run_pool(fn, units, labels, backend, on_done)
    out = []
    for i, args in enumerate(units):
        t0 = time.perf_counter()
        out.append(fn(*args))
        if on_done is not None:
            on_done(i, out[-1], time.perf_counter() - t0)
    return out


# ------------------------------------------------------------------------------ in a worker
def limit_threads(n: int = 1) -> None:
    """Size this process's math thread pools to ``n``: the environment (read by libraries
    imported after this) and torch's and OpenCV's pools when they are already imported."""
    for k in THREAD_VARS:
        os.environ[k] = str(int(n))
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(int(n))
    cv2 = sys.modules.get("cv2")
    if cv2 is not None:
        cv2.setNumThreads(int(n))


def _init_worker(threads: int) -> None:
    limit_threads(threads)


def _portable(e: BaseException) -> BaseException:
    """``e`` when it survives pickling (so the caller catches its own type), else a
    :class:`UnitError` with its type and message."""
    try:
        back = pickle.loads(pickle.dumps(e))
        if type(back) is type(e) and str(back) == str(e):
            return e
    except Exception:  # any failure to travel means: wrap it
        pass
    return UnitError(f"{type(e).__name__}: {e}")


def _call(fn: Callable, args: tuple) -> tuple[bool, object, float, str]:
    """(ok, result or exception, seconds, traceback): a unit in a worker. SIGTERM unwinds
    through the unit's clean-up (atomic writes leave no temporary files)."""
    from tabletop.atomic import exit_on_signals

    t0 = time.perf_counter()
    try:
        with exit_on_signals():
            return True, fn(*args), time.perf_counter() - t0, ""
    except Exception as e:  # sent back, raised in the caller
        tb = traceback.format_exc()
        return False, _portable(e), time.perf_counter() - t0, tb


def _raise(e: BaseException, label: str, tb: str, where: str):
    if tb and hasattr(e, "add_note"):
        e.add_note(f"in {where} ({label}):\n{tb.rstrip()}")
    raise e


# ------------------------------------------------------------------------------ processes
@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """Within the block ``os.environ`` has ``values`` (what a spawned process inherits)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run_pool(fn, units, labels, backend: Backend, on_done) -> list:
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    n = min(int(backend.workers), len(units))
    env = {k: str(backend.threads) for k in THREAD_VARS}
    ex = ProcessPoolExecutor(
        max_workers=n,
        mp_context=mp.get_context("spawn"),
        initializer=_init_worker,
        initargs=(backend.threads,),
    )
    results: list = [None] * len(units)
    try:
        # The processes start at the first submit (spawn starts them all at once): with the
        # thread limits in their environment, before they import numpy or torch.
        with _environment(env):
            futures = {ex.submit(_call, fn, args): i for i, args in enumerate(units)}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in sorted(done, key=futures.__getitem__):
                i = futures[f]
                ok, value, secs, tb = f.result()
                if not ok:
                    _raise(value, labels[i], tb, "a worker process")
                results[i] = value
                if on_done is not None:
                    on_done(i, value, secs)
    except BaseException:
        _stop_pool(ex)
        raise
    ex.shutdown(wait=True)
    return results


def _stop_pool(ex) -> None:
    """Cancel the units not started and stop the running ones (SIGTERM: they clean up)."""
    procs = list(getattr(ex, "_processes", {}).values())  # no public way before Python 3.14
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=10)


# ------------------------------------------------------------------------------ Ray
#: Set before Ray is imported for a cluster on a loopback address: Ray then keeps 127.0.0.1 as
#: it is instead of replacing it with this machine's network address (which a cluster started
#: with ``--node-ip-address 127.0.0.1`` does not answer on).
RAY_LOOPBACK_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


def _host_port(address: str) -> tuple[str, int] | None:
    """(host, port) of ``HOST:PORT`` or ``ray://HOST:PORT``; None for ``auto`` and the like."""
    rest = address.strip().removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def _loopback(host: str) -> bool:
    return host in ("localhost", "::1") or host.startswith("127.")


def import_ray(address: str | None = None):
    """The ``ray`` module, or a :class:`ConfigError` naming the extra that installs it. For a
    cluster at a loopback ``address``, Ray is told to stay on loopback (:data:`RAY_LOOPBACK_ENV`,
    read when Ray is first imported)."""
    hp = _host_port(address) if address else None
    if hp is not None and _loopback(hp[0]) and "ray" not in sys.modules:
        os.environ.setdefault(RAY_LOOPBACK_ENV, "0")
    try:
        import ray
    except ImportError:
        raise ConfigError(
            f"--ray needs Ray, an optional extra of tabletop: pip install -e '.[{RAY_EXTRA}]' "
            "(on the driver and on every node of the cluster)"
        ) from None
    return ray


def source_fingerprint() -> str:
    """Hash of this tabletop's Python source and shipped data: a Ray worker computes the same
    results as the driver only with the same files."""
    from tabletop.paths import PACKAGE_DIR

    h = hashlib.sha1()
    for f in sorted(PACKAGE_DIR.rglob("*")):
        if f.is_file() and "__pycache__" not in f.parts and f.suffix != ".pyc":
            h.update(f.relative_to(PACKAGE_DIR).as_posix().encode())
            h.update(hashlib.sha1(f.read_bytes()).digest())
    return h.hexdigest()[:16]


_CHECKED: dict[str, str] = {}


def _ray_call(fn, args, cwd: str, threads: int, fingerprint: str):
    """A unit as a Ray task: in the driver's working directory, with the thread limits, on
    the same tabletop source as the driver's."""
    here = _CHECKED.get("fingerprint") or _CHECKED.setdefault("fingerprint", source_fingerprint())
    if here != fingerprint:
        e = ConfigError(
            f"the Ray worker on {os.uname().nodename} has another tabletop "
            f"(source {here}, the driver's {fingerprint}): install the same tabletop on every "
            "node (one container image, or one shared checkout)"
        )
        return False, e, 0.0, ""
    if not Path(cwd).is_dir():
        e = ConfigError(
            f"the driver's working directory {cwd} does not exist on the Ray worker's node "
            f"{os.uname().nodename}: run from a shared file system mounted at the same path on "
            "every node (the cache and the report are written there)"
        )
        return False, e, 0.0, ""
    os.chdir(cwd)
    limit_threads(threads)
    return _call(fn, args)


def _check_reachable(address: str, timeout: float = 10.0) -> None:
    """Fail fast on an address where nothing listens (Ray itself retries for minutes)."""
    import socket

    hp = _host_port(address)
    if hp is None:
        return  # "auto": Ray finds the cluster this node runs, or says there is none
    try:
        socket.create_connection(hp, timeout=timeout).close()
    except OSError as e:
        raise ConfigError(
            f"--ray {address}: no Ray cluster to connect to ({e.strerror or e}); start one with "
            "`ray start --head` (docs/evaluation.md)"
        ) from None


def _run_ray(fn, units, labels, backend: Backend, on_done) -> list:
    ray = import_ray(backend.ray)
    connected = not ray.is_initialized()
    if connected:
        _check_reachable(backend.ray)
        try:
            ray.init(
                address=backend.ray,
                logging_level=logging.WARNING,
                log_to_driver=False,
            )
        except (ConnectionError, RuntimeError, ValueError) as e:
            raise ConfigError(
                f"--ray {backend.ray}: no Ray cluster to connect to ({e}); start one with "
                "`ray start --head` (docs/evaluation.md)"
            ) from None
    try:
        task = ray.remote(num_cpus=backend.threads, max_retries=0)(_ray_call)
        cwd, fingerprint = os.getcwd(), source_fingerprint()
        cap = backend.workers or len(units)
        queue = list(enumerate(units))
        running: dict = {}
        results: list = [None] * len(units)
        try:
            while queue or running:
                while queue and len(running) < cap:
                    i, args = queue.pop(0)
                    ref = task.remote(fn, args, cwd, backend.threads, fingerprint)
                    running[ref] = i
                done, _ = ray.wait(list(running), num_returns=1)
                for ref in done:
                    i = running.pop(ref)
                    ok, value, secs, tb = ray.get(ref)
                    if not ok:
                        _raise(value, labels[i], tb, "a Ray task")
                    results[i] = value
                    if on_done is not None:
                        on_done(i, value, secs)
        except BaseException:
            for ref in running:
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
            raise
        return results
    finally:
        if connected:
            ray.shutdown()

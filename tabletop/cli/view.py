"""``tabletop view``: a map in 3D in the browser (the optional ``viewer`` extra)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tabletop.errors import ConfigError

__all__ = ["add_commands", "cmd_view", "main_view", "view_command"]


def view_command(map_path, recording=None, eval_dir=None) -> str:
    """The one command line that opens ``map_path`` in the viewer."""
    import shlex

    parts = ["tabletop", "view", str(map_path)]
    if recording:
        parts += ["--recording", str(recording)]
    if eval_dir:
        parts += ["--eval", str(eval_dir)]
    return " ".join(shlex.quote(p) for p in parts)


def check_host(host: str) -> str:
    """``--host``: an IP address (``127.0.0.1``, ``0.0.0.0``, ``::1``) or a hostname (labels of
    letters, digits and '-', dot-separated), checked before anything is served."""
    import ipaddress
    import re

    try:
        ipaddress.ip_address(host)
        return host
    except ValueError:
        pass
    label = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)")
    name = host[:-1] if host.endswith(".") else host
    if 0 < len(name) <= 253 and all(label.fullmatch(p) for p in name.split(".")):
        if not name.replace(".", "").isdigit():  # "1.2.3" is a malformed address, not a name
            return host
    raise ConfigError(
        f"--host {host!r} is neither an IP address nor a hostname; give e.g. 127.0.0.1 (this "
        "machine only, the default), 0.0.0.0 (every interface), ::1, or a name like localhost"
    )


def cmd_view(args: argparse.Namespace) -> int:
    from tabletop.viewer import require_viewer

    require_viewer()  # before the map is read: the message names the extra
    if not 0 <= args.port <= 65535:
        raise ConfigError(f"--port {args.port}: valid 0 (any free port) to 65535")
    check_host(args.host)
    if args.reader is not None:
        from tabletop.reader.reading import READERS

        if args.reader not in READERS:
            raise ConfigError(f"--reader {args.reader!r}: valid {', '.join(READERS)}")
    if args.scene is not None:  # a shipped scene's name or a scene file, read before serving
        from tabletop.sim.scene import load_scene_spec

        load_scene_spec(args.scene)
    from tabletop.paths import input_file_problem

    problem = input_file_problem(args.map)
    if problem:
        raise ConfigError(f"map {args.map!r} {problem}")
    for flag, path in (("--recording", args.recording), ("--eval", args.eval)):
        if path is not None and not Path(path).is_dir():
            raise ConfigError(f"{flag} {path!r} is not a directory")
    from tabletop.viewer.app import Viewer
    from tabletop.viewer.session import ViewerSession

    t0 = time.perf_counter()
    session = ViewerSession(args.map, args.recording, args.eval, args.scene, args.reader)
    viewer = Viewer(session, host=args.host, port=args.port)
    print(f"tabletop view: serving {session.title}", flush=True)
    print(f"open {viewer.url} in a browser ({time.perf_counter() - t0:.2f} s); Ctrl-C stops it",
          flush=True)  # fmt: skip
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"tabletop view: warning: bound to {args.host}: other machines can reach it",
              file=sys.stderr)  # fmt: skip
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
    return 0


def main_view(argv: list[str]) -> int:
    """``tabletop view ARGS`` as :func:`tabletop.cli.app.main` runs a command (its errors, its
    signals), without importing the other commands: the map's first picture does not wait for
    them."""
    import logging

    from tabletop.atomic import exit_on_signals
    from tabletop.errors import TabletopError

    parser = argparse.ArgumentParser(prog="tabletop")
    add_commands(parser.add_subparsers(dest="command", required=True, metavar="COMMAND"))
    args = parser.parse_args(["view", *argv])
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        with exit_on_signals():
            return args.func(args)
    except TabletopError as e:
        print(f"tabletop view: error: {e}", file=sys.stderr)
        return 2


def add_commands(sub) -> None:
    """Register ``view`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser(
        "view",
        help="the map in 3D in the browser: voxels, queries, sounds, reaches (extra 'viewer')",
    )
    p.add_argument("map", help="map file (.npz)")
    p.add_argument("--recording", help="its recording directory (camera path, joints, audio)")
    p.add_argument("--eval", help="an evaluation's output directory (results.json) to step through")
    p.add_argument(
        "--scene", help="the scene the arm reaches in (default: the one the map was built from)"
    )
    p.add_argument("--reader", help="the reader of requests (default: the robot's, rules+learned)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080; 0: any free one)")
    p.set_defaults(func=cmd_view)

"""The ``tabletop`` parser, built from the command groups, and :func:`main`."""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys

from tabletop.atomic import exit_on_signals
from tabletop.cli import bench, encoders, evaluate, ingest, language, maps, room, scan, view
from tabletop.cli.progress import interactive, no_library_bars
from tabletop.errors import TabletopError

__all__ = ["build_parser", "main"]

DESCRIPTION = (
    "The `tabletop` command line: scan scenes, inspect the sound bank, run the demo and benchmarks."
)

#: The command groups, in the order ``tabletop --help`` lists their commands.
GROUPS = (scan, ingest, room, maps, evaluate, language, encoders, bench, view)


def build_parser() -> argparse.ArgumentParser:
    """The ``tabletop`` argument parser with every command of :data:`GROUPS`."""
    parser = argparse.ArgumentParser(prog="tabletop", description=DESCRIPTION)
    parser.add_argument("-v", "--verbose", action="store_true", help="log more")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one ``tabletop`` command; returns its exit status (2 for a :class:`TabletopError`)."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        # without a terminal (a log file, a pipe) no bars at all: ours are summary lines
        # (ProgressBars), the libraries' are switched off
        # a kill unwinds like Ctrl-C: partial outputs are removed
        with exit_on_signals(), contextlib.nullcontext() if interactive() else no_library_bars():
            return args.func(args)
    except TabletopError as e:
        print(f"tabletop {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C (or a kill): the work's partial outputs are removed
        print(f"tabletop {args.command}: interrupted", file=sys.stderr)
        return 130

"""The ``tabletop`` parser, built from the command groups, and :func:`main`."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import logging
import re
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


#: A negative number is a value, not an option (argparse's own rule).
_NEGATIVE_NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+$")

#: The actions that keep one value (the last, when given twice): store, store_const,
#: store_true/false and type-converted stores; append, count and extend collect instead.
_SINGLE_VALUE_ACTIONS = (
    argparse._StoreAction,
    argparse._StoreConstAction,
    argparse.BooleanOptionalAction,
)


class Parser(argparse.ArgumentParser):
    """An argument parser that names an option it does not know, with the nearest valid one
    ("unknown option '--hlep' (did you mean --help?)"), before any other complaint: argparse
    reports a missing command or argument first ("the following arguments are required"),
    which hides the misspelt option. Each command's parser checks the options given to it."""

    def parse_known_args(self, args=None, namespace=None):
        args = list(sys.argv[1:] if args is None else args)
        self._refuse_unknown_options(args)
        self._refuse_repeated_options(args)
        return super().parse_known_args(args, namespace)

    def _refuse_repeated_options(self, args: list[str]) -> None:
        """Refuse an option that stores one value given more than once: argparse keeps the last
        and drops the others without a word. Options that collect (append, count, extend) may
        repeat. ``--opt=value`` and argparse's abbreviations count as the option they name."""
        commands = set()
        for a in self._actions:
            if isinstance(a, argparse._SubParsersAction):
                commands.update(a.choices)
        by_string = {o: a for a in self._actions for o in a.option_strings}
        seen: dict[int, str] = {}
        skip = False
        for token in args:
            if skip:
                skip = False
                continue
            if token == "--" or token in commands:
                return
            if not token.startswith("-") or token == "-" or _NEGATIVE_NUMBER.match(token):
                continue
            name = token.split("=", 1)[0]
            action = by_string.get(name)
            if action is None and name.startswith("--"):
                matches = {id(a): a for o, a in by_string.items() if o.startswith(name)}
                if len(matches) == 1:
                    action = next(iter(matches.values()))
            if action is None:
                continue
            if (
                action.nargs is None
                and "=" not in token
                and isinstance(action, argparse._StoreAction)
            ):
                skip = True  # the next token is its value
            if not isinstance(action, _SINGLE_VALUE_ACTIONS):
                continue
            if id(action) in seen:
                self.error(
                    f"option {action.option_strings[-1]} is given more than once "
                    f"({seen[id(action)]!r}, then {token!r}): it takes one value; give it once"
                )
            seen[id(action)] = token

    def _refuse_unknown_options(self, args: list[str]) -> None:
        known = [o for a in self._actions for o in a.option_strings]
        commands = set()  # the names of this parser's commands, if it has any
        for a in self._actions:
            if isinstance(a, argparse._SubParsersAction):
                commands.update(a.choices)
        for token in args:
            if token == "--" or token in commands:
                return  # what follows is a value, or the command's own
            if not token.startswith("-") or token == "-" or _NEGATIVE_NUMBER.match(token):
                continue
            name = token.split("=", 1)[0]
            if any(o.startswith(name) for o in known if o.startswith("--") and len(name) > 2):
                continue  # an option, or argparse's abbreviation of one
            if name in known or (not name.startswith("--") and name[:2] in known):
                continue  # "-vh": short options together
            near = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
            hint = f" (did you mean {near[0]}?)" if near else ""
            self.error(
                f"unknown option {name!r}{hint}; the options of {self.prog!r} are: "
                f"{', '.join(known)} (see {self.prog} --help)"
            )


def build_parser() -> argparse.ArgumentParser:
    """The ``tabletop`` argument parser with every command of :data:`GROUPS`."""
    parser = Parser(prog="tabletop", description=DESCRIPTION)
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

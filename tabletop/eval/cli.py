"""The ``tabletop eval`` command (registered by :func:`add_commands`) and its progress bars."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time

__all__ = ["ProgressBars", "add_commands", "print_result", "stdout_to_stderr"]


class ProgressBars:
    """``progress(stage, done, total)`` as one tqdm bar per stage, on stderr."""

    def __init__(self) -> None:
        self._bar = None
        self._stage = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        from tqdm import tqdm

        if stage != self._stage:
            self.close()
            unit = "goal" if stage.startswith("goals") else "frame"
            self._bar = tqdm(
                total=total, desc=stage, unit=unit, dynamic_ncols=True, file=sys.stderr
            )
            self._stage = stage
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        self._bar = None
        self._stage = None


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


def cmd_eval(args: argparse.Namespace) -> int:
    from tabletop.eval.runner import run_eval

    encoders = [e.strip() for e in args.encoders.split(",") if e.strip()]
    t0 = time.perf_counter()
    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        res = run_eval(
            args.tasks,
            encoders=encoders,
            out_dir=args.out,
            progress=not args.json,
            cache_dir=None if args.no_cache else args.cache_dir,
        )
    wall = time.perf_counter() - t0
    if args.json:
        d = res.to_json()
        d["wall_s"] = round(wall, 1)
        print(json.dumps(d if args.goals else _without_goals(d), indent=1, default=float))
        return 0
    print_result(res, wall)
    return 0


def print_result(res, wall: float, what: str = "") -> None:
    """The table, the goals-in-a-row table, the goal count and wall time, the report path."""
    print(res.table_markdown())
    row = res.in_a_row_markdown()
    if row:
        print("\n" + row)
    print(f"\n{sum(len(r.goals) for r in res.runs)} goals in {wall:.0f} s{what}")
    if res.report_path is not None:
        print(f"report: {res.report_path}")


def _without_goals(d: dict) -> dict:
    d = dict(d)
    d["rows"] = [
        {**r, "tasks": [{k: v for k, v in t.items() if k != "goals"} for t in r["tasks"]]}
        for r in d["rows"]
    ]
    return d


def add_commands(sub) -> None:
    """Register ``tabletop eval`` on the CLI's subparsers."""
    p = sub.add_parser(
        "eval",
        help="run goal-reaching task files (scan, map, query, reach) and report per goal type",
    )
    p.add_argument(
        "tasks",
        nargs="+",
        help="task files (.toml/.json), directories of them, or shipped names: 'default' (the "
        "default suites), 'demo'",
    )
    p.add_argument(
        "--encoders",
        default="oracle",
        help="encoder set(s), comma-separated, as the map's registry names them: oracle "
        "(simulator upper bound), default (embedded learned), ...; e.g. oracle,default for "
        "both rows (default: oracle)",
    )
    p.add_argument("--out", default="out/eval", help="report directory (default: out/eval)")
    p.add_argument("--json", action="store_true", help="print the machine-readable summary")
    p.add_argument("--goals", action="store_true", help="with --json: include every goal")
    p.add_argument(
        "--cache-dir",
        default="out/eval-cache",
        help="recordings and maps reused across runs (default: out/eval-cache)",
    )
    p.add_argument("--no-cache", action="store_true", help="scan and map afresh, keep nothing")
    p.set_defaults(func=cmd_eval)

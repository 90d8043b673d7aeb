"""``tabletop parse`` and ``tabletop run``: instructions to robot code, run on a map."""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from tabletop.embodiments import EMBODIMENTS
from tabletop.errors import ConfigError
from tabletop.language.run import BACKENDS
from tabletop.reader.reading import DEFAULT_READER, READERS

__all__ = ["add_commands", "cmd_parse", "cmd_run", "cmd_train_reader"]

REFERENCE = "reference"
"""The MAP value that selects the suite's reference map (built from the scene's geometry)."""


def _add_backend_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--backend",
        choices=BACKENDS,
        default="offline",
        help="offline: the built-in instruction parser (default); llm: an OpenAI-compatible "
        "chat endpoint",
    )
    p.add_argument(
        "--reader",
        default=DEFAULT_READER,
        help=f"with --backend offline, the reader: {', '.join(READERS)} (default: "
        f"{DEFAULT_READER})",
    )
    p.add_argument("--llm-url", help="chat endpoint root, e.g. http://127.0.0.1:8000/v1")
    p.add_argument("--llm-model", help="model name the endpoint serves")
    p.add_argument(
        "--llm-config",
        metavar="FILE",
        help="TOML file with an [llm] table (base_url, model, api_key_env, timeout_s)",
    )


def _llm_config(args: argparse.Namespace):
    if args.backend != "llm":
        given = [f for f, v in (("--llm-url", args.llm_url), ("--llm-model", args.llm_model),
                                ("--llm-config", args.llm_config)) if v is not None]  # fmt: skip
        if given:  # not silently ignored
            raise ConfigError(
                f"{', '.join(given)}: only with --backend llm (--reader llm reads its endpoint "
                "from TABLETOP_LLM_BASE_URL and TABLETOP_LLM_MODEL)"
            )
        return None
    from tabletop.language.llm import LLMConfig

    if args.llm_config:
        return LLMConfig.from_file(args.llm_config).with_overrides(
            base_url=args.llm_url, model=args.llm_model
        )
    return LLMConfig.from_env(base_url=args.llm_url, model=args.llm_model)


def _numbered(code: str) -> str:
    lines = code.rstrip("\n").split("\n")
    return "\n".join(f"  {i:3d} | {line}" for i, line in enumerate(lines, start=1))


def _fmt(p) -> str:
    return "(" + ", ".join(f"{v:+.3f}" for v in np.asarray(p, float)) + ") m"


# ---------------------------------------------------------------------- parse
def cmd_parse(args: argparse.Namespace) -> int:
    from tabletop.language.run import generate_code
    from tabletop.language.sandbox import check_code

    if args.suite and args.instruction:
        raise ConfigError(
            f"give an instruction or --suite, not both (got {args.instruction!r} and --suite)"
        )
    if args.json and not args.suite:
        raise ConfigError("--json is the suite's report: give --suite too (or leave --json out)")
    if args.suite_file is not None and not args.suite:
        raise ConfigError(
            f"--suite-file {args.suite_file!r} is the suite --suite scores: give --suite too "
            "(or leave --suite-file out)"
        )
    if args.suite:
        return _suite_on_reference(args)
    if not args.instruction:
        print("tabletop parse: give an instruction (or --suite)", file=sys.stderr)
        return 2
    code = generate_code(args.instruction, args.backend, _llm_config(args), args.robot, args.reader)
    sys.stdout.write(code)
    check_code(code)  # a refusal is reported as an error (exit status 2)
    return 0


def _suite_on_reference(args: argparse.Namespace) -> int:
    from tabletop.language.suite import (
        PointRobot,
        load_suite,
        reference_map,
        write_suite_images,
    )

    suite = load_suite(args.suite_file)
    robot = PointRobot(reference_map(suite), suite.start)
    with tempfile.TemporaryDirectory() as d:
        write_suite_images(suite, d)
        return _report_suite(args, suite, robot, d)


def _report_suite(args, suite, robot, image_dir) -> int:
    from tabletop.language.run import generate_code
    from tabletop.language.suite import evaluate_suite
    from tabletop.reader.errors import ParseError

    config = _llm_config(args)
    report = evaluate_suite(
        robot,
        lambda text: generate_code(text, args.backend, config, reader=args.reader),
        suite,
        image_dir=image_dir,
    )
    refused = []
    if args.backend == "offline":
        for bad in suite.unparseable:
            try:
                generate_code(bad.instruction, "offline", reader=args.reader)
            except ParseError as e:
                refused.append(bad.fragment in e.fragment)
            else:
                refused.append(False)
    if args.json:
        out = {
            "matched": report.matched,
            "cases": report.evaluated,
            "skipped": report.skipped,
            "share": report.share,
            "tol_m": report.tol_m,
            "by_family": {
                k: {"matched": a, "cases": n} for k, (a, n) in report.by_family().items()
            },
            "failures": [
                {"id": r.case.id, "instruction": r.case.instruction, "reason": r.reason}
                for r in report.results
                if not r.match
            ],
            "unparseable_refused": sum(refused),
            "unparseable": len(refused),
        }
        print(json.dumps(out, indent=2))
    else:
        print(f"suite: {len(report.results)} instructions, backend {args.backend}")
        for fam, (a, n) in report.by_family().items():
            print(f"  {fam:10s} {a:3d} / {n:3d}")
        for r in report.results:
            if not r.match and not r.skipped:
                print(f"  MISS {r.case.id}: {r.case.instruction!r}: {r.reason}")
        skipped = [r for r in report.results if r.skipped]
        if skipped:
            print(
                f"  skipped, their expected code fails on this map ({len(skipped)}): "
                + ", ".join(r.case.id for r in skipped)
            )
            reasons = dict.fromkeys(r.reason.split("on this map: ", 1)[-1] for r in skipped)
            for reason in list(reasons)[:3]:
                print(f"    e.g. {reason}")
        print(
            f"targets match (within {report.tol_m * 1000:.0f} mm): {report.matched} / "
            f"{report.evaluated} = {report.share:.1%}"
            + (f" ({report.skipped} skipped)" if report.skipped else "")
        )
        if refused:
            print(f"unparseable instructions refused: {sum(refused)} / {len(refused)}")
    return 0 if report.matched == report.evaluated and all(refused) else 1


# ---------------------------------------------------------------------- run
def _load_map(path: str, suite):
    if path == REFERENCE:
        from tabletop.language.suite import reference_map

        return reference_map(suite)
    from tabletop.mapping.avlmap import AVLMap

    return AVLMap.load(path)


def cmd_run(args: argparse.Namespace) -> int:
    from tabletop.language.run import run_instruction
    from tabletop.language.sandbox import SandboxConfig
    from tabletop.language.suite import PointRobot, load_suite, write_suite_images

    if args.json and not args.suite:
        raise ConfigError("--json is the suite's report: give --suite too (or leave --json out)")
    if not (math.isfinite(args.timeout) and args.timeout > 0):  # before the map loads
        raise ConfigError(f"--timeout {args.timeout:g}: a time limit in seconds, > 0 (default 600)")
    if args.room is not None and (args.embodiment != "room" or args.suite):
        with_what = "--suite" if args.suite else f"--embodiment {args.embodiment}"
        raise ConfigError(
            f"--room {args.room!r} names the room of the wheeled base, and {with_what} has no "
            "room: give --room with --embodiment room only (without --suite), or leave it out"
        )
    if args.embodiment == "room" and args.room is None:
        args.room = "default"
    if args.image_dir is not None and not Path(args.image_dir).is_dir():
        what = "is not a directory" if Path(args.image_dir).exists() else "does not exist"
        raise ConfigError(f"--image-dir {str(args.image_dir)!r} {what}")
    if args.suite_file is not None and not (args.suite or args.map == REFERENCE):
        raise ConfigError(
            f"--suite-file {args.suite_file!r} is the suite --suite scores, or whose reference "
            f"map '{REFERENCE}' names: give --suite or the map '{REFERENCE}' (or leave "
            "--suite-file out)"
        )
    llm_config = _llm_config(args)  # its flags and file, before the map and the robot
    suite = load_suite(args.suite_file) if (args.suite or args.map == REFERENCE) else None
    m = _load_map(args.map, suite)
    if args.suite:
        robot = PointRobot(m, suite.start)
        if args.image_dir:
            return _report_suite(args, suite, robot, args.image_dir)
        with tempfile.TemporaryDirectory() as d:
            return _report_suite(args, suite, robot, write_suite_images(suite, d))
    if not args.instruction:
        print("tabletop run: give an instruction (or --suite)", file=sys.stderr)
        return 2
    image_dir = args.image_dir
    tmp = None
    if args.map == REFERENCE and image_dir is None:  # its goal images, for trying it out
        tmp = tempfile.TemporaryDirectory()
        image_dir = write_suite_images(suite, tmp.name)
    world = None  # the room's simulator, for the wheeled base
    if args.embodiment == "room":  # a dry run too: the targets are the room map's
        from tabletop.sim.room import load_room_spec

        load_room_spec(args.room)  # an unknown room is named, with the shipped ones
        _check_map_room(args, m)
    if args.dry_run and args.embodiment == "arm" and args.map != REFERENCE:
        # the arm's run checks --scene against the map: its dry run too (the suite's reference
        # map is a try-out map of no shipped scene)
        _scene_of_map(args, m)
    if args.dry_run or args.embodiment == "point":
        robot = PointRobot(m, (0.3, 0.0, 0.3))
    elif args.embodiment == "base":
        from tabletop.robot import MobileBase

        robot = MobileBase(m)
    elif args.embodiment == "room":
        from tabletop.robot import MobileRobot
        from tabletop.sim.room import load_room_spec
        from tabletop.sim.room_world import RoomWorld

        print(f"starting the wheeled base in room {args.room!r} ...", file=sys.stderr)
        world = RoomWorld(load_room_spec(args.room))
        robot = MobileRobot(m, world.driver)
    else:
        from tabletop.robot import SimArm

        spec = _scene_of_map(args, m)
        print("starting the simulated arm ...", file=sys.stderr)
        robot = SimArm(m, spec, other_scene=bool(args.other_scene))

    def on_code(code: str) -> None:
        print(f"code ({args.backend}, checked by the sandbox):")
        print(_numbered(code))
        print("dry run: nothing moves" if args.dry_run else "running:")

    def on_motion(motion) -> None:
        if motion.result is None:
            print(f"  {motion.method:17s} target {_fmt(motion.target)}", flush=True)
            return
        r = motion.result
        reached = getattr(r, "reached", None)
        reason = getattr(getattr(r, "reason", None), "value", getattr(r, "reason", ""))
        err = getattr(r, "target_error_m", getattr(r, "error_m", None))
        where = getattr(r, "final_tcp", getattr(r, "final_position", None))
        line = f"  {'':17s} -> {'reached' if reached else 'NOT reached'} ({reason})"
        if where is not None:
            line += f", ends at {_fmt(where)}"
        requested = getattr(r, "requested", None)
        if requested is not None:  # the arm: measured from the point asked, not the one commanded
            line += f", {r.requested_error_m * 100:.1f} cm from the point asked {_fmt(requested)}"
        elif err is not None:
            line += f", {err * 100:.1f} cm from the target"
        if getattr(r, "standoff_applied", False):
            line += " (the target was inside an obstacle: stopped at a standoff)"
        print(line, flush=True)
        if getattr(r, "note", ""):
            print(f"  {'':17s}    why: {r.note}", flush=True)

    try:
        run = run_instruction(
            args.instruction,
            robot,
            backend=args.backend,
            llm_config=llm_config,
            dry_run=args.dry_run,
            image_dir=image_dir,
            sandbox=SandboxConfig(timeout_s=args.timeout),
            on_code=on_code,
            on_motion=on_motion,
            reader=args.reader,
        )
    finally:
        if hasattr(robot, "close"):
            robot.close()
        if world is not None:
            world.close()
        if tmp is not None:
            tmp.cleanup()
    results = [mo.result for mo in run.motions]
    failed = sum(1 for r in results if r is not None and not getattr(r, "reached", True))
    print(
        f"{len(run.motions)} target(s), {run.run.steps} steps, {run.run.elapsed_s:.2f} s"
        + ("" if args.dry_run else f", {len(results) - failed} reached, {failed} not reached")
        + (f"; WARNING: {mismatch}" if (mismatch := getattr(args, "_scene_mismatch", "")) else "")
    )
    return 0 if failed == 0 else 1


def _scene_of_map(args: argparse.Namespace, m):
    """The scene spec of ``--scene``, checked against the scene the map was built from (a map
    reached in another world is refused); with ``--other-scene`` a mismatch is a warning, printed
    now and in the summary."""
    from tabletop.errors import TabletopError
    from tabletop.mapping.persistence import check_map_scene
    from tabletop.sim.scene import load_scene_spec

    spec = load_scene_spec(args.scene)
    try:
        check_map_scene(args.map, getattr(m, "source", None), spec.to_dict(), args.scene)
    except TabletopError as e:
        if not args.other_scene:
            raise ConfigError(f"{e} (or pass --other-scene to run it anyway)") from None
        args._scene_mismatch = str(e)
        print(f"WARNING (--other-scene): {e}", file=sys.stderr)
    return spec


def _check_map_room(args: argparse.Namespace, m) -> None:
    """``--embodiment room``: the map must have been built in ``--room`` (a table scene's map,
    or another room's, would send the base to the map's places in another world); with
    ``--other-scene`` a mismatch is a warning, printed now and in the summary."""
    built = (getattr(m, "source", None) or {}).get("room")
    if built == args.room:
        return
    what = f"room {built!r}" if built else "no room (a table scene's map, or one that does not say)"
    msg = (
        f"{args.map} was built in {what}, not in --room {args.room!r}: the base would drive to "
        "the map's places in another world; give the room the map was built in"
    )
    if not args.other_scene:
        raise ConfigError(f"{msg} (or pass --other-scene to run it anyway)")
    args._scene_mismatch = msg
    print(f"WARNING (--other-scene): {msg}", file=sys.stderr)


# ---------------------------------------------------------------------- registration
def add_commands(sub) -> None:
    """Register ``parse`` and ``run`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser(
        "parse", help="print the robot code of an instruction (as the sandbox receives it)"
    )
    p.add_argument("instruction", nargs="?", help='e.g. "go to the mug near the sound of a dog"')
    _add_backend_args(p)
    p.add_argument(
        "--robot",
        choices=list(EMBODIMENTS),
        default="arm",
        help="the robot the code is for: the arm (default) or a mobile base (turns, drives)",
    )
    p.add_argument(
        "--suite",
        action="store_true",
        help="score the backend on the instruction suite over its reference map instead",
    )
    p.add_argument("--suite-file", help="a suite TOML (default: the shipped suite)")
    p.add_argument("--json", action="store_true", help="with --suite: machine-readable output")
    p.set_defaults(func=cmd_parse)

    p = sub.add_parser("run", help="run an instruction on a map: code, targets, reach results")
    p.add_argument("map", help=f"map file (.npz), or '{REFERENCE}' for the suite's reference map")
    p.add_argument("instruction", nargs="?", help='e.g. "move to the left of the red mug"')
    _add_backend_args(p)
    p.add_argument("--dry-run", action="store_true", help="print code and targets; nothing moves")
    p.add_argument(
        "--embodiment",
        choices=["arm", "base", "room", "point"],
        default="arm",
        help="arm: the simulated Panda (default); base: the kinematic disc on the table; "
        "room: the wheeled base in the room a room map was built from (--room); point: a "
        "robot that jumps to each target",
    )
    p.add_argument(
        "--scene",
        default="default",
        help="the scene the map was built from (checked against the map; default: default)",
    )
    p.add_argument(
        "--other-scene",
        action="store_true",
        help="run the arm in --scene although the map was not built from it (or does not say "
        "what it was built from): warned, not refused",
    )
    p.add_argument(
        "--room",
        help="with --embodiment room (and only with it): the room (default: default)",
    )
    p.add_argument(
        "--image-dir",
        help="the directory images in instructions are read from (relative paths from here; "
        "a path outside it is refused; default: the working directory)",
    )
    p.add_argument("--timeout", type=float, default=600.0, help="time limit of the run [s]")
    p.add_argument(
        "--suite",
        action="store_true",
        help="score the backend on the instruction suite over this map (dry; nothing moves)",
    )
    p.add_argument("--suite-file", help="a suite TOML (default: the shipped suite)")
    p.add_argument("--json", action="store_true", help="with --suite: machine-readable output")
    p.set_defaults(func=cmd_run)


def cmd_train_reader(args: argparse.Namespace) -> int:
    """``tabletop train reader``: the learned reader's tagger on generated requests (seeded;
    minutes on two cores; MiniLM's word states cached under out/cache)."""
    from pathlib import Path

    from tabletop.eval.reader_texts import reader_texts
    from tabletop.train.reader import train_reader

    given = [f for f, v in (("--steps", args.steps), ("--max-minutes", args.max_minutes)) if v]
    if args.backbone is not None or args.device != "cpu" or given:
        raise ConfigError("tabletop train reader takes --out and --threads only")
    out = Path(args.out) if args.out is not None else Path("out/weights/reader.pt")
    if out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a directory; give a weights file path")
    from tabletop.cli.output import check_output_flag

    check_output_flag("--out", out, hint="; give a weights file path")
    if args.threads is not None:
        import torch

        torch.set_num_threads(int(args.threads))
    pools = reader_pools()
    texts = reader_texts(pools, n_per_pool=READER_TEXTS_PER_POOL, seed=0)
    tagger = train_reader(texts, out, val_pools=READER_VAL_POOLS, seed=0, refit=True)
    v = tagger.meta.get("validation", {})
    print(f"reader written: {out} ({len(texts)} texts from {len(pools)} tune pools)")
    if v:
        print(
            f"on pools it never saw ({', '.join(v['pools'])}): plans right "
            f"{v['plans_right']:.3f} (rule reader with spelling {v['rules_plans_right']:.3f}), "
            f"words' roles right {v['words_role_right']:.3f}"
        )
    return 0


#: Generated requests per tune pool, and the pools a first network is measured on unseen (the
#: two newest pools it trains on: the last writers' words, read only after their report).
READER_TEXTS_PER_POOL = 1000
READER_VAL_POOLS = ("heldout-26", "heldout-27")
#: The tagger's pools (:func:`reader_pools`): the tune pools through heldout-27 (the shipped
#: tagger's, 42ad637). heldout-28 and heldout-29 joined the kind and place readers; a tagger
#: refitted with them by the same recipe read their instructions no better (its first
#: network, which saw neither, 39 of 48 as the shipped one) and changed four readings the
#: tests hold, so it was not shipped.
READER_LEFT_OUT = ("heldout-28", "heldout-29")


def reader_pools() -> tuple[str, ...]:
    """The tune pools the tagger is trained on (all but :data:`READER_LEFT_OUT`)."""
    from tabletop.eval.paraphrase import TUNE_POOLS

    return tuple(p for p in TUNE_POOLS if p not in READER_LEFT_OUT)

"""``tabletop eval``, ``tabletop eval-map``, ``tabletop demo`` and ``tabletop calibrate``: goal
suites end to end, map goals alone, the demo, and the query confidence's calibration."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
import tomllib
from pathlib import Path

from tabletop.cli.output import check_output_flag, check_parents_are_directories, stdout_to_stderr
from tabletop.cli.progress import ProgressBars
from tabletop.embodiments import EMBODIMENTS
from tabletop.errors import ConfigError
from tabletop.eval.harness import DEFAULT_CACHE_DIR
from tabletop.reader.reading import DEFAULT_READER, READERS

__all__ = [
    "add_backend_flags",
    "add_commands",
    "cmd_calibrate",
    "cmd_demo",
    "cmd_eval",
    "cmd_eval_compare",
    "cmd_eval_map",
    "print_result",
]

CALIBRATION_OUT_DIR = Path("out/calibration")


def _cache_flags(args: argparse.Namespace) -> None:
    """``--no-cache`` keeps nothing, so a ``--cache-dir`` beside it is refused; otherwise the
    cache directory is the one given or the default, checked."""
    if args.no_cache and args.cache_dir is not None:
        raise ConfigError(
            f"--no-cache and --cache-dir {args.cache_dir!r} exclude each other: --no-cache "
            "keeps nothing; leave one out"
        )
    if args.cache_dir is None:
        args.cache_dir = str(DEFAULT_CACHE_DIR)
    if not args.no_cache:
        _check_directory_flag("--cache-dir", args.cache_dir)


"""Where ``tabletop calibrate`` writes ``<set>.json`` unless given ``--out``."""


# ---------------------------------------------------------------------- eval
def cmd_eval(args: argparse.Namespace) -> int:
    from tabletop.eval.runner import run_eval

    encoders = [e.strip() for e in args.encoders.split(",") if e.strip()]
    try:
        overrides = parse_map_settings(args.map_set)
        check_map_settings(overrides)
        scan_overrides = parse_map_settings(args.scan_set, "--scan-set", "snr_db=5")
        _check_scan_settings(scan_overrides)
        noise = parse_map_settings(args.noise, "--noise", "pose_translation_m=0.005")
        _check_noise_settings(noise)
        conditions = _robustness_conditions(args.robustness)
        if conditions is not None and noise:
            raise ConfigError("--noise and --robustness exclude each other")
        _check_directory_flag("--out", args.out)
        _cache_flags(args)
        _check_backend_flags(args)
        if args.goals and not args.json:
            raise ConfigError("--goals adds every goal to --json's output: give --json too")
    except ConfigError as e:
        print(f"tabletop eval: {e}", file=sys.stderr)
        return 2
    if conditions is not None:
        return _cmd_robustness(args, encoders, conditions)
    tasks = _tasks_with_map_settings(args.tasks, overrides)  # before the cache is created
    if noise and not args.json:
        print(f"sensor noise applied to every task: {noise}")
    if overrides and not args.json:
        print(f"map settings changed for every task: {overrides}")
    if scan_overrides and not args.json:
        print(f"scan settings changed for every task: {scan_overrides}")
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        if args.json:  # stdout carries only the JSON, and no progress is shown
            stack.enter_context(stdout_to_stderr())
            bars = None
        else:
            bars = stack.enter_context(ProgressBars())
        res = run_eval(
            tasks,
            encoders=encoders,
            out_dir=args.out,
            progress=bars,
            cache_dir=None if args.no_cache else args.cache_dir,
            map_overrides=overrides,
            scan_overrides=scan_overrides,
            noise=noise,
            reader=args.reader,
            workers=args.workers,
            ray=args.ray,
        )
    wall = time.perf_counter() - t0
    if args.json:
        from tabletop.eval.results import dumps

        d = res.to_json()
        d["wall_s"] = round(wall, 1)
        d["map_overrides"] = overrides
        d["scan_overrides"] = scan_overrides
        d["noise"] = noise
        print(dumps(d if args.goals else _without_goals(d)))
        return 0
    print_result(res, wall)
    return 0


def _check_backend_flags(args: argparse.Namespace) -> None:
    """``--workers`` and ``--ray`` are checked before any scan: a whole number of workers, and
    Ray installed when ``--ray`` is given (it is an optional extra)."""
    from tabletop.parallel import Backend, import_ray

    Backend(workers=args.workers, ray=args.ray)  # --workers 0 fails here, not in a pool
    if args.ray is not None:
        import_ray(args.ray)


def add_backend_flags(p, what: str = "units of work") -> None:
    """``--workers N`` and ``--ray ADDRESS`` (:mod:`tabletop.parallel`) on a parser."""
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help=f"run the {what} in N worker processes on this machine (one math thread each); "
        "default: one after another in this process",
    )
    p.add_argument(
        "--ray",
        default=None,
        metavar="ADDRESS",
        help=f"send the {what} as Ray tasks to the cluster at ADDRESS (HOST:PORT, or auto for "
        "the one `ray start` runs on this node; the `ray` extra); run from a directory every "
        "node sees at the same path (docs/evaluation.md); with --workers N, at most N at once",
    )


def _check_directory_flag(flag: str, path: str | Path) -> None:
    """A directory flag's value must be a directory or not exist yet (it is created), and what
    of it exists must be directories: checked before any scan, so no work is lost to it."""
    p = Path(path)
    if str(path) == "":
        raise ConfigError(f"{flag} is empty: give a directory (created if missing)")
    if p.exists() and not p.is_dir():
        raise ConfigError(
            f"{flag} {str(path)!r} exists and is not a directory: give a directory "
            "(created if missing)"
        )
    check_parents_are_directories(flag, path, ": give a directory (created if missing)")


def _tasks_with_map_settings(tasks, overrides: dict) -> list:
    """The task files of ``tasks`` with every file's map settings (its ``[map]`` changed by
    ``--map-set``) checked, before the cache directory is created and before any scan."""
    from tabletop.errors import TabletopError
    from tabletop.eval.harness import map_config
    from tabletop.eval.runner import collect_task_files

    files = collect_task_files(tasks)
    if overrides:
        for tf in files:
            try:
                map_config(**{**dict(tf.map), **overrides})
            except (TypeError, TabletopError) as e:
                raise ConfigError(f"--map-set {overrides} ({tf.path or tf.name}): {e}") from None
    return files


def _check_scan_settings(d: dict) -> None:
    """Unknown ``--scan-set`` fields fail before any scan, naming the valid ones."""
    from dataclasses import fields

    from tabletop.sim.scan import ScanConfig

    valid = sorted(f.name for f in fields(ScanConfig))
    bad = sorted(k for k in d if k not in valid)
    if bad:
        raise ConfigError(f"--scan-set: unknown scan fields {bad}; valid: {', '.join(valid)}")


def _check_noise_settings(d: dict) -> None:
    """``--noise`` settings are checked before any scan: unknown fields and bad values."""
    from tabletop.sim.noise import NoiseConfig

    NoiseConfig.from_dict(d, "--noise")


def _robustness_conditions(given: str | None) -> list[str] | None:
    """``--robustness [all|NAME,...]`` -> condition names (None: not a robustness run)."""
    from tabletop.eval.robustness import CONDITIONS

    if given is None:
        return None
    names = list(CONDITIONS) if given == "all" else [n.strip() for n in given.split(",")]
    bad = [n for n in names if n not in CONDITIONS]
    if bad or not names:
        raise ConfigError(
            f"--robustness: unknown conditions {bad}; valid: all, or some of {list(CONDITIONS)}"
        )
    return names


def _cmd_robustness(args: argparse.Namespace, encoders: list[str], conditions: list[str]) -> int:
    """``tabletop eval TASKS --robustness``: clean and noisy runs, the drop per goal type."""
    from tabletop.eval.results import dumps
    from tabletop.eval.robustness import MAX_DROP_POINTS, run_robustness

    log = sys.stderr if args.json else sys.stdout
    with contextlib.ExitStack() as stack:
        if args.json:
            stack.enter_context(stdout_to_stderr())
            bars = None
        else:
            bars = stack.enter_context(ProgressBars())
        res = run_robustness(
            args.tasks,
            encoders=encoders,
            out_dir=args.out,
            progress=bars,
            cache_dir=None if args.no_cache else args.cache_dir,
            conditions=conditions,
            on_condition=lambda n: print(f"condition: {n}", file=log, flush=True),
            workers=args.workers,
            ray=args.ray,
        )
    if args.json:
        d = res.to_json()
        if not args.goals:
            d["results"] = {k: _without_goals(v) for k, v in d["results"].items()}
        print(dumps(d))
        return 0
    print(res.table_markdown())
    print(
        f"worst drop {res.worst_drop:.0f} points (target <= {MAX_DROP_POINTS:.0f}); "
        f"contacts under noise {res.contacts}; {res.wall_s:.0f} s"
    )
    print(f"report: {Path(args.out) / 'robustness.md'}")
    return 0


def parse_map_settings(
    items, flag: str = "--map-set", example: str = "object.instances=false"
) -> dict:
    """``["object.instances=false", "frame_step=2"]`` -> ``{"object": {"instances": False},
    "frame_step": 2}``: config fields (``module.field`` for a module's) with TOML values."""
    out: dict = {}
    for item in items or ():
        key, sep, raw = str(item).partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"{flag} {item!r}: expected FIELD=VALUE (e.g. {example})")
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()  # a bare word: a string
        *parents, leaf = key.strip().split(".")
        d = out
        for part in parents:
            d = d.setdefault(part, {})
            if not isinstance(d, dict):
                raise ConfigError(f"{flag} {item!r}: {part!r} is set twice")
        d[leaf] = value
    return out


def check_map_settings(d: dict, flag: str = "--map-set") -> None:
    """``--map-set`` fields and value types checked against :class:`MapConfig` (its module
    configs field by field) before any work: an unknown field is named with the valid ones, a
    value of the wrong type with the type its default has."""
    from tabletop.mapping import MapConfig

    _check_config_fields(d, MapConfig(), flag, "", extra={"voxel_size": 0.01})


def _check_config_fields(d: dict, config, flag: str, prefix: str, extra=None) -> None:
    import dataclasses

    defaults = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    defaults.update(extra or {})
    for key, value in d.items():
        name = f"{prefix}{key}"
        if key not in defaults:
            where = f"fields of {prefix.rstrip('.')}" if prefix else "map fields"
            raise ConfigError(
                f"{flag} {name}: unknown field; valid {where}: {', '.join(sorted(defaults))}"
            )
        default = defaults[key]
        if dataclasses.is_dataclass(default) and not isinstance(default, type):
            if not isinstance(value, dict):
                sub = ", ".join(f"{name}.{f.name}" for f in dataclasses.fields(default))
                raise ConfigError(f"{flag} {name}={value!r}: set its fields, one of {sub}")
            _check_config_fields(value, default, flag, f"{name}.")
            continue
        want = _value_kind(default)
        if want is not None and not _value_fits(value, want):
            raise ConfigError(
                f"{flag} {name}={value!r}: expected {want} (the default is {default!r}); "
                'values are TOML (true/false, numbers, "strings", [lists])'
            )


def _value_kind(default) -> str | None:
    if isinstance(default, bool):
        return "true or false"
    if isinstance(default, int):
        return "an integer"
    if isinstance(default, float):
        return "a number"
    if isinstance(default, str):
        return "a string"
    if isinstance(default, (tuple, list)):
        return "a list"
    return None  # None, a mapping, a grid: checked when the config is built


def _value_fits(value, want: str) -> bool:
    if want == "true or false":
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False
    if want == "an integer":
        return isinstance(value, int)
    if want == "a number":
        return isinstance(value, (int, float))
    if want == "a string":
        return isinstance(value, str)
    return isinstance(value, list)


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


# ---------------------------------------------------------------------- eval-compare
def cmd_eval_compare(args: argparse.Namespace) -> int:
    """``tabletop eval-compare A B``: 0 when the two evaluations' JSON are equal but for the
    timings (:data:`tabletop.eval.compare.IGNORED`), else 1 with the differences."""
    from tabletop.eval.compare import IGNORED, compare_results, goal_count, load_results

    docs = []
    for path in args.results:
        try:
            docs.append(load_results(path))
        except (OSError, ValueError) as e:
            raise ConfigError(str(e)) from None
    a, b = docs
    diffs = compare_results(a, b)
    if diffs:
        for line in diffs[:50]:
            print(line)
        more = " (the first 50 shown)" if len(diffs) > 50 else ""
        print(f"{len(diffs)} differences{more}")
        return 1
    print(
        f"the same: {goal_count(a)} goals in {len(a.get('rows', ()))} rows, every field but "
        f"{', '.join(sorted(IGNORED))}"
    )
    return 0


# ---------------------------------------------------------------------- eval-map
def cmd_eval_map(args: argparse.Namespace) -> int:
    from tabletop.eval.map_goals import check_map_eval, run_map_eval

    check_map_eval(args.seeds, args.speed)  # refused before the banner, not after it
    log = sys.stderr if args.json else sys.stdout  # --json: stdout carries only the JSON

    def show(run):
        r = run["result"]
        print(
            f"  {run['scene']:8s} seed {run['seed']}: "
            + ", ".join(f"{k} {v['successes']}/{v['goals']}" for k, v in r.items()),
            file=log,
            flush=True,
        )

    print(
        f"map goals on {args.seeds} x 2 scans (default scene and a generated one), "
        f"{args.encoders} encoders; success = target within 10 cm of the truth",
        file=log,
    )
    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        res = run_map_eval(args.seeds, args.speed, args.encoders, progress=show)
    if args.json:
        keys = ("by_type", "by_scene", "encoders")
        print(json.dumps({k: res[k] for k in keys}, indent=1))
        return 0
    print(f"encoders: {res['encoders'].get('set')}")
    scenes = list(res["by_scene"])
    print(
        f"{'goal type':16s} {'goals':>6s} {'success':>8s}" + "".join(f" {s:>12s}" for s in scenes)
    )
    for k, v in res["by_type"].items():
        per = [res["by_scene"][s].get(k) for s in scenes]
        cells = "".join(
            f" {'-':>12s}"
            if c is None
            else f" {c['successes']:>4d}/{c['goals']:<3d}{c['success_rate']:4.0%}"
            for c in per
        )
        print(f"{k:16s} {v['goals']:6d} {v['success_rate']:8.1%}" + cells)
    return 0


# ---------------------------------------------------------------------- demo
def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: scan the default scene, map it with the embedded default encoders, run
    the demo suite (a few goals of every type) with the simulated arm, print the table and
    write the report (``--robot``: another robot's demo, its embodiment's)."""
    _check_directory_flag("--out", args.out)  # before the scan, not after it
    out = Path(args.out)
    encoders = [e.strip() for e in args.encoders.split(",") if e.strip()]
    from tabletop.mapping.encoders.registry import ENCODER_SETS

    if not encoders or (unknown := [e for e in encoders if e not in ENCODER_SETS]):
        # refused before the banner that names them, not after it
        named = f"unknown encoder set {unknown[0]!r}" if encoders else "no encoder set named"
        raise ConfigError(f"--encoders: {named}; valid: {list(ENCODER_SETS)}")
    from tabletop.embodiments import embodiment

    body = embodiment(args.robot)
    if args.driver not in body.drivers:
        print(
            f"tabletop demo: --driver {args.driver} does not move the {body.name} robot; its "
            f"demo runs on {' or '.join(repr(d) for d in body.drivers)}",
            file=sys.stderr,
        )
        return 2
    return body.load("demo")(out, encoders, args.driver)


def _arm_demo(out: Path, encoders: list[str], driver: str) -> int:
    """``tabletop demo`` (the arm's embodiment's demo): the Panda at the default table."""
    from tabletop.eval.runner import run_eval

    print(
        "tabletop demo: default scene -> teleop scan with inserted sounds -> AVLMap with the "
        f"encoders {encoders} -> the demo suite (object, sound, image, area, ambiguous, "
        "spatial, multimodal spatial and instruction goals) reached by the simulated Panda.\n"
        "'default' = the embedded learned encoders (MiniLM text, an EfficientNet-Lite0 image "
        "network LSeg-style, a head on the frozen AudioSet-trained YAMNet for sounds, with its "
        "sound vocabulary and AudioSet's class names); "
        "'oracle' = the simulator's ground truth, an upper bound.\n",
        flush=True,
    )
    if driver != "sim":
        print(
            f"--driver {driver}: every reach is sent through franky (libfranka's network "
            "protocol) to franky-sim's FR3 in MuJoCo, started on a loopback address; contacts "
            "are counted by replaying the measured joints in a PyBullet copy of the scene.\n",
            flush=True,
        )
    t0 = time.perf_counter()
    with ProgressBars() as bars:
        res = run_eval(
            "demo",
            encoders=encoders,
            out_dir=out,
            cache_dir=out / "cache",
            progress=bars,
            driver=driver,
        )
    wall = time.perf_counter() - t0
    print()
    print_result(res, wall, " (scan, map, reaches)")
    _print_tracking(res)
    _print_view_command([(t.map_path, t.recording_path) for r in res.runs for t in r.tasks], out)
    return 0 if all(r.available for r in res.runs) else 1


def _print_tracking(res) -> None:
    """franky's tracking and reflexes of a run on franky-sim, one line per encoder set."""
    for r in res.runs:
        tr = [t.tracking for t in r.tasks if t.tracking]
        if not tr:
            continue
        n = sum(t["trajectories"] for t in tr)
        worst = max(t["max_error_rad"] for t in tr)
        final = max(t["max_final_error_rad"] for t in tr)
        reflexes = sum(t["reflexes"] for t in tr)
        print(
            f"franky-sim ({r.encoders}): {n} trajectories executed, tracking error at most "
            f"{worst:.4f} rad (measured joints against franky's command), final joint error at "
            f"most {final:.4f} rad, {reflexes} reflexes"
        )


def _print_view_command(maps: list[tuple[str, str]], eval_dir: Path | None) -> None:
    """The one command that opens the demo's map in the viewer (the optional viewer extra)."""
    from tabletop.cli.view import view_command

    for map_path, rec in maps:
        if map_path:
            print(
                "see it in 3D (pip install -e '.[viewer]'): "
                + view_command(map_path, rec or None, eval_dir)
            )
            return


def _mobile_demo(out: Path, encoders: list[str], driver: str = "sim") -> int:
    """``tabletop demo --robot mobile`` (the mobile embodiment's demo): the wheeled base in the
    default room (its one driver, the simulator)."""
    from tabletop.eval.room_demo import run_room_demo

    print(
        "tabletop demo --robot mobile: default room -> a drive of the wheeled base with "
        "inserted sounds -> AVLMap of the room -> goals reached on the room's physics (1 m "
        "radius); the flyer's path beside the ground base's.\n",
        flush=True,
    )
    for enc in encoders:
        t0 = time.perf_counter()
        where = out if len(encoders) == 1 else out / enc
        with ProgressBars() as bars:
            res = run_room_demo(where, enc, progress=bars)
        print(f"\n{enc}: {res['successes']}/{len(res['goals'])} goals reached within 1 m")
        for g in res["goals"]:
            print(
                f"  {g['type']:<12} {g.get('text', ''):<45} {g['status']:<10} "
                f"error {g.get('error_m', '–')} m, collisions {g.get('collisions', '–')}"
            )
        print(f"report: {where / 'report.md'} ({time.perf_counter() - t0:.0f} s)")
        _print_view_command([(res.get("map_file", ""), res.get("recording_dir", ""))], None)
    return 0


# ---------------------------------------------------------------------- calibrate
def _check_calibration_output(out: Path) -> None:
    """``out`` may be replaced only when it is a calibration file (its ``format`` says so):
    never a directory or a file this package did not write."""
    if not out.exists():
        return
    try:
        ok = out.is_file() and json.loads(out.read_text())["format"] == "tabletop-calibration"
    except (OSError, ValueError, KeyError, TypeError):
        ok = False
    if not ok:
        raise ConfigError(
            f"--out {out} exists and is not a calibration file (format 'tabletop-calibration'); "
            "calibrate only replaces a previous calibration: choose another path"
        )


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Fit the confidence calibration of an encoder set on seeded scenes (first half) and
    report it on the others; writes out/calibration/<set>.json (or --out)."""
    from tabletop.eval.calibration import CALIBRATION_SEEDS, run_calibration
    from tabletop.mapping.calibration import MODALITIES
    from tabletop.mapping.encoders.registry import ENCODER_SETS

    # every flag before a quarter of an hour of scanning, not after
    keep_prior = [m.strip() for m in args.keep_prior.split(",") if m.strip()]
    bad = sorted(set(keep_prior) - set(MODALITIES))
    if args.keep_prior and not keep_prior:  # given, but only commas and white space
        bad = [args.keep_prior]
    if bad:
        print(f"tabletop calibrate: --keep-prior {bad}: valid {list(MODALITIES)}", file=sys.stderr)
        return 2
    if args.encoders not in ENCODER_SETS:
        raise ConfigError(f"--encoders {args.encoders!r}: unknown set; valid: {list(ENCODER_SETS)}")
    n = len(CALIBRATION_SEEDS)
    if args.scenes is not None and not 1 <= args.scenes <= n:
        raise ConfigError(
            f"--scenes {args.scenes}: a count of calibration scenes, valid 1..{n} (the first N); "
            f"leave it out for all {n}"
        )
    if args.rooms and (args.encoders != "default" or args.scenes is not None):
        raise ConfigError(
            "--rooms: the default set's room-aware network on the calibration rooms; it takes "
            "neither another --encoders nor --scenes"
        )
    _cache_flags(args)
    stem = f"{args.encoders}-room" if args.rooms else args.encoders
    out = args.out if args.out is not None else CALIBRATION_OUT_DIR / f"{stem}.json"
    check_output_flag("--out", out)
    _check_calibration_output(Path(out))
    cache_dir = None if args.no_cache else args.cache_dir
    if args.rooms:
        from tabletop.eval.calibration import ROOM_CALIBRATION_SEEDS, run_room_calibration

        print(f"calibrating room maps on rooms {list(ROOM_CALIBRATION_SEEDS)} ...", file=sys.stderr)
        cal = run_room_calibration(
            progress=lambda seed, s: print(f"  room {seed}: {len(s)} queries", file=sys.stderr),
            cache_dir=cache_dir,
        )
    else:
        seeds = list(CALIBRATION_SEEDS)[: args.scenes or n]
        print(f"calibrating {args.encoders!r} on scenes {seeds} ...", file=sys.stderr)
        cal = run_calibration(
            args.encoders,
            seeds,
            progress=lambda seed, s: print(f"  scene {seed}: {len(s)} queries", file=sys.stderr),
            cache_dir=cache_dir,
        )
    if keep_prior:
        cal = cal.keep_prior(keep_prior)
    path = cal.save(out)
    print(json.dumps(cal.to_json(), indent=1))
    print(f"written {path}", file=sys.stderr)
    return 0


# ---------------------------------------------------------------------- registration
def add_commands(sub) -> None:
    """Register ``eval``, ``eval-map``, ``demo`` and ``calibrate`` on the ``tabletop``
    sub-command parser."""
    p = sub.add_parser(
        "eval",
        help="run goal-reaching task files (scan, map, query, reach) and report per goal type",
    )
    p.add_argument(
        "tasks",
        nargs="+",
        help="task files (.toml/.json), directories of them, or shipped names: 'default' (the "
        "default suites), 'demo', 'paraphrase-tune', 'paraphrase-tune-2', "
        "'paraphrase-heldout', 'paraphrase-heldout-2', 'paraphrase-heldout-3', "
        "'paraphrase-heldout-4', 'paraphrase-heldout-5', 'paraphrase-heldout-6', "
        "'paraphrase-heldout-7', 'paraphrase-heldout-8', 'paraphrase-heldout-9', "
        "'paraphrase-heldout-10', 'paraphrase-heldout-11', 'paraphrase-heldout-12', "
        "'paraphrase-heldout-16', 'paraphrase-heldout-18' ... "
        "'paraphrase-heldout-27' (goals asked as people ask, to tune on; all but the first "
        "two were held out until their report), 'paraphrase-heldout-13', "
        "'paraphrase-heldout-14', 'paraphrase-heldout-15', 'paraphrase-heldout-17', "
        "'paraphrase-heldout-28', 'paraphrase-heldout-29', 'paraphrase-heldout-30', "
        "'paraphrase-heldout-31', 'paraphrase-heldout-32', 'paraphrase-heldout-33' (held out: "
        "each run once for a report; the misses of heldout-28 ... heldout-32 were read after "
        "it), "
        "'clutter' (dense tables: goals on, beside and between objects), "
        "'mobile' (a wheeled base in rooms, 1 m success radius)",
    )
    p.add_argument(
        "--encoders",
        default="oracle",
        help="encoder set(s), comma-separated, as the map's registry names them: oracle "
        "(simulator upper bound), default (embedded learned), ...; e.g. oracle,default for "
        "both rows (default: oracle)",
    )
    p.add_argument("--out", default="out/eval", help="report directory (default: out/eval)")
    p.add_argument(
        "--reader",
        default=DEFAULT_READER,
        help=f"the reader of every goal's words: {', '.join(READERS)} (default: {DEFAULT_READER})",
    )
    p.add_argument("--json", action="store_true", help="print the machine-readable summary")
    p.add_argument("--goals", action="store_true", help="with --json: include every goal")
    p.add_argument(
        "--cache-dir",
        default=None,
        help=f"recordings and maps reused across runs (default: {DEFAULT_CACHE_DIR})",
    )
    p.add_argument("--no-cache", action="store_true", help="scan and map afresh, keep nothing")
    p.add_argument(
        "--map-set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="change a map config field for every task (an ablation; repeatable), e.g. "
        "object.instances=false",
    )
    p.add_argument(
        "--scan-set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="change a scan setting for every task (repeatable), e.g. snr_db=5: the same scan "
        "with the sounds 10 dB quieter than the default 15 dB",
    )
    p.add_argument(
        "--noise",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="sensor noise applied to every task's clean scan before mapping (repeatable; "
        "replaces the task files' [noise]), e.g. pose_translation_m=0.005; fields: seed, "
        "pose_translation_m, pose_rotation_rad, depth_relative, depth_dropout, drop_frames, "
        "extrinsic_translation_m, extrinsic_rotation_rad, clock_offset_s",
    )
    p.add_argument(
        "--robustness",
        nargs="?",
        const="all",
        default=None,
        metavar="CONDITIONS",
        help="run the tasks clean and under each sensor condition (all, or comma-separated "
        "names: pose, depth, drop-frames, extrinsic, clock) and print the drop per goal type",
    )
    add_backend_flags(p, "units of work (an encoder set x a task file)")
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser(
        "eval-compare",
        help="whether two evaluations' results are the same goal for goal (timings aside)",
    )
    p.add_argument(
        "results",
        nargs=2,
        metavar="RESULTS",
        help="results.json files, report directories holding one, or `tabletop eval --json "
        "--goals` output",
    )
    p.set_defaults(func=cmd_eval_compare)

    p = sub.add_parser("eval-map", help="score map goals: object, sound, ambiguous, image")
    p.add_argument("--seeds", type=int, default=3, help="seeds per scene (default 3)")
    p.add_argument("--speed", type=float, default=0.3, help="scan speed [m/s]")
    p.add_argument("--encoders", default="oracle", choices=["oracle", "default"])
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_eval_map)

    p = sub.add_parser("demo", help="the end-to-end demo on the embedded defaults")
    p.add_argument("--out", default="out/demo", help="output directory (default: out/demo)")
    p.add_argument(
        "--robot",
        choices=list(EMBODIMENTS),
        default="arm",
        help="the Panda at the default table (default), or the wheeled base in the default room "
        "(mobile); any robot registered in tabletop.embodiments with a demo",
    )
    p.add_argument(
        "--encoders",
        default="default",
        help="encoder sets, comma-separated: default, oracle (default: default)",
    )
    p.add_argument(
        "--driver",
        choices=["sim", "franky-sim"],
        default="sim",
        help="what moves the arm: the PyBullet simulator (default), or franky-sim's FR3 "
        "through libfranka's protocol (pip install 'tabletop[frankysim]')",
    )
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("calibrate", help="fit query confidence of an encoder set on seeded scenes")
    p.add_argument("--encoders", default="default", help="encoder set (default: default)")
    p.add_argument(
        "--scenes", type=int, default=None, help="use the first N calibration scenes (default all)"
    )
    p.add_argument(
        "--out",
        default=None,
        metavar="FILE",
        help=f"file to write (default: {CALIBRATION_OUT_DIR}/SET.json). Queries read the "
        "shipped file: to update it, pass --out tabletop/data/calibration/SET.json",
    )
    p.add_argument(
        "--keep-prior",
        default="",
        help="modalities that keep the prior (comma-separated; their fits go to the report)",
    )
    p.add_argument(
        "--cache-dir",
        default=None,
        help=f"recordings and maps reused across runs (default: {DEFAULT_CACHE_DIR})",
    )
    p.add_argument("--no-cache", action="store_true", help="scan and map afresh, keep nothing")
    p.add_argument(
        "--rooms",
        action="store_true",
        help="the default set as room maps run it (the room-aware image network, frames "
        "enlarged twice), on generated rooms the wheeled base scans; writes SET-room.json",
    )
    p.set_defaults(func=cmd_calibrate)

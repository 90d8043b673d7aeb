"""``tabletop rooms`` and ``tabletop scan-room``: list, print or generate rooms, and record a
room scan with the wheeled base."""

from __future__ import annotations

import argparse
import time

from tabletop.cli.progress import ProgressBars

__all__ = ["add_commands", "cmd_rooms", "cmd_scan_room"]


def _room(args: argparse.Namespace):
    from tabletop.errors import ConfigError
    from tabletop.sim.room import generate_room, load_room_spec

    if args.generate is not None:
        if args.room is not None:
            flag = "ROOM" if args.func is cmd_rooms else "--room"
            raise ConfigError(
                f"{flag} {args.room!r} and --generate {args.generate} both name a room; give "
                f"either a room spec or shipped room's name, or --generate SEED, not both"
            )
        return generate_room(args.generate)
    return load_room_spec("default" if args.room is None else args.room)


def _tables(args: argparse.Namespace, spec) -> tuple[str, ...]:
    """The furniture names of ``--tables`` (empty: every table); an empty list is refused."""
    from tabletop.errors import ConfigError

    if args.tables is None:
        return ()
    tables = tuple(t.strip() for t in args.tables.split(",") if t.strip())
    if not tables:
        raise ConfigError(
            f"--tables {args.tables!r} names no table; give comma-separated furniture names "
            f"of room {spec.name!r}: {[f.name for f in spec.furniture]}, or leave --tables out "
            f"to visit every table"
        )
    return tables


def cmd_rooms(args: argparse.Namespace) -> int:
    from tabletop.sim.room import list_default_rooms, load_room_spec

    if args.room is None and args.generate is None:
        for name in list_default_rooms():
            spec = load_room_spec(name)
            items = ", ".join(f"{f.name} ({f.category})" for f in spec.furniture)
            n = sum(len(f.objects) for f in spec.furniture)
            print(f"{name:12s} {spec.size[0]} x {spec.size[1]} m, {n} objects: {items}")
        return 0
    print(_room(args).to_toml(), end="")
    return 0


def cmd_scan_room(args: argparse.Namespace) -> int:
    from tabletop.cli.output import check_output_flag
    from tabletop.recording import check_output, save_recording
    from tabletop.sim.ground_truth import GroundTruth
    from tabletop.sim.room_scan import RoomScanConfig, scan_room

    check_output_flag("--out", args.out, directory=True)  # before the scan, not after it
    check_output(args.out, args.overwrite)
    spec = _room(args)
    tables = _tables(args, spec)
    config = RoomScanConfig(
        seed=args.seed,
        rate_hz=args.rate,
        episodes=args.episodes,
        tables=tables,
        views_per_table=args.views,
        look_around=not args.no_look_around,
        renderer=args.renderer,
    )
    with ProgressBars() as bars:
        report = bars.stage(f"scan {spec.name}")
        rec, stats = scan_room(spec, config, progress=lambda n: report(n, n))
    t0 = time.perf_counter()
    save_recording(rec, args.out, overwrite=args.overwrite)
    write_s = time.perf_counter() - t0
    w, h = rec.image_size
    print(f"room:             {spec.name} ({len(spec.furniture)} items, {len(spec.tables)} tables)")
    print(
        f"frames recorded:  {len(rec)} at {w}x{h}, {stats.simulated_s:.1f} s of simulated time "
        f"({config.rate_hz:g} Hz); {stats.distance_m:.1f} m driven, {stats.collisions} collisions"
    )
    print(f"wall time:        {stats.wall_s:.1f} s (rendering {stats.render_s:.1f} s)")
    print(f"written:          {args.out} in {write_s:.1f} s")
    events = GroundTruth.of(rec).sound_events
    if events:
        print(
            f"sounds inserted:  {len(events)}: "
            + ", ".join(f"{e.category}@{e.place}" for e in events)
        )
    return 0


def _add_room_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--generate",
        type=int,
        metavar="SEED",
        help="a room drawn by the seeded generator instead of a spec",
    )


def add_commands(sub) -> None:
    """Register ``rooms`` and ``scan-room`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser("rooms", help="list shipped rooms, or print one (or a generated one)")
    p.add_argument("room", nargs="?", help="a room spec path or shipped room name")
    _add_room_args(p)
    p.set_defaults(func=cmd_rooms)

    p = sub.add_parser("scan-room", help="record a room scan with the wheeled base")
    p.add_argument(
        "--room",
        default=None,
        help="room spec (.toml/.json) or the name of a shipped room (default: default)",
    )
    _add_room_args(p)
    p.add_argument("--seed", type=int, default=0, help="seed of the sound placement")
    p.add_argument("--rate", type=float, default=30.0, help="frame rate [Hz] (default 30)")
    p.add_argument("--episodes", type=int, default=3, help="audio episodes at tables")
    p.add_argument("--tables", help="comma-separated tables to visit (default: all)")
    p.add_argument("--views", type=int, default=2, help="viewpoints per large table")
    p.add_argument("--no-look-around", action="store_true", help="skip the final turn")
    p.add_argument("--renderer", default="auto", choices=["auto", "egl", "tiny"])
    p.add_argument("--out", required=True, help="output recording directory")
    p.add_argument("--overwrite", action="store_true", help="replace an existing recording")
    p.set_defaults(func=cmd_scan_room)

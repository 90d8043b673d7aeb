"""``tabletop scan``, ``tabletop scenes`` and ``tabletop sounds``: record scans, list the shipped
scenes, describe the sound bank."""

from __future__ import annotations

import argparse
import json
import time

from tabletop.cli.progress import ProgressBars

__all__ = ["add_commands", "cmd_scan", "cmd_scenes", "cmd_sounds", "format_bank_table"]


# ---------------------------------------------------------------------- scan
def _add_scan_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--scene",
        default="default",
        help="scene spec (.toml/.json) or the name of a shipped scene (default: default)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the sweep and sound placement")
    p.add_argument("--episodes", type=int, default=6, help="audio episodes after the sweep")
    p.add_argument("--renderer", default="auto", choices=["auto", "egl", "tiny"])
    p.add_argument("--width", type=int, default=320, help="image width [px] (320 to 1920)")
    p.add_argument("--height", type=int, default=240, help="image height [px] (240 to 1440)")
    p.add_argument(
        "--pose-noise",
        type=float,
        default=0.0,
        metavar="M",
        help="std of end-effector position noise [m]",
    )
    p.add_argument(
        "--rot-noise",
        type=float,
        default=0.0,
        metavar="RAD",
        help="std of end-effector orientation noise [rad]",
    )
    p.add_argument(
        "--depth-noise",
        type=float,
        default=0.0,
        metavar="R",
        help="depth noise std relative to depth^2 [1/m]",
    )
    p.add_argument(
        "--depth-dropout",
        type=float,
        default=0.0,
        metavar="P",
        help="fraction of depth pixels dropped",
    )
    p.add_argument(
        "--drop-frames",
        type=float,
        default=0.0,
        metavar="P",
        help="probability that a frame is lost",
    )
    p.add_argument("--noise-seed", type=int, default=0)


def _scan_config(args: argparse.Namespace):
    from tabletop.errors import ConfigError
    from tabletop.sim.camera import WristCameraConfig
    from tabletop.sim.scan import NoiseConfig, ScanConfig

    noise = NoiseConfig(
        seed=args.noise_seed,
        pose_translation_m=args.pose_noise,
        pose_rotation_rad=args.rot_noise,
        depth_relative=args.depth_noise,
        depth_dropout=args.depth_dropout,
        drop_frames=args.drop_frames,
    )
    try:
        camera = WristCameraConfig(width=args.width, height=args.height)
    except ConfigError as e:
        raise ConfigError(f"--width {args.width} --height {args.height}: {e}") from None
    return ScanConfig(
        seed=args.seed,
        episodes=args.episodes,
        renderer=args.renderer,
        camera=camera,
        noise=noise,
        repeat_sounds=min(1, args.episodes // 2),
    )


def _do_scan(args: argparse.Namespace):
    from tabletop.sim.scan import run_scan
    from tabletop.sim.scene import load_scene_spec

    spec = load_scene_spec(args.scene)
    config = _scan_config(args)
    with ProgressBars() as bars:
        rec, stats = run_scan(spec, config, progress=bars.stage(f"scan {spec.name}"))
    return spec, rec, stats


def cmd_scan(args: argparse.Namespace) -> int:
    from tabletop.cli.output import check_output_flag
    from tabletop.recording import check_output, save_recording
    from tabletop.sim.ground_truth import GroundTruth

    check_output_flag("--out", args.out, directory=True)  # before the scan, not after it
    check_output(args.out, args.overwrite)
    spec, rec, stats = _do_scan(args)
    t0 = time.perf_counter()
    save_recording(rec, args.out, overwrite=args.overwrite)
    write_s = time.perf_counter() - t0
    w, h = rec.image_size
    print(f"scene:            {spec.name} ({len(spec.objects)} objects)")
    print(
        f"frames recorded:  {len(rec)} at {w}x{h}, {stats.simulated_s:.1f} s of simulated time "
        f"(30 Hz)"
    )
    print(
        f"frames/s:         {stats.fps:.1f} (scan: IK, collision checks and rendering; "
        f"renderer {rec.meta['renderer']}); render alone {len(rec) / stats.render_s:.1f}"
    )
    print(f"written:          {args.out} in {write_s:.1f} s")
    events = () if rec.ground_truth is None else GroundTruth.of(rec).sound_events
    if events:
        print(
            f"sounds inserted:  {len(events)}: "
            + ", ".join(
                f"{e.category}@({e.table_point[0]:.2f},{e.table_point[1]:.2f})" for e in events
            )
        )
    return 0


# ---------------------------------------------------------------------- sounds
def format_bank_table(bank) -> str:
    """A human-readable table of a :class:`~tabletop.sim.SoundBank`: one row per category
    (clips per split, licences, caption), then clips per licence and per source."""
    s = bank.summary()
    width = max(len("category"), *(len(c) for c in s["categories"]))
    lines = [
        f"sound bank {s['name']!r}: {s['n_clips']} clips in {s['n_categories']} categories "
        f"({s['n_train']} train, {s['n_heldout']} heldout), {s['sample_rate']} Hz mono, "
        f"{s['total_duration_s']:.1f} s in all",
        "",
        f"{'category':<{width}}  train  heldout  licences / caption",
    ]
    for cat, row in s["categories"].items():
        lines.append(
            f"{cat:<{width}}  {row['train']:>5}  {row['heldout']:>7}  "
            f"{', '.join(row['licences'])} / {row['caption']}"
        )
    lines += ["", "licences:"]
    lines += [f"  {lic:<20} {n:>4} clips" for lic, n in s["licences"].items()]
    lines += ["sources:"]
    lines += [f"  {src:<28} {n:>4} clips" for src, n in s["sources"].items()]
    return "\n".join(lines)


def cmd_sounds(args: argparse.Namespace) -> int:
    from tabletop.sim.esc50 import load_esc50
    from tabletop.sim.sound_bank import SoundBank

    if args.esc50 is not None and not args.esc50.strip():
        from tabletop.errors import ConfigError

        raise ConfigError(
            f"--esc50 {args.esc50!r} is empty: give an ESC-50 directory (audio/*.wav and "
            "meta/esc50.csv in it), or leave --esc50 out for the shipped sound bank"
        )
    bank = load_esc50(args.esc50) if args.esc50 is not None else SoundBank.default()
    if args.json:
        print(json.dumps(bank.summary(), indent=1))
    else:
        print(format_bank_table(bank))
    return 0


# ---------------------------------------------------------------------- scenes
def cmd_scenes(args: argparse.Namespace) -> int:
    from tabletop.sim.scene import list_default_scenes, load_scene_spec

    if args.scene is None:
        for name in list_default_scenes():
            spec = load_scene_spec(name)
            print(
                f"{name:12s} {len(spec.objects)} objects: "
                + ", ".join(o.label for o in spec.objects)
            )
        return 0
    spec = load_scene_spec(args.scene)
    print(json.dumps(spec.to_dict(), indent=1))
    return 0


# ---------------------------------------------------------------------- registration
def add_commands(sub) -> None:
    """Register ``scan``, ``scenes`` and ``sounds`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser("scan", help="record a teleop-style scan of a scene")
    _add_scan_args(p)
    p.add_argument("--out", required=True, help="output recording directory")
    p.add_argument("--overwrite", action="store_true", help="replace an existing recording")
    p.set_defaults(func=cmd_scan)

    p = sub.add_parser("scenes", help="list shipped scenes, or print one spec")
    p.add_argument("scene", nargs="?", help="a spec path or shipped scene name")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("sounds", help="list the sound bank's categories, clips and licences")
    p.add_argument("--esc50", metavar="DIR", help="describe an ESC-50 directory instead")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_sounds)

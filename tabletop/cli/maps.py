"""``tabletop build-map`` and ``tabletop query``: fuse a recording into an AVLMap, query it."""

from __future__ import annotations

import argparse
import sys
import time

from tabletop.cli.output import check_output_flag
from tabletop.cli.progress import ProgressBars
from tabletop.reader.reading import DEFAULT_READER, READERS

__all__ = ["MIN_MAP_VOXELS", "MIN_PIXELS_PER_FRAME", "add_commands", "cmd_build_map", "cmd_query"]

MIN_PIXELS_PER_FRAME = 100
"""``--pixel-step`` must keep at least this many pixels of each frame (320x240 at the default
step 3 keeps 8560); fewer leaves a map of a few dozen voxels."""
MIN_MAP_VOXELS = 1000
"""A map of fewer occupied voxels is reported as too sparse to answer queries (a scan of the
default table at 1 cm keeps about 19 000)."""


def _check_pixel_step(step: int, width: int, height: int) -> None:
    """``--pixel-step`` keeps at least :data:`MIN_PIXELS_PER_FRAME` pixels of a frame of
    ``width`` x ``height`` px: else :class:`ConfigError` naming the largest step that does."""
    from tabletop.errors import ConfigError

    def kept(s: int) -> int:
        return -(-width // s) * -(-height // s)

    if step >= 1 and kept(step) < MIN_PIXELS_PER_FRAME:
        largest = max(
            (s for s in range(1, max(width, height) + 1) if kept(s) >= MIN_PIXELS_PER_FRAME),
            default=1,
        )
        raise ConfigError(
            f"--pixel-step {step} keeps {kept(step)} pixels of each {width}x{height} frame, fewer "
            f"than {MIN_PIXELS_PER_FRAME}: the map would hold a few dozen voxels; valid: 1 to "
            f"{largest} for this recording (default 3)"
        )


def cmd_build_map(args: argparse.Namespace) -> int:
    from tabletop.errors import ConfigError
    from tabletop.eval.harness import build_map, build_map_online, map_config
    from tabletop.mapping.persistence import check_map_output
    from tabletop.recording import load_recording, read_header

    given = [f for f, v in (("--rate", args.rate), ("--drop", args.drop)) if v is not None]
    if given and not args.online:
        raise ConfigError(f"{', '.join(given)}: only with --online")
    check_output_flag("--out", args.out)  # before the map is built, not after
    check_map_output(args.out, args.overwrite)
    config = map_config(voxel_size=args.voxel_size, pixel_step=args.pixel_step)
    header = read_header(args.recording)  # the flags are checked before the frames load
    _check_pixel_step(config.pixel_step, int(header["width"]), int(header["height"]))
    print(f"loading {args.recording} ...", file=sys.stderr)
    rec = load_recording(args.recording)
    t0 = time.perf_counter()
    report = None
    with ProgressBars() as bars:
        stage = bars.stage(f"map ({args.encoders} encoders{', online' if args.online else ''})")
        if args.online:
            rate = 1.0 if args.rate is None else args.rate
            m, report = build_map_online(
                rec, args.encoders, config, rate=rate, drop=args.drop or "none", progress=stage
            )
        else:
            m = build_map(rec, args.encoders, config, progress=stage)
    wall = time.perf_counter() - t0
    path = m.save(args.out)
    st = m.stats
    print(f"encoders:  {m.encoder_names.get('set', args.encoders)}")
    print(f"frames:    {st.frames} ({st.fused_frames} fused), {wall:.1f} s in all")
    if report is not None:
        r = report
        print(
            f"online:    camera {r.camera_fps:.1f} frames/s; {r.fused} of {r.frames} frames "
            f"given to the map, {r.dropped} dropped (--drop {args.drop or 'none'}); lag median "
            f"{r.lag_median_s * 1e3:.0f} ms, p95 {r.lag_p95_s * 1e3:.0f} ms, max "
            f"{r.lag_max_s * 1e3:.0f} ms; keeps up: {'yes' if r.keeps_up else 'no'}"
        )
    print(f"encoder:   {st.frames / max(st.encoder_s, 1e-9):.1f} frames/s")
    print(f"fusion:    {st.fused_frames / max(st.fusion_s, 1e-9):.1f} frames/s (encoder excluded)")
    print(
        f"map:       {st.voxels} occupied voxels at {config.grid.voxel_size * 100:g} cm, "
        f"{m.voxels.nbytes / 1e6:.1f} MB; {st.audio_segments} audio segments"
    )
    if m.visual is not None:
        print(
            f"visual:    {st.reference_frames} reference frames ({m.visual.config.matcher} "
            f"features, {st.visual_s:.1f} s)"
        )
    print(f"written:   {path}")
    if st.voxels < MIN_MAP_VOXELS:
        print(
            f"tabletop build-map: warning: the map holds {st.voxels} occupied voxels, fewer than "
            f"{MIN_MAP_VOXELS}: too sparse to answer queries reliably (a smaller --pixel-step or "
            "--voxel-size, or a recording that sees more of the table)",
            file=sys.stderr,
        )
        return 1
    return 0


def _query_reader(args: argparse.Namespace, get_reader):
    """``--reader``; the llm reader's endpoint from ``--llm-config``, ``--llm-url`` and
    ``--llm-model`` or the ``TABLETOP_LLM_*`` environment variables."""
    from tabletop.errors import ConfigError

    given = [f for f, v in (("--llm-url", args.llm_url), ("--llm-model", args.llm_model),
                            ("--llm-config", args.llm_config)) if v is not None]  # fmt: skip
    if args.reader != "llm":
        if given:
            raise ConfigError(f"{', '.join(given)}: only with --reader llm")
        return get_reader(args.reader)  # an unknown name is refused
    from tabletop.reader.llm import LLMReader
    from tabletop.reader.llm_client import LLMConfig

    print(
        "reader llm: a query's words are read here (spelling, places); the endpoint reads "
        "whole instructions (tabletop run)",
        file=sys.stderr,
    )
    if args.llm_config:
        config = LLMConfig.from_file(args.llm_config).with_overrides(
            base_url=args.llm_url, model=args.llm_model
        )
    else:
        config = LLMConfig.from_env(base_url=args.llm_url, model=args.llm_model)
    return LLMReader(config)


def cmd_query(args: argparse.Namespace) -> int:
    from tabletop.errors import ConfigError
    from tabletop.mapping import AVLMap, fuse
    from tabletop.mapping.render import heatmap_view_paths, write_heatmap_views
    from tabletop.reader.reading import get_reader
    from tabletop.robot.api import RobotAPI

    # (the flag's name, its modality, whether it is the major part), majors first
    given = [
        (prefix + k, k, not prefix)
        for prefix in ("", "near_")
        for k in ("obj", "sound", "area", "img")
        if getattr(args, prefix + k) is not None
    ]
    if given and not any(major for _, _, major in given):
        # a landmark alone would send the robot to the landmark
        nears = ", ".join("--" + dest.replace("_", "-") for dest, _, _ in given)
        raise ConfigError(
            f"{nears} only narrows a target: give what to find near it with one "
            "of --obj, --sound, --area, --img"
        )
    if args.out is not None:  # before the map is loaded and queried
        existing = [p for p in heatmap_view_paths(args.out, what="--out") if p.exists()]
        if existing and not args.overwrite:
            raise ConfigError(
                f"--out {args.out!r}: {', '.join(str(p) for p in existing)} already "
                "exist; pass --overwrite to replace them, or another prefix"
            )
    if args.encoders is not None:  # before the map is loaded
        from tabletop.mapping.persistence import check_map_encoders

        check_map_encoders(args.map, args.encoders)
    reader = _query_reader(args, get_reader)  # refused before the map is loaded
    m = AVLMap.load(args.map)
    parts = []
    for dest, modality, major in given:
        q = getattr(args, dest)
        # the words of a reference are read by the one reader every caller asks
        value = RobotAPI.load_image(q) if modality == "img" else reader.reference(modality, q)
        parts.append(m.query(modality, value, major))
    if not parts:
        print("tabletop query: give at least one of --obj, --sound, --area, --img", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    fused = fuse(*parts)
    target = m.get_max_pos_3d(fused) if fused.found else None
    dt = time.perf_counter() - t0
    print(f"encoders: {m.encoder_names.get('set', m.encoder_set)}")
    for h in parts:
        status = "found" if h.found else f"NOT FOUND ({h.reason})"
        print(
            f"  {h.modality:6s} {h.query!r:40s} decay {h.decay:g}/m  "
            f"confidence {h.confidence:.2f}  {status}"
        )
        if h.modality == "image" and h.found:
            print(
                f"         the image shows x={h.target[0]:.3f} y={h.target[1]:.3f} "
                f"z={h.target[2]:.3f} m (world frame); its pose agrees with the map's "
                f"colours beyond chance by kappa {h.evidence:.2f}"
            )
    if target is None:
        print(f"target:   none, not found ({fused.reason})")
        return 1
    print(
        f"target:   x={target[0]:.3f} y={target[1]:.3f} z={target[2]:.3f} m (world frame)"
        f"   fusion+argmax {dt * 1000:.1f} ms"
    )
    if args.out is not None:
        for p in write_heatmap_views(m, fused.values, args.out, target):
            print(f"picture:  {p}")
    return 0


# ---------------------------------------------------------------------- registration
def add_commands(sub) -> None:
    """Register ``build-map`` and ``query`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser("build-map", help="fuse a recording into an AVLMap")
    p.add_argument("recording", help="recording directory (tabletop scan --out ...)")
    p.add_argument("--out", required=True, help="map file (.npz)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing map file")
    p.add_argument(
        "--encoders",
        default="oracle",
        choices=["oracle", "default"],
        help="encoder set (oracle = simulator upper bound)",
    )
    p.add_argument(
        "--voxel-size",
        type=float,
        default=0.01,
        help="voxel size [m], 0.001 to 0.2 (default 0.01; the shipped figures use 0.01 and 0.005)",
    )
    p.add_argument("--pixel-step", type=int, default=3, help="fuse every n-th pixel row/column")
    p.add_argument(
        "--online",
        action="store_true",
        help="replay the recording's frames as the camera delivered them and report how far "
        "the map lags (no table registration: it needs the whole scan)",
    )
    p.add_argument(
        "--rate",
        type=float,
        help="with --online: replay speed, 1 = as recorded (default), 2 = twice as fast",
    )
    p.add_argument(
        "--drop",
        choices=["none", "late"],
        help="with --online: 'none' fuses every frame however late (default); 'late' skips a "
        "frame when the next has already arrived",
    )
    p.set_defaults(func=cmd_build_map)

    p = sub.add_parser("query", help="query a map; print the target and write heatmap pictures")
    p.add_argument("map", help="map file (.npz)")
    p.add_argument("--obj", help="object description (primary, sharp heatmap)")
    p.add_argument("--sound", help="sound description (primary)")
    p.add_argument("--area", help="area description (primary)")
    p.add_argument("--img", help="image of the table (PNG/JPEG from the wrist camera; primary)")
    p.add_argument("--near-obj", help="object the target is near (auxiliary, broad)")
    p.add_argument("--near-sound", help="sound the target is near (auxiliary)")
    p.add_argument("--near-area", help="area the target is in (auxiliary)")
    p.add_argument("--near-img", help="image of a place the target is near (auxiliary)")
    p.add_argument(
        "--encoders",
        choices=["oracle", "default"],
        help="the encoder set the map must have been built with (refused otherwise)",
    )
    p.add_argument("--out", help="picture prefix: writes PREFIX_top.png and PREFIX_side.png")
    p.add_argument("--overwrite", action="store_true", help="replace existing --out pictures")
    p.add_argument(
        "--reader",
        default=DEFAULT_READER,
        help=f"the reader of the words: {', '.join(READERS)} (default: {DEFAULT_READER})",
    )
    p.add_argument("--llm-url", help="with --reader llm: chat endpoint root (or env var "
                   "TABLETOP_LLM_BASE_URL), e.g. http://127.0.0.1:8000/v1")  # fmt: skip
    p.add_argument("--llm-model", help="with --reader llm: model name the endpoint serves (or "
                   "env var TABLETOP_LLM_MODEL)")  # fmt: skip
    p.add_argument(
        "--llm-config",
        metavar="FILE",
        help="with --reader llm: TOML file with an [llm] table (base_url, model, api_key_env, "
        "timeout_s)",
    )
    p.set_defaults(func=cmd_query)

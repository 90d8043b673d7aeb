"""``tabletop bench``: performance figures of the scan, the map and the arm, in one run."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import sys
import tempfile
from pathlib import Path

from tabletop.cli.output import stdout_to_stderr

__all__ = ["add_commands", "cmd_bench"]


#: Most reach targets of ``--arm-targets`` (50 times the default).
MAX_ARM_TARGETS = 10_000


def _machine() -> dict:
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "processor": platform.processor() or platform.machine(),
    }


def cmd_bench(args: argparse.Namespace) -> int:
    if args.room_images:
        from tabletop.eval.room_bench import run_room_image_benchmark

        with stdout_to_stderr() if args.json else contextlib.nullcontext():
            results = {"machine": _machine(), **run_room_image_benchmark()}
        if args.json:
            print(json.dumps(results, indent=1))
        else:
            _print_room_images(results)
        return 0
    if args.viewer:
        with stdout_to_stderr() if args.json else contextlib.nullcontext():
            results = {"machine": _machine(), **_viewer_bench(None)}
        if args.json:
            print(json.dumps(results, indent=1))
        else:
            _print_viewer(results)
        return 0
    if not 1 <= args.arm_targets <= MAX_ARM_TARGETS:  # before the scan and the map
        print(
            f"tabletop bench: --arm-targets {args.arm_targets}: valid an integer >= 1 and at "
            f"most {MAX_ARM_TARGETS} (default 200)",
            file=sys.stderr,
        )
        return 2
    # --json: native libraries' banners (the EGL plugin's) must not reach stdout
    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        results = _bench(args)
    if args.json:
        print(json.dumps(results, indent=1))
        return 0
    _print_bench(results)
    return 0


def _bench(args: argparse.Namespace) -> dict:
    from tabletop.arm.bench import run_arm_benchmark
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec

    results: dict = {"machine": _machine()}
    print("bench: scanning the default scene ...", file=sys.stderr)
    spec = load_scene_spec("default")
    rec, stats = run_scan(spec, ScanConfig(seed=0, episodes=2, repeat_sounds=0))
    results.update(
        {
            "scan_frames": len(rec),
            "scan_fps": round(stats.fps, 2),
            "scan_render_fps": round(len(rec) / stats.render_s, 2),
            "scan_image_size": list(rec.image_size),
            "renderer": rec.meta["renderer"],
        }
    )
    print("bench: map (oracle encoders) and its references ...", file=sys.stderr)
    from tabletop.mapping.bench import run_map_benchmark

    with tempfile.TemporaryDirectory() as tmp:
        saved = Path(tmp) / "default-1cm.npz"
        results.update(run_map_benchmark(rec, save_to=saved))
        results.update(_viewer_bench(saved))
    print("bench: readers ...", file=sys.stderr)
    from tabletop.reader.bench import run_reader_benchmark

    results.update(run_reader_benchmark())
    print(f"bench: arm, {args.arm_targets} seeded reach targets ...", file=sys.stderr)
    arm = run_arm_benchmark(n_targets=args.arm_targets, seed=0)
    results.update(
        {f"reach_{k}" if k in ("n_targets", "reachable", "seed") else k: v for k, v in arm.items()}
    )
    return results


#: The default table's scan of the viewer's figure when it runs alone (``--viewer``): the
#: bench's own scan, through the evaluation cache.
VIEWER_SCAN = {"seed": 0, "episodes": 2, "repeat_sounds": 0}


def _viewer_bench(map_path) -> dict:
    """The viewer's time to first picture on a 1 cm map of the default table (``map_path``; None:
    the bench's scan of the default table, mapped with the oracle encoders, from the cache)."""
    print("bench: viewer, time to first picture in headless chromium ...", file=sys.stderr)
    try:
        import viser  # noqa: F401
    except ImportError:
        return {"viewer_skipped": "the viewer extra is not installed (pip install -e '.[viewer]')"}
    from tabletop.viewer.bench import time_to_first_picture

    if map_path is not None:
        return time_to_first_picture(map_path)
    from tabletop.eval.harness import DEFAULT_CACHE_DIR, scene_map
    from tabletop.sim.scene import load_scene_spec

    _, m = scene_map(load_scene_spec("default"), VIEWER_SCAN, "oracle", cache_dir=DEFAULT_CACHE_DIR)
    with tempfile.TemporaryDirectory() as tmp:
        return time_to_first_picture(m.save(Path(tmp) / "default-1cm.npz"))


def _print_room_images(r: dict) -> None:
    print(f"machine: {r['machine']}")
    print(f"room image queries (oracle map of a short default-room scan; panoramas once: "
          f"{r['room_image_panoramas_s']} s):")  # fmt: skip
    for name, what in (("upright", "upright pictures (the room's setting)"),
                       ("four_turns", "four quarter turns (reference)")):  # fmt: skip
        print(
            f"  {what}: {r[f'room_image_{name}_s_median']} s median, "
            f"{r[f'room_image_{name}_s_max']} s max; found at "
            f"{r[f'room_image_{name}_error_m']} m from where each was taken"
        )
    print(f"  ratio upright / four turns: {r['room_image_ratio']} (aim: <= 2 s a query)")


def _print_viewer(r: dict) -> None:
    if "viewer_skipped" in r:
        print(f"viewer: skipped: {r['viewer_skipped']}")
        return
    print(
        f"viewer: first picture of a {r['viewer_voxel_size_m'] * 100:g} cm map of the default "
        f"table ({r['viewer_voxels']} voxels) {r['viewer_first_picture_s']} s after `tabletop "
        f"view` started, the browser opening it the first time (served after "
        f"{r['viewer_served_s']} s, drawn {r['viewer_drawn_s']} s after the page was asked for); "
        f"{r['viewer_first_picture_warm_s']} s the second time (its scripts cached: served "
        f"{r['viewer_served_warm_s']} s, drawn {r['viewer_drawn_warm_s']} s); aim 3 s; "
        f"{r['viewer_browser']}"
    )


def _print_bench(results: dict) -> None:
    m = results["machine"]
    r = results
    print(f"machine: {m['cpus']} cpus, {m['platform']}, python {m['python']}")
    print(
        f"scan:  {r['scan_frames']} frames at {r['scan_image_size'][0]}x{r['scan_image_size'][1]}: "
        f"{r['scan_fps']} frames/s end to end (IK, clearance checks, rendering), "
        f"{r['scan_render_fps']} frames/s rendering alone ({r['renderer']})"
    )
    print(
        f"encoders: {r['encoder']} {r['encoder_fps']} frames/s (dense + global, one pass); "
        f"audio {r['audio_encoder_ms_per_1s']} ms per 1 s segment (one thread; budget 5 ms; "
        f"the log-mel network {r.get('audio_melcnn_ms_per_1s')} ms); "
        f"oracle "
        f"{r['oracle_encoder_fps']} frames/s"
    )
    print(
        f"map:   fusion {r['fusion_fps']} frames/s at 1 cm without the encoder "
        f"(x{r['fusion_speedup']} the per-point loop reference, {r['fusion_reference_fps']} "
        f"frames/s; mean features within {r['fusion_reference_max_abs_diff']:.1e} of it; aim "
        f"400 frames/s); object query {r['query_ms']} ms (x{r['query_speedup']} the O(N*M) loop, "
        f"{r['query_reference_ms']} ms; max difference {r['query_reference_max_abs_diff']:.1e}); "
        f"sound query {r['sound_query_ms']} ms ({r['sound_query_ms_p95']} p95), area "
        f"{r['area_query_ms']} ms ({r['area_query_ms_p95']} p95), image {r['image_query_ms']} "
        f"ms ({r['image_query_ms_p95']} p95), each with its target, on this oracle map "
        f"(aim 2 ms for object, sound and area); map {r['map_mb']} MB"
    )
    readers = sorted({k[len("reader_") : -len("_ms_median")] for k in r if k.endswith("_ms_median")
                      and k.startswith("reader_") and k != "reader_places_ms_median"})  # fmt: skip
    print(
        "reader: "
        + "; ".join(
            f"{n} {r[f'reader_{n}_ms_median']} ms median ({r[f'reader_{n}_ms_p95']} p95, "
            f"refused {r[f'reader_{n}_refused']})"
            for n in readers
        )
        + f" per request, one thread; places {r.get('reader_places_ms_median')} ms median "
        f"({r.get('reader_places_ms_p95')} p95) per area phrase; "
        f"words listed by hand: rules {r['listed_words_rules']}, "
        f"place_words {r['listed_words_place_words']}, colour_words "
        f"{r['listed_words_colour_words']}, the lexicon {r['listed_words_lexicon']}"
    )
    print(
        f"arm:   {r['reach_n_targets']} targets, {r['reach_reachable']} reachable: "
        f"{r['reach_within_1cm']:.1%} within 1 cm, objects within 10 cm "
        f"{r['object_within_10cm']:.1%}, contacts {r['contacts']}, "
        f"probes with the right reason {r['probes_right_reason']}"
    )
    print(f"       reasons {r['reasons']}")
    print(
        f"       routes {r['routes']}: global-planner fallback on {r['fallback_share']:.1%} of "
        f"the reaches that moved ({r['fallback_reached']} of them reached); planning "
        f"{r['planning_ms_median']:.0f} ms median ({r['planning_ms_p95']:.0f} p95); "
        f"alternative goals {r['alternative_goals']}"
    )
    print(
        f"       mink IK step {r['ik_step_ms_median']:.3f} ms median "
        f"({r['ik_step_ms_p95']:.3f} p95); collision check "
        f"{r['collision_check_ms_median']:.3f} ms ({r['collision_check_ms_p95']:.3f} p95); "
        f"together {r['ik_plus_collision_ms_median']:.3f} ms"
    )
    print(
        f"       DLS reference {r['dls_iter_ms_median']:.3f} ms per iteration "
        f"(mink step / DLS iteration = {r['mink_over_dls_ratio']:.2f}); a whole reach "
        f"{r['reach_s_median']:.2f} s median ({r['reach_s_p95']:.2f} p95)"
    )
    _print_viewer(r)


def add_commands(sub) -> None:
    """Register ``bench`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser("bench", help="performance figures of every part, in one run")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument(
        "--arm-targets",
        type=int,
        default=200,
        help=f"reach targets, 1 to {MAX_ARM_TARGETS} (default 200)",
    )
    p.add_argument(
        "--viewer",
        action="store_true",
        help="only the viewer's time to first picture (1 cm map of the default table, headless "
        "chromium; the viewer extra)",
    )
    p.add_argument(
        "--room-images",
        action="store_true",
        help="only image queries on a room map (a short scan of the default room, three "
        "pictures taken off its path), upright-only matching against all four turns",
    )
    p.set_defaults(func=cmd_bench)

"""The `tabletop` command line: scan scenes, inspect the sound bank, run the demo and benchmarks."""

from __future__ import annotations

import argparse
import json
import logging
import platform
import sys
import time
from pathlib import Path

from tabletop.errors import TabletopError

log = logging.getLogger("tabletop")


def _progress(desc: str, total: int | None = None):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="frame", dynamic_ncols=True, file=sys.stderr)


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
    p.add_argument("--width", type=int, default=320, help="image width [px] (>= 320)")
    p.add_argument("--height", type=int, default=240, help="image height [px] (>= 240)")
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
    camera = WristCameraConfig(width=args.width, height=args.height)
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
    bar = _progress(f"scan {spec.name}")

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        rec, stats = run_scan(spec, config, progress=progress)
    finally:
        bar.close()
    return spec, rec, stats


def cmd_scan(args: argparse.Namespace) -> int:
    from tabletop.sim.recording import save_recording

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
    events = (rec.ground_truth or {}).get("sound_events", [])
    if events:
        print(
            f"sounds inserted:  {len(events)}: "
            + ", ".join(
                f"{e['category']}@({e['table_point'][0]:.2f},{e['table_point'][1]:.2f})"
                for e in events
            )
        )
    return 0


# ---------------------------------------------------------------------- maps
def cmd_build_map(args: argparse.Namespace) -> int:
    from tabletop.mapping.avlmap import AVLMap, MapConfig
    from tabletop.mapping.grid import VoxelGrid
    from tabletop.sim.recording import load_recording

    print(f"loading {args.recording} ...", file=sys.stderr)
    rec = load_recording(args.recording)
    config = MapConfig(grid=VoxelGrid(voxel_size=args.voxel_size), pixel_step=args.pixel_step)
    bar = _progress(f"map ({args.encoders} encoders)", total=len(rec))
    t0 = time.perf_counter()
    try:
        m = AVLMap.build(
            rec, config, encoders=args.encoders, progress=lambda d, t: bar.update(d - bar.n)
        )
    finally:
        bar.close()
    wall = time.perf_counter() - t0
    path = m.save(args.out)
    st = m.stats
    print(f"encoders:  {m.encoder_names.get('set', args.encoders)}")
    print(f"frames:    {st.frames} ({st.fused_frames} fused), {wall:.1f} s in all")
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
    return 0


def cmd_query(args: argparse.Namespace) -> int:
    from tabletop.mapping.avlmap import AVLMap
    from tabletop.mapping.heatmaps import fuse
    from tabletop.mapping.render import write_heatmap_views
    from tabletop.robot.api import RobotAPI

    m = AVLMap.load(args.map)
    parts = []
    for kind, major in (
        ("obj", True),
        ("sound", True),
        ("area", True),
        ("img", True),
        ("near_obj", False),
        ("near_sound", False),
        ("near_area", False),
        ("near_img", False),
    ):
        q = getattr(args, kind)
        if q is None:
            continue
        modality = kind.removeprefix("near_")
        if modality == "img":
            parts.append(m.image_heatmap(RobotAPI.load_image(q), major=major))
            continue
        fn = {"obj": m.object_heatmap, "sound": m.sound_heatmap, "area": m.area_heatmap}[modality]
        parts.append(fn(q, major=major))
    if not parts:
        print("tabletop query: give at least one of --obj, --sound, --area, --img", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    fused = fuse(*[h.values for h in parts])
    target = m.get_max_pos_3d(fused)
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
    if not all(h.found for h in parts):
        print("target:   none (a part of the query matches nothing in the map)")
        return 1
    print(
        f"target:   x={target[0]:.3f} y={target[1]:.3f} z={target[2]:.3f} m (world frame)"
        f"   fusion+argmax {dt * 1000:.1f} ms"
    )
    if args.out:
        for p in write_heatmap_views(m, fused, args.out, target):
            print(f"picture:  {p}")
    return 0


def cmd_eval_map(args: argparse.Namespace) -> int:
    import contextlib

    from tabletop.eval.cli import stdout_to_stderr
    from tabletop.eval.map_goals import run_map_eval

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


def cmd_check_encoders(args: argparse.Namespace) -> int:
    """Measure the committed weights on held-out data (figures are null where a learned
    encoder does not exist yet: never a stand-in value)."""
    from tabletop.train.audio import evaluate_audio

    out = {"vision_top1_heldout": None, "vision_miou_heldout": None, "vision_synonym_top1": None}
    try:
        from tabletop.train.vision import evaluate_vision
    except ImportError:
        evaluate_vision = None
    import contextlib

    from tabletop.eval.cli import stdout_to_stderr

    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        if evaluate_vision is not None:
            out.update({k: v for k, v in evaluate_vision().items() if k.startswith("vision_")})
        a = evaluate_audio()
    out.update({k: v for k, v in a.items() if k.startswith("audio_")})
    out["encoders"] = "embedded default (learned; held-out data)"
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    for k, v in out.items():
        shown = (
            "not available in this version"
            if v is None
            else (f"{v:.3f}" if isinstance(v, float) else v)
        )
        print(f"{k:36s} {shown}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    if args.what == "audio":
        from tabletop.train.audio import AudioTrainConfig, train_audio

        path = train_audio(AudioTrainConfig())
    else:
        try:
            from tabletop.train.vision import VisionTrainConfig, train_vision
        except ImportError:
            print(
                "tabletop train vision: the vision encoder's training is not in this version",
                file=sys.stderr,
            )
            return 2
        path = train_vision(VisionTrainConfig())
    print(f"weights written: {path}")
    return 0


# ---------------------------------------------------------------------- sounds
def cmd_sounds(args: argparse.Namespace) -> int:
    from tabletop.sim.sound_bank import SoundBank, load_esc50

    bank = load_esc50(args.esc50) if args.esc50 else SoundBank.default()
    if args.json:
        print(json.dumps(bank.summary(), indent=1))
    else:
        print(bank.format_table())
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


# ---------------------------------------------------------------------- demo
def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: scan the default scene, map it with the embedded default encoders, run
    the demo suite (a few goals of every type) with the simulated arm, print the table and
    write the report."""
    from tabletop.eval.cli import print_result
    from tabletop.eval.runner import run_eval

    out = Path(args.out)
    encoders = [e.strip() for e in args.encoders.split(",") if e.strip()]
    print(
        "tabletop demo: default scene -> teleop scan with inserted sounds -> AVLMap with the "
        f"encoders {encoders} -> the demo suite (object, sound, image, area, ambiguous, "
        "spatial, multimodal spatial and instruction goals) reached by the simulated Panda.\n"
        "'default' = the embedded learned encoders (MiniLM text, the small LSeg-style image "
        "network, the mel-CNN audio encoder); 'oracle' = the simulator's ground truth, an upper "
        "bound.\n",
        flush=True,
    )
    t0 = time.perf_counter()
    res = run_eval("demo", encoders=encoders, out_dir=out, cache_dir=out / "cache")
    wall = time.perf_counter() - t0
    print()
    print_result(res, wall, " (scan, map, reaches)")
    return 0 if all(r.available for r in res.runs) else 1


# ---------------------------------------------------------------------- calibrate
def cmd_calibrate(args: argparse.Namespace) -> int:
    """Fit the confidence calibration of an encoder set on seeded scenes (first half) and
    report it on the others; writes tabletop/data/calibration/<set>.json (or --out)."""
    from tabletop.mapping.calibration import CALIBRATION_SEEDS, MODALITIES, run_calibration

    keep_prior = [m.strip() for m in args.keep_prior.split(",") if m.strip()]
    bad = sorted(set(keep_prior) - set(MODALITIES))
    if bad:  # before a quarter of an hour of scanning, not after
        print(f"tabletop calibrate: --keep-prior {bad}: valid {list(MODALITIES)}", file=sys.stderr)
        return 2
    seeds = list(CALIBRATION_SEEDS)[: args.scenes] if args.scenes else list(CALIBRATION_SEEDS)
    print(f"calibrating {args.encoders!r} on scenes {seeds} ...", file=sys.stderr)
    cal = run_calibration(
        args.encoders,
        seeds,
        progress=lambda seed, s: print(f"  scene {seed}: {len(s)} queries", file=sys.stderr),
    )
    if keep_prior:
        cal = cal.keep_prior(keep_prior)
    path = cal.save(args.out)
    print(json.dumps(cal.to_json(), indent=1))
    print(f"written {path}", file=sys.stderr)
    return 0


# ---------------------------------------------------------------------- bench
def _machine() -> dict:
    import os

    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "processor": platform.processor() or platform.machine(),
    }


def cmd_bench(args: argparse.Namespace) -> int:
    import contextlib

    from tabletop.eval.cli import stdout_to_stderr

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

    results.update(run_map_benchmark(rec))
    print(f"bench: arm, {args.arm_targets} seeded reach targets ...", file=sys.stderr)
    arm = run_arm_benchmark(n_targets=args.arm_targets, seed=0)
    results.update(
        {f"reach_{k}" if k in ("n_targets", "reachable", "seed") else k: v for k, v in arm.items()}
    )
    return results


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
        f"audio {r['audio_encoder_ms_per_1s']} ms per 1 s segment; oracle "
        f"{r['oracle_encoder_fps']} frames/s"
    )
    print(
        f"map:   fusion {r['fusion_fps']} frames/s at 1 cm without the encoder "
        f"(x{r['fusion_speedup']} the per-point loop reference, {r['fusion_reference_fps']} "
        f"frames/s); object query {r['query_ms']} ms (x{r['query_speedup']} the O(N*M) loop, "
        f"{r['query_reference_ms']} ms; max difference {r['query_reference_max_abs_diff']:.1e}); "
        f"map {r['map_mb']} MB"
    )
    print(
        f"arm:   {r['reach_n_targets']} targets, {r['reach_reachable']} reachable: "
        f"{r['reach_within_1cm']:.1%} within 1 cm, objects within 10 cm "
        f"{r['object_within_10cm']:.1%}, contacts {r['contacts']}, "
        f"probes with the right reason {r['probes_right_reason']}"
    )
    print(f"       reasons {r['reasons']}")
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


# ---------------------------------------------------------------------- main
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tabletop", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log more")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("scan", help="record a teleop-style scan of a scene")
    _add_scan_args(p)
    p.add_argument("--out", required=True, help="output recording directory")
    p.add_argument("--overwrite", action="store_true", help="replace an existing recording")
    p.set_defaults(func=cmd_scan)

    p = sub.add_parser("build-map", help="fuse a recording into an AVLMap")
    p.add_argument("recording", help="recording directory (tabletop scan --out ...)")
    p.add_argument("--out", required=True, help="map file (.npz)")
    p.add_argument(
        "--encoders",
        default="oracle",
        choices=["oracle", "default"],
        help="encoder set (oracle = simulator upper bound)",
    )
    p.add_argument("--voxel-size", type=float, default=0.01, help="voxel size [m] (0.01, 0.005)")
    p.add_argument("--pixel-step", type=int, default=3, help="fuse every n-th pixel row/column")
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
    p.add_argument("--out", help="picture prefix: writes PREFIX_top.png and PREFIX_side.png")
    p.set_defaults(func=cmd_query)

    p = sub.add_parser("eval-map", help="score map goals: object, sound, ambiguous, image")
    p.add_argument("--seeds", type=int, default=3, help="seeds per scene (default 3)")
    p.add_argument("--speed", type=float, default=0.3, help="scan speed [m/s]")
    p.add_argument("--encoders", default="oracle", choices=["oracle", "default"])
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_eval_map)

    p = sub.add_parser("check-encoders", help="measure the committed encoders on held-out data")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_check_encoders)

    p = sub.add_parser("train", help="train an embedded default encoder (seeded)")
    p.add_argument("what", choices=["audio", "vision"])
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("sounds", help="list the sound bank's categories, clips and licences")
    p.add_argument("--esc50", metavar="DIR", help="describe an ESC-50 directory instead")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_sounds)

    p = sub.add_parser("scenes", help="list shipped scenes, or print one spec")
    p.add_argument("scene", nargs="?", help="a spec path or shipped scene name")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("demo", help="the end-to-end demo on the embedded defaults")
    p.add_argument("--out", default="out/demo", help="output directory (default: out/demo)")
    p.add_argument(
        "--encoders",
        default="default",
        help="encoder sets, comma-separated: default, oracle (default: default)",
    )
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("calibrate", help="fit query confidence of an encoder set on seeded scenes")
    p.add_argument("--encoders", default="default", help="encoder set (default: default)")
    p.add_argument("--scenes", type=int, default=0, help="use the first N calibration scenes")
    p.add_argument("--out", default=None, help="file to write (default: the shipped location)")
    p.add_argument(
        "--keep-prior",
        default="",
        help="modalities that keep the prior (comma-separated; their fits go to the report)",
    )
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("bench", help="performance figures of every part, in one run")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--arm-targets", type=int, default=200, help="reach targets (default 200)")
    p.set_defaults(func=cmd_bench)

    from tabletop.language.cli import add_commands as add_language_commands

    add_language_commands(sub)  # tabletop parse, tabletop run
    from tabletop.eval.cli import add_commands as add_eval_commands

    add_eval_commands(sub)  # tabletop eval
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return args.func(args)
    except TabletopError as e:
        print(f"tabletop {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

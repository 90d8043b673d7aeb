"""The mobile base's end-to-end demo: the default room scanned by the wheeled base, mapped,
and a few goals reached through the robot API, with pictures.

:func:`run_room_demo` scans the shipped default room (a shorter drive than the suites': one
view per table), builds the map with the chosen encoder set, then sends the ground base to an
object, a sound, the point between two objects and through an instruction, on the room's
physics; for the same object goal it plans the flyer's path on the flyer's obstacles. The
report (``report.md``) holds the results and four pictures: the room from above, the map from
above, and the two embodiments' obstacle maps with their planned and driven paths.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import GoalNotFound, TabletopError

__all__ = ["DEMO_SCAN", "run_room_demo"]

#: The demo's scan of the default room: one view per table, no look around.
DEMO_SCAN = {"seed": 0, "views_per_table": 1, "look_around": False, "episodes": 3}
_PX_PER_M = 80


def _top_view(world, spec, px_per_m: int = _PX_PER_M) -> np.ndarray:
    """(H, W, 3) uint8: the room rendered from straight above (a pinhole 12 m up)."""
    from tabletop.sim.camera import WristCameraConfig
    from tabletop.sim.world import render_camera

    sx, sy = spec.size
    h_m = 12.0
    w, h = int(sy * px_per_m), int(sx * px_per_m)  # image x along -y... see T below
    fov = math.degrees(2 * math.atan((sx / 2) / h_m))
    cam = WristCameraConfig(
        width=w, height=h, fov_y_deg=fov, near=1.0, far=20.0, depth_resolution=1e-3
    )
    from tabletop.sim.camera import gl_projection_matrix

    proj = gl_projection_matrix(cam.intrinsics, cam.near, cam.far)
    # optical frame: z down; image right = -y (the room's right seen from above, x up)
    T = np.eye(4)
    T[:3, 0] = [0.0, -1.0, 0.0]
    T[:3, 1] = [-1.0, 0.0, 0.0]
    T[:3, 2] = [0.0, 0.0, -1.0]
    T[:3, 3] = [sx / 2, sy / 2, h_m]
    img = render_camera(world._pb, world._client, cam, proj, world.renderer, T, world._seg_lut)
    return np.ascontiguousarray(img.rgb)


def _to_px(xy, spec, shape) -> np.ndarray:
    """(N, 2) int pixel (col, row) of room points (N, 2) [m] in the top-view images."""
    xy = np.atleast_2d(np.asarray(xy, np.float64))
    h, w = shape[:2]
    col = (spec.size[1] - xy[:, 1]) / spec.size[1] * w
    row = (spec.size[0] - xy[:, 0]) / spec.size[0] * h
    return np.stack([col, row], axis=1).round().astype(np.int32)


def _map_view(avlmap, spec, shape) -> np.ndarray:
    """(H, W, 3) uint8: the map from above, each column's highest voxel in its colour (white
    where nothing was seen), in the pictures' frame (:func:`_to_px`)."""
    import cv2

    h, w = shape[:2]
    g = avlmap.grid
    idx = avlmap.voxels.indices
    cols = np.full((*g.shape[:2], 3), 255, np.uint8)
    if len(idx):
        order = np.argsort(idx[:, 2], kind="stable")  # the highest voxel is written last
        cols[idx[order, 0], idx[order, 1]] = avlmap.voxels.mean_colors()[order]
    # cells covering the room [0, X] x [0, Y], then x up and y to the left, as seen from above
    vs = g.voxel_size
    i0 = round((0.0 - g.lower[0]) / vs)
    j0 = round((0.0 - g.lower[1]) / vs)
    i1 = i0 + round(spec.size[0] / vs)
    j1 = j0 + round(spec.size[1] / vs)
    room = cols[max(i0, 0) : i1, max(j0, 0) : j1][::-1, ::-1]
    return cv2.resize(np.ascontiguousarray(room), (w, h), interpolation=cv2.INTER_NEAREST)


def _paths_view(base_img, grid, spec, runs, colour) -> np.ndarray:
    """``base_img`` with an embodiment's inflated obstacles tinted and each run's planned
    (thin) and driven (thick) path, its target (cross) and truth (circle)."""
    import cv2

    img = base_img.copy()
    occ = np.argwhere(grid.occupied)
    if len(occ):
        px = _to_px(grid.to_world(occ), spec, img.shape)
        ok = (px[:, 0] >= 0) & (px[:, 0] < img.shape[1]) & (px[:, 1] >= 0)
        ok &= px[:, 1] < img.shape[0]
        tint = np.zeros_like(img)
        r = max(round(grid.cell_size * _PX_PER_M / 2), 1)
        for p in px[ok]:
            cv2.rectangle(tint, tuple(p - r), tuple(p + r), colour, -1)
        mask = tint.any(axis=2)
        img[mask] = (0.55 * img[mask] + 0.45 * tint[mask]).astype(np.uint8)
    for run in runs:
        if len(run["planned"]) > 1:
            cv2.polylines(img, [_to_px(run["planned"], spec, img.shape)], False, (40, 40, 40), 1)
        if len(run["driven"]) > 1:
            cv2.polylines(img, [_to_px(run["driven"][:, :2], spec, img.shape)], False, colour, 3)
        if run.get("target") is not None:
            t = tuple(int(v) for v in _to_px(run["target"][:2], spec, img.shape)[0])
            cv2.drawMarker(img, t, (0, 0, 0), cv2.MARKER_CROSS, 14, 2)
        if run.get("truth") is not None:
            t = tuple(int(v) for v in _to_px(run["truth"][:2], spec, img.shape)[0])
            cv2.circle(img, t, int(run["radius"] * _PX_PER_M), (0, 140, 0), 1)
    return img


def _write_png(path: Path, rgb: np.ndarray) -> None:
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]))
    if not ok:
        raise TabletopError(f"could not encode {path.name} as PNG")
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.tobytes())


def run_room_demo(out_dir, encoders: str = "default", progress=None) -> dict:
    """Scan, map and reach a few goals in the default room; write ``report.md``,
    ``results.json`` and the pictures into ``out_dir``; return the results."""
    from tabletop.base import TABLETOP_BASE, KinematicBaseDriver
    from tabletop.eval.harness import cached_map, cached_map_path, map_config
    from tabletop.eval.room import cached_room_recording, room_map_settings, room_recording_key
    from tabletop.eval.tasks import Truth
    from tabletop.eval.truth import resolve_truth
    from tabletop.robot.wheeled import FLYER, GROUND_BASE, MobileRobot
    from tabletop.sim.ground_truth import GroundTruth
    from tabletop.sim.room import load_room_spec
    from tabletop.sim.room_world import RoomWorld, mast_camera_config

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cache = out / "cache"
    t0 = time.perf_counter()
    spec = load_room_spec("default")
    rec, scan_s, _ = cached_room_recording("room-demo", dict(DEMO_SCAN), spec, cache, progress)
    settings = {**room_map_settings(spec), "frame_step": 3}
    map_config(**settings)
    key = room_recording_key(spec, dict(DEMO_SCAN))
    map_path = cached_map_path(settings, encoders, cache, key)  # beside its use (hashes the source)
    m, map_s, _ = cached_map("room-demo", settings, rec, encoders, cache, key, progress)
    gt = GroundTruth.of(rec)
    labels = [o.label for o in gt.objects]
    objs = [o for o in gt.objects if labels.count(o.label) == 1]
    # what a person would try first: the largest things in the room, seen from the mast
    size = {o.name: float(np.prod(np.subtract(o.aabb_max, o.aabb_min))) for o in objs}
    big = sorted(objs, key=lambda o: -size[o.name])
    far = big[0]
    a = big[1]
    b = next((o for o in big[2:] if o.table != a.table), big[2])
    snd = gt.sound_events_by_onset[0] if gt.sound_events else None
    goals = [
        ("object", far.label, {"obj": far.label}, Truth("object", object=far.name)),
        (
            "spatial",
            f"between the {a.label} and the {b.label}",
            ("between", a.label, b.label),
            Truth(
                "relation",
                relation="between",
                of=(Truth("object", object=a.name), Truth("object", object=b.name)),
            ),
        ),
        (
            "instruction",
            f"go to the {a.label}, then turn around",
            f"go to the {a.label}, then turn around",
            Truth("object", object=a.name),
        ),
    ]
    if snd is not None:
        goals.insert(
            1, ("sound", snd.caption, {"sound": snd.caption}, Truth("sound", sound=snd.category))
        )
    radius = 1.0
    results, runs = [], []
    h, w = rec.rgb.shape[1:3]
    with RoomWorld(spec, mast_camera_config(width=w, height=h), "auto") as world:
        top = _top_view(world, spec)
        robot = MobileRobot(m, world.driver, embodiment=GROUND_BASE)
        for kind, text, query, truth in goals:
            region = resolve_truth(truth, gt)
            row = {"type": kind, "text": text, "status": "done"}
            n0 = len(robot.history)
            try:
                if kind == "instruction":
                    from tabletop.language import run_instruction

                    run_instruction(query, robot)
                    target = robot.history[n0].target if len(robot.history) > n0 else None
                elif kind == "spatial":
                    target = robot.between(query[1], query[2])
                    robot.move_to(target)
                else:
                    target = robot.get_max_pos_3d(robot.get_major_map(**query))
                    robot.move_to(target)
            except GoalNotFound as e:
                row.update(status="not_found", reason=str(e))
                target = None
            except TabletopError as e:
                row.update(status="failed", reason=f"{type(e).__name__}: {e}")
                target = None
            moves = robot.history[n0:]
            here = robot.current_position()
            err = region.distance_xy(here)
            row.update(
                target=None if target is None else [round(float(v), 3) for v in target],
                final=[round(float(v), 3) for v in here],
                error_m=round(err, 3),
                success=bool(row["status"] == "done" and err <= radius),
                collisions=int(sum(r.collisions for r in moves)),
            )
            results.append(row)
            for r in moves:
                runs.append(
                    {
                        "planned": r.planned,
                        "driven": r.driven,
                        "target": r.target if r.planned.size else None,
                        "truth": region.center,
                        "radius": radius,
                    }
                )
        # the flyer and the ground base, from where the base stands, to the first goal's
        # target that was found (the room's far corner when none was)
        start = world.driver.read_odometry()
        flyer = MobileRobot(m, KinematicBaseDriver(TABLETOP_BASE, start), embodiment=FLYER)
        ground_plan = MobileRobot(m, KinematicBaseDriver(TABLETOP_BASE, start))
        flyer_runs, ground_runs = [], []
        fr = ground = None
        found = [r["target"] for r in results if r.get("target") is not None]
        sx, sy = spec.start.position
        corner = [spec.size[0] - 0.5 if sx < spec.size[0] / 2 else 0.5, 0.0, 0.0]
        corner[1] = spec.size[1] - 0.5 if sy < spec.size[1] / 2 else 0.5
        tgt = np.array(found[0] if found else corner, np.float64)
        try:
            fr = flyer.move_to(tgt)
            ground = ground_plan.move_to(tgt)
            for r, lst in ((fr, flyer_runs), (ground, ground_runs)):
                lst.append(
                    {"planned": r.planned, "driven": r.driven, "target": r.target, "radius": 0}
                )
        except TabletopError as e:
            results.append({"type": "flyer", "status": "failed", "reason": str(e)})
    base = _map_view(m, spec, top.shape)
    pictures = {
        "room_from_above.png": top,
        "map_from_above.png": base,
        "ground_base_paths.png": _paths_view(base, robot.blocked, spec, runs, (200, 60, 30)),
        "ground_vs_flyer.png": np.concatenate(
            [
                _paths_view(base, ground_plan.blocked, spec, ground_runs, (200, 60, 30)),
                _paths_view(base, flyer.blocked, spec, flyer_runs, (30, 90, 200)),
            ],
            axis=1,
        ),
    }
    for name, img in pictures.items():
        _write_png(out / name, img)
    summary = {
        "encoders": encoders,
        "encoder_names": dict(m.encoder_names),
        "room": spec.name,
        "frames": len(rec),
        "scan_s": round(scan_s, 1),
        "map_s": round(map_s, 1),
        "wall_s": round(time.perf_counter() - t0, 1),
        "success_radius_m": radius,
        "map_file": str(map_path),
        "recording_dir": str(cache / f"rec-room-{spec.name}-{key}"),
        "goals": results,
        "successes": sum(r.get("success", False) for r in results),
        "flyer_vs_ground": None
        if fr is None
        else {
            "goal": [round(float(v), 2) for v in tgt],
            "flyer_path_m": round(fr.length_m, 2),
            "ground_path_m": round(ground.length_m, 2),
            "flyer_blocked_cells": int(flyer.blocked.occupied.sum()),
            "ground_blocked_cells": int(ground_plan.blocked.occupied.sum()),
        },
    }
    with atomic_path(out / "results.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=2, allow_nan=False))
    lines = [
        "# Mobile-base demo",
        "",
        f"The default room, scanned by the wheeled base ({len(rec)} frames at 30 Hz, "
        f"{scan_s:.0f} s), mapped with the **{encoders}** encoders ({map_s:.0f} s; "
        + ", ".join(f"{k}: {v}" for k, v in m.encoder_names.items() if k != "set")
        + f"). A goal is reached when the base ends within {radius:g} m of the truth.",
        "",
        "| goal | text | status | success | error m | collisions |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['type']} | {r.get('text', '')} | {r['status']} | {r.get('success', '')} | "
            f"{r.get('error_m', '')} | {r.get('collisions', '')} |"
        )
    if summary["flyer_vs_ground"]:
        fv = summary["flyer_vs_ground"]
        lines += [
            "",
            f"Ground base and flyer to {fv['goal']}: paths of {fv['ground_path_m']} m and "
            f"{fv['flyer_path_m']} m; blocked cells {fv['ground_blocked_cells']} and "
            f"{fv['flyer_blocked_cells']} (the flyer passes over tables).",
        ]
    lines += ["", *(f"![{n}]({n})" for n in pictures)]
    with atomic_path(out / "report.md") as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return summary

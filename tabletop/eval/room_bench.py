"""How long an image query takes on a room map (``tabletop bench --room-images``).

A short scan of the default room (to the work table, one look), its oracle map with the room's
settings (:func:`~tabletop.eval.room.room_map_settings`), and three pictures taken upright
1.1-2 m off the scan's path, looking at the dining table it saw from afar: feature matching
finds none of them, so each query searches the map. Each picture is asked once with the room's
settings (upright pictures: feature matching tries the image as it is) and once trying its
four quarter turns as well (the arm's setting), back to back, after the map's panoramas were
built by a first query: per query the seconds, whether it was found and how far from where the
picture was taken. One core (the machine's other jobs share it).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

__all__ = ["ROOM_BENCH_SCAN", "run_room_image_benchmark"]

#: The room bench's scan: the base drives to the work table and looks once (a few seconds).
ROOM_BENCH_SCAN = dict(
    rate_hz=10.0,
    tables=("work_table",),
    views_per_table=1,
    look_s=0.5,
    pan_rad=0.0,
    look_around=False,
    episodes=1,
    episode_s=1.5,
    renderer="egl",
)
#: Where the pictures are taken (x, y, height [m]) and the point they look at.
_EYES = ((2.0, 3.0, 1.1), (1.2, 2.2, 1.1), (2.6, 2.9, 1.1))
_LOOK_AT = (2.0, 3.7, 0.65)


def run_room_image_benchmark(repeats: int = 2) -> dict:
    """Image queries on a room map, the room's setting against all four turns (see the
    module): seconds per query (median, max) of each, and each query's result."""
    from tabletop.eval.harness import map_config
    from tabletop.eval.images import render_view, view_pose
    from tabletop.eval.room import room_map_settings
    from tabletop.eval.tasks import ImageView
    from tabletop.mapping import AVLMap
    from tabletop.mapping.encoders.base import torch_threads
    from tabletop.sim.room import load_room_spec
    from tabletop.sim.room_scan import RoomScanConfig, run_room_scan
    from tabletop.sim.room_world import RoomWorld, mast_camera_config

    spec = load_room_spec("default")
    rec = run_room_scan(spec, RoomScanConfig(**ROOM_BENCH_SCAN))
    m = AVLMap.build(rec, map_config(**room_map_settings(spec)), encoders="oracle")
    views = [ImageView(eye=e, look_at=_LOOK_AT, up=(0.0, 0.0, 1.0)) for e in _EYES]
    h, w = rec.rgb.shape[1:3]
    with RoomWorld(spec, mast_camera_config(width=w, height=h), "egl") as world:
        images = [render_view(world, v) for v in views]
    db = m.images.database
    room = db.config
    with torch_threads(1):
        t = time.perf_counter()
        m.images.localize(images[0])  # the panoramas: once per map
        panoramas_s = time.perf_counter() - t
        times: dict[str, list[float]] = {"upright": [], "four_turns": []}
        found: dict[str, list] = {"upright": [], "four_turns": []}
        for _ in range(repeats):
            for name, upright in (("upright", True), ("four_turns", False)):
                db.config = dataclasses.replace(room, upright=upright)
                for v, rgb in zip(views, images, strict=True):
                    t = time.perf_counter()
                    loc = m.images.localize(rgb)
                    times[name].append(time.perf_counter() - t)
                    err = (
                        float(np.linalg.norm(loc.position[:2] - view_pose(v)[:2, 3]))
                        if loc.ok
                        else None
                    )
                    found[name].append(None if err is None else round(err, 3))
        db.config = room
    out = {"room_image_panoramas_s": round(panoramas_s, 2)}
    for name in times:
        out[f"room_image_{name}_s_median"] = round(float(np.median(times[name])), 2)
        out[f"room_image_{name}_s_max"] = round(float(np.max(times[name])), 2)
        out[f"room_image_{name}_error_m"] = found[name][: len(views)]
    out["room_image_ratio"] = round(
        out["room_image_upright_s_median"] / out["room_image_four_turns_s_median"], 2
    )
    return out

"""Maps of rooms for the mobile base: the same map code as the arm's, at room scale.

:func:`room_map_settings` is what changes between a tabletop map and a room map (everything
else, the encoders and the modules, is shared):

- the grid is the room's box (its floor plus a margin, up to the walls' height) at
  ``voxel_size`` (3 cm by default: the paper maps rooms at 5 cm; 3 cm keeps the objects on
  the tables several voxels across, which the object instances need);
- the vocabulary is the catalog's objects, the tabletop background concepts and the room's own
  concepts (:data:`ROOM_CONCEPTS`: walls, shelves, ...), so a voxel of a wall is not forced
  onto "table" or "other" when an embodiment's obstacle list names walls;
- objects stand on every raised surface (each table top, a cabinet's top, a shelf's boards),
  not on one fitted table (``object.segmentation.supports = "surfaces"``), and at most
  ``max_object_height_m`` above it; heights are the voxels' points' mean heights
  (``heights = "points"``): a flat object lies in its table top's 3 cm voxel layer;
- the table registration (a wrist camera's height, roll and pitch corrected onto the table)
  is off: a base's camera sees the floor and several tables; its poses come from the wheel
  odometry, whose errors are in x, y and yaw;
- no robot self-filter (the mast camera does not see the base).
"""

from __future__ import annotations

__all__ = ["ROOM_CONCEPTS", "room_map_settings"]

#: Decays [1/m] of a room's primary and auxiliary heatmaps (the table's 10 and 2.5, over 5):
#: a sound heard where the base stood, a metre or two from the table, still narrows down
#: which object is meant.
ROOM_MAJOR_DECAY, ROOM_AUX_DECAY = 2.0, 0.5
#: Concepts a room holds besides the catalog's objects and the tabletop background.
ROOM_CONCEPTS = ("wall", "shelf", "cabinet", "sofa", "robot")


def room_map_settings(
    spec, voxel_size: float = 0.03, max_object_height_m: float = 0.40, margin_m: float = 0.3
) -> dict:
    """Map config overrides (:func:`tabletop.eval.harness.map_config`) for a room
    (:class:`~tabletop.sim.room.RoomSpec`)."""
    from tabletop.eval.harness import catalog_descriptions
    from tabletop.mapping import BACKGROUND
    from tabletop.sim.catalog import OBJECT_KINDS

    sx, sy = spec.size
    top = float(spec.wall_height) + 0.1
    desc = catalog_descriptions()
    return {
        "grid": {
            "lower": [-margin_m, -margin_m, -0.06],
            "upper": [sx + margin_m, sy + margin_m, top],
            "voxel_size": voxel_size,
        },
        "categories": (
            *(k.label for k in OBJECT_KINDS.values()),
            *BACKGROUND,
            *(c for c in ROOM_CONCEPTS if c not in BACKGROUND),
        ),
        "descriptions": {k.label: desc[n] for n, k in OBJECT_KINDS.items() if n in desc},
        "object": {
            "segmentation": {
                "supports": "surfaces",
                "max_height_m": max_object_height_m,
                # a jenga block lying on a table is half a 3 cm voxel tall; a table top seen
                # from metres away (depth resolution falls with distance) spreads over a cm
                "heights": "points",
                "above_table_m": 0.012,
                # two touching things of one colour whose features the room network tells
                # apart only somewhat (a brick against a ball) part where their tops fold
                "split_crease_m": 0.015,
            }
        },
        # the room-aware image network; objects metres away are a few dozen pixels, so it sees
        # each frame enlarged twice, as it was trained (tabletop train vision --rooms)
        "image_network": "room",
        "image_scale": 2,
        "registration": {"enabled": False},
        "self_filter_margin": None,
        # a room is about five times a table's size: heat spreads five times as far
        "major_decay": ROOM_MAJOR_DECAY,
        "aux_decay": ROOM_AUX_DECAY,
        # an image goal is where it was taken; a mast camera looks across the room, its
        # references reach 5 m, and a 3 cm map reproduces a view less exactly than 1 cm
        "visual": {
            "target": "camera",
            "localization": {
                "require_look_down": False,
                # the base's pictures and the goals' are taken upright: no quarter turns
                "upright": True,
                "max_depth_m": 5.0,
                "min_agreement": 0.5,
                # an image taken a metre or two off the scan's path matches few features
                "search": True,
            },
        },
    }


def room_recording_key(spec, scan: dict) -> str:
    """The cache key of the scan of room ``spec`` with ``scan`` (RoomScanConfig fields)."""
    from tabletop.eval.harness import _fingerprint, _key

    return _key({"room": spec.to_dict(), "scan": scan, "sim": _fingerprint("sim", "base")})


def cached_room_recording(name: str, scan: dict, spec, cache, progress=None):
    """(recording, scan seconds, cached?) of a room scanned with ``scan``, through the cache
    (:func:`~tabletop.eval.harness.through_cache`)."""
    import time
    from pathlib import Path

    from tabletop.eval.harness import through_cache
    from tabletop.sim.room_scan import RoomScanConfig, run_room_scan

    key = room_recording_key(spec, scan)
    path = Path(cache) / f"rec-room-{spec.name}-{key}" if cache is not None else None

    def scan_it():
        t0 = time.perf_counter()
        # the drive takes what the physics takes: the total is not known ahead
        cb = (lambda d: progress(f"scan {name}", d, d)) if progress else None
        rec = run_room_scan(spec, RoomScanConfig(**scan), progress=cb)
        return rec, time.perf_counter() - t0

    return through_cache(path, scan_it)

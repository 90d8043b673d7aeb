"""Room views for the image encoder (``tabletop train vision --room-layouts N``).

The wrist camera sees a table from 0.2-0.85 m; the wheeled base's mast camera sees rooms from
1.1 m up and metres away, where the catalogue's objects are a few dozen pixels and most of the
picture is floor, walls and furniture. These renders teach the network that view: seeded
random rooms (:func:`~tabletop.sim.room.generate_room`), cameras on free floor at mast height
(and lower or higher, some of the time) looking at an object, a piece of furniture or a wall
0.5-3.2 m away, a random light. Each pixel's class comes from the simulator's segmentation, in
the space of :func:`~tabletop.train.vision.vision_classes` with ``rooms=True``: objects as on
the table ("red mug"), the furniture by its category ("table", "shelf", "cabinet", "sofa"),
"wall", "floor", the base itself "robot", anything else "other".

Room seeds: training draws ``ROOM_SEED_BASE + seed * 1000 + i``; the held-out rooms measured
after training start at :data:`EVAL_ROOM_SEED_BASE`. Neither range is a suite's room (those are
the default room, generated room 1 and the held-out suites' 9101-9108).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from tabletop.parallel import Backend

__all__ = [
    "EVAL_ROOM_SEED_BASE",
    "ROOM_SEED_BASE",
    "evaluate_room_vision",
    "render_room_dataset",
    "room_camera",
]

log = logging.getLogger(__name__)

ROOM_SEED_BASE = 20_000
EVAL_ROOM_SEED_BASE = 40_000
#: How far the camera stands from what it looks at [m], and its height above the floor [m]:
#: mostly the mast's (1.10 m), sometimes a person's hand or a taller robot's.
_DISTANCE = (0.5, 3.2)
_MAST_HEIGHT = (0.95, 1.25)
_OTHER_HEIGHT = (0.45, 1.7)


def _targets(spec) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(object centres, furniture points) a camera may look at, world frame."""
    objs = []
    for f, obj in spec.objects:
        lo, hi = f.object_aabb(obj)
        objs.append((np.asarray(lo) + np.asarray(hi)) / 2)
    furn = []
    for f in spec.furniture:
        lo, hi = (np.asarray(v, dtype=float) for v in f.aabb())
        furn.append(np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2]]))
    return objs, furn


def room_camera(rng: np.random.Generator, spec, free: np.ndarray, cell: float) -> np.ndarray:
    """A random camera pose (OpenCV) on free floor of ``spec`` looking at an object (60 %), a
    piece of furniture (25 %) or a wall or the floor (15 %). ``free``: (nx, ny) bool grid of
    floor cells the camera may stand over (``cell`` metres each)."""
    objs, furn = _targets(spec)
    sx, sy = spec.size
    r = rng.random()
    if objs and r < 0.6:
        target = objs[int(rng.integers(len(objs)))] + np.array([*rng.normal(0, 0.1, 2), 0.0])
    elif furn and r < 0.85:
        target = furn[int(rng.integers(len(furn)))] + np.array([*rng.normal(0, 0.2, 2), 0.0])
    else:
        target = np.array([rng.uniform(0, sx), rng.uniform(0, sy), rng.uniform(0.0, 1.5)])
    eye_xy = None
    for _ in range(60):
        d = rng.uniform(*_DISTANCE)
        a = rng.uniform(-math.pi, math.pi)
        xy = target[:2] + d * np.array([math.cos(a), math.sin(a)])
        i, j = int(xy[0] // cell), int(xy[1] // cell)
        if 0 <= i < free.shape[0] and 0 <= j < free.shape[1] and free[i, j]:
            eye_xy = xy
            break
    if eye_xy is None:  # nowhere free at that range: any free cell
        cells = np.argwhere(free)
        i, j = cells[int(rng.integers(len(cells)))]
        eye_xy = np.array([(i + 0.5) * cell, (j + 0.5) * cell])
    lo_hi = _MAST_HEIGHT if rng.random() < 0.7 else _OTHER_HEIGHT
    eye = np.array([*eye_xy, rng.uniform(*lo_hi)])
    if np.linalg.norm(target - eye) < 0.2:
        target = eye + np.array([0.5, 0.0, -0.3])
    return level_look_at(eye, target, roll=float(rng.normal(0.0, 0.06)))


def level_look_at(eye, target, roll: float = 0.0) -> np.ndarray:
    """(4, 4) OpenCV camera pose at ``eye`` looking at ``target`` with the image's "down"
    along the world's -z (a camera held level, as on a mast), then rolled by ``roll``."""
    eye = np.asarray(eye, dtype=np.float64)
    fwd = np.asarray(target, dtype=np.float64) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-6:  # straight down or up: any right will do
        right = np.array([0.0, -1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    c, s = math.cos(roll), math.sin(roll)
    R = np.stack([c * right + s * down, -s * right + c * down, fwd], axis=1)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, eye
    return T


def _label_lut(world, index: dict) -> np.ndarray:
    """Segmentation instance -> class id of ``index`` ((kind, colour) -> id)."""
    from tabletop.sim.catalog import object_kind
    from tabletop.sim.room_world import INSTANCE_FLOOR, INSTANCE_NONE, INSTANCE_ROBOT

    other = index[("other", None)]
    lut = np.full(max(world.instance_names) + 1, other, np.int16)
    lut[INSTANCE_NONE] = other
    lut[INSTANCE_FLOOR] = index[("floor", None)]
    lut[INSTANCE_ROBOT] = index[("robot", None)]
    for f in world.spec.furniture:
        lut[world.item_instance[f.name]] = index.get((f.category, None), other)
    for w in world.spec.walls():
        lut[world.item_instance[w.name]] = index[("wall", None)]
    for _f, o in world.spec.objects:
        col = None if object_kind(o.kind).keep_texture else o.color
        lut[world.object_instance[o.name]] = index[(o.kind, col)]
    return lut


def render_room_dataset(
    room_seeds, views: int, seed: int, lit: bool = True, backend: Backend | None = None,
    progress=None, scale: int = 1,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Render ``views`` images in each generated room: ((N, H, W, 3) uint8, (N, H, W) int16
    class ids into ``vision_classes(rooms=True)``). ``lit=False``: the scan's fixed light (the
    held-out measure). ``scale``: images enlarged this many times (bilinear; labels nearest),
    as ``LSegEncoder(upscale=scale)`` enlarges what it is given. ``backend`` renders slices of
    the rooms in parallel, each room from its own seeded streams, so the images are the same as
    one process renders."""
    room_seeds = [int(s) for s in room_seeds]
    if scale != 1:
        import cv2

        rgbs, labels = render_room_dataset(room_seeds, views, seed, lit, backend, progress)
        H, W = labels.shape[1:]
        size = (W * scale, H * scale)
        return (
            np.stack([cv2.resize(r, size, interpolation=cv2.INTER_LINEAR) for r in rgbs]),
            np.stack([cv2.resize(lab, size, interpolation=cv2.INTER_NEAREST) for lab in labels]),
        )
    if backend is not None and not backend.serial and len(room_seeds) > 1:
        from tabletop.parallel import run_units

        n = backend.workers or 8
        size = max(1, math.ceil(len(room_seeds) / (2 * n)))
        parts = [room_seeds[i : i + size] for i in range(0, len(room_seeds), size)]
        out = run_units(
            render_room_dataset, [(p, views, seed, lit) for p in parts], backend,
            labels=[f"rooms {p[0]}..{p[-1]}" for p in parts],
        )  # fmt: skip
        return np.concatenate([r for r, _ in out]), np.concatenate([lab for _, lab in out])
    from tabletop.sim.room import generate_room
    from tabletop.sim.room_world import RoomWorld
    from tabletop.train.vision_render import render_lit, vision_classes

    classes = vision_classes(rooms=True)
    index = {(c["kind"], c["color"]): i for i, c in enumerate(classes)}
    rgbs, labels = [], []
    for k, rs in enumerate(room_seeds):
        spec = generate_room(rs)
        rng = np.random.default_rng([rs, seed, 7])
        cell = 0.05
        free = ~spec.occupancy(cell=cell, inflate=0.3)
        with RoomWorld(spec) as world:
            lut = _label_lut(world, index)
            for _ in range(views):
                T = room_camera(rng, spec, free, cell)
                if lit:
                    rgb, inst = render_lit(world, T, rng)
                else:
                    img = world.render(T)
                    rgb, inst = img.rgb, img.segmentation
                rgbs.append(rgb)
                labels.append(lut[np.clip(inst, 0, len(lut) - 1)])
        if progress is not None:
            progress(k + 1, len(room_seeds))
    return np.stack(rgbs), np.stack(labels)


def evaluate_room_vision(
    weights=None, rooms: int = 6, views: int = 8, seed: int = 0, encoder=None, upscale: int = 1
) -> dict:
    """Measure an image encoder on held-out generated rooms (seeds from
    :data:`EVAL_ROOM_SEED_BASE`), rendered with the scan's fixed light from
    :func:`room_camera` poses. The vocabulary is ``vision_classes(rooms=True)``'s canonical
    names; a pixel's prediction is the class of the best dot product with its cell.

    Returns fractions in [0, 1]: ``room_object_top1`` (per pixel over object pixels),
    ``room_object_kind_top1`` (the same, colour ignored), ``room_instance_top1`` (per object
    seen in a view with >= 12 px, the class of its mean cell embedding), ``room_stuff_top1``
    (per pixel over floor, wall and furniture pixels), and the counts measured. ``upscale``:
    the encoder of ``weights`` enlarges each image this many times first."""
    from tabletop.mapping.encoders.lseg import LSegEncoder
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
    from tabletop.sim.catalog import OBJECT_KINDS
    from tabletop.train.vision_render import predict_pixels, vision_classes

    enc = encoder if encoder is not None else LSegEncoder(weights, upscale=upscale)
    classes = vision_classes(rooms=True)
    T = MiniLMTextEncoder().encode_text([c["name"] for c in classes])
    seeds = [EVAL_ROOM_SEED_BASE + i for i in range(rooms)]
    rgbs, labels = render_room_dataset(seeds, views, seed=seed + 1, lit=False)
    is_obj = np.array([c["kind"] in OBJECT_KINDS for c in classes])
    other = next(i for i, c in enumerate(classes) if c["kind"] == "other")
    robot = next(i for i, c in enumerate(classes) if c["kind"] == "robot")
    kind_of = np.array([c["kind"] for c in classes])
    obj_ok = kind_ok = obj_n = stuff_ok = stuff_n = inst_ok = inst_n = 0
    for rgb, lab in zip(rgbs, labels, strict=True):
        dense, rows, cols, pred = predict_pixels(enc, rgb, T, *lab.shape)
        objm = is_obj[lab]
        obj_ok += int(np.sum((pred == lab) & objm))
        kind_ok += int(np.sum((kind_of[pred] == kind_of[lab]) & objm))
        obj_n += int(objm.sum())
        stuffm = ~objm & (lab != other) & (lab != robot)
        stuff_ok += int(np.sum((pred == lab) & stuffm))
        stuff_n += int(stuffm.sum())
        for c in np.unique(lab[objm]):
            m = lab == c
            if m.sum() < 12:
                continue
            yy, xx = np.nonzero(m)
            g = dense[rows[yy], cols[xx]].mean(0)
            inst_ok += int(np.argmax(T @ g) == c)
            inst_n += 1
    frac = lambda a, b: float(a / b) if b else float("nan")  # noqa: E731
    return {
        "room_object_top1": frac(obj_ok, obj_n),
        "room_object_kind_top1": frac(kind_ok, obj_n),
        "room_instance_top1": frac(inst_ok, inst_n),
        "room_stuff_top1": frac(stuff_ok, stuff_n),
        "room_eval_images": len(rgbs),
        "room_eval_instances": inst_n,
    }

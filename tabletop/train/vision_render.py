"""What the image encoder's training renders are labelled with, and the lit render itself:
shared by the table's training data (:mod:`tabletop.train.vision`) and the rooms'
(:mod:`tabletop.train.vision_rooms`)."""

from __future__ import annotations

import numpy as np

__all__ = ["ROOM_STUFF", "STUFF", "predict_pixels", "render_lit", "vision_classes"]

STUFF = ("table", "robot", "other")
#: What a room adds to the vocabulary (``vision_classes(rooms=True)``): its furniture by
#: category, its walls and its floor. With them "other" loses its floor phrasings.
ROOM_STUFF = ("floor", "wall", "shelf", "cabinet", "sofa")


def vision_classes(rooms: bool = False) -> list[dict]:
    """The vocabulary: one dict per class with ``name`` (the canonical text), ``kind``
    (catalog kind, or "table"/"robot"/"other"), ``color`` (None when the class has none).
    ``rooms``: :data:`ROOM_STUFF` follows, so the table's classes keep their indices."""
    from tabletop.sim.catalog import OBJECT_KINDS

    out = []
    for k in sorted(OBJECT_KINDS):
        kind = OBJECT_KINDS[k]
        if kind.keep_texture:
            out.append({"name": kind.label, "kind": k, "color": None})
        else:
            for c in kind.colors:
                out.append({"name": f"{c} {kind.label}", "kind": k, "color": c})
    for s in STUFF + (ROOM_STUFF if rooms else ()):
        out.append({"name": s, "kind": s, "color": None})
    return out


def render_lit(world, T_world_cam: np.ndarray, rng: np.random.Generator, others=()):
    """Render like :meth:`SimWorld.render` with a random light (direction, colour, strength).

    Uses the world's PyBullet client directly: ``SimWorld.render`` has a fixed light. Bodies
    in ``others`` (distractors the world does not know) are labelled as nothing ("other").
    """
    from tabletop.sim.camera import gl_view_matrix

    pb, cam = world._pb, world.camera
    W, H = cam.width, cam.height
    d = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.3, 1.5)])
    renderer = pb.ER_BULLET_HARDWARE_OPENGL if world.renderer == "egl" else pb.ER_TINY_RENDERER
    _, _, rgba, _, seg = pb.getCameraImage(
        W,
        H,
        gl_view_matrix(T_world_cam),
        world._projection,
        renderer=renderer,
        lightDirection=d.tolist(),
        lightColor=(1.0 - rng.uniform(0, 0.15, 3)).tolist(),
        lightDistance=2.0,
        lightAmbientCoeff=float(rng.uniform(0.4, 0.8)),
        lightDiffuseCoeff=float(rng.uniform(0.25, 0.6)),
        lightSpecularCoeff=float(rng.uniform(0.0, 0.3)),
        shadow=int(rng.random() < 0.5),
        physicsClientId=world._client,
    )
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(H, W, 4)[..., :3].copy()
    seg = np.asarray(seg, dtype=np.int64).reshape(H, W)
    lut = world._seg_lut
    inst = np.where(seg >= 0, lut[np.clip(seg, 0, len(lut) - 1)], 0)
    if len(others):
        inst[np.isin(seg, list(others))] = 0  # INSTANCE_NONE
    return rgb, inst


def predict_pixels(encoder, rgb: np.ndarray, T: np.ndarray, H: int, W: int):
    """(cell embeddings (h, w, D), each pixel row's and column's cell, the (H, W) class of the
    best dot product with the class texts ``T`` (C, D)): how the held-out measures read a
    dense encoder on an image labelled at H x W."""
    from tabletop.errors import ConfigError

    dense = encoder.encode_dense(rgb)  # pixel (y, x) takes cell (y // s, x // s)
    s = encoder.stride
    if dense.shape[0] * s < H or dense.shape[1] * s < W:
        raise ConfigError(f"dense output {dense.shape[:2]} x stride {s} < image {W}x{H}")
    rows, cols = np.arange(H) // s, np.arange(W) // s
    pred = (dense @ T.T).argmax(-1)[rows[:, None], cols[None, :]]
    return dense, rows, cols, pred

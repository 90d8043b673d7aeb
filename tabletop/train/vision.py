"""Train and evaluate the embedded default image encoder (``tabletop train vision``).

LSeg-style training into MiniLM's text space. Images come from :mod:`tabletop.sim`: seeded
random layouts (:func:`~tabletop.sim.generator.generate_objects`), random camera poses over the
table (0.3-0.7 m above it, tilted and rolled like the wrist camera of a scan), random light
direction, colour and strength, a jittered table colour. Each pixel's class comes from the
simulator's segmentation: an object's label with its colour ("red mug"; textured kinds —
jenga block, domino, soccer ball, tray — have no colour in their class since their texture
hides it), "table", "robot" or "other" (floor, nothing).

The network's pixel embeddings (:class:`~tabletop.mapping.encoders.lseg.LSegEncoder`) are
contrasted (softmax cross-entropy, learned temperature) against MiniLM embeddings of the
class names, one phrasing per class drawn each step from several templates ("a red mug",
"the red mug", "red mug", ...), plus two auxiliary terms against kind-only ("mug") and
colour-only ("something red") texts that push the embedding to be compositional.

Held out from training: the layouts of the evaluation seeds, and the colour-kind combinations
of :data:`HELDOUT_COMBOS` (a training scene that draws one is repainted). Synonym queries
(:data:`SYNONYMS`) are never training texts. :func:`evaluate_vision` defines the metrics.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError, SceneError

__all__ = [
    "HELDOUT_COMBOS",
    "SYNONYMS",
    "VisionTrainConfig",
    "evaluate_vision",
    "render_dataset",
    "train_vision",
    "vision_classes",
]

log = logging.getLogger(__name__)

#: (kind, colour) pairs never rendered for training; measured zero-shot.
HELDOUT_COMBOS: tuple[tuple[str, str], ...] = (
    ("duck", "pink"),
    ("mug", "green"),
    ("lego_brick", "yellow"),
    ("toy_cube", "blue"),
    ("teddy_bear", "grey"),
    ("ball", "purple"),
)

#: Query nouns that are never training texts, per kind (measured by ``vision_synonym_top1``).
SYNONYMS: dict[str, tuple[str, ...]] = {
    "mug": ("coffee cup", "cup"),
    "duck": ("rubber duck", "rubber ducky"),
    "teddy_bear": ("stuffed bear", "teddy", "plush bear"),
    "lego_brick": ("building block", "lego"),
    "jenga_block": ("wooden block", "jenga piece"),
    "domino": ("domino tile",),
    "soccer_ball": ("football",),
    "tray": ("serving tray",),
    "toy_cube": ("cube", "toy block"),
    "toy_cylinder": ("cylinder",),
    "toy_prism": ("triangular prism",),
    "ball": ("sphere", "small ball"),
}

_OBJECT_TEMPLATES = ("{}", "a {}", "the {}", "a photo of a {}", "a {} on the table", "this {}")
_STUFF_PHRASES = {
    "table": ("table", "the table", "a wooden table", "table top", "the table surface"),
    "robot": ("robot", "the robot", "a robot arm", "the robot arm"),
    "other": ("other", "background", "the floor", "something else"),
}
_COLOUR_TEMPLATES = ("{}", "something {}", "a {} object", "{} thing")
STUFF = ("table", "robot", "other")


def vision_classes() -> list[dict]:
    """The vocabulary: one dict per class with ``name`` (the canonical text), ``kind``
    (catalog kind, or "table"/"robot"/"other"), ``color`` (None when the class has none)."""
    from tabletop.sim.catalog import OBJECT_KINDS

    out = []
    for k in sorted(OBJECT_KINDS):
        kind = OBJECT_KINDS[k]
        if kind.keep_texture:
            out.append({"name": kind.label, "kind": k, "color": None})
        else:
            for c in kind.colors:
                out.append({"name": f"{c} {kind.label}", "kind": k, "color": c})
    for s in STUFF:
        out.append({"name": s, "kind": s, "color": None})
    return out


@dataclass(frozen=True)
class VisionTrainConfig:
    """How ``tabletop train vision`` renders its data and trains (seeded, CPU)."""

    seed: int = 0
    """Seeds layouts, cameras, lighting, initialisation and batches."""
    train_layouts: int = 110
    """Random scenes rendered for training (layout seeds ``seed * 100_000 + i``)."""
    views_per_layout: int = 14
    """Camera poses rendered per training scene."""
    eval_layouts: int = 16
    """Held-out scenes measured after training (layout seeds ``EVAL_SEED_BASE + i``)."""
    eval_views: int = 6
    """Camera poses per held-out scene."""
    steps: int = 2000
    """Optimiser steps."""
    batch_size: int = 8
    """Images per step."""
    crop: tuple[int, int] = (256, 192)
    """(width, height) [px] of the random training crop (at the camera's native scale)."""
    lr: float = 3e-3
    """Peak AdamW learning rate (one-cycle cosine schedule)."""
    weight_decay: float = 1e-4
    width: int = 32
    """Network width (channels at stride 4; deeper levels use 2x and 4x)."""
    aux_weight: float = 0.3
    """Weight of each auxiliary loss (kind-only, colour-only texts)."""
    n_threads: int = 2
    """torch threads (the machine is shared; 1-2 keeps training polite)."""
    max_minutes: float = 45.0
    """Stop training early (and still save) after this many minutes."""
    out: Path | None = None
    """Where to write the weights; default ``tabletop/data/weights/vision_dense.pt``."""

    def __post_init__(self) -> None:
        for name in ("train_layouts", "views_per_layout", "steps", "batch_size", "n_threads"):
            if getattr(self, name) < 1:
                raise ConfigError(f"VisionTrainConfig.{name} must be >= 1")
        if self.crop[0] % 16 or self.crop[1] % 16:
            raise ConfigError(f"crop {self.crop} must be multiples of 16 px")


EVAL_SEED_BASE = 9_000_000


# --------------------------------------------------------------------------- rendering
def _layout(layout_seed: int, heldout: bool):
    """A scene spec for a layout seed; held-out combos repainted (training) or favoured."""
    from tabletop.sim.catalog import object_kind
    from tabletop.sim.generator import generate_objects
    from tabletop.sim.scene import ObjectSpec, RandomSpec, SceneSpec, TableSpec

    rng = np.random.default_rng([layout_seed, 17])
    base = np.array(TableSpec().color)
    table = TableSpec(color=tuple(np.clip(base + rng.uniform(-0.08, 0.08, 3), 0, 1)))
    count = int(rng.integers(6, 12))
    while True:  # a crowded draw may not fit: ask for one object fewer
        try:
            objs = generate_objects(RandomSpec(seed=layout_seed, count=count, duplicates=2), table)
            break
        except SceneError:
            count -= 1
    held = set(HELDOUT_COMBOS)
    out, names = [], set()
    for o in objs:
        colors = [c for c in object_kind(o.kind).colors]
        twins = {p.color for p in objs if p.kind == o.kind and p is not o}
        color = o.color
        if not object_kind(o.kind).keep_texture:
            if not heldout and (o.kind, color) in held:
                ok = [c for c in colors if (o.kind, c) not in held and c not in twins]
                color = str(rng.choice(ok)) if ok else color
            elif heldout:
                hc = [c for k, c in HELDOUT_COMBOS if k == o.kind and c not in twins]
                if hc and rng.random() < 0.6:
                    color = hc[0]
        name = f"{color}_{o.kind}"
        i = 2
        while name in names:
            name, i = f"{color}_{o.kind}_{i}", i + 1
        names.add(name)
        out.append(ObjectSpec(name, o.kind, color, o.position, o.yaw_deg))
    return SceneSpec(name=f"vision-{layout_seed}", table=table, objects=tuple(out))


def _camera(rng: np.random.Generator, objects) -> np.ndarray:
    """A random wrist-camera-like pose (OpenCV) looking at the table."""
    from tabletop.sim.teleop import look_at

    if objects and rng.random() < 0.7:
        o = objects[int(rng.integers(len(objects)))]
        target = np.array([*o.position, 0.0]) + np.array([*rng.normal(0, 0.08, 2), 0.0])
    elif rng.random() < 0.15:  # towards the robot base: the arm in view
        target = np.array([rng.uniform(0.0, 0.25), rng.uniform(-0.3, 0.3), 0.0])
    else:
        target = np.array([rng.uniform(0.25, 0.78), rng.uniform(-0.48, 0.48), 0.0])
    h = rng.uniform(0.3, 0.7)
    back = rng.uniform(0.0, 0.35)  # horizontal offset of the eye: the tilt
    a = rng.uniform(-np.pi / 2, np.pi / 2) if rng.random() < 0.3 else rng.normal(0, 0.5)
    eye = target + np.array([-back * np.cos(a), -back * np.sin(a), h])
    eye[0] = max(eye[0], 0.1)
    return look_at(eye, target, roll=float(rng.uniform(-0.7, 0.7)))


def _render_lit(world, T_world_cam: np.ndarray, rng: np.random.Generator):
    """Render like :meth:`SimWorld.render` with a random light (direction, colour, strength).

    Uses the world's PyBullet client directly: ``SimWorld.render`` has a fixed light.
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
    return rgb, inst


def render_dataset(
    layout_seeds, views: int, heldout: bool, seed: int, lit: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Render ``views`` images of each layout: ((N, H, W, 3) uint8, (N, H, W) int16 class ids
    into :func:`vision_classes`). ``lit=False`` uses :meth:`SimWorld.render` (fixed light)."""
    from tabletop.sim.catalog import object_kind
    from tabletop.sim.world import (
        INSTANCE_FLOOR,
        INSTANCE_NONE,
        INSTANCE_ROBOT,
        INSTANCE_TABLE,
        SimWorld,
    )

    classes = vision_classes()
    index = {(c["kind"], c["color"]): i for i, c in enumerate(classes)}
    rgbs, labels = [], []
    for ls in layout_seeds:
        spec = _layout(int(ls), heldout)
        rng = np.random.default_rng([int(ls), seed, 5])
        with SimWorld(spec) as world:
            lut = np.full(max(world.instance_names) + 1, index[("other", None)], np.int16)
            lut[INSTANCE_TABLE] = index[("table", None)]
            lut[INSTANCE_ROBOT] = index[("robot", None)]
            lut[INSTANCE_FLOOR] = lut[INSTANCE_NONE] = index[("other", None)]
            for o in spec.objects:
                col = None if object_kind(o.kind).keep_texture else o.color
                lut[world.object_instance[o.name]] = index[(o.kind, col)]
            q = world.arm_q() + rng.normal(0, 0.25, 7)
            world.set_arm(q)
            for _ in range(views):
                T = _camera(rng, spec.objects)
                if lit:
                    rgb, inst = _render_lit(world, T, rng)
                else:
                    img = world.render(T)
                    rgb, inst = img.rgb, img.segmentation
                rgbs.append(rgb)
                labels.append(lut[inst])
    return np.stack(rgbs), np.stack(labels)


# --------------------------------------------------------------------------- text side
def _text_tables(encoder) -> dict:
    """MiniLM embeddings: per class a (P, 384) stack of phrasings; kind and colour tables."""
    from tabletop.sim.catalog import COLORS, OBJECT_KINDS

    classes = vision_classes()
    phr = []
    for c in classes:
        if c["kind"] in _STUFF_PHRASES:
            phr.append(list(_STUFF_PHRASES[c["kind"]]))
        else:
            phr.append([t.format(c["name"]) for t in _OBJECT_TEMPLATES])
    kinds = sorted(OBJECT_KINDS) + list(STUFF)
    kind_phr = [
        [t.format(OBJECT_KINDS[k].label) for t in _OBJECT_TEMPLATES]
        if k in OBJECT_KINDS
        else list(_STUFF_PHRASES[k])
        for k in kinds
    ]
    colours = sorted(COLORS)
    col_phr = [[t.format(c) for t in _COLOUR_TEMPLATES] for c in colours]
    return {
        "cls": [encoder.encode_text(p) for p in phr],
        "kind": [encoder.encode_text(p) for p in kind_phr],
        "kinds": kinds,
        "col": [encoder.encode_text(p) for p in col_phr],
        "colours": colours,
    }


# --------------------------------------------------------------------------- training
def _default_out() -> Path:
    from tabletop.mapping.encoders.lseg import VISION_WEIGHTS_PATH

    return VISION_WEIGHTS_PATH


def _augment(x, rng: np.random.Generator, torch):
    """Photometric jitter of a (B, 3, h, w) [0, 1] batch: gain, per-channel tint, noise."""
    B = x.shape[0]
    gain = torch.from_numpy(rng.uniform(0.75, 1.25, (B, 1, 1, 1)).astype(np.float32))
    tint = torch.from_numpy(rng.uniform(0.95, 1.05, (B, 3, 1, 1)).astype(np.float32))
    x = x * gain * tint + torch.randn_like(x) * float(rng.uniform(0, 0.02))
    return x.clamp_(0, 1)


def train_vision(config: VisionTrainConfig | None = None) -> Path:
    """Render the data, train the network, measure it on held-out layouts, save the weights.

    Returns the path written (``config.out`` or ``tabletop/data/weights/vision_dense.pt``).
    Deterministic for a given config on a given machine (seeded renders, init and batches).
    """
    import torch
    import torch.nn.functional as F

    from tabletop.mapping.encoders.lseg import _MEAN, _STD, LSegNet
    from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder

    cfg = config or VisionTrainConfig()
    out = Path(cfg.out) if cfg.out is not None else _default_out()
    t0 = time.monotonic()
    old_threads = torch.get_num_threads()
    torch.set_num_threads(cfg.n_threads)
    try:
        torch.manual_seed(cfg.seed)
        rng = np.random.default_rng(cfg.seed)
        seeds = [cfg.seed * 100_000 + i for i in range(cfg.train_layouts)]
        log.info("rendering %d layouts x %d views", len(seeds), cfg.views_per_layout)
        rgbs, labels = render_dataset(seeds, cfg.views_per_layout, heldout=False, seed=cfg.seed)
        t_render = time.monotonic() - t0
        log.info("rendered %d images in %.0f s", len(rgbs), t_render)

        classes = vision_classes()
        tables = _text_tables(MiniLMTextEncoder())
        C = len(classes)
        held_idx = [
            i for i, c in enumerate(classes) if (c["kind"], c["color"]) in set(HELDOUT_COMBOS)
        ]
        train_cls = np.array([i for i in range(C) if i not in held_idx])
        remap = np.full(C, -1, np.int64)
        remap[train_cls] = np.arange(len(train_cls))
        kind_of = np.array([tables["kinds"].index(c["kind"]) for c in classes])
        col_of = np.array(
            [tables["colours"].index(c["color"]) if c["color"] else -1 for c in classes]
        )
        counts = np.bincount(labels.ravel(), minlength=C).astype(np.float64)
        w_cls = 1.0 / np.sqrt(np.maximum(counts[train_cls], 1.0))
        w_cls = torch.tensor(w_cls / w_cls.mean(), dtype=torch.float32)

        net = LSegNet(width=cfg.width)
        opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        sched = torch.optim.lr_scheduler.OneCycleLR(
            opt, max_lr=cfg.lr, total_steps=cfg.steps, pct_start=0.08
        )
        mean = torch.tensor(_MEAN).view(1, 3, 1, 1)
        std = torch.tensor(_STD).view(1, 3, 1, 1)
        N, H, W = labels.shape
        cw, ch = cfg.crop
        net.train()
        step = 0
        for step in range(cfg.steps):
            idx = rng.integers(0, N, cfg.batch_size)
            x0s = rng.integers(0, W - cw + 1, cfg.batch_size)
            y0s = rng.integers(0, H - ch + 1, cfg.batch_size)
            flip = rng.random(cfg.batch_size) < 0.5
            xb = np.stack(
                [
                    rgbs[i, y : y + ch, x : x + cw][:, :: -1 if f else 1]
                    for i, x, y, f in zip(idx, x0s, y0s, flip, strict=True)
                ]
            )
            yb = np.stack(
                [
                    labels[i, y + 2 : y + ch : 4, x + 2 : x + cw : 4][:, :: -1 if f else 1]
                    for i, x, y, f in zip(idx, x0s, y0s, flip, strict=True)
                ]
            )
            x = torch.from_numpy(xb).float().div_(255).permute(0, 3, 1, 2)
            x = (_augment(x, rng, torch) - mean) / std
            y = torch.from_numpy(yb.astype(np.int64))
            emb = net(x)  # (B, D, h, w)
            f = emb.permute(0, 2, 3, 1).reshape(-1, emb.shape[1])
            yf = y.reshape(-1)
            scale = net.logit_scale.exp().clamp(max=100)
            pick = lambda tab: torch.from_numpy(  # noqa: E731 - one phrasing per entry
                np.stack([t[rng.integers(len(t))] for t in tab])
            )
            T_cls = pick(tables["cls"])[torch.from_numpy(train_cls)]
            loss = F.cross_entropy(scale * f @ T_cls.T, torch.from_numpy(remap)[yf], weight=w_cls)
            T_kind = pick(tables["kind"])
            loss_k = F.cross_entropy(scale * f @ T_kind.T, torch.from_numpy(kind_of)[yf])
            cy = torch.from_numpy(col_of)[yf]
            m = cy >= 0
            loss_c = (
                F.cross_entropy(scale * f[m] @ pick(tables["col"]).T, cy[m])
                if bool(m.any())
                else torch.zeros(())
            )
            total = loss + cfg.aux_weight * (loss_k + loss_c)
            opt.zero_grad(set_to_none=True)
            total.backward()
            opt.step()
            sched.step()
            if step % 50 == 0:
                log.info(
                    "step %d/%d loss %.3f (kind %.3f colour %.3f) scale %.1f  %.0f s",
                    step, cfg.steps, loss.item(), loss_k.item(), loss_c.item(),
                    scale.item(), time.monotonic() - t0,
                )  # fmt: skip
            if (time.monotonic() - t0) / 60 > cfg.max_minutes:
                log.warning("stopping at step %d: max_minutes reached", step)
                break
        net.eval()
        t_train = time.monotonic() - t0 - t_render
        ckpt = {
            "space": MINILM_SPACE,
            "dim": 384,
            "width": cfg.width,
            "stride": 4,
            "state_dict": {k: v.detach().half() for k, v in net.state_dict().items()},
            "config": {
                k: (list(v) if isinstance(v, tuple) else v)
                for k, v in asdict(cfg).items()
                if k != "out"
            },
            "steps_done": step + 1,
            "render_s": round(t_render, 1),
            "train_s": round(t_train, 1),
            "classes": [c["name"] for c in classes],
            "metrics": {},
        }
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(".tmp")
        torch.save(ckpt, tmp)
        tmp.replace(out)
        from tabletop.mapping.encoders import lseg

        lseg._load.cache_clear()
        metrics = evaluate_vision(
            weights=out, layouts=cfg.eval_layouts, views=cfg.eval_views, seed=cfg.seed
        )
        ckpt["metrics"] = metrics
        torch.save(ckpt, tmp)
        tmp.replace(out)
        lseg._load.cache_clear()
        log.info("held-out: %s", metrics)
        return out
    finally:
        torch.set_num_threads(old_threads)


# --------------------------------------------------------------------------- evaluation
def evaluate_vision(
    weights: str | Path | None = None,
    layouts: int = 3,
    views: int = 4,
    seed: int = 0,
    encoder=None,
) -> dict:
    """Measure an image encoder on held-out layouts (seeds training never used).

    ``layouts`` scenes (``EVAL_SEED_BASE + i``) x ``views`` camera poses, rendered with the
    simulator's fixed light, held-out colour-kind combinations favoured. The vocabulary is
    every class of :func:`vision_classes` (all catalog colour-kind labels, held-out combos
    included, plus "table", "robot", "other"); a pixel's prediction is the class whose
    canonical text embedding has the highest dot product with the pixel's cell embedding.

    Returns fractions in [0, 1]:

    - ``vision_top1_heldout``: per-pixel top-1 over object pixels (pixels of any object).
    - ``vision_miou_heldout``: mean IoU over the classes present in the ground truth.
    - ``vision_top1_unseen_combos``: per-pixel top-1 over pixels of :data:`HELDOUT_COMBOS`.
    - ``vision_kind_top1_heldout``: per-pixel kind accuracy (colour ignored) on object pixels.
    - ``vision_object_top1_heldout``: per object instance in a view (>= 30 px), the class of the
      mean cell embedding over its pixels.
    - ``vision_synonym_top1``: per object instance in a view, with its class text replaced by
      a synonym phrase ("red coffee cup"; :data:`SYNONYMS`, never training texts), whether the
      mean embedding's best match is the synonym phrase; averaged over all synonyms.
    - ``vision_synonym_pixel_top1``: the same per pixel.
    """
    from tabletop.mapping.encoders.lseg import LSegEncoder
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    enc = encoder if encoder is not None else LSegEncoder(weights)
    text = MiniLMTextEncoder()
    classes = vision_classes()
    C = len(classes)
    T = text.encode_text([c["name"] for c in classes])  # (C, 384)
    seeds = [EVAL_SEED_BASE + i for i in range(layouts)]
    rgbs, labels = render_dataset(seeds, views, heldout=True, seed=seed + 1, lit=False)
    stuff = {classes.index(next(c for c in classes if c["kind"] == s)) for s in STUFF}
    held = {i for i, c in enumerate(classes) if (c["kind"], c["color"]) in set(HELDOUT_COMBOS)}
    kind_of = np.array([c["kind"] for c in classes])

    inter = np.zeros(C)
    union = np.zeros(C)
    present = np.zeros(C, bool)
    obj_ok = obj_n = held_ok = held_n = kind_ok = 0
    inst_ok = inst_n = 0
    syn_ok = syn_n = syn_px_ok = syn_px_n = 0
    for rgb, lab in zip(rgbs, labels, strict=True):
        dense = enc.encode_dense(rgb)
        s = enc.stride
        feat = np.repeat(np.repeat(dense, s, axis=0), s, axis=1)[: lab.shape[0], : lab.shape[1]]
        scores = feat @ T.T  # (H, W, C)
        pred = scores.argmax(-1)
        for c in np.unique(lab):
            present[c] = True
        for c in range(C):
            a, b = pred == c, lab == c
            inter[c] += np.sum(a & b)
            union[c] += np.sum(a | b)
        objm = ~np.isin(lab, list(stuff))
        obj_ok += int(np.sum((pred == lab) & objm))
        obj_n += int(objm.sum())
        kind_ok += int(np.sum((kind_of[pred] == kind_of[lab]) & objm))
        hm = np.isin(lab, list(held))
        held_ok += int(np.sum((pred == lab) & hm))
        held_n += int(hm.sum())
        for c in np.unique(lab[objm]):
            m = lab == c
            if m.sum() < 30:
                continue
            f = feat[m]
            g = f.mean(0)
            inst_ok += int(np.argmax(T @ g) == c)
            inst_n += 1
            kind = classes[c]["kind"]
            col = classes[c]["color"]
            for syn in SYNONYMS[kind]:
                q = text.encode_text([f"{col} {syn}" if col else syn])[0]
                Tq = T.copy()
                Tq[c] = q
                syn_ok += int(np.argmax(Tq @ g) == c)
                syn_n += 1
                syn_px_ok += int(np.sum((f @ Tq.T).argmax(-1) == c))
                syn_px_n += int(m.sum())
    valid = present & (union > 0)
    frac = lambda a, b: float(a / b) if b else float("nan")  # noqa: E731
    return {
        "vision_top1_heldout": frac(obj_ok, obj_n),
        "vision_miou_heldout": float(np.mean(inter[valid] / union[valid])),
        "vision_top1_unseen_combos": frac(held_ok, held_n),
        "vision_kind_top1_heldout": frac(kind_ok, obj_n),
        "vision_object_top1_heldout": frac(inst_ok, inst_n),
        "vision_synonym_top1": frac(syn_ok, syn_n),
        "vision_synonym_pixel_top1": frac(syn_px_ok, syn_px_n),
        "vision_eval_images": len(rgbs),
        "vision_eval_instances": inst_n,
    }

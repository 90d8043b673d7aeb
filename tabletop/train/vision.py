"""Train and evaluate the embedded default image encoder (``tabletop train vision``).

LSeg-style training into MiniLM's text space. Images come from :mod:`tabletop.sim`: seeded
random layouts (:func:`~tabletop.sim.generator.generate_objects`), random camera poses over the
table (tilted and rolled like the wrist camera of a scan), random light direction, colour and
strength, a jittered table colour. :class:`RenderVariety` adds more (all of it on by default
since the EfficientNet encoder): table colours from a palette, table textures, wider camera
heights and tilts, and distractor objects from ``pybullet_data/random_urdfs`` labelled
"other". Each pixel's class comes from the simulator's segmentation: an object's label with
its colour ("red mug"; textured kinds — jenga block, domino, soccer ball, tray — have no
colour in their class since their texture hides it), "table", "robot" or "other" (floor,
nothing, distractors).

Two networks (``VisionTrainConfig.backbone``): ``"effnet-lite0"`` (the default: an
ImageNet-pretrained EfficientNet-Lite0 with an FPN head,
:mod:`tabletop.mapping.encoders.effnet`; initialising it needs the ``train`` extra) and
``"small"`` (:class:`~tabletop.mapping.encoders.lseg.LSegNet` from scratch, the first
encoder). Their pixel embeddings are contrasted (softmax cross-entropy, learned temperature)
against MiniLM embeddings of the class names, one phrasing per class drawn each step from
several templates ("a red mug", "the red mug", "red mug", ...) or, with ``prompt_ensemble``,
half the time the normalised mean of every phrasing (a prompt ensemble, as CLIP and LSeg use),
plus two auxiliary terms against kind-only ("mug") and colour-only ("something red") texts
that push the embedding to be compositional.

Held out from training: the layouts of the evaluation seeds, and the colour-kind combinations
of :data:`HELDOUT_COMBOS` (a training scene that draws one is repainted). Synonym queries
(:data:`SYNONYMS`) are never training texts. :func:`evaluate_vision` defines the metrics.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import ConfigError, SceneError
from tabletop.parallel import Backend
from tabletop.train.vision_render import ROOM_STUFF, STUFF, predict_pixels, vision_classes
from tabletop.train.vision_render import render_lit as _render_lit

__all__ = [
    "BACKBONES",
    "HELDOUT_COMBOS",
    "SYNONYMS",
    "TABLE_PALETTE",
    "RenderVariety",
    "VisionTrainConfig",
    "default_vision_out",
    "evaluate_vision",
    "render_dataset",
    "train_vision",
    "training_texts",
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
# More phrasings for ``prompt_ensemble`` (none of them a synonym of SYNONYMS).
_OBJECT_TEMPLATES_MORE = (
    "a photo of the {}",
    "a rendering of a {}",
    "a {} seen from above",
    "there is a {} here",
    "an image of a {}",
    "a close-up photo of a {}",
)
_STUFF_PHRASES_MORE = {
    "table": ("a table", "the tabletop", "the top of the table", "a table surface"),
    "robot": ("a robotic arm", "the robot's arm", "part of the robot"),
    "other": ("an unknown object", "some other object", "the ground", "nothing of interest"),
}
_COLOUR_TEMPLATES_MORE = ("the {} one", "an object that is {}", "a {} thing")
_ROOM_PHRASES = {
    "floor": ("floor", "the floor", "the ground", "a floor"),
    "wall": ("wall", "the wall", "a wall", "a room wall"),
    "shelf": ("shelf", "the shelf", "a shelf", "a shelving unit"),
    "cabinet": ("cabinet", "the cabinet", "a cabinet", "a cupboard"),
    "sofa": ("sofa", "the sofa", "a sofa", "a couch"),
}
_ROOM_PHRASES_MORE = {
    "floor": ("the floor of the room", "floor tiles"),
    "wall": ("the wall of the room", "a painted wall"),
    "shelf": ("a tall shelf", "the shelving"),
    "cabinet": ("a wooden cabinet", "the cupboard"),
    "sofa": ("a fabric sofa", "the couch"),
}

BACKBONES = ("effnet-lite0", "small")
"""``VisionTrainConfig.backbone`` values: the ImageNet-pretrained EfficientNet-Lite0 with an
FPN head (``effnet-lite0-fpn`` weights), or the small network trained from scratch
(``lseg-small``)."""

#: Table-top colours (RGB [0, 1]) a training layout may take (``RenderVariety.table_palette``).
TABLE_PALETTE: tuple[tuple[float, float, float], ...] = (
    (0.62, 0.47, 0.33),  # the default wood
    (0.80, 0.66, 0.48),  # light wood
    (0.40, 0.26, 0.16),  # dark wood
    (0.88, 0.87, 0.84),  # white laminate
    (0.68, 0.68, 0.68),  # light grey
    (0.32, 0.32, 0.34),  # dark grey
    (0.14, 0.14, 0.15),  # black
    (0.22, 0.42, 0.30),  # green felt
    (0.30, 0.40, 0.58),  # blue-grey
    (0.84, 0.77, 0.62),  # beige
)


@dataclass(frozen=True)
class RenderVariety:
    """What training renders vary beyond layouts, lights and the jittered default table.

    All off (the defaults here) = the renders the first (``small``) encoder was trained on;
    held-out evaluation renders never use any of it. Drawn from their own random stream
    (seeded by the layout seed), so switching one off leaves the others' draws unchanged.
    """

    table_palette: float = 0.0
    """Probability [0, 1] that a layout's table takes a :data:`TABLE_PALETTE` colour (jittered)
    instead of the jittered default wood."""
    table_texture: float = 0.0
    """Probability [0, 1] that a view's table pixels get a texture (wood-like grain and
    blotches, drawn in image space on the table's segmentation mask)."""
    wide_cameras: bool = False
    """Cameras 0.2-0.85 m above the table, up to 0.5 m of horizontal offset (steeper tilts),
    roll up to 1.0 rad; off: 0.3-0.7 m, 0.35 m, 0.7 rad (the scan's range)."""
    max_distractors: int = 0
    """Up to this many ``pybullet_data/random_urdfs`` objects per layout (random shape, size,
    colour), labelled "other"."""

    def __post_init__(self) -> None:
        for name in ("table_palette", "table_texture"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"RenderVariety.{name} must be a probability in [0, 1]")
        if self.max_distractors < 0:
            raise ConfigError("RenderVariety.max_distractors must be >= 0")

    @property
    def active(self) -> bool:
        return bool(
            self.table_palette or self.table_texture or self.wide_cameras or self.max_distractors
        )


@dataclass(frozen=True)
class VisionTrainConfig:
    """How ``tabletop train vision`` renders its data and trains (seeded, CPU).

    The defaults train the EfficientNet-Lite0 encoder (``vision_dense_effnet.pt``). The first
    encoder (``vision_dense.pt``) was ``backbone="small"``, 110 layouts x 14 views, 2000 steps,
    no :class:`RenderVariety`, ``prompt_ensemble=False``, 2 threads.
    """

    seed: int = 0
    """Seeds layouts, cameras, lighting, initialisation and batches."""
    backbone: str = "effnet-lite0"
    """Network: one of :data:`BACKBONES`."""
    pretrained: bool = True
    """``effnet-lite0``: start the backbone from the ImageNet weights (the ``train`` extra);
    False = random initialisation (an ablation)."""
    train_layouts: int = 220
    """Random scenes rendered for training (layout seeds ``seed * 100_000 + i``)."""
    views_per_layout: int = 12
    """Camera poses rendered per training scene."""
    eval_layouts: int = 16
    """Held-out scenes measured after training (layout seeds ``EVAL_SEED_BASE + i``)."""
    eval_views: int = 6
    """Camera poses per held-out scene."""
    steps: int = 2400
    """Optimiser steps."""
    batch_size: int = 8
    """Images per step."""
    crop: tuple[int, int] = (256, 192)
    """(width, height) [px] of the random training crop (at the camera's native scale)."""
    lr: float = 3e-3
    """Peak AdamW learning rate of the head (one-cycle cosine schedule)."""
    backbone_lr_mult: float = 0.1
    """``effnet-lite0``: the pretrained backbone's learning rate as a fraction of ``lr``."""
    freeze_stages: int = 2
    """``effnet-lite0`` (pretrained): the stem and this many MBConv stages stay frozen (2 = up
    to stride 4); every backbone BatchNorm keeps its ImageNet statistics."""
    weight_decay: float = 1e-4
    width: int = 32
    """``small``: network width (channels at stride 4; deeper levels use 2x and 4x)."""
    fpn: int = 96
    """``effnet-lite0``: channels of the top-down fusion."""
    last_stage: int = 6
    """``effnet-lite0``: the last backbone stage kept (6 = all, to stride 32; 4 = stride 16)."""
    aux_weight: float = 0.3
    """Weight of each auxiliary loss (kind-only, colour-only texts)."""
    table_palette: float = 0.5
    """See :class:`RenderVariety`."""
    table_texture: float = 0.3
    """See :class:`RenderVariety`."""
    wide_cameras: bool = True
    """See :class:`RenderVariety`."""
    max_distractors: int = 3
    """See :class:`RenderVariety`."""
    prompt_ensemble: bool = True
    """More phrasings per class, and half the steps contrast against the mean of all of them."""
    room_layouts: int = 0
    """Generated rooms rendered for training (:mod:`tabletop.train.vision_rooms`: the mast
    camera's view, furniture, walls and floor as classes); 0 = the table alone."""
    room_views: int = 16
    """Camera poses rendered per training room."""
    room_share: float = 0.5
    """With rooms: the fraction of each batch drawn from the room renders."""
    room_scale: int = 1
    """With rooms: the room renders are enlarged this many times (objects metres away then look
    as large as on the table), as a room map's encoder enlarges its frames
    (``MapConfig.image_scale``)."""
    eval_rooms: int = 6
    """With rooms: held-out rooms measured after training."""
    eval_room_views: int = 8
    """With rooms: camera poses per held-out room."""
    init: str | None = None
    """A weights file of the same network to start from instead of the ImageNet backbone (a
    fine-tune; the file's own recipe is how it was made)."""
    n_threads: int = 1
    """torch threads (the machine is shared; 1 keeps training polite)."""
    max_minutes: float = 75.0
    """Stop training early (and still save) after this many minutes."""
    out: Path | None = None
    """Where to write the weights; default :func:`default_vision_out` of the backbone."""

    def __post_init__(self) -> None:
        for name in ("train_layouts", "views_per_layout", "steps", "batch_size", "n_threads"):
            if getattr(self, name) < 1:
                raise ConfigError(f"VisionTrainConfig.{name} must be >= 1")
        for name in ("room_layouts", "room_views", "eval_rooms", "eval_room_views"):
            if getattr(self, name) < 0:
                raise ConfigError(f"VisionTrainConfig.{name} must be >= 0")
        if self.room_scale not in (1, 2):
            raise ConfigError(f"room_scale must be 1 or 2, got {self.room_scale!r}")
        if not 0.0 <= self.room_share < 1.0:
            raise ConfigError(f"room_share must be in [0, 1), got {self.room_share}")
        if self.init is not None and not Path(self.init).is_file():
            raise ConfigError(f"init weights {self.init!r} are not a file")
        if self.crop[0] % 16 or self.crop[1] % 16:
            raise ConfigError(f"crop {self.crop} must be multiples of 16 px")
        if self.backbone not in BACKBONES:
            raise ConfigError(f"unknown backbone {self.backbone!r}; valid: {list(BACKBONES)}")
        if not 0 <= self.freeze_stages <= 7:
            raise ConfigError(f"freeze_stages must be in 0..7, got {self.freeze_stages}")
        if self.backbone_lr_mult < 0:
            raise ConfigError("backbone_lr_mult must be >= 0")
        self.variety  # noqa: B018 - checks the RenderVariety fields

    @property
    def variety(self) -> RenderVariety:
        return RenderVariety(
            table_palette=self.table_palette,
            table_texture=self.table_texture,
            wide_cameras=self.wide_cameras,
            max_distractors=self.max_distractors,
        )


EVAL_SEED_BASE = 9_000_000


def room_recipe() -> dict:
    """:class:`VisionTrainConfig` fields of the room-aware encoder (``tabletop train vision
    --rooms``, ``vision_dense_room.pt``): the committed table encoder fine-tuned on half
    table, half room renders enlarged twice (:mod:`tabletop.train.vision_rooms`), as room maps
    enlarge their frames (``MapConfig.image_scale``)."""
    from tabletop.mapping.encoders.lseg import EFFNET_WEIGHTS_PATH

    return {
        "init": str(EFFNET_WEIGHTS_PATH),
        "train_layouts": 80,
        "views_per_layout": 12,
        "room_layouts": 60,
        "room_views": 16,
        "room_share": 0.5,
        "room_scale": 2,
        "steps": 1200,
        "lr": 1.5e-3,
    }


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


def _camera(rng: np.random.Generator, objects, wide: bool = False) -> np.ndarray:
    """A random wrist-camera-like pose (OpenCV) looking at the table (``wide``: see
    :attr:`RenderVariety.wide_cameras`)."""
    from tabletop.sim.teleop import look_at

    if objects and rng.random() < 0.7:
        o = objects[int(rng.integers(len(objects)))]
        target = np.array([*o.position, 0.0]) + np.array([*rng.normal(0, 0.08, 2), 0.0])
    elif rng.random() < 0.15:  # towards the robot base: the arm in view
        target = np.array([rng.uniform(0.0, 0.25), rng.uniform(-0.3, 0.3), 0.0])
    else:
        target = np.array([rng.uniform(0.25, 0.78), rng.uniform(-0.48, 0.48), 0.0])
    h = rng.uniform(0.2, 0.85) if wide else rng.uniform(0.3, 0.7)
    back = rng.uniform(0.0, 0.5 if wide else 0.35)  # horizontal offset of the eye: the tilt
    a = rng.uniform(-np.pi / 2, np.pi / 2) if rng.random() < 0.3 else rng.normal(0, 0.5)
    eye = target + np.array([-back * np.cos(a), -back * np.sin(a), h])
    eye[0] = max(eye[0], 0.1)
    roll = 1.0 if wide else 0.7
    return look_at(eye, target, roll=float(rng.uniform(-roll, roll)))


def _vary_table(spec, rng: np.random.Generator, variety: RenderVariety):
    """``spec`` with its table painted a jittered :data:`TABLE_PALETTE` colour (sometimes)."""
    from tabletop.sim.scene import SceneSpec

    if variety.table_palette and rng.random() < variety.table_palette:
        base = np.array(TABLE_PALETTE[int(rng.integers(len(TABLE_PALETTE)))])
        color = tuple(float(v) for v in np.clip(base + rng.uniform(-0.05, 0.05, 3), 0, 1))
        return SceneSpec(
            name=spec.name,
            table=replace(spec.table, color=color),
            objects=spec.objects,
            areas=spec.areas,
        )
    return spec


def _add_distractors(world, spec, rng: np.random.Generator, n: int) -> list[int]:
    """Place up to ``n`` random ``pybullet_data/random_urdfs`` objects on free table spots
    (random size, yaw and, half the time, colour). Returns their PyBullet body ids."""
    from tabletop.sim.catalog import pybullet_data_dir

    pb, cid = world._pb, world._client
    root = pybullet_data_dir() / "random_urdfs"
    boxes = [o.aabb() for o in spec.objects]
    bodies: list[int] = []
    for _ in range(n):
        i = int(rng.integers(1000))
        urdf = root / f"{i:03d}" / f"{i:03d}.urdf"
        if not urdf.is_file():
            continue
        body = pb.loadURDF(
            str(urdf),
            [0.0, 0.0, 1.0],
            useFixedBase=True,
            globalScaling=float(rng.uniform(0.5, 1.2)),
            physicsClientId=cid,
        )
        lo, hi = (np.array(v) for v in pb.getAABB(body, physicsClientId=cid))
        half = (hi[:2] - lo[:2]) / 2
        yaw = float(rng.uniform(-np.pi, np.pi))
        for _try in range(20):
            xy = np.array([rng.uniform(0.15, 0.75), rng.uniform(-0.5, 0.5)])
            blo, bhi = xy - half - 0.015, xy + half + 0.015
            if all(np.any(blo > h[:2]) or np.any(bhi < l_[:2]) for l_, h in boxes):
                break
        else:
            pb.removeBody(body, physicsClientId=cid)
            continue
        centre = (lo + hi) / 2
        pos = [xy[0] - centre[0], xy[1] - centre[1], 1.0 - lo[2] + 0.001]
        quat = pb.getQuaternionFromEuler([0.0, 0.0, yaw])
        pb.resetBasePositionAndOrientation(body, pos, quat, physicsClientId=cid)
        if rng.random() < 0.5:
            rgba = [*rng.uniform(0.05, 0.95, 3).tolist(), 1.0]
            pb.changeVisualShape(body, -1, rgbaColor=rgba, physicsClientId=cid)
        boxes.append((np.array([*blo, 0.0]), np.array([*bhi, 0.0])))
        bodies.append(body)
    return bodies


def _texture(rgb: np.ndarray, mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``rgb`` with a random wood-like texture (low-frequency blotches, grain stripes) on the
    pixels of ``mask`` (H, W) bool: a multiplicative field drawn in image space."""
    import cv2

    H, W = mask.shape
    blot = rng.normal(0, 1, (max(H // 24, 2), max(W // 24, 2))).astype(np.float32)
    field = cv2.resize(blot, (W, H), interpolation=cv2.INTER_CUBIC) * rng.uniform(0.04, 0.15)
    th = rng.uniform(0, np.pi)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    u = xx * np.cos(th) + yy * np.sin(th)
    wobble = cv2.resize(
        rng.normal(0, 1, (max(H // 40, 2), max(W // 40, 2))).astype(np.float32), (W, H)
    )
    period = rng.uniform(3.0, 14.0)
    grain = np.sin(2 * np.pi * u / period + 3.0 * wobble) * rng.uniform(0.0, 0.12)
    gain = 1.0 + field + grain
    out = rgb.astype(np.float32)
    out[mask] *= gain[mask][:, None]
    return np.clip(out, 0, 255).astype(np.uint8)


def render_dataset(
    layout_seeds,
    views: int,
    heldout: bool,
    seed: int,
    lit: bool = True,
    variety: RenderVariety | None = None,
    backend: Backend | None = None,
    progress=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Render ``views`` images of each layout: ((N, H, W, 3) uint8, (N, H, W) int16 class ids
    into :func:`vision_classes`). ``lit=False`` uses :meth:`SimWorld.render` (fixed light).
    ``variety`` adds :class:`RenderVariety` (training; a robustness check of held-out layouts
    in :func:`evaluate_vision`); None or all off renders what the first encoder was trained
    on, and what the recorded held-out figures measure.

    ``backend`` (:class:`~tabletop.parallel.Backend`: worker processes or Ray tasks) renders
    slices of the layouts in parallel; every layout draws from its own seeded streams, so the
    images are the same as one process renders. ``progress(done, total)`` counts layouts."""
    layout_seeds = [int(ls) for ls in layout_seeds]
    if backend is not None and not backend.serial and len(layout_seeds) > 1:
        from tabletop.parallel import run_units

        n = backend.workers or 8  # Ray: slices for as many CPUs as the cluster gives
        size = max(1, math.ceil(len(layout_seeds) / (4 * n)))  # a few slices per worker
        parts = [layout_seeds[i : i + size] for i in range(0, len(layout_seeds), size)]
        units = [(p, views, heldout, seed, lit, variety) for p in parts]
        done = [0]

        def step(i, _res, _secs):
            done[0] += len(parts[i])
            if progress is not None:
                progress(done[0], len(layout_seeds))

        out = run_units(
            render_dataset, units, backend,
            labels=[f"layouts {p[0]}..{p[-1]}" for p in parts], on_done=step,
        )  # fmt: skip
        return np.concatenate([r for r, _ in out]), np.concatenate([lab for _, lab in out])
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
    variety = variety if variety is not None and variety.active else None
    for ls in layout_seeds:
        spec = _layout(int(ls), heldout)
        rng = np.random.default_rng([int(ls), seed, 5])
        vrng = np.random.default_rng([int(ls), seed, 23])  # variety: its own stream
        if variety is not None:
            spec = _vary_table(spec, vrng, variety)
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
            others: list[int] = []
            if variety is not None and variety.max_distractors:
                n = int(vrng.integers(variety.max_distractors + 1))
                others = _add_distractors(world, spec, vrng, n)
            wide = variety is not None and variety.wide_cameras
            for _ in range(views):
                T = _camera(rng, spec.objects, wide=wide)
                if lit:
                    rgb, inst = _render_lit(world, T, rng, others)
                else:
                    img = world.render(T)
                    rgb, inst = img.rgb, img.segmentation
                    if others:
                        raise ConfigError("distractors need lit renders")
                lab = lut[inst]
                if variety is not None and variety.table_texture:
                    if vrng.random() < variety.table_texture:
                        rgb = _texture(rgb, lab == lut[INSTANCE_TABLE], vrng)
                rgbs.append(rgb)
                labels.append(lab)
        if progress is not None:
            progress(len(rgbs) // views, len(layout_seeds))
    return np.stack(rgbs), np.stack(labels)


# --------------------------------------------------------------------------- text side
def training_texts(ensemble: bool = False, rooms: bool = False) -> dict:
    """The phrasings training contrasts against: ``cls`` (one list per class of
    :func:`vision_classes`), ``kind`` (per kind of ``kinds``), ``col`` (per colour of
    ``colours``). ``ensemble`` adds the extra templates of the prompt ensemble; ``rooms`` the
    classes of :data:`ROOM_STUFF` (and "other" loses its floor phrasings)."""
    from tabletop.sim.catalog import COLORS, OBJECT_KINDS

    obj_t = _OBJECT_TEMPLATES + (_OBJECT_TEMPLATES_MORE if ensemble else ())
    col_t = _COLOUR_TEMPLATES + (_COLOUR_TEMPLATES_MORE if ensemble else ())
    floorish = ("floor", "ground")

    def stuff(k):
        if k in _ROOM_PHRASES:
            return list(_ROOM_PHRASES[k]) + (list(_ROOM_PHRASES_MORE[k]) if ensemble else [])
        out = list(_STUFF_PHRASES[k]) + (list(_STUFF_PHRASES_MORE[k]) if ensemble else [])
        if rooms and k == "other":
            out = [p for p in out if not any(w in p for w in floorish)]
        return out

    classes = vision_classes(rooms)
    phr = [
        [t.format(c["name"]) for t in obj_t] if c["kind"] in OBJECT_KINDS else stuff(c["kind"])
        for c in classes
    ]
    kinds = sorted(OBJECT_KINDS) + list(STUFF) + (list(ROOM_STUFF) if rooms else [])
    kind_phr = [
        [t.format(OBJECT_KINDS[k].label) for t in obj_t] if k in OBJECT_KINDS else stuff(k)
        for k in kinds
    ]
    colours = sorted(COLORS)
    col_phr = [[t.format(c) for t in col_t] for c in colours]
    return {"cls": phr, "kind": kind_phr, "kinds": kinds, "col": col_phr, "colours": colours}


def _text_tables(encoder, ensemble: bool = False, rooms: bool = False) -> dict:
    """MiniLM embeddings of :func:`training_texts`: per entry a (P, 384) stack of phrasings,
    with the normalised mean of the stack appended as one more row when ``ensemble``."""
    texts = training_texts(ensemble, rooms)

    def embed(groups):
        out = []
        for p in groups:
            e = encoder.encode_text(p)
            if ensemble:
                m = e.mean(0, keepdims=True)
                e = np.concatenate([e, m / np.linalg.norm(m)], 0)
            out.append(e.astype(np.float32))
        return out

    return {
        "cls": embed(texts["cls"]),
        "kind": embed(texts["kind"]),
        "kinds": texts["kinds"],
        "col": embed(texts["col"]),
        "colours": texts["colours"],
    }


# --------------------------------------------------------------------------- training
def default_vision_out(backbone: str = "effnet-lite0") -> Path:
    """The committed weights file of a backbone (``vision_dense.pt`` for ``small``,
    ``vision_dense_effnet.pt`` for ``effnet-lite0``)."""
    from tabletop.mapping.encoders.lseg import EFFNET_WEIGHTS_PATH, VISION_WEIGHTS_PATH

    if backbone not in BACKBONES:
        raise ConfigError(f"unknown backbone {backbone!r}; valid: {list(BACKBONES)}")
    return EFFNET_WEIGHTS_PATH if backbone == "effnet-lite0" else VISION_WEIGHTS_PATH


def _augment(x, rng: np.random.Generator, torch):
    """Photometric jitter of a (B, 3, h, w) [0, 1] batch: gain, per-channel tint, noise."""
    B = x.shape[0]
    gain = torch.from_numpy(rng.uniform(0.75, 1.25, (B, 1, 1, 1)).astype(np.float32))
    tint = torch.from_numpy(rng.uniform(0.95, 1.05, (B, 3, 1, 1)).astype(np.float32))
    x = x * gain * tint + torch.randn_like(x) * float(rng.uniform(0, 0.02))
    return x.clamp_(0, 1)


def _build_net(cfg: VisionTrainConfig):
    """(network, parameter groups [(params, lr multiplier)], input mean, input std)."""
    import torch

    from tabletop.mapping.encoders.lseg import _MEAN, _STD, LSegNet

    if cfg.backbone == "small":
        net = LSegNet(width=cfg.width)
        return net, [(list(net.parameters()), 1.0)], _MEAN, _STD
    from tabletop.mapping.encoders.effnet import (
        EFFNET_INPUT_MEAN,
        EFFNET_INPUT_STD,
        LITE0_STAGES,
        build_effnet_lseg_net,
        load_imagenet_backbone,
    )

    net = build_effnet_lseg_net(last_stage=cfg.last_stage, fpn=cfg.fpn)
    bb = net.backbone
    if not cfg.pretrained:
        return net, [(list(net.parameters()), 1.0)], EFFNET_INPUT_MEAN, EFFNET_INPUT_STD
    if cfg.init is None:  # else the init weights replace every parameter (train_vision)
        load_imagenet_backbone(bb)
    n_frozen = sum(r for *_, r in LITE0_STAGES[: cfg.freeze_stages])
    frozen = [*bb.stem.parameters()] if cfg.freeze_stages > 0 else []
    for blk in list(bb.blocks)[:n_frozen]:
        frozen += list(blk.parameters())
    for m in bb.modules():  # BatchNorms keep ImageNet's affine and statistics
        if isinstance(m, torch.nn.BatchNorm2d):
            frozen += [m.weight, m.bias]
    for p in frozen:
        p.requires_grad_(False)
    trainable = [p for p in bb.parameters() if p.requires_grad]
    groups = [(net.head_parameters(), 1.0)]
    if trainable and cfg.backbone_lr_mult > 0:
        groups.append((trainable, cfg.backbone_lr_mult))
    else:
        for p in trainable:
            p.requires_grad_(False)
    return net, groups, EFFNET_INPUT_MEAN, EFFNET_INPUT_STD


def _load_init(net, path) -> None:
    """Start ``net`` from the weights file at ``path`` (the same architecture)."""
    import torch

    ckpt = torch.load(path, map_location="cpu", weights_only=True)
    if ckpt.get("arch") != net.arch or dict(ckpt.get("arch_config", {})) != dict(net.arch_config):
        raise ConfigError(
            f"init weights {path} are {ckpt.get('arch')!r} {ckpt.get('arch_config')}; "
            f"this run trains {net.arch!r} {dict(net.arch_config)}"
        )
    net.load_state_dict({k: v.float() for k, v in ckpt["state_dict"].items()})
    log.info("starting from %s", path)


def _set_train_mode(net, cfg: VisionTrainConfig) -> None:
    """Training mode, except a pretrained backbone's BatchNorms keep their statistics."""
    import torch

    net.train()
    if cfg.backbone == "effnet-lite0" and cfg.pretrained:
        for m in net.backbone.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.eval()


def train_vision(
    config: VisionTrainConfig | None = None, progress=None, backend: Backend | None = None
) -> Path:
    """Render the data, train the network, measure it on held-out layouts, save the weights.

    Returns the path written (``config.out`` or :func:`default_vision_out` of the backbone).
    Deterministic for a given config on a given machine (seeded renders, init and batches).
    ``progress(step, steps)`` is called after every optimiser step when given. ``backend``
    renders the training data in worker processes or on a Ray cluster
    (:func:`render_dataset`: the same images as rendered here).
    """
    import torch
    import torch.nn.functional as F

    from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder

    cfg = config or VisionTrainConfig()
    out = Path(cfg.out) if cfg.out is not None else default_vision_out(cfg.backbone)
    if cfg.backbone == "effnet-lite0" and cfg.pretrained and cfg.init is None:
        from tabletop.mapping.encoders.effnet import imagenet_weights_path

        imagenet_weights_path()  # fail before rendering when the `train` extra is missing
    t0 = time.monotonic()
    old_threads = torch.get_num_threads()
    torch.set_num_threads(cfg.n_threads)
    try:
        torch.manual_seed(cfg.seed)
        rng = np.random.default_rng(cfg.seed)
        seeds = [cfg.seed * 100_000 + i for i in range(cfg.train_layouts)]
        where = backend.describe() if backend is not None else "this process"
        log.info("rendering %d layouts x %d views (%s)", len(seeds), cfg.views_per_layout, where)
        rgbs, labels = render_dataset(
            seeds,
            cfg.views_per_layout,
            heldout=False,
            seed=cfg.seed,
            variety=cfg.variety,
            backend=backend,
        )
        rooms = cfg.room_layouts > 0
        room_rgbs = room_labels = None
        if rooms:
            from tabletop.train.vision_rooms import ROOM_SEED_BASE, render_room_dataset

            room_seeds = [ROOM_SEED_BASE + cfg.seed * 1000 + i for i in range(cfg.room_layouts)]
            log.info("rendering %d rooms x %d views", len(room_seeds), cfg.room_views)
            room_rgbs, room_labels = render_room_dataset(
                room_seeds, cfg.room_views, seed=cfg.seed, backend=backend, scale=cfg.room_scale
            )
        t_render = time.monotonic() - t0
        n_img = len(rgbs) + (0 if room_rgbs is None else len(room_rgbs))
        log.info("rendered %d images in %.0f s", n_img, t_render)

        classes = vision_classes(rooms)
        tables = _text_tables(MiniLMTextEncoder(), ensemble=cfg.prompt_ensemble, rooms=rooms)
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
        if rooms:
            counts += np.bincount(room_labels.ravel(), minlength=C)
        w_cls = 1.0 / np.sqrt(np.maximum(counts[train_cls], 1.0))
        w_cls = torch.tensor(w_cls / w_cls.mean(), dtype=torch.float32)

        net, groups, in_mean, in_std = _build_net(cfg)
        if cfg.init is not None:
            _load_init(net, cfg.init)
        opt = torch.optim.AdamW(
            [{"params": ps, "lr": cfg.lr * m} for ps, m in groups], weight_decay=cfg.weight_decay
        )
        sched = torch.optim.lr_scheduler.OneCycleLR(
            opt, max_lr=[cfg.lr * m for _, m in groups], total_steps=cfg.steps, pct_start=0.08
        )
        mean = torch.tensor(in_mean).view(1, 3, 1, 1)
        std = torch.tensor(in_std).view(1, 3, 1, 1)
        n_room = round(cfg.batch_size * cfg.room_share) if rooms else 0
        parts = [(rgbs, labels, cfg.batch_size - n_room)]
        if n_room:
            parts.append((room_rgbs, room_labels, n_room))
        cw, ch = cfg.crop
        s = int(net.stride)
        _set_train_mode(net, cfg)
        log.info(
            "%s: %.2f M parameters (%.2f M trained)",
            net.arch,
            sum(p.numel() for p in net.parameters()) / 1e6,
            sum(p.numel() for ps, _ in groups for p in ps) / 1e6,
        )

        def pick(tab, use_mean: bool):
            """One phrasing per entry (the last row, the ensemble mean, when ``use_mean``)."""
            if use_mean:
                return torch.from_numpy(np.stack([t[-1] for t in tab]))
            n_ph = (lambda t: len(t) - 1) if cfg.prompt_ensemble else len
            return torch.from_numpy(np.stack([t[rng.integers(n_ph(t))] for t in tab]))

        step = 0
        for step in range(cfg.steps):
            xs, ys = [], []
            for imgs, labs, n in parts:  # the table's draws come first, as without rooms
                N, H, W = labs.shape
                idx = rng.integers(0, N, n)
                x0s = rng.integers(0, W - cw + 1, n)
                y0s = rng.integers(0, H - ch + 1, n)
                flip = rng.random(n) < 0.5
                h2 = s // 2  # the label at each output cell's centre
                for i, x, y, f in zip(idx, x0s, y0s, flip, strict=True):
                    xs.append(imgs[i, y : y + ch, x : x + cw][:, :: -1 if f else 1])
                    ys.append(
                        labs[i, y + h2 : y + ch : s, x + h2 : x + cw : s][:, :: -1 if f else 1]
                    )
            xb, yb = np.stack(xs), np.stack(ys)
            x = torch.from_numpy(xb).float().div_(255).permute(0, 3, 1, 2)
            x = (_augment(x, rng, torch) - mean) / std
            y = torch.from_numpy(yb.astype(np.int64))
            emb = net(x)  # (B, D, h, w)
            f = emb.permute(0, 2, 3, 1).reshape(-1, emb.shape[1])
            yf = y.reshape(-1)
            if rooms:  # rooms are not repainted: their held-out colour-kind pairs train nothing
                keep = torch.from_numpy(remap)[yf] >= 0
                f, yf = f[keep], yf[keep]
            scale = net.logit_scale.exp().clamp(max=100)
            use_mean = cfg.prompt_ensemble and bool(rng.random() < 0.5)
            T_cls = pick(tables["cls"], use_mean)[torch.from_numpy(train_cls)]
            loss = F.cross_entropy(scale * f @ T_cls.T, torch.from_numpy(remap)[yf], weight=w_cls)
            T_kind = pick(tables["kind"], use_mean)
            loss_k = F.cross_entropy(scale * f @ T_kind.T, torch.from_numpy(kind_of)[yf])
            cy = torch.from_numpy(col_of)[yf]
            m = cy >= 0
            loss_c = (
                F.cross_entropy(scale * f[m] @ pick(tables["col"], use_mean).T, cy[m])
                if bool(m.any())
                else torch.zeros(())
            )
            total = loss + cfg.aux_weight * (loss_k + loss_c)
            opt.zero_grad(set_to_none=True)
            total.backward()
            opt.step()
            sched.step()
            if progress is not None:
                progress(step + 1, cfg.steps)
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
            "arch": net.arch,
            "arch_config": dict(net.arch_config),
            "input_mean": list(in_mean),
            "input_std": list(in_std),
            "stride": s,
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
        if cfg.backbone == "small":
            ckpt["width"] = cfg.width  # what loaders before the arch record read
        with atomic_path(out) as tmp:
            torch.save(ckpt, tmp)
        from tabletop.mapping.encoders import lseg

        lseg._load.cache_clear()
        metrics = evaluate_vision(
            weights=out, layouts=cfg.eval_layouts, views=cfg.eval_views, seed=cfg.seed
        )
        if rooms and cfg.eval_rooms:
            from tabletop.train.vision_rooms import evaluate_room_vision

            metrics.update(
                evaluate_room_vision(
                    out, rooms=cfg.eval_rooms, views=cfg.eval_room_views, upscale=cfg.room_scale
                )
            )
        ckpt["metrics"] = metrics
        with atomic_path(out) as tmp:
            torch.save(ckpt, tmp)
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
    variety: RenderVariety | None = None,
) -> dict:
    """Measure an image encoder on held-out layouts (seeds training never used).

    ``layouts`` scenes (``EVAL_SEED_BASE + i``) x ``views`` camera poses, rendered with the
    simulator's fixed light, held-out colour-kind combinations favoured. ``variety`` (not the
    figures the weights record: a robustness check) renders them instead with random lights
    and the given :class:`RenderVariety` (other tables, distractors, ...). The vocabulary is
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
    varied = variety is not None and variety.active
    rgbs, labels = render_dataset(
        seeds, views, heldout=True, seed=seed + 1, lit=varied, variety=variety if varied else None
    )
    stuff = {classes.index(next(c for c in classes if c["kind"] == s)) for s in STUFF}
    held = {i for i, c in enumerate(classes) if (c["kind"], c["color"]) in set(HELDOUT_COMBOS)}
    kind_of = np.array([c["kind"] for c in classes])

    inter = np.zeros(C)
    union = np.zeros(C)
    present = np.zeros(C, bool)
    obj_ok = obj_n = held_ok = held_n = kind_ok = 0
    inst_ok = inst_n = 0
    syn_ok = syn_n = syn_px_ok = syn_px_n = 0
    syn_emb: dict[str, np.ndarray] = {}
    for rgb, lab in zip(rgbs, labels, strict=True):
        dense, rows, cols, pred = predict_pixels(enc, rgb, T, *lab.shape)
        present[np.unique(lab)] = True
        conf = np.bincount((lab.astype(np.int64) * C + pred).ravel(), minlength=C * C)
        conf = conf.reshape(C, C)  # [truth, prediction] pixel counts
        tp = np.diag(conf)
        inter += tp
        union += conf.sum(0) + conf.sum(1) - tp
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
            yy, xx = np.nonzero(m)
            f = dense[rows[yy], cols[xx]]  # (n, D) the pixels' cell embeddings
            g = f.mean(0)
            inst_ok += int(np.argmax(T @ g) == c)
            inst_n += 1
            kind = classes[c]["kind"]
            col = classes[c]["color"]
            for syn in SYNONYMS[kind]:
                phrase = f"{col} {syn}" if col else syn
                if phrase not in syn_emb:
                    syn_emb[phrase] = text.encode_text([phrase])[0]
                q = syn_emb[phrase]
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

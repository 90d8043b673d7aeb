"""``tabletop train shape``: the object module's shape prior (:mod:`tabletop.mapping.shape`).

Generated scenes (seeds :data:`SHAPE_TRAIN_SEEDS` and :data:`SHAPE_VAL_SEEDS`, used by no
evaluation, calibration or tuning) are scanned and mapped with the default encoders exactly as
the evaluation maps its scenes; each map's object instances are matched to the simulator's
objects (the object holding most of an instance's voxels, at least half of them) and described
by :func:`~tabletop.mapping.shape.shape_features`. A logistic regression is fitted on the
training scenes and measured on the validation scenes (top-1 kind from shape alone); both
figures go into the file's ``meta``.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError

__all__ = [
    "SHAPE_TRAIN_SEEDS",
    "SHAPE_VAL_SEEDS",
    "collect_scene",
    "fit_from_scenes",
    "fused_probabilities",
    "instance_shapes",
    "train_shape",
]

log = logging.getLogger(__name__)

#: Generator seeds of the training scenes (no other experiment uses 400-439).
SHAPE_TRAIN_SEEDS = tuple(range(400, 412))
#: Generator seeds of the validation scenes.
SHAPE_VAL_SEEDS = tuple(range(430, 434))
#: Objects per generated scene (more than the suites' 9: more instances per scan).
SHAPE_SCENE_OBJECTS = 12


def instance_shapes(m, truth) -> tuple[np.ndarray, list[str], np.ndarray]:
    """((n, F) features, n kind labels, (n, V) image cosines with the map's vocabulary) of the
    instances of map ``m`` matched to the objects of ``truth``
    (:class:`~tabletop.sim.ground_truth.GroundTruth`)."""
    from tabletop.mapping.shape import FEATURES, shape_features
    from tabletop.sim.catalog import OBJECT_KINDS

    nv = len(m.objects.vocabulary)
    table = m.table()
    if table is None:
        return np.zeros((0, len(FEATURES))), [], np.zeros((0, nv))
    centers = m.voxels.centers
    feats, labels, rows = [], [], []
    items = m.objects.instances.items
    for i, inst in enumerate(items):
        pts = centers[inst.rows]
        inside = [
            np.all((pts >= o.aabb_min - 0.01) & (pts <= o.aabb_max + 0.01), axis=1).mean()
            for o in truth.objects
        ]
        k = int(np.argmax(inside)) if inside else -1
        if k < 0 or inside[k] < 0.5:
            continue
        feats.append(shape_features(pts, m.grid.voxel_size, table.z))
        labels.append(OBJECT_KINDS[truth.objects[k].kind].label)
        rows.append(i)
    cos = m.objects.class_scores([items[i] for i in rows])[:, :nv] if rows else np.zeros((0, nv))
    return np.array(feats).reshape(-1, len(FEATURES)), labels, cos


def collect_scene(seed: int, cache_dir=None) -> dict:
    """One generated scene's matched instances: ``{"x", "y", "cos", "vocabulary"}``."""
    from tabletop.eval.harness import generated_scene, scene_map
    from tabletop.sim.ground_truth import GroundTruth

    spec = generated_scene(seed, f"shape-{seed}", count=SHAPE_SCENE_OBJECTS)
    rec, m = scene_map(spec, {"seed": seed, "speed": 0.3}, "default", cache_dir=cache_dir)
    x, y, cos = instance_shapes(m, GroundTruth.of(rec))
    log.info("shape scene %d: %d instances", seed, len(y))
    return {
        "x": x,
        "y": y,
        "cos": cos,
        "vocabulary": list(m.objects.vocabulary),
        "voxel_size": m.grid.voxel_size,
    }


def fused_probabilities(prior, scene: dict, weight: float, temperature: float) -> np.ndarray:
    """(n, V) the object module's kind probabilities over a scene's vocabulary: the image
    cosines' softmax at ``temperature`` times the prior's probabilities to the ``weight``."""
    z = scene["cos"] / temperature
    logp = z - z.max(axis=1, keepdims=True)
    if weight:
        g = prior.for_names(scene["x"], scene["vocabulary"])
        logp = logp + weight * np.log(np.maximum(g, 1e-300))
    p = np.exp(logp - logp.max(axis=1, keepdims=True))
    return p / p.sum(axis=1, keepdims=True)


#: Exponents of the prior tried when fitting how much it counts against the image encoder.
WEIGHTS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0)


def train_shape(
    out: str | Path | None = None,
    train_seeds=SHAPE_TRAIN_SEEDS,
    val_seeds=SHAPE_VAL_SEEDS,
    cache_dir: str | Path | None = "out/eval-cache",
    progress=None,
) -> Path:
    """Collect, fit, measure and save the shape prior; returns the path written."""
    from tabletop.mapping.object_module import ObjectConfig
    from tabletop.mapping.shape import SHAPE_PRIOR_PATH

    t0 = time.monotonic()
    out = Path(out) if out is not None else SHAPE_PRIOR_PATH
    train = [collect_scene(s, cache_dir) for s in train_seeds]
    val = [collect_scene(s, cache_dir) for s in val_seeds]
    for scene in train + val:
        if progress is not None:
            progress(scene)
    return fit_from_scenes(train, val, ObjectConfig().temperature, out, t0)


def fit_from_scenes(train: list[dict], val: list[dict], temperature: float, out, t0=None):
    """Fit the prior on ``train`` scenes and its weight against the image encoder (the
    smallest of :data:`WEIGHTS` within one nat of the best log-likelihood of the true kinds,
    each training scene judged by a prior fitted without it), measure both on ``val``, save to
    ``out``."""
    from tabletop.mapping.shape import ShapePrior, fit_shape_prior

    t0 = time.monotonic() if t0 is None else t0
    train = [s for s in train if len(s["y"])]
    if len(train) < 2 or not any(len(s["y"]) for s in val):
        raise ConfigError("the shape prior needs instances in 2 training scenes and 1 validation")
    stack = lambda ss, k: np.vstack([s[k] for s in ss])  # noqa: E731
    labels = lambda ss: [t for s in ss for t in s["y"]]  # noqa: E731
    prior = fit_shape_prior(stack(train, "x"), labels(train))

    def loglik(prior_of, scenes, w):
        total = 0.0
        for s, p_ in zip(scenes, prior_of, strict=True):
            p = fused_probabilities(p_, s, w, temperature)
            idx = [s["vocabulary"].index(t) for t in s["y"]]
            total += float(np.log(np.maximum(p[np.arange(len(idx)), idx], 1e-12)).sum())
        return total

    # Cross-fitted priors: each training scene judged by a prior that never saw it.
    held = [
        fit_shape_prior(
            stack([t for t in train if t is not s], "x"), labels([t for t in train if t is not s])
        )
        for s in train
    ]
    fits = {w: loglik(held, train, w) for w in WEIGHTS}
    # The smallest weight within one nat of the best: the image encoder keeps a say wherever
    # trusting the shape more buys (almost) nothing.
    weight = min(w for w, v in fits.items() if v >= max(fits.values()) - 1.0)

    def accuracy(scenes, probs) -> float:
        ok = [
            names[int(i)] == t
            for s in scenes
            for names, p in [probs(s)]
            for i, t in zip(p.argmax(1), s["y"], strict=True)
        ]
        return float(np.mean(ok))

    def top1(scenes, w):
        return accuracy(
            scenes, lambda s: (s["vocabulary"], fused_probabilities(prior, s, w, temperature))
        )

    def shape_top1(scenes):
        return accuracy(scenes, lambda s: (prior.kinds, prior.probabilities(s["x"])))

    meta = {
        "train_scenes": len(train),
        "val_scenes": len(val),
        "objects_per_scene": SHAPE_SCENE_OBJECTS,
        "encoders": "default",
        "train_instances": len(labels(train)),
        "val_instances": len(labels(val)),
        "shape_only_val_top1": shape_top1(val),
        "image_only_val_top1": top1(val, 0.0),
        "fused_val_top1": top1(val, weight),
        "weight": weight,
        "weight_loglik": {str(k): round(v, 2) for k, v in fits.items()},
        "temperature": temperature,
        "seconds": round(time.monotonic() - t0, 1),
    }
    sizes = {float(s.get("voxel_size", 0.01)) for s in train + val}
    if len(sizes) != 1:
        raise ConfigError(f"the scenes' maps have different voxel sizes {sorted(sizes)}")
    prior = ShapePrior(prior.kinds, prior.mean, prior.std, prior.weights, meta, weight, *sizes)
    prior.save(out)
    log.info("shape prior: weight %.2f, validation top-1 image %.3f -> fused %.3f",
             weight, meta["image_only_val_top1"], meta["fused_val_top1"])  # fmt: skip
    return Path(out)

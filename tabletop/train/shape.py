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

__all__ = ["SHAPE_TRAIN_SEEDS", "SHAPE_VAL_SEEDS", "instance_shapes", "train_shape"]

log = logging.getLogger(__name__)

#: Generator seeds of the training scenes (no other experiment uses 400-439).
SHAPE_TRAIN_SEEDS = tuple(range(400, 418))
#: Generator seeds of the validation scenes.
SHAPE_VAL_SEEDS = tuple(range(430, 434))
#: Objects per generated scene (more than the suites' 9: more instances per scan).
SHAPE_SCENE_OBJECTS = 12


def instance_shapes(m, truth) -> tuple[np.ndarray, list[str]]:
    """((n, F) features, n kind labels) of the instances of map ``m`` matched to the objects of
    ``truth`` (:class:`~tabletop.sim.ground_truth.GroundTruth`)."""
    from tabletop.mapping.shape import shape_features
    from tabletop.sim.catalog import OBJECT_KINDS

    table = m.table()
    if table is None:
        return np.zeros((0, 0)), []
    centers = m.voxels.centers
    feats, labels = [], []
    for inst in m.objects.instances.items:
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
    return np.array(feats), labels


def _collect(seeds, cache_dir, progress) -> tuple[np.ndarray, list[str]]:
    from tabletop.eval.harness import generated_scene, scene_map
    from tabletop.sim.ground_truth import GroundTruth

    xs, ys = [], []
    for seed in seeds:
        spec = generated_scene(seed, f"shape-{seed}", count=SHAPE_SCENE_OBJECTS)
        rec, m = scene_map(spec, {"seed": seed, "speed": 0.3}, "default", cache_dir=cache_dir)
        x, y = instance_shapes(m, GroundTruth.of(rec))
        if len(y):
            xs.append(x)
            ys += y
        log.info("shape scene %d: %d instances", seed, len(y))
        if progress is not None:
            progress(seed)
    if not ys:
        raise ConfigError("no instance of any scene matched an object: nothing to train on")
    return np.vstack(xs), ys


def train_shape(
    out: str | Path | None = None,
    train_seeds=SHAPE_TRAIN_SEEDS,
    val_seeds=SHAPE_VAL_SEEDS,
    cache_dir: str | Path | None = "out/eval-cache",
    progress=None,
) -> Path:
    """Collect, fit, measure and save the shape prior; returns the path written."""
    from tabletop.mapping.shape import SHAPE_PRIOR_PATH, ShapePrior, fit_shape_prior

    t0 = time.monotonic()
    out = Path(out) if out is not None else SHAPE_PRIOR_PATH
    x, y = _collect(train_seeds, cache_dir, progress)
    xv, yv = _collect(val_seeds, cache_dir, progress)
    prior = fit_shape_prior(x, y)
    acc = lambda p, xs, ys: float(  # noqa: E731
        np.mean([p.kinds[i] == t for i, t in zip(p.probabilities(xs).argmax(1), ys, strict=True)])
    )
    meta = {
        "train_seeds": list(train_seeds),
        "val_seeds": list(val_seeds),
        "objects_per_scene": SHAPE_SCENE_OBJECTS,
        "encoders": "default",
        "train_instances": len(y),
        "val_instances": len(yv),
        "train_top1": acc(prior, x, y),
        "val_top1": acc(prior, xv, yv),
        "val_top1_per_kind": {
            k: acc(prior, xv[np.array(yv) == k], [k] * int(np.sum(np.array(yv) == k)))
            for k in sorted(set(yv))
        },
        "seconds": round(time.monotonic() - t0, 1),
    }
    prior = ShapePrior(prior.kinds, prior.mean, prior.std, prior.weights, meta)
    prior.save(out)
    log.info("shape prior: train top-1 %.3f, validation top-1 %.3f", meta["train_top1"],
             meta["val_top1"])  # fmt: skip
    return out

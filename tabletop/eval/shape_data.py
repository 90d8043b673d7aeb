"""The shape prior's data (``tabletop train shape``): generated scenes scanned and mapped with
the default encoders exactly as the evaluation maps its scenes, each map's object instances
matched to the simulator's objects (the object holding most of an instance's voxels, at least
half of them) and described by :func:`~tabletop.mapping.shape.shape_features`, with the image
encoder's cosines beside them. :func:`tabletop.train.shape.fit_from_scenes` fits the prior.
"""

from __future__ import annotations

import logging

import numpy as np

__all__ = [
    "SHAPE_SCENE_OBJECTS",
    "SHAPE_TRAIN_SEEDS",
    "SHAPE_VAL_SEEDS",
    "collect_scene",
    "instance_shapes",
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

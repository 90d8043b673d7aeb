"""The image encoder measured per object instance in a map (``vision_instance_top1_heldout``).

Per-pixel figures say how an image encoder labels pixels; what the object module uses is the
embedding fused over every view of an instance. :func:`evaluate_instances` scans held-out
generated scenes (generator seeds no training, calibration, tuning or evaluation suite uses),
builds each map with an encoder set, segments its instances and matches each to the scene's
object holding most of its voxels. Per matched instance:

- ``kind``: the instance's most probable class (:meth:`ObjectModule.kind_probabilities`:
  catalog names and the background) is its object's kind;
- ``label``: that, and the basic colour term its measured colour fits best
  (:meth:`ObjectModule.colour_match`) is its object's colour (painted objects only; textured
  ones count on the kind).

Also reported: how many objects came out as exactly one instance (segmentation).
"""

from __future__ import annotations

import numpy as np

__all__ = ["INSTANCE_EVAL_SEEDS", "evaluate_instances"]

#: Generator seeds of the held-out scenes (used by no other experiment: the shipped suites use
#: 11-15, eval-map 10-12, calibration 700-705, the paraphrase suites 750-752, 760-762,
#: 800-803 ... 890-893 (by tens), 910-913, 920-923 and 930-933, the shape prior 400-411 and
#: 430-433, vision training layouts 0-219 and 9,000,000 on).
INSTANCE_EVAL_SEEDS = (900, 901, 902)


def evaluate_instances(
    encoder_set: str = "default",
    seeds=INSTANCE_EVAL_SEEDS,
    cache_dir="out/eval-cache",
    scan: dict | None = None,
) -> dict:
    """Instance-level figures of ``encoder_set`` on the scenes of ``seeds`` (see the module
    docstring); scans and maps are reused from ``cache_dir`` (None: none kept). ``scan``:
    ``ScanConfig`` fields beside the seed (default: speed 0.3, as the suites scan)."""
    from tabletop.eval.harness import generated_scene, scene_map
    from tabletop.reader.lexicon.colour_names import BASIC_COLOURS
    from tabletop.sim.catalog import OBJECT_KINDS
    from tabletop.sim.ground_truth import GroundTruth

    kind_ok = label_ok = n = objects = single = 0
    for seed in seeds:
        spec = generated_scene(seed, f"instances-{seed}")
        settings = {"speed": 0.3, **(scan or {}), "seed": seed}
        rec, m = scene_map(spec, settings, encoder_set, cache_dir=cache_dir)
        truth = GroundTruth.of(rec)
        names = list(m.objects.vocabulary) + list(m.config.object.background)
        inst = m.objects.instances.items
        colour_weights = [m.objects.colour_weights(c) for c in BASIC_COLOURS]
        scores = m.objects.kind_probabilities(inst)
        centers = m.voxels.centers
        owner_count: dict[str, int] = {}
        for i, s in zip(inst, scores, strict=True):
            pts = centers[i.rows]
            inside = [
                np.all((pts >= o.aabb_min - 0.01) & (pts <= o.aabb_max + 0.01), axis=1).mean()
                for o in truth.objects
            ]
            k = int(np.argmax(inside))
            if inside[k] < 0.5:
                continue  # not an object of the scene (a speck, a piece of the robot)
            o = truth.objects[k]
            owner_count[o.name] = owner_count.get(o.name, 0) + 1
            n += 1
            ok = names[int(np.argmax(s))] == OBJECT_KINDS[o.kind].label
            kind_ok += ok
            if OBJECT_KINDS[o.kind].keep_texture:
                label_ok += ok
            else:
                fit = [m.objects.colour_match(w, [i])[0] for w in colour_weights]
                label_ok += ok and BASIC_COLOURS[int(np.argmax(fit))] == o.color
        objects += len(truth.objects)
        single += sum(1 for o in truth.objects if owner_count.get(o.name) == 1)
    frac = lambda a, b: float(a / b) if b else float("nan")  # noqa: E731
    return {
        "vision_instance_top1_heldout": frac(kind_ok, n),
        "vision_instance_label_top1_heldout": frac(label_ok, n),
        "instance_segmentation_single": frac(single, objects),
        "instance_eval_instances": n,
        "instance_eval_objects": objects,
        "instance_eval_seeds": list(seeds),
    }

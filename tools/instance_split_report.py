"""How the map's instance segmentation fares against the simulator's objects, per split rule.

For every task file named (arm or room suites), the cached scan and map are loaded (built
when missing) and the voxels segmented again with each candidate :class:`InstanceConfig`
override; every scene object is then counted as

- ``single``: one instance holds at least half of its voxels and no other object's majority;
- ``merged``: the instance holding most of its voxels also holds most of another object's;
- ``split``: a second instance holds at least a quarter of its voxels;
- ``missed``: no instance holds a quarter of its voxels.

Voxels belong to an object when they lie in its box (1 cm margin). Usage::

    python tools/instance_split_report.py --suites default mobile --encoders oracle default \
        --rule split_cos_alone=0.3 --rule split_cos_alone=0.5
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np


def _maps(suite: str, encoders: str, cache: Path):
    from tabletop.eval.harness import cached_map, cached_recording, recording_key
    from tabletop.eval.room import cached_room_recording, room_map_settings, room_recording_key
    from tabletop.eval.runner import _map_settings, collect_task_files
    from tabletop.sim.ground_truth import GroundTruth

    for tf in collect_task_files(suite):
        spec = tf.scene.load()
        scan = dict(tf.scan)
        if tf.robot.kind == "mobile":
            settings = _map_settings(tf, None, room_map_settings(spec))
            rec, _, _ = cached_room_recording(tf.name, scan, spec, cache)
            key = room_recording_key(spec, scan)
        else:
            settings = _map_settings(tf, None)
            rec, _, _ = cached_recording(spec.name, scan, spec, cache, None)
            key = recording_key(spec, scan)
        m, _, _ = cached_map(tf.name, settings, rec, encoders, cache, key, None)
        yield tf.name, m, GroundTruth.of(rec)


def score(m, truth, config, segment_instances) -> dict:
    inst = segment_instances(m.voxels, m.objects.instances.table(), config)
    centers = m.voxels.centers
    owner = np.full(m.voxels.n, -1)
    for k, i in enumerate(inst):
        owner[i.rows] = k
    share = []  # per object: voxel share of each instance
    for o in truth.objects:
        inside = np.all((centers >= o.aabb_min - 0.01) & (centers <= o.aabb_max + 0.01), axis=1)
        own = owner[inside]
        counts = np.bincount(own[own >= 0], minlength=len(inst)) if len(inst) else np.zeros(0)
        share.append(counts / max(int(inside.sum()), 1))
    share = np.array(share) if share else np.zeros((0, len(inst)))
    out = {"single": 0, "merged": 0, "split": 0, "missed": 0, "instances": len(inst)}
    names = []
    for j, o in enumerate(truth.objects):
        row = share[j]
        if not len(row) or row.max() < 0.25:
            out["missed"] += 1
            names.append(f"missed:{o.name}")
            continue
        best = int(np.argmax(row))
        others = [
            q
            for q in range(len(truth.objects))
            if q != j and share[q].argmax() == best and share[q].max() >= 0.25
        ]
        if others:
            out["merged"] += 1
            names.append(f"merged:{o.name}+{truth.objects[others[0]].name}")
        elif (np.sort(row)[-2] if len(row) > 1 else 0) >= 0.25:
            out["split"] += 1
            names.append(f"split:{o.name}")
        else:
            out["single"] += 1
    out["problems"] = names
    return out


def _segmenter(path: str | None):
    """The instances module: the installed one, or the copy at ``path`` (to try a rule on
    maps cached by the committed code: run with that code on the path)."""
    if path is None:
        from tabletop.mapping import instances

        return instances
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location("_trial_instances", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def main() -> None:

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suites", nargs="+", default=["default"])
    ap.add_argument("--encoders", nargs="+", default=["oracle"])
    ap.add_argument("--rule", action="append", default=[], help="FIELD=VALUE[,FIELD=VALUE]")
    ap.add_argument("--cache-dir", default="out/eval-cache")
    ap.add_argument("--segmenter", help="a copy of tabletop/mapping/instances.py to segment with")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args()
    seg = _segmenter(args.segmenter)
    rules = [{}] + [
        {k: float(v) for k, v in (kv.split("=") for kv in r.split(","))} for r in args.rule
    ]
    for enc in args.encoders:
        totals = [dict.fromkeys(("single", "merged", "split", "missed"), 0) for _ in rules]
        for suite in args.suites:
            for name, m, truth in _maps(suite, enc, Path(args.cache_dir)):
                prev = None
                base = seg.InstanceConfig(**dataclasses.asdict(m.objects.config.segmentation))
                for t, (rule, tot) in enumerate(zip(rules, totals, strict=True)):
                    r = score(m, truth, dataclasses.replace(base, **rule), seg.segment_instances)
                    for k in tot:
                        tot[k] += r[k]
                    if args.verbose and (t == 0 or r["problems"] != prev) and (r["problems"] or t):
                        print(f"  {enc} {name} {rule or 'as built'}: {r['problems']}")
                    if t == 0:
                        prev = r["problems"]
        for rule, tot in zip(rules, totals, strict=True):
            print(f"{enc:8s} {rule or 'as built'!s:40s} {tot}")


if __name__ == "__main__":
    main()

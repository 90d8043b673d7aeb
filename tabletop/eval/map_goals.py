"""Map-level goals from a recording's ground truth: where does the map put each goal?

Goal types (the paper's tabletop experiment): ``object`` (an object's label, e.g. "red mug"),
``sound`` (a caption of an inserted sound; a sound heard in two regions counts at either),
``ambiguous`` (a duplicated kind, e.g. "mug", disambiguated by a sound heard near one of the
duplicates: the product of the object's sharp heatmap and the sound's broad one). A goal
succeeds when the map's target lies within 10 cm of the truth: the object's box, or the table
point beneath where the sound was heard.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.mapping.heatmaps import fuse

__all__ = ["SUCCESS_M", "MapGoal", "evaluate_map_goals", "map_goals"]

SUCCESS_M = 0.10


@dataclass(frozen=True)
class MapGoal:
    kind: str  # "object" | "sound" | "ambiguous"
    obj: str | None  # object query
    sound: str | None  # sound query
    truth_boxes: tuple  # ((lo, hi), ...) acceptable object boxes, or ()
    truth_points: tuple  # acceptable table points, or ()


def _box_dist(p, lo, hi) -> float:
    return float(
        np.linalg.norm(np.maximum(np.subtract(lo, p), 0) + np.maximum(np.subtract(p, hi), 0))
    )


def map_goals(ground_truth: dict, min_margin: float = 0.05) -> list[MapGoal]:
    """Object, sound and ambiguous goals of a recording. An ambiguous goal is kept only when the
    sound was heard at least ``min_margin`` [m] nearer one duplicate than the other."""
    objs = ground_truth["objects"]
    events = ground_truth.get("sound_events", [])
    goals = [
        MapGoal("object", o["label"], None, ((o["aabb_min"], o["aabb_max"]),), ()) for o in objs
    ]
    for e in events:
        pts = tuple(tuple(x["table_point"]) for x in events if x["category"] == e["category"])
        goals.append(MapGoal("sound", None, e["caption"], (), pts))
    kinds = [o["kind"] for o in objs]
    for kind in sorted({k for k in kinds if kinds.count(k) > 1}):
        dups = [o for o in objs if o["kind"] == kind]
        for e in events:
            if [x["category"] for x in events].count(e["category"]) > 1:
                continue  # an ambiguous sound cannot disambiguate
            d = [_box_dist(e["table_point"], o["aabb_min"], o["aabb_max"]) for o in dups]
            order = np.argsort(d)
            if d[order[1]] - d[order[0]] < min_margin:
                continue
            near = dups[order[0]]
            goals.append(
                MapGoal(
                    "ambiguous",
                    near["category"],
                    e["caption"],
                    ((near["aabb_min"], near["aabb_max"]),),
                    (),
                )
            )
    return goals


def evaluate_map_goals(m, ground_truth: dict) -> dict:
    """Per goal type: goals, successes, success rate, mean error [m]."""
    out: dict = {}
    for g in map_goals(ground_truth):
        if g.kind == "object":
            target = m.get_max_pos_3d(m.object_heatmap(g.obj))
        elif g.kind == "sound":
            target = m.get_max_pos_3d(m.sound_heatmap(g.sound))
        else:
            target = m.get_max_pos_3d(
                fuse(m.object_heatmap(g.obj).values, m.sound_heatmap(g.sound, major=False).values)
            )
        errs = [_box_dist(target, lo, hi) for lo, hi in g.truth_boxes]
        errs += [float(np.linalg.norm(np.subtract(target, p))) for p in g.truth_points]
        err = min(errs)
        r = out.setdefault(g.kind, {"goals": 0, "successes": 0, "errors": []})
        r["goals"] += 1
        r["successes"] += int(err <= SUCCESS_M)
        r["errors"].append(err)
    for r in out.values():
        r["success_rate"] = r["successes"] / r["goals"]
        r["mean_error_m"] = float(np.mean(r.pop("errors")))
    return out


def run_map_eval(
    seeds: int = 3, speed: float = 0.3, encoders: str = "oracle", progress=None
) -> dict:
    """Scan the default scene and a generated scene per seed, build maps, score the goals.

    Returns {"runs": [...], "by_type": {type: {goals, successes, success_rate}}, "encoders"}.
    """
    import tempfile
    from pathlib import Path

    from tabletop.mapping.avlmap import AVLMap
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec

    runs, totals = [], {}
    names = None
    for seed in range(seeds):
        for scene in ("default", "random"):
            if scene == "default":
                spec = load_scene_spec("default")
            else:
                path = Path(tempfile.mkdtemp()) / "random.toml"
                path.write_text(f"[random]\nseed = {seed + 10}\ncount = 9\nduplicates = 2\n")
                spec = load_scene_spec(path)
            rec, _ = run_scan(spec, ScanConfig(seed=seed, speed=speed, episodes=6))
            m = AVLMap.build(rec, encoders=encoders)
            names = m.encoder_names
            r = evaluate_map_goals(m, rec.ground_truth)
            runs.append({"scene": scene, "seed": seed, "result": r})
            for k, v in r.items():
                t = totals.setdefault(k, {"goals": 0, "successes": 0})
                t["goals"] += v["goals"]
                t["successes"] += v["successes"]
            if progress is not None:
                progress(runs[-1])
    for t in totals.values():
        t["success_rate"] = t["successes"] / t["goals"]
    return {"runs": runs, "by_type": totals, "encoders": names}

"""Map-level goals from a recording's ground truth: where does the map put each goal?

Goal types (the paper's tabletop experiment): ``object`` (an object's label, e.g. "red mug"),
``sound`` (a caption of an inserted sound; truth: the column above the table point where it
was inserted, up to where the microphone heard it; a sound heard in two places counts at
either),
``ambiguous`` (a duplicated kind, e.g. "mug", disambiguated by a sound heard near one of the
duplicates: the product of the object's sharp heatmap and the sound's broad one), and with a
simulator of the scene, ``image`` (an image the wrist camera would take over an object or a
table point, rendered at a pose the scan never took; the truth is what the image looks at)
and ``image_ambiguous`` (a duplicated kind disambiguated by an image of the table beside one
duplicate: the object's sharp heatmap times the image's broad one). A goal succeeds when the
map's target lies within 10 cm of the truth: the object's box, the sound's column, or the table
point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.errors import ConfigError, SimulationError
from tabletop.mapping.heatmaps import fuse
from tabletop.sim.ground_truth import GroundTruth, ObjectTruth, SoundEventTruth
from tabletop.transforms import aabb_distance

__all__ = [
    "ImageGoalConfig",
    "MapGoal",
    "evaluate_map_goals",
    "heard_column",
    "image_goals",
    "map_goals",
]


@dataclass(frozen=True)
class MapGoal:
    kind: str  # "object" | "sound" | "ambiguous" | "image" | "image_ambiguous"
    obj: str | None  # object query
    sound: str | None  # sound query
    truth_boxes: tuple  # ((lo, hi), ...) acceptable object boxes, or ()
    truth_points: tuple  # acceptable table points, or ()
    image: np.ndarray | None = field(default=None, compare=False, repr=False)
    """(H, W, 3) uint8 image query, rendered from ``T_world_cam``."""
    T_world_cam: np.ndarray | None = field(default=None, compare=False, repr=False)
    """(4, 4) [m] pose of the camera that took ``image`` (OpenCV optical frame)."""


@dataclass(frozen=True)
class ImageGoalConfig:
    """How image goals are posed: a wrist camera over the table at a pose the scan never took."""

    seed: int = 0
    """Seed of the camera poses."""
    distance_m: tuple[float, float] = (0.28, 0.45)
    """Range of the camera's distance [m] from the point it looks at."""
    elevation_deg: tuple[float, float] = (60.0, 85.0)
    """Range of the viewing ray's angle [deg] above the table plane: a picture taken over a
    spot of the table. (From 50 deg, the top of a 58 deg-high image reaches 0.8 m past the
    target: such views showed more floor than table.)"""
    roll_rad: float = np.pi / 2
    """Roll about the viewing ray, uniform in [-roll_rad, roll_rad]."""
    table_points: int = 4
    """Table-point goals per scene: points 8-15 cm beside a random object (so that the image
    shows something), outside every object's footprint."""
    min_new_m: float = 0.05
    """A goal camera is at least this far [m] from every camera pose of the recording."""


def _disambiguated(point, dups: tuple[ObjectTruth, ...], min_margin: float) -> ObjectTruth | None:
    """The duplicate nearest ``point`` if it is at least ``min_margin`` [m] nearer than the
    others, else None."""
    d = [aabb_distance(point, o.aabb_min, o.aabb_max) for o in dups]
    order = np.argsort(d)
    return dups[order[0]] if d[order[1]] - d[order[0]] >= min_margin else None


def _duplicates(gt: GroundTruth) -> list[tuple[ObjectTruth, ...]]:
    return [gt.objects_of_kind(k) for k in gt.duplicated_kinds]


def _box(o: ObjectTruth) -> tuple:
    """An object's truth box as (lower, upper) corner lists [m]."""
    return (o.aabb_min.tolist(), o.aabb_max.tolist())


def heard_column(event: SoundEventTruth) -> tuple:
    """A sound's truth box: the column from its table point up to where the microphone heard
    it (a sound has a place on the table, not a height; the evaluation suites use the same
    column, :mod:`tabletop.eval.truth`)."""
    p = np.array(event.table_point, np.float64)
    return (p, np.array([p[0], p[1], max(float(event.tcp_mean[2]), 0.0)]))


def map_goals(ground_truth: GroundTruth, min_margin: float = 0.05) -> list[MapGoal]:
    """Object, sound and ambiguous goals of a recording. An ambiguous goal is kept only when the
    sound was heard at least ``min_margin`` [m] nearer one duplicate than the other."""
    gt = ground_truth
    events = gt.sound_events
    goals = [MapGoal("object", o.label, None, (_box(o),), ()) for o in gt.objects]
    for e in events:
        same = [x for x in events if x.category == e.category]
        goals.append(MapGoal("sound", None, e.caption, tuple(heard_column(x) for x in same), ()))
    for dups in _duplicates(gt):
        for e in events:
            if [x.category for x in events].count(e.category) > 1:
                continue  # an ambiguous sound cannot disambiguate
            near = _disambiguated(e.table_point, dups, min_margin)
            if near is not None:
                goals.append(MapGoal("ambiguous", near.category, e.caption, (_box(near),), ()))
    return goals


def image_goals(
    ground_truth: GroundTruth | dict,
    world,
    config: ImageGoalConfig | None = None,
    recorded_T_world_cam: np.ndarray | None = None,
    min_margin: float = 0.05,
) -> list[MapGoal]:
    """Image and image-ambiguous goals rendered by ``world`` (a
    :class:`~tabletop.sim.world.SimWorld` of the recording's scene). ``ground_truth``: the
    recording's, typed or as the recording stores it (a dict).

    One image per object (looking at its centre), ``config.table_points`` images of table
    points beside objects, and per duplicate of a duplicated kind one image of a table point
    6-12 cm beside it (kept when that point is ``min_margin`` [m] nearer it than the other
    duplicates). Camera poses are drawn until they lie ``config.min_new_m`` from every pose in
    ``recorded_T_world_cam`` (N, 4, 4).
    """
    from tabletop.arm import HOME_Q, PandaModel, solve_ik
    from tabletop.sim.teleop import look_at
    from tabletop.transforms import invert

    config = config or ImageGoalConfig()
    rng = np.random.default_rng(config.seed)
    gt = ground_truth
    if not isinstance(gt, GroundTruth):  # as a recording stores it
        gt = GroundTruth.from_dict(gt)
    objs = gt.objects
    model = PandaModel()
    T_cam_hand = invert(world.camera.T_hand_cam)
    recorded = None if recorded_T_world_cam is None else recorded_T_world_cam[:, :3, 3]

    def render(target) -> tuple[np.ndarray, np.ndarray]:
        # The arm holds the camera (IK), so the image shows what a wrist camera would: the
        # fingers at the bottom, never the arm itself in front of the table.
        for _ in range(100):
            dist = rng.uniform(*config.distance_m)
            elev = np.deg2rad(rng.uniform(*config.elevation_deg))
            azim = rng.uniform(np.pi / 2, 3 * np.pi / 2)  # from the robot's side of the point
            ray = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
            eye = np.asarray(target, float) + dist * ray
            if (
                recorded is not None
                and np.linalg.norm(recorded - eye, axis=1).min() < config.min_new_m
            ):
                continue
            T = look_at(eye, target, rng.uniform(-config.roll_rad, config.roll_rad))
            res = solve_ik(model, T @ T_cam_hand, HOME_Q, frame="panda_hand")
            if res.pos_error_m > 0.002 or res.rot_error_rad > np.deg2rad(0.5):
                continue
            world.set_arm(res.q)
            if world.min_clearance(0.02) < 0.01:
                continue
            T = world.T_world_cam()
            return world.render(T).rgb, T
        raise SimulationError(
            f"no reachable new camera pose looks at {np.round(target, 3).tolist()}"
        )

    def beside(o, lo_m: float, hi_m: float) -> np.ndarray:
        for _ in range(100):
            a, r = rng.uniform(0, 2 * np.pi), rng.uniform(lo_m, hi_m)
            p = np.array([*np.add(o.center[:2], r * np.array([np.cos(a), np.sin(a)])), 0.0])
            free = all(aabb_distance(p, b.aabb_min, b.aabb_max) > 0.01 for b in objs)
            t = gt.table
            on_table = t.x[0] + 0.03 < p[0] < t.x[1] - 0.03 and t.y[0] + 0.03 < p[1] < (
                t.y[1] - 0.03
            )
            if free and on_table:
                return p
        return np.array([*o.center[:2], 0.0])

    goals = []
    for o in objs:
        img, T = render(o.center)
        goals.append(MapGoal("image", None, None, (_box(o),), (), img, T))
    for _ in range(config.table_points):
        p = beside(objs[rng.integers(len(objs))], 0.08, 0.15)
        img, T = render(p)
        goals.append(MapGoal("image", None, None, (), (tuple(p),), img, T))
    for dups in _duplicates(gt):
        for o in dups:
            p = beside(o, 0.06, 0.12)
            if _disambiguated(p, dups, min_margin) is not o:
                continue
            img, T = render(p)
            goals.append(MapGoal("image_ambiguous", o.category, None, (_box(o),), (), img, T))
    return goals


def _target(m, g: MapGoal) -> tuple[np.ndarray, bool]:
    """The map's target for ``g`` and whether every part of the query was found (a part that
    is not found stops the robot API before anything moves)."""
    if g.kind == "object":
        parts = [m.object_heatmap(g.obj)]
    elif g.kind == "sound":
        parts = [m.sound_heatmap(g.sound)]
    elif g.kind == "ambiguous":
        parts = [m.object_heatmap(g.obj), m.sound_heatmap(g.sound, major=False)]
    elif g.kind == "image":
        parts = [m.image_heatmap(g.image)]
    else:
        parts = [m.object_heatmap(g.obj), m.image_heatmap(g.image, major=False)]
    fused = fuse(*parts)
    if not fused.found:
        return None, False
    return m.get_max_pos_3d(fused), True


def evaluate_map_goals(
    m,
    ground_truth: GroundTruth,
    *,
    world=None,
    image_config: ImageGoalConfig | None = None,
    recorded_T_world_cam: np.ndarray | None = None,
) -> dict:
    """Per goal type: goals, successes, not found, success rate, mean error [m]. A goal
    succeeds when every part of its query is found and the target lies within 10 cm of the
    truth. With ``world`` (a :class:`~tabletop.sim.world.SimWorld` of the scene), image goals
    too (:func:`image_goals`)."""
    goals = map_goals(ground_truth)
    if world is not None:
        goals += image_goals(ground_truth, world, image_config, recorded_T_world_cam)
    out: dict = {}
    for g in goals:
        target, found = _target(m, g)
        r = out.setdefault(g.kind, {"goals": 0, "successes": 0, "not_found": 0, "errors": []})
        r["goals"] += 1
        r["not_found"] += int(not found)
        if found:
            errs = [aabb_distance(target, lo, hi) for lo, hi in g.truth_boxes]
            errs += [float(np.linalg.norm(np.subtract(target, p))) for p in g.truth_points]
            err = min(errs)
            r["successes"] += int(err <= SUCCESS_RADIUS_M)
            r["errors"].append(err)
    for r in out.values():
        r["success_rate"] = r["successes"] / r["goals"]
        errors = r.pop("errors")
        r["mean_error_m"] = float(np.mean(errors)) if errors else None
    return out


def check_map_eval(seeds, speed) -> None:
    """ConfigError naming the first of :func:`run_map_eval`'s arguments that is out of range
    (checked before anything is printed or scanned)."""
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ConfigError(f"seeds must be a whole number >= 1, got {seeds!r}")
    if not (isinstance(speed, (int, float)) and np.isfinite(speed) and speed > 0):
        raise ConfigError(f"speed must be a positive number [m/s], got {speed!r}")


def run_map_eval(
    seeds: int = 3, speed: float = 0.3, encoders: str = "oracle", progress=None
) -> dict:
    """Scan the default scene and a generated scene per seed, build maps, score the goals
    (image goals rendered by a second simulator of the same scene).

    Returns {"runs": [...], "by_type": {type: {goals, successes, not_found, success_rate}},
    "by_scene": {"default" | "random": {type: ...}}, "encoders"}.
    """
    check_map_eval(seeds, speed)
    from tabletop.eval.harness import generated_scene, scene_map
    from tabletop.sim.scene import load_scene_spec
    from tabletop.sim.world import SimWorld

    runs, totals, by_scene = [], {}, {}
    names = None
    for seed in range(seeds):
        for scene in ("default", "random"):
            if scene == "default":
                spec = load_scene_spec("default")
            else:
                spec = generated_scene(seed + 10)
            scan = {"seed": seed, "speed": speed, "episodes": 6}
            rec, m = scene_map(spec, scan, encoders)
            names = m.encoder_names
            with SimWorld(spec) as world:
                r = evaluate_map_goals(
                    m,
                    GroundTruth.of(rec),
                    world=world,
                    image_config=ImageGoalConfig(seed=seed),
                    recorded_T_world_cam=rec.T_world_cam,
                )
            runs.append({"scene": scene, "seed": seed, "result": r})
            for k, v in r.items():
                zero = {"goals": 0, "successes": 0, "not_found": 0}
                for t in (
                    totals.setdefault(k, dict(zero)),
                    by_scene.setdefault(scene, {}).setdefault(k, dict(zero)),
                ):
                    for key in zero:
                        t[key] += v[key]
            if progress is not None:
                progress(runs[-1])
    for t in [*totals.values(), *(t for sc in by_scene.values() for t in sc.values())]:
        t["success_rate"] = t["successes"] / t["goals"]
    return {"runs": runs, "by_type": totals, "by_scene": by_scene, "encoders": names}

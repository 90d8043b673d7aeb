"""Fitting the maps' query confidence on seeded scenes (``tabletop calibrate``): labelled
queries of every modality from simulated scans, a Platt fit per modality on the fit scenes, an
operating point, and the reliability on held-out scenes.

The calibration value and its math live in :mod:`tabletop.mapping.calibration`; this is the
experiment that produces it, so it may use the simulator and the evaluation's goals.
"""

from __future__ import annotations

import numpy as np

from tabletop.arm.success import SUCCESS_RADIUS_M
from tabletop.errors import ConfigError
from tabletop.mapping.calibration import (
    MODALITIES,
    UNCALIBRATED,
    Calibration,
    expected_calibration_error,
    fit_platt,
)
from tabletop.reader.reading import get_reader
from tabletop.sim.ground_truth import GroundTruth
from tabletop.transforms import aabb_distance

# --------------------------------------------------------------------------- fitting from maps

#: An area's truth is its rectangle from the table top up to this height [m] (as in the
#: evaluation's ground truth).
AREA_HEIGHT_M = 0.30

#: Modalities whose module decides found / not found itself (the image module's photometric
#: check; a named table area is always there); calibration gives them a confidence but no
#: operating point.
GATED = ("image", "area")


def calibration_samples(
    m, ground_truth: GroundTruth, image_goals=(), foreign_images=()
) -> list[dict]:
    """Labelled queries of one map: ``{"modality", "query", "margin", "correct"}`` each.

    An answer is right when it lands within the arm's success radius (10 cm) of the truth:
    whether the map found the thing, for a room's map too (a base's 1 m would count lucky
    answers in a small room as right). Objects: every object label and every kind name
    present (right when the target lands near an object carrying it), every catalog kind
    absent from the scene and,
    for each present kind, a colour it may take that none of its objects has (always wrong).
    Sounds: the caption of every inserted category (right near the column above a
    place it was inserted, up to where it was heard) and of sound-bank categories never
    inserted (always wrong). Areas: each named table area (right near its rectangle, up to
    :data:`AREA_HEIGHT_M`). Images: ``image_goals``
    (:class:`~tabletop.eval.map_goals.MapGoal` of kind ``"image"``, pictures of this scene:
    right when found and near the truth) and ``foreign_images`` ((H, W, 3) uint8
    pictures of other scenes: always wrong). The map's operating point is set aside while it
    is queried: every object and sound query is answered, and ``found`` is the gated
    modalities' own decision.
    """
    previous = m.calibration
    # Every query answers with its heatmap, whatever the map's operating point: a query the
    # committed threshold refuses is zero everywhere and could not be labelled, so every
    # refused query would count as wrong and a refit would only confirm the threshold.
    m.calibration = Calibration(
        previous.encoder_set,
        previous.models,
        previous.report,
        {mod: -np.inf for mod in MODALITIES if mod not in GATED},
    )
    try:
        return _calibration_samples(m, ground_truth, image_goals, foreign_images)
    finally:
        m.calibration = previous


def _calibration_samples(m, ground_truth, image_goals, foreign_images) -> list[dict]:
    from tabletop.eval.map_goals import heard_column
    from tabletop.sim.catalog import OBJECT_KINDS
    from tabletop.sim.sound_bank import SoundBank

    out = []

    def add(modality, query, h, truth):
        if h.found and h.evidence is None:
            return  # decided by geometry (a named table region), not by a margin to calibrate
        if not h.found and h.evidence is None:
            margin, ok = -1.0, False  # nothing matched at all: the weakest evidence there is
        else:
            margin = float(h.evidence)
            # The label is where the target is with every query accepted: the calibration
            # decides acceptance, so it must see the targets of queries a threshold refuses.
            ok = bool(truth) and h.peak > 0 and min(truth(m.get_max_pos_3d(h))) <= SUCCESS_RADIUS_M
        out.append(
            {
                "modality": modality,
                "query": query,
                "margin": margin,
                "correct": ok,
                "found": h.found,
            }
        )

    objs = ground_truth.objects
    by_query: dict[str, list] = {}
    for o in objs:
        by_query.setdefault(o.label, []).append(o)
        by_query.setdefault(OBJECT_KINDS[o.kind].label, []).append(o)
    for q, os_ in sorted(by_query.items()):
        boxes = [(o.aabb_min, o.aabb_max) for o in os_]
        add("object", q, m.object_heatmap(q), lambda p, b=boxes: [aabb_distance(p, *x) for x in b])
    present = {o.kind for o in objs}
    for k in sorted(set(OBJECT_KINDS) - present):
        add("object", OBJECT_KINDS[k].label, m.object_heatmap(OBJECT_KINDS[k].label), None)
    for k in sorted(present):  # a colour the kind may take that no object of it has here
        worn = {o.color for o in objs if o.kind == k}
        absent = [c for c in OBJECT_KINDS[k].colors if c not in worn]
        if absent and not OBJECT_KINDS[k].keep_texture:
            q = f"{absent[0]} {OBJECT_KINDS[k].label}"
            add("object", q, m.object_heatmap(q), None)

    events = ground_truth.sound_events
    if events:
        heard: dict[str, list] = {}
        for e in events:
            heard.setdefault(e.category, []).append(e)
        for _cat, es in sorted(heard.items()):
            cols = [heard_column(e) for e in es]
            add(
                "sound",
                es[0].caption,
                m.sound_heatmap(es[0].caption),
                lambda p, cols=cols: [aabb_distance(p, *c) for c in cols],
            )
        bank = SoundBank.default()
        for cat in sorted(set(bank.categories) - set(heard)):
            cap = bank.caption(cat)
            add("sound", cap, m.sound_heatmap(cap), None)

    for a in ground_truth.areas:
        lo, hi = (a.x[0], a.y[0], 0.0), (a.x[1], a.y[1], AREA_HEIGHT_M)
        add(
            "area",
            a.name,
            m.area_heatmap(get_reader().reference("area", a.name)),
            lambda p, b=(lo, hi): [aabb_distance(p, *b)],
        )

    def add_image(query, h, truth) -> None:
        # a refused pose is no answer at all: the weakest evidence there is
        margin = float(h.evidence) if h.found else -1.0
        right = h.found and truth is not None and min(truth(h.target)) <= SUCCESS_RADIUS_M
        out.append(
            {"modality": "image", "query": query, "margin": margin, "correct": right}
            | {"found": h.found}
        )

    for i, g in enumerate(image_goals):
        add_image(
            f"goal {i}",
            m.image_heatmap(g.image),
            lambda p, g=g: (
                [aabb_distance(p, *b) for b in g.truth_boxes]
                + [float(np.linalg.norm(p - np.asarray(x))) for x in g.truth_points]
            ),
        )
    for i, img in enumerate(foreign_images):
        add_image(f"foreign {i}", m.image_heatmap(img), None)
    return out


#: How an operating point is chosen (:func:`operating_point`).
OPERATING_RULES = ("keep", "balanced")


def operating_point(
    right: np.ndarray, wrong: np.ndarray, keep_right: float = 0.95, rule: str = "keep"
) -> float:
    """The smallest margin reported as found.

    ``rule="keep"``: the threshold that keeps ``keep_right`` of the ``right`` answers'
    margins, moved down to the middle of the gap below it (halfway to the highest ``wrong``
    margin under it), so that right answers slightly weaker than the fit's are still kept where
    nothing wrong scored. Right for an encoder whose right answers stand clear of its wrong ones.

    ``rule="balanced"``: the threshold with the largest share of right answers kept plus share
    of wrong ones refused (Youden's J; the lowest such threshold, moved to the middle of the gap
    below it). Right where an encoder's weak right answers score among its wrong ones (a small
    object seen from 2 m): keeping 95 % of the right answers would then also accept most wrong
    ones, and a query of something absent would be found.
    """
    if rule not in OPERATING_RULES:
        raise ConfigError(f"operating rule {rule!r}: valid {list(OPERATING_RULES)}")
    right, wrong = np.asarray(right, float), np.asarray(wrong, float)
    if rule == "keep" or not len(wrong):
        t = float(np.quantile(right, 1 - keep_right, method="lower"))
    else:
        cands = np.unique(right)
        j = [np.mean(right >= c) + np.mean(wrong < c) for c in cands]
        t = float(cands[int(np.argmax(j))])
    below = wrong[wrong < t]
    return (t + float(below.max())) / 2 if len(below) else t


def fit_calibration(
    encoder_set: str,
    train: list[dict],
    test: list[dict],
    keep_right: float = 0.95,
    rule: str = "keep",
) -> Calibration:
    """Platt parameters per modality fitted on ``train``, and an operating point
    (:func:`operating_point` by ``rule``; by default a margin threshold that keeps
    ``keep_right`` of the right answers of ``train`` reported as found
    (a query of something present is rarely refused; what a weak encoder cannot tell apart
    is then reported with a low confidence instead). The report holds ``test`` figures:
    samples, expected calibration error (fitted and uncalibrated prior), share of right
    answers kept and of wrong ones refused at the operating point."""
    models, report, thresholds = {}, {}, {}
    for mod in MODALITIES:
        tr = [s for s in train if s["modality"] == mod]
        te = [s for s in test if s["modality"] == mod]
        if len(tr) < 4 or len({s["correct"] for s in tr}) < 2:
            continue  # too few labelled queries (or one class only) to fit: the prior stays
        f = fit_platt([s["margin"] for s in tr], [s["correct"] for s in tr])
        models[mod] = f
        right = np.array([s["margin"] for s in tr if s["correct"]])
        wrong = np.array([s["margin"] for s in tr if not s["correct"]])
        t = operating_point(right, wrong, keep_right, rule)
        if mod not in GATED:
            thresholds[mod] = t
        if te:
            x = np.array([s["margin"] for s in te])
            y = np.array([s["correct"] for s in te], dtype=bool)
            p = np.asarray(f(x))
            if mod in GATED:  # the module's own found / not-found decision, not a threshold
                kept = np.array([s["found"] for s in te], dtype=bool)
                empty = None
            else:
                kept, empty = x >= t, float("nan")
            report[mod] = {
                "train_samples": len(tr),
                "test_samples": len(te),
                "test_right": int(y.sum()),
                "ece_test": expected_calibration_error(p, y),
                "ece_test_uncalibrated": expected_calibration_error(UNCALIBRATED(x), y),
                "decision_accuracy_test": float(np.mean((p >= 0.5) == y)),
                "threshold_margin": None if mod in GATED else t,
                "right_kept_test": float(np.mean(kept[y])) if y.any() else empty,
                "wrong_refused_test": float(np.mean(~kept[~y])) if (~y).any() else empty,
            }
    return Calibration(encoder_set, models, report, thresholds)


#: Generator seeds of the calibration scenes (apart from the evaluation suites' seeds).
CALIBRATION_SEEDS = tuple(range(700, 706))


def run_calibration(
    encoder_set: str = "default",
    seeds=CALIBRATION_SEEDS,
    speed: float = 0.3,
    progress=None,
    images: bool = True,
    cache_dir=None,
) -> Calibration:
    """Scan a generated scene per seed, build its map with ``encoder_set``, label queries,
    fit on the first half of the scenes and report on the second (held-out scenes). With
    ``images``, each scene's image goals (rendered by a second simulator of it, at poses the
    scan never took) and the previous scene's pictures (foreign: always wrong) are queried too.
    ``cache_dir``: scans and maps are reused from (and kept in) it, as the evaluation does.
    """
    from tabletop.eval.harness import generated_scene, scene_map
    from tabletop.eval.map_goals import ImageGoalConfig, image_goals
    from tabletop.sim.world import SimWorld

    seeds = list(seeds)
    if len(seeds) < 2:
        raise ConfigError("calibration needs at least 2 scene seeds (fit and held-out halves)")
    per_scene, previous = [], []
    for seed in seeds:
        spec = generated_scene(seed, f"calib-{seed}")
        rec, m = scene_map(spec, {"seed": seed, "speed": speed}, encoder_set, cache_dir=cache_dir)
        truth = GroundTruth.of(rec)
        goals = []
        if images:
            with SimWorld(spec) as world:
                cfg = ImageGoalConfig(seed=seed)
                goals = image_goals(truth, world, cfg, rec.T_world_cam)
            goals = [g for g in goals if g.kind == "image"]
        per_scene.append(calibration_samples(m, truth, goals, previous))
        previous = [g.image for g in goals]
        if progress is not None:
            progress(seed, per_scene[-1])
    half = len(per_scene) // 2
    train = [s for scene in per_scene[:half] for s in scene]
    test = [s for scene in per_scene[half:] for s in scene]
    cal = fit_calibration(encoder_set, train, test)
    cal.report["seeds_fit"] = seeds[:half]
    cal.report["seeds_heldout"] = seeds[half:]
    return cal


#: Generator seeds of the rooms the room-aware network's calibration is fitted and measured on
#: (apart from the suites' rooms and the image network's training and held-out rooms).
ROOM_CALIBRATION_SEEDS = (30000, 30001, 30002)
#: How the room maps' operating points are chosen: a small object 2 m from the mast scores
#: among the wrong answers, so the arm's rule (keep 95 % of the right answers) would accept
#: most queries of absent things (:func:`operating_point`).
ROOM_OPERATING_RULE = "balanced"
#: The rooms' scan: the suites' (three sound episodes, each sound played again once).
ROOM_CALIBRATION_SCAN = {"episodes": 3, "repeat_sounds": 1}


def run_room_calibration(
    encoder_set: str = "default", seeds=ROOM_CALIBRATION_SEEDS, progress=None, cache_dir=None
) -> Calibration:
    """:func:`run_calibration` for room maps (``tabletop calibrate --rooms``): a generated room
    per seed, scanned by the wheeled base and mapped with the room's settings
    (:func:`~tabletop.eval.room.room_map_settings`: the room-aware image network, frames
    enlarged twice), its objects, sounds and areas queried (no image goals) and labelled as
    the arm's are (:func:`calibration_samples`); fitted on the first rooms, reported on the
    last (one room in three)."""
    from tabletop.eval.harness import cached_map
    from tabletop.eval.room import cached_room_recording, room_map_settings, room_recording_key
    from tabletop.sim.room import generate_room

    seeds = [int(s) for s in seeds]
    if len(seeds) < 2:
        raise ConfigError("calibration needs at least 2 room seeds (fit and held-out rooms)")
    per_room = []
    for seed in seeds:
        spec = generate_room(seed)
        scan = {"seed": seed, **ROOM_CALIBRATION_SCAN}
        name = f"calib-room-{seed}"
        rec, _, _ = cached_room_recording(name, scan, spec, cache_dir)
        key = room_recording_key(spec, scan)
        m, _, _ = cached_map(name, room_map_settings(spec), rec, encoder_set, cache_dir, key, None)
        per_room.append(calibration_samples(m, GroundTruth.of(rec)))
        if progress is not None:
            progress(seed, per_room[-1])
    fit = (len(per_room) + 1) // 2
    train = [s for room in per_room[:fit] for s in room]
    test = [s for room in per_room[fit:] for s in room]
    cal = fit_calibration(encoder_set, train, test, rule=ROOM_OPERATING_RULE)
    cal.report["operating_rule"] = ROOM_OPERATING_RULE
    cal.report["seeds_fit"] = seeds[:fit]
    cal.report["seeds_heldout"] = seeds[fit:]
    cal.report["rooms"] = True
    return cal

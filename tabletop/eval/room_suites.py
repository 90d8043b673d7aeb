"""Task files for the mobile base, generated from a room scan's ground truth.

``python -m tabletop.eval.room_suites [--only NAME]`` writes ``tabletop/data/tasks/mobile/``
(:data:`ROOM_SUITES`), ``tabletop/data/tasks/mobile-heldout/`` (:data:`HELDOUT_ROOM_SUITES`:
rooms of generator seeds no tuning saw; evaluate them at the end, do not read them while
tuning) and ``mobile-heldout-2/`` (:data:`HELDOUT_ROOM_SUITES_2`, drawn after the first
held-out pair had been looked at), ``mobile-heldout-3/`` (:data:`HELDOUT_ROOM_SUITES_3`,
drawn after the second had been), ``mobile-heldout-4/`` (:data:`HELDOUT_ROOM_SUITES_4`,
drawn after the third had been) and ``mobile-heldout-5/`` (:data:`HELDOUT_ROOM_SUITES_5`,
drawn after the fourth had been): one task file per room (the shipped default room and
generated rooms), each with every goal type of the arm's suites, worded with the catalog's
labels and the sound bank's captions, and the robot section of a mobile base
(``kind = "mobile"``, the paper's 1 m success radius).

What differs from the arm's suites (:mod:`tabletop.eval.suites`): a spatial goal is "between"
two landmarks (side relations depend on which way the base faces, so their truth is not a
fixed point of the room); an area is the top of a table, named by what stands on it ("the
area around the teddy bear"); an image is taken from a standing height at a free place of the
room, looking at an object, and reached where it was taken; truth points of spatial goals lie
on free floor the base can stand on.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
from pathlib import Path

import numpy as np

from tabletop.eval.suites import (
    _the,
    draw,
    relation_goal,
    relation_truth_point,
    sound_object_pairs,
    to_toml,
)
from tabletop.eval.tasks import FORMAT_NAME, FORMAT_VERSION, parse_tasks
from tabletop.eval.truth import sound_occurrences
from tabletop.paths import DATA_DIR
from tabletop.sim.ground_truth import GroundTruth

__all__ = [
    "HELDOUT_ROOM_SUITES",
    "HELDOUT_ROOM_SUITES_2",
    "HELDOUT_ROOM_SUITES_3",
    "HELDOUT_ROOM_SUITES_4",
    "HELDOUT_ROOM_SUITES_5",
    "ROOM_SUITES",
    "generate_room_suite",
    "write_room_suites",
]


def _generated(seed: int, goal_seed: int) -> tuple[dict, dict, int]:
    """A suite of generated room ``seed``: its [room] and [scan] sections and goal seed."""
    return {"random": {"seed": seed}}, {"seed": seed, "episodes": 3, "repeat_sounds": 1}, goal_seed


def _heldout_pair(n: int) -> dict:
    """Held-out suites ``room-heldout-<n>`` and ``room-heldout-<n + 1>``: rooms of generator
    seeds 9100 + n on, goals of seeds 9300 + n on."""
    return {f"room-heldout-{k}": _generated(9100 + k, 9300 + k) for k in (n, n + 1)}


#: The shipped mobile suites: name -> ([room] section, [scan] section, goal seed).
ROOM_SUITES = {
    "room-default": ({"name": "default"}, {"seed": 0, "episodes": 3, "repeat_sounds": 1}, 300),
    "room-random-1": _generated(1, 301),
}
#: Held-out mobile suites: rooms drawn with generator seeds that neither the room settings'
#: tuning nor any test used, goals drawn with seeds of their own.
HELDOUT_ROOM_SUITES = _heldout_pair(1)
#: A second held-out pair, drawn when the first had been looked at (its figures reported once,
#: then its image goals' pictures studied): for figures after that study.
HELDOUT_ROOM_SUITES_2 = _heldout_pair(3)
#: A third held-out pair, drawn when the second had been run once and its two missed image
#: goals diagnosed: for figures after that.
HELDOUT_ROOM_SUITES_3 = _heldout_pair(5)
#: A fourth held-out pair, drawn when the third had been run once and its missed spatial goals
#: traced to two touching objects of one colour segmented as one: for figures after that.
HELDOUT_ROOM_SUITES_4 = _heldout_pair(7)
#: A fifth held-out pair, drawn when the fourth had been run and read (its object misses and
#: image goals diagnosed), after the rooms' calibration, the shape split and the map loading
#: fix: for figures after those.
HELDOUT_ROOM_SUITES_5 = _heldout_pair(9)
#: Where each set of suites is written, under ``tabletop/data/tasks/``.
SUITE_DIRS = {
    "mobile": ROOM_SUITES,
    "mobile-heldout": HELDOUT_ROOM_SUITES,
    "mobile-heldout-2": HELDOUT_ROOM_SUITES_2,
    "mobile-heldout-3": HELDOUT_ROOM_SUITES_3,
    "mobile-heldout-4": HELDOUT_ROOM_SUITES_4,
    "mobile-heldout-5": HELDOUT_ROOM_SUITES_5,
}
#: Goals per type in each suite (at most; fewer when the room has fewer).
COUNTS = {
    "object": 8,
    "sound": 5,
    "image": 4,
    "area": 3,
    "ambiguous": 4,
    "spatial": 4,
    "multimodal_spatial": 3,
    "instruction": 6,
    "absent": 3,
    "sequences": 2,
}
#: Things no generated room holds (absent goals).
ABSENT = ("the giraffe", "a grand piano", "the fire truck", "a bicycle", "the laptop")
_CAMERA_HEIGHT_M = 1.1
_VERBS = ("go to", "drive to", "head to", "move to")
_TASKS_ROOT = DATA_DIR / "tasks"


def _free(occ: np.ndarray, cell: float, xy) -> bool:
    i, j = math.floor(xy[0] / cell), math.floor(xy[1] / cell)
    return 0 <= i < occ.shape[0] and 0 <= j < occ.shape[1] and not occ[i, j]


def generate_room_suite(
    name: str, room: dict, scan: dict, spec, gt: GroundTruth, seed: int, counts=COUNTS
) -> dict:
    """A mobile task document (dict) for room ``spec`` from its scan's ground truth ``gt``;
    the goals drawn depend on ``seed`` and the ground truth only."""
    rng = np.random.default_rng(seed)
    cell = 0.05
    occ = spec.occupancy(cell, inflate=0.3)  # where the base's centre may stand
    labels = [o.label for o in gt.objects]
    objs = [o for o in gt.objects if labels.count(o.label) == 1]
    events = list(gt.sound_events_by_onset)
    cats = [e.category for e in events]
    first = {}
    for e in events:
        first.setdefault(e.category, e)
    unique = [e for e in events if cats.count(e.category) == 1]
    goals: list[dict] = []

    def add(gid, gtype, text, truth, **kw):
        goals.append({"id": gid, "type": gtype, "text": text, **kw, "truth": truth})

    pick = functools.partial(draw, rng)

    for o in pick(objs, counts["object"]):
        add(f"object-{o.name}", "object", _the(o.label), {"object": o.name}, query={"obj": o.label})
    for cat in pick(dict.fromkeys(cats), counts["sound"]):
        s = first[cat].caption
        add(f"sound-{cat}", "sound", s, {"sound": cat}, query={"sound": s})
    # images from a standing height at free floor 1.0-1.6 m from an object, looking at it
    views = []
    for o in objs:
        for _ in range(40):
            a, r = rng.uniform(0, 2 * math.pi), rng.uniform(1.0, 1.6)
            eye = o.center[:2] + r * np.array([math.cos(a), math.sin(a)])
            if _free(occ, cell, eye):
                views.append((o, [float(eye[0]), float(eye[1]), _CAMERA_HEIGHT_M]))
                break
    for i, (o, eye) in enumerate(pick(views, counts["image"])):
        v = {"eye": [round(x, 3) for x in eye], "look_at": [round(x, 3) for x in o.center]}
        v["up"] = [0.0, 0.0, 1.0]
        text = f"where this image was taken (looking at the {o.label})"
        add(f"image-{i}", "image", text, {"camera": v["eye"]}, query={"img": v})
    # areas: a table's top, named by what stands on it
    areas = []
    for a in gt.areas:
        on = [
            o for o in objs if a.x[0] <= o.center[0] <= a.x[1] and a.y[0] <= o.center[1] <= a.y[1]
        ]
        if on:
            areas.append((a, on[int(rng.integers(len(on)))]))
    for a, o in pick(areas, counts["area"]):
        q = f"the area around the {o.label}"
        add(f"area-{a.name.replace(' ', '_')}", "area", q, {"area": a.name}, query={"area": q})
    # ambiguous: a duplicated kind, disambiguated by a sound heard nearer one of them
    amb = []
    for k in gt.duplicated_kinds:
        dups = gt.objects_of_kind(k)
        for e in unique:
            d = sorted(
                (float(np.linalg.norm(np.subtract(e.table_point[:2], o.center[:2]))), o.name)
                for o in dups
            )
            if d[1][0] - d[0][0] >= 1.0:
                amb.append((gt.object(d[0][1]), e))
    # ... or a sound heard in two places, disambiguated by an object near one of them
    amb_obj = []
    for cat in sorted({c for c in cats if cats.count(c) > 1}):
        occs = sound_occurrences(gt, cat)
        for i, e in enumerate(occs):
            for o in objs:
                mine = float(np.linalg.norm(np.subtract(e.table_point[:2], o.center[:2])))
                other = min(
                    float(np.linalg.norm(np.subtract(x.table_point[:2], o.center[:2])))
                    for j, x in enumerate(occs)
                    if j != i
                )
                if mine <= 1.2 and other - mine >= 1.0:
                    amb_obj.append((cat, i, o))
    n_amb = counts["ambiguous"]
    for o, e in pick(amb, n_amb - min(len(amb_obj), n_amb // 2)):
        add(
            f"ambiguous-{o.name}-sound-{e.category}",
            "ambiguous",
            f"the {o.category} near {e.caption}",
            {"object": o.name},
            query={"obj": o.category, "sound": e.caption},
            primary="obj",
        )
    for cat, i, o in pick(amb_obj, n_amb - sum(g["type"] == "ambiguous" for g in goals)):
        s = first[cat].caption
        add(
            f"ambiguous-sound-{cat}-{i}-near-{o.name}",
            "ambiguous",
            f"{s} near the {o.label}",
            {"sound": cat, "occurrence": i},
            query={"obj": o.label, "sound": s},
            primary="sound",
        )
    # spatial: between two objects on different tables, the midpoint on free floor
    spatial = []
    for i, a in enumerate(objs):
        for b in objs[i + 1 :]:
            p = relation_truth_point(gt, "between", a, b)
            if _free(occ, cell, p) and np.linalg.norm(np.subtract(a.center, b.center)) >= 1.5:
                spatial.append((a, b))
    for a, b in pick(spatial, counts["spatial"]):
        marks = [("object", a.name, "obj", a.label), ("object", b.name, "obj", b.label)]
        text = f"between the {a.label} and the {b.label}"
        gid = f"spatial-between-{a.name}-{b.name}"
        goals.append(relation_goal(gid, "spatial", text, "between", marks))
    mm = sound_object_pairs(unique, objs, functools.partial(_free, occ, cell), 1.5, math.inf)
    for e, o in pick(mm, counts["multimodal_spatial"]):
        marks = [("sound", e.category, "sound", e.caption), ("object", o.name, "obj", o.label)]
        text = f"between {e.caption} and the {o.label}"
        gid = f"mm-between-{e.category}-{o.name}"
        goals.append(relation_goal(gid, "multimodal_spatial", text, "between", marks))
    # instructions in free text, through the instruction parser
    inst = [(("object", o), {"object": o.name}) for o in objs]
    inst += [(("sound", first[c]), {"sound": c}) for c in dict.fromkeys(cats) if cats.count(c) == 1]
    inst += [(("near", o, e), {"object": o.name}) for o, e in amb]
    inst += [
        (("between", a, b), {"relation": "between", "of": [{"object": a.name}, {"object": b.name}]})
        for a, b in spatial
    ]
    inst += [(("object_then_turn", o), {"object": o.name}) for o in objs]
    # every form in turn (objects, sounds, near a sound, between, then a turn), each drawn
    by_form: dict[str, list] = {}
    for form, truth in inst:
        by_form.setdefault(form[0], []).append((form, truth))
    for k in by_form:
        by_form[k] = pick(by_form[k], len(by_form[k]))
        rng.shuffle(by_form[k])
    chosen = []
    while len(chosen) < counts["instruction"] and any(by_form.values()):
        for k in list(by_form):
            if by_form[k] and len(chosen) < counts["instruction"]:
                chosen.append(by_form[k].pop())
    for j, (form, truth) in enumerate(chosen):
        v = _VERBS[j % len(_VERBS)]
        kind, *args = form
        if kind == "object_then_turn":
            text = f"{v} the {args[0].label}, then turn around"
        elif kind == "object":
            text = f"{v} the {args[0].label}"
        elif kind == "sound":
            text = f"{v} {args[0].caption}"
        elif kind == "near":
            text = f"{v} the {args[0].category} near {args[1].caption}"
        else:
            text = f"move in between the {args[0].label} and the {args[1].label}"
        add(f"instruction-{j}", "instruction", text, truth, instruction=text)
    kinds = {o.category for o in gt.objects} | {o.label for o in gt.objects}
    for i, q in enumerate(
        pick([a for a in ABSENT if a.split()[-1] not in kinds], counts["absent"])
    ):
        add(
            f"absent-{i}",
            "absent",
            q,
            {"absent": True},
            query={"obj": q.removeprefix("the ").removeprefix("a ")},
        )
    seqs = []
    by = {t: [g["id"] for g in goals if g["type"] == t] for t in ("sound", "image", "object")}
    for i in range(min(counts["sequences"], len(by["sound"]), len(by["image"]))):
        if len(by["object"]) < 2 * i + 2:
            break
        seqs.append(
            {
                "id": f"sequence-{i}",
                "goals": [by["sound"][i], by["image"][i], *by["object"][2 * i : 2 * i + 2]],
            }
        )
    doc = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "name": name,
        "description": "mobile-base suite: every goal type in one room, 1 m success radius",
        "robot": {"kind": "mobile", "success_radius": 1.0},
        "room": room,
        "scan": scan,
        "generator": {"seed": seed, "module": "tabletop.eval.room_suites"},
        "goals": goals,
        "sequences": seqs,
    }
    parse_tasks(json.loads(json.dumps(doc)), source=name)  # what is written must load
    return doc


def write_room_suites(
    out_root: Path = _TASKS_ROOT, cache_dir="out/eval-cache", only=None
) -> list[Path]:
    """Scan each room of :data:`SUITE_DIRS` (or take the cached scan) and write its task
    file into ``out_root/<suite directory>/``."""
    written = []
    for dirname, suites in SUITE_DIRS.items():
        written += _write(Path(out_root) / dirname, suites, cache_dir, only)
    return written


def _write(out_dir: Path, suites: dict, cache_dir, only) -> list[Path]:
    from tabletop.eval.room import cached_room_recording
    from tabletop.eval.tasks import room_ref

    written = []
    for name, (room, scan, seed) in suites.items():
        if only and name not in only:
            continue
        out_dir.mkdir(parents=True, exist_ok=True)
        spec = room_ref(room, name).load()
        cache = Path(cache_dir) if cache_dir is not None else None
        rec, _, _ = cached_room_recording(name, dict(scan), spec, cache)
        doc = generate_room_suite(name, room, scan, spec, GroundTruth.of(rec), seed)
        path = out_dir / f"{name}.toml"
        header = (
            "Generated by `python -m tabletop.eval.room_suites` from the room scan's ground\n"
            "truth; plain data: edit it or write another, the runner takes any task file."
        )
        path.write_text(to_toml(doc, header))
        written.append(path)
    return written


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(_TASKS_ROOT), help="the tasks directory")
    p.add_argument("--cache-dir", default="out/eval-cache")
    p.add_argument("--only", action="append")
    a = p.parse_args(argv)
    for path in write_room_suites(Path(a.out), a.cache_dir, a.only):
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())

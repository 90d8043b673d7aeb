"""Generate task files from a scene's ground truth (the shipped default suites come from here).

The generator scans the scene once (through the evaluation cache) to learn which sounds the
seeded scan inserts and where, then writes goals of every type whose truth it can state
unambiguously. The files it writes are plain data: they are committed, and the runner takes
any task file, generated or written by hand. Regenerate the shipped suites with::

    python -m tabletop.eval.suites            # writes tabletop/data/tasks/default/*.toml, demo.toml
    python -m tabletop.eval.suites --clutter  # writes tabletop/data/tasks/clutter/*.toml

Goal choices are seeded (``generator.seed`` in each file), so the same scan gives the same file.
How goals are worded is a :class:`Wording`: this one asks with the scene's exact catalog labels
and the sound bank's captions; :mod:`tabletop.eval.paraphrase` words the same goals the way
people do.
"""

from __future__ import annotations

import argparse
import functools
import json
from pathlib import Path

import numpy as np

from tabletop.eval.tasks import FORMAT_NAME, FORMAT_VERSION, Truth, parse_tasks
from tabletop.eval.truth import resolve_truth, sound_occurrences
from tabletop.relations import RELATIONS
from tabletop.sim.ground_truth import AreaTruth, GroundTruth, ObjectTruth, SoundEventTruth
from tabletop.transforms import aabb_distance

__all__ = [
    "CLUTTER_SEEDS",
    "CLUTTER_SUITES",
    "DEFAULT_SUITES",
    "Wording",
    "generate_suite",
    "to_toml",
    "write_clutter_suites",
    "write_default_suites",
]

#: (file stem, scene section, scan section, map section, goal counts) of the shipped suites.
_SCAN = {"speed": 0.3, "episodes": 6, "episode_s": 4.0, "repeat_sounds": 1}
_MAP = {"frame_step": 2}
DEFAULT_SUITES = [
    ("scene-default", {"name": "default"}, {"seed": 0, **_SCAN}),
    *[
        (
            f"scene-random-{s}",
            {"random": {"seed": s, "count": 9, "duplicates": 2}},
            {"seed": i + 1, **_SCAN},
        )
        for i, s in enumerate((11, 12, 13, 14, 15))
    ],
]
#: Generator seeds of the clutter suites' dense tables (and their scans), used by no other
#: experiment: not the shipped suites (11-15, scan seeds 0-5), eval-map (10-12), the
#: calibration (700-705), the paraphrase suites (750-752, 760-762, 800-803 ... 890-893 by tens,
#: 910-913, 920-923, 930-933), the shape prior (400-411, 430-433), the instance evaluation
#: (900-902), vision training layouts (0-219 at seed 0, and from 9,000,000 held out).
CLUTTER_SEEDS = (950, 951, 952, 953)
#: (file stem, scene section, scan section) of the clutter suites: 12 objects, 3 kinds twice,
#: packed by the generator's ``clutter`` profile (tall kinds beside low ones).
CLUTTER_SUITES = [
    (
        f"scene-clutter-{s}",
        {"random": {"seed": s, "count": 12, "duplicates": 3, "profile": "clutter"}},
        {"seed": s, **_SCAN},
    )
    for s in CLUTTER_SEEDS
]
#: Goals of a clutter suite: on objects (object goals) and beside and between them (spatial).
_CLUTTER = dict(
    object=10,
    sound=0,
    image=0,
    area=0,
    amb_sound=0,
    amb_image=0,
    amb_object=0,
    amb_area=0,
    spatial=15,
    mm_spatial=0,
    instruction=0,
    sequences=0,
)
#: Free table [m] a clutter suite's spatial truth keeps from every object box (between, beside):
#: the gaps between packed objects (the shipped suites keep 3 and 5 cm).
_CLUTTER_CLEAR = (0.01, 0.015)
_FULL = dict(
    object=8,
    sound=5,
    image=3,
    area=5,
    amb_sound=2,
    amb_image=2,
    amb_object=1,
    amb_area=1,
    spatial=5,
    mm_spatial=3,
    instruction=6,
    sequences=3,
)
_DEMO = dict(
    object=3,
    sound=2,
    image=2,
    area=2,
    amb_sound=1,
    amb_image=1,
    amb_object=1,
    amb_area=0,
    spatial=2,
    mm_spatial=2,
    instruction=3,
    sequences=1,
)


# ---------------------------------------------------------------------------- TOML output
def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(round(float(v), 4))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def to_toml(doc: dict, header: str = "") -> str:
    """A task document as TOML: scalars, then tables, then arrays of tables."""
    lines = [f"# {x}" if x else "#" for x in header.splitlines()]
    scalars = {k: v for k, v in doc.items() if not isinstance(v, (dict, list)) or k == "x"}
    tables = {k: v for k, v in doc.items() if isinstance(v, dict)}
    arrays = {k: v for k, v in doc.items() if isinstance(v, list)}
    lines += [f"{k} = {_toml_value(v)}" for k, v in scalars.items()]
    for k, t in tables.items():
        lines += ["", f"[{k}]"] + [f"{a} = {_toml_value(b)}" for a, b in t.items()]
    for k, items in arrays.items():
        for it in items:
            lines += ["", f"[[{k}]]"] + [f"{a} = {_toml_value(b)}" for a, b in it.items()]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- goal drawing
def _box_dist(p, o: ObjectTruth) -> float:
    return aabb_distance(p, o.aabb_min, o.aabb_max)


def _xy_clear(p, objects: tuple[ObjectTruth, ...], exclude=(), margin: float = 0.03) -> bool:
    """The point's column is at least ``margin`` [m] from every object box but ``exclude``."""
    for o in objects:
        if o.name in exclude:
            continue
        q = np.array([p[0], p[1], 0.0])
        lo, hi = np.array(o.aabb_min), np.array(o.aabb_max)
        d = np.maximum(lo[:2] - q[:2], 0) + np.maximum(q[:2] - hi[:2], 0)
        if np.linalg.norm(d) < margin:
            return False
    return True


def _reachable(p) -> bool:
    """Inside the part of the table the scans cover and the arm reaches from above."""
    return 0.25 <= p[0] <= 0.72 and abs(p[1]) <= 0.42


def _view(rng, target_xy) -> dict:
    """A camera 0.36-0.42 m above the table, up to 4 cm beside ``target_xy``, looking at it."""
    eye = [
        float(target_xy[0] + rng.uniform(-0.04, 0.04)),
        float(target_xy[1] + rng.uniform(-0.04, 0.04)),
        float(rng.uniform(0.36, 0.42)),
    ]
    return {
        "eye": [round(v, 3) for v in eye],
        "look_at": [round(float(v), 3) for v in target_xy] + [0.0],
    }


def relation_truth_point(gt: GroundTruth, relation: str, *landmarks: ObjectTruth) -> np.ndarray:
    """The truth point (3,) [m] of ``relation`` ("between", a side relation) to the objects
    ``landmarks`` of ``gt``: where a spatial goal's truth lies, checked before it is asked."""
    of = tuple(Truth("object", object=o.name) for o in landmarks)
    return resolve_truth(Truth("relation", relation=relation, of=of), gt).center


def sound_object_pairs(
    events, objects, free, near: float, far: float
) -> list[tuple[SoundEventTruth, ObjectTruth]]:
    """(sound event, object) pairs, events first, whose midpoint is free (``free(point)``:
    table, or floor a base can stand on) and whose distance [m] in the plane is in
    [``near``, ``far``]: the landmarks of "between a sound and an object" goals."""
    pairs = []
    for e in events:
        for o in objects:
            mid = (np.array(e.table_point) + np.array(o.center)) / 2
            d = np.linalg.norm(np.subtract(e.table_point[:2], o.center[:2]))
            if free(mid) and near <= d <= far:
                pairs.append((e, o))
    return pairs


def relation_goal(gid: str, gtype: str, text: str, relation: str, landmarks) -> dict:
    """A spatial or multimodal spatial goal (``gtype``): ``text`` asks for the point in
    ``relation`` to ``landmarks``, each (what, name, key, words): what the truth names
    ("object", "sound") and its name in the ground truth, the query's key ("obj", "sound")
    and the words that ask for it."""
    return {
        "id": gid,
        "type": gtype,
        "text": text,
        "relation": relation,
        "landmarks": [{key: words} for _, _, key, words in landmarks],
        "truth": {"relation": relation, "of": [{what: name} for what, name, _, _ in landmarks]},
    }


def draw(rng: np.random.Generator, seq, n: int) -> list:
    """``n`` items of ``seq`` drawn with ``rng``, in their order (all of them when it has no
    more than ``n``)."""
    seq = list(seq)
    if len(seq) <= n:
        return seq
    return [seq[i] for i in sorted(rng.choice(len(seq), n, replace=False))]


def _the(phrase: str) -> str:
    """``phrase`` with a leading article: "the red mug"; one that has an article keeps it."""
    return phrase if phrase.split(" ", 1)[0] in ("the", "a", "an") else f"the {phrase}"


#: Relation words of goal texts and instructions.
RELATION_WORDS = {r.name: r.wording for r in RELATIONS if r.name != "above"}
#: The side relations, in declaration order.
SIDE_RELATIONS = tuple(r.name for r in RELATIONS if r.side is not None)
_VERBS = ("go to", "move to", "reach", "approach")


class Wording:
    """How generated goals word their queries: this one with the scene's exact catalog labels
    ("red mug") and the sound bank's captions (the shipped suites). A subclass words them
    otherwise (:class:`tabletop.eval.paraphrase.ParaphraseWording`); the goals and their truth
    stay what :func:`generate_suite` draws. Each call words one mention: a goal's text and its
    query use the same call's result."""

    def object(self, o: ObjectTruth) -> str:
        """A query naming object ``o`` unambiguously in its scene."""
        return o.label

    def kind(self, o: ObjectTruth) -> str:
        """A query naming ``o``'s kind, which another object of the scene shares (the
        ambiguous goals' primary part)."""
        return o.category

    def sound(self, event: SoundEventTruth) -> str:
        """A query naming the sound category of ``event``."""
        return event.caption

    def area(self, area: AreaTruth) -> str:
        """A query naming a table area."""
        return area.name

    def instruction(self, j: int, form: str, *args) -> str:
        """The ``j``-th instruction of a suite in free text. ``form`` and ``args``: "object"
        (o), "sound" (event), "near" (o, event: o's kind near the sound), "between" (a, b),
        or a side relation of :data:`RELATION_WORDS` (o)."""
        v = _VERBS[j % len(_VERBS)]
        if form == "object":
            return f"{v} the {args[0].label}"
        if form == "sound":
            return f"{v} {args[0].caption}"
        if form == "near":
            return f"{v} the {args[0].category} near {args[1].caption}"
        if form == "between":
            return f"move in between the {args[0].label} and the {args[1].label}"
        return f"go {RELATION_WORDS[form]} the {args[0].label}"


def generate_suite(
    name: str,
    scene: dict,
    scan: dict,
    ground_truth: GroundTruth,
    counts: dict,
    seed: int = 0,
    map_section: dict | None = None,
    description: str = "",
    wording: Wording | None = None,
    generator: dict | None = None,
    spatial_clear: tuple[float, float] = (0.03, 0.05),
) -> dict:
    """A task document (dict) for one scene from its recording's ground truth. ``wording``
    (default :class:`Wording`: exact labels and captions) words the queries; the goals drawn
    depend on ``seed`` and the ground truth only. ``generator`` replaces the document's
    ``[generator]`` section (default: the seed and this module). ``spatial_clear``: how far
    [m] a spatial goal's truth point (between two objects, beside one) keeps from every object
    box, so that it is free table."""
    clear_between, clear_beside = (float(v) for v in spatial_clear)
    rng = np.random.default_rng(seed)
    w = wording if wording is not None else Wording()
    gt = ground_truth
    objs = [o for o in gt.objects if _reachable(o.center)]
    by_name = {o.name: o for o in gt.objects}
    kinds = [o.kind for o in gt.objects]
    dup_kinds = list(gt.duplicated_kinds)
    events = list(gt.sound_events_by_onset)
    cats = [e.category for e in events]
    unique_events = [e for e in events if cats.count(e.category) == 1]
    first_event = {}
    for e in events:
        first_event.setdefault(e.category, e)
    goals: list[dict] = []

    def add(gid, gtype, text, truth, **kw):
        goals.append({"id": gid, "type": gtype, "text": text, **kw, "truth": truth})

    pick = functools.partial(draw, rng)

    # object goals: a colour and a noun, unambiguous in the scene
    for o in pick(objs, counts["object"]):
        q = w.object(o)
        add(f"object-{o.name}", "object", _the(q), {"object": o.name}, query={"obj": q})
    # sound goals: every category inserted (a repeated one counts wherever it was heard)
    for cat in pick(dict.fromkeys(cats), counts["sound"]):
        s = w.sound(first_event[cat])
        add(f"sound-{cat}", "sound", s, {"sound": cat}, query={"sound": s})
    # image goals: views from above a reachable table point near an object
    for i, o in enumerate(pick(objs, counts["image"])):
        v = _view(rng, o.center[:2])
        add(
            f"image-{i}",
            "image",
            f"where this image was taken (over the {o.label})",
            {"camera": v["eye"]},
            query={"img": v},
        )
    # area goals
    for a in pick(list(gt.areas), counts["area"]):
        q = w.area(a)
        add(
            f"area-{a.name.replace(' ', '-')}", "area", _the(q), {"area": a.name}, query={"area": q}
        )
    # ambiguous: a duplicated kind disambiguated by a sound heard near one of them
    amb = []
    for k in dup_kinds:
        dups = gt.objects_of_kind(k)
        for e in unique_events:
            d = sorted((_box_dist(e.table_point, o), o.name) for o in dups)
            if d[1][0] - d[0][0] >= 0.10:
                amb.append((by_name[d[0][1]], e))
    for o, e in pick(amb, counts["amb_sound"]):
        k, s = w.kind(o), w.sound(e)
        add(
            f"ambiguous-{o.name}-sound-{e.category}",
            "ambiguous",
            f"{_the(k)} near {s}",
            {"object": o.name},
            query={"obj": k, "sound": s},
            primary="obj",
        )
    # ambiguous: a duplicated kind disambiguated by an image taken above one of them
    amb_img = [o for k in dup_kinds for o in gt.objects_of_kind(k) if _reachable(o.center)]
    for o in pick(amb_img, counts["amb_image"]):
        v = _view(rng, o.center[:2])
        k = w.kind(o)
        add(
            f"ambiguous-{o.name}-image",
            "ambiguous",
            f"{_the(k)} near this image",
            {"object": o.name},
            query={"obj": k, "img": v},
            primary="obj",
        )
    # ambiguous: a sound heard in two places, disambiguated by an object near one of them
    amb_obj = []
    for cat in sorted({c for c in cats if cats.count(c) > 1}):
        occ = sound_occurrences(gt, cat)
        for i, e in enumerate(occ):
            for o in gt.objects:
                if kinds.count(o.kind) > 1:
                    continue
                mine = _box_dist(e.table_point, o)
                other = min(_box_dist(x.table_point, o) for j, x in enumerate(occ) if j != i)
                if mine <= 0.15 and other - mine >= 0.15:
                    amb_obj.append((cat, i, o))
    for cat, i, o in pick(amb_obj, counts["amb_object"]):
        q, s = w.object(o), w.sound(first_event[cat])
        add(
            f"ambiguous-sound-{cat}-{i}-near-{o.name}",
            "ambiguous",
            f"{s} near {_the(q)}",
            {"sound": cat, "occurrence": i},
            query={"obj": q, "sound": s},
            primary="sound",
        )
    # ambiguous: a duplicated kind disambiguated by the table area it is in
    amb_area = []
    for k in dup_kinds:
        dups = gt.objects_of_kind(k)
        for a in gt.areas:
            inside = [
                o
                for o in dups
                if a.x[0] <= o.center[0] <= a.x[1] and a.y[0] <= o.center[1] <= a.y[1]
            ]
            if len(inside) == 1 and a.name in (
                "left side of the table",
                "right side of the table",
            ):
                amb_area.append((inside[0], a))
    for o, a in pick(amb_area, counts["amb_area"]):
        k, q = w.kind(o), w.area(a)
        add(
            f"ambiguous-{o.name}-area",
            "ambiguous",
            f"{_the(k)} on {_the(q)}",
            {"object": o.name},
            query={"obj": k, "area": q},
            primary="obj",
        )
    # spatial: between two objects, beside one (the truth point must be free table)
    spatial = []
    for i, a in enumerate(objs):
        for b in objs[i + 1 :]:
            p = relation_truth_point(gt, "between", a, b)
            if (
                _xy_clear(p, gt.objects, margin=clear_between)
                and 0.12 <= np.linalg.norm(np.subtract(a.center, b.center)) <= 0.45
            ):
                spatial.append(("between", [a, b]))
        for rel in SIDE_RELATIONS:
            p = relation_truth_point(gt, rel, a)
            if _reachable(p) and _xy_clear(p, gt.objects, margin=clear_beside):
                spatial.append((rel, [a]))
    words = RELATION_WORDS
    for rel, os_ in pick(spatial, counts["spatial"]):
        qs = [w.object(o) for o in os_]
        text = (
            f"between {_the(qs[0])} and {_the(qs[1])}"
            if rel == "between"
            else f"{words[rel]} {_the(qs[0])}"
        )
        gid = f"spatial-{rel}-" + "-".join(o.name for o in os_)
        marks = [("object", o.name, "obj", q) for o, q in zip(os_, qs, strict=True)]
        goals.append(relation_goal(gid, "spatial", text, rel, marks))
    # multimodal spatial: between a sound and an object; beside an object found by a sound
    free = functools.partial(_xy_clear, objects=gt.objects)
    mm = [
        ("between-sound", e, o)
        for e, o in sound_object_pairs(unique_events, objs, free, 0.12, 0.45)
    ]
    for o, e in amb:
        for rel in SIDE_RELATIONS:
            p = relation_truth_point(gt, rel, o)
            if _reachable(p) and _xy_clear(p, gt.objects, margin=0.05):
                mm.append((rel, e, o))
    for kind, e, o in pick(mm, counts["mm_spatial"]):
        if kind == "between-sound":
            s, q = w.sound(e), w.object(o)
            marks = [("sound", e.category, "sound", s), ("object", o.name, "obj", q)]
            text = f"between {s} and {_the(q)}"
            gid = f"mm-between-{e.category}-{o.name}"
            goals.append(relation_goal(gid, "multimodal_spatial", text, "between", marks))
        else:
            k, s = w.kind(o), w.sound(e)
            add(
                f"mm-{kind}-{o.name}-{e.category}",
                "multimodal_spatial",
                f"{words[kind]} {_the(k)} near {s}",
                {"relation": kind, "of": [{"object": o.name}]},
                relation=kind,
                landmarks=[{"obj": k, "sound": s}],
            )
    # free-language instructions, phrased as a person would, through the instruction parser
    inst = []
    for o in objs:
        inst.append((("object", o), {"object": o.name}))
    for cat in dict.fromkeys(cats):
        if cats.count(cat) == 1:
            inst.append((("sound", first_event[cat]), {"sound": cat}))
    for o, e in amb:
        inst.append((("near", o, e), {"object": o.name}))
    for rel, os_ in spatial:
        inst.append(((rel, *os_), {"relation": rel, "of": [{"object": o.name} for o in os_]}))
    for j, (form, truth) in enumerate(pick(inst, counts["instruction"])):
        text = w.instruction(j, *form)
        add(f"instruction-{j}", "instruction", text, truth, instruction=text)
    # sequences like the paper's tables: a sound, an image, then two objects, in a row
    seqs = []
    snd = [g["id"] for g in goals if g["type"] == "sound"]
    img = [g["id"] for g in goals if g["type"] == "image"]
    obj = [g["id"] for g in goals if g["type"] == "object"]
    for i in range(min(counts["sequences"], len(snd), len(img), len(obj) // 2)):
        seqs.append({"id": f"sequence-{i}", "goals": [snd[i], img[i], obj[2 * i], obj[2 * i + 1]]})
    doc = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "name": name,
        "description": description,
        "scene": scene,
        "scan": scan,
        "map": dict(map_section or _MAP),
        "generator": dict(generator or {"seed": seed, "module": "tabletop.eval.suites"}),
        "goals": goals,
        "sequences": seqs,
    }
    parse_tasks(json.loads(json.dumps(doc)), source=name)  # what is written must load
    return doc


def _scan_ground_truth(scene: dict, scan: dict, cache_dir) -> GroundTruth:
    from tabletop.eval.runner import scan_recording

    return GroundTruth.of(scan_recording(scene, scan, cache_dir)[0])


def write_default_suites(out_dir: Path, cache_dir="out/eval-cache", only=None) -> list[Path]:
    """Write the shipped suites (``default/*.toml``) and the demo suite (``demo.toml``)."""
    out_dir = Path(out_dir)
    (out_dir / "default").mkdir(parents=True, exist_ok=True)
    written = []
    header = (
        "Generated by `python -m tabletop.eval.suites` from the scene's ground truth and the\n"
        "seeded scan below; plain data: edit it or write another, the runner takes any task file."
    )
    for i, (stem, scene, scan) in enumerate(DEFAULT_SUITES):
        if only and stem not in only:
            continue
        gt = _scan_ground_truth(scene, scan, cache_dir)
        doc = generate_suite(
            stem,
            scene,
            scan,
            gt,
            _FULL,
            seed=100 + i,
            description="default suite: every goal type on one seeded scene",
        )
        p = out_dir / "default" / f"{stem}.toml"
        p.write_text(to_toml(doc, header))
        written.append(p)
    if not only or "demo" in only:
        scene, scan = (
            {"name": "default"},
            {"seed": 0, "speed": 0.3, "episodes": 6, "episode_s": 4.0, "repeat_sounds": 1},
        )
        gt = _scan_ground_truth(scene, scan, cache_dir)
        doc = generate_suite(
            "demo",
            scene,
            scan,
            gt,
            _DEMO,
            seed=7,
            description="the demo's short suite: a few goals of each type",
        )
        p = out_dir / "demo.toml"
        p.write_text(to_toml(doc, header))
        written.append(p)
    return written


def write_clutter_suites(out_dir: Path, cache_dir="out/eval-cache", only=None) -> list[Path]:
    """Write the clutter suites (``clutter/*.toml``): dense tables of :data:`CLUTTER_SEEDS`,
    goals on objects and beside and between them. Scans each scene once through the cache."""
    d = Path(out_dir) / "clutter"
    d.mkdir(parents=True, exist_ok=True)
    header = (
        "Clutter suite, generated by `python -m tabletop.eval.suites --clutter` from the\n"
        "scene's ground truth and the seeded scan below; plain data."
    )
    written = []
    for stem, scene, scan in CLUTTER_SUITES:
        if only and stem not in only:
            continue
        gt = _scan_ground_truth(scene, scan, cache_dir)
        doc = generate_suite(
            stem,
            scene,
            scan,
            gt,
            _CLUTTER,
            seed=scan["seed"],
            description=(
                "clutter suite: a dense table (12 objects, 3 kinds twice, tall beside low); "
                "goals on objects and beside and between them"
            ),
            spatial_clear=_CLUTTER_CLEAR,
        )
        p = d / f"{stem}.toml"
        p.write_text(to_toml(doc, header))
        written.append(p)
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--out",
        default="out/tasks",
        help="tasks directory (default: out/tasks); the shipped suites: tabletop/data/tasks",
    )
    ap.add_argument("--cache-dir", default="out/eval-cache")
    ap.add_argument("--only", nargs="*", help="suite stems to write (default: all)")
    ap.add_argument(
        "--clutter", action="store_true", help="write the clutter suites instead (clutter/)"
    )
    args = ap.parse_args(argv)
    write = write_clutter_suites if args.clutter else write_default_suites
    for p in write(Path(args.out), args.cache_dir, args.only):
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

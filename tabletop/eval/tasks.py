"""Task files: a scene, how to scan it, and goals with their ground truth, as data.

A task file is TOML or JSON (``tabletop-tasks`` version 1; see ``docs/evaluation.md``)::

    format = "tabletop-tasks"
    version = 1
    name = "default scene"

    [scene]                 # exactly one of: name (shipped), path (relative to this file), random
    name = "default"

    [scan]                  # tabletop.sim.ScanConfig fields (seeded, so the scan is repeatable)
    seed = 0
    speed = 0.3

    [[goals]]
    id = "object-red-mug"
    type = "object"
    text = "the red mug"
    query = { obj = "red mug" }
    truth = { object = "red_mug" }

A mobile-base task file has ``[robot] kind = "mobile"`` and a ``[room]`` (name, path or
``random = { seed = N }``) instead of ``[scene]``; its ``[scan]`` holds
:class:`tabletop.sim.room_scan.RoomScanConfig` fields. ``[robot]`` may set ``success_radius``
[m] (0.10 for the arm's TCP, 1.0 for a base, the paper's radius) and, for a base,
``embodiment`` ("ground" or "flyer"). Each robot's kind, defaults, workspace section and scan
settings are its :class:`~tabletop.embodiments.Embodiment`'s.

Goal types: object, sound, image, area, ambiguous, spatial, multimodal_spatial, instruction,
absent. A *query* goal (every type but spatial ones and instructions) names map queries by modality
(``obj``, ``sound``, ``img``, ``area``); with several, ``primary`` is the sharp one and the
others broad constraints, as in :meth:`tabletop.robot.RobotAPI.get_major_map`. A spatial goal
has a ``relation`` and ``landmarks`` (each a query). An instruction goal has free text for the
instruction parser. An *absent* goal asks for one thing (``obj``, ``sound`` or ``area``: a place
the table does not have) that is not there; its truth is ``{ absent = true }`` and it succeeds
when the map finds nothing. Ground truth is given by reference to the recording's ground
truth (``object``, ``sound`` [+ ``occurrence``], ``area``), explicitly (``point``, ``box``,
``camera``), as a relation of other truths (``relation`` + ``of``), or as ``absent``.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from tabletop.errors import ConfigError
from tabletop.relations import RELATIONS as _RELATIONS

__all__ = [
    "ABSENT_MODALITIES",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "GOAL_TYPES",
    "MODALITIES",
    "RELATIONS",
    "Goal",
    "ImageView",
    "Landmark",
    "RobotRef",
    "RoomRef",
    "SceneRef",
    "TaskFile",
    "TaskFileError",
    "Truth",
    "load_tasks",
    "parse_tasks",
]

FORMAT_NAME = "tabletop-tasks"
FORMAT_VERSION = 1

#: Goal types, in report order.
GOAL_TYPES = (
    "object",
    "sound",
    "image",
    "area",
    "ambiguous",
    "spatial",
    "multimodal_spatial",
    "instruction",
    "absent",
)
#: Query parts, as the robot API names them.
MODALITIES = ("obj", "sound", "img", "area")
#: What an ``absent`` goal may ask for (one of them): a thing, a sound, a place.
ABSENT_MODALITIES = ("obj", "sound", "area")
#: Spatial relations and how many landmarks each takes.
RELATIONS = {r.name: r.landmarks for r in _RELATIONS}
_TRUTH_KINDS = ("object", "sound", "area", "point", "box", "camera", "relation", "absent")
_MAP_FIELDS = ("frame_step", "pixel_step", "voxel_size")


class TaskFileError(ConfigError):
    """A task file is malformed: the message names the file, the goal and the valid options."""


@dataclass(frozen=True)
class ImageView:
    """A query image rendered in the scene from a camera at ``eye`` looking at ``look_at``
    (world frame [m]); the image's top points along ``up`` (default +x, across the table)."""

    eye: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (1.0, 0.0, 0.0)


@dataclass(frozen=True)
class Truth:
    """Where a goal really is. Exactly one kind is set:

    - ``object``: an object's name in the scene (its ground-truth box);
    - ``sound``: a sound category inserted in the scan (the column from the table point beneath
      where it was heard up to the microphone); with ``occurrence`` (0-based, in time order) one
      of several insertions, else any of them;
    - ``area``: a named table area (its rectangle, up to 0.30 m above the table);
    - ``point`` (3,) / ``box`` ((3,), (3,)) [m]: explicit;
    - ``camera`` (3,) [m]: where a query image was taken (the column beneath the camera);
    - ``relation`` with ``of``: a spatial relation of other truths (see :data:`RELATIONS`);
    - ``absent``: nowhere, the goal's query names nothing in the scene (``absent`` goals only,
      written ``truth = { absent = true }``).
    """

    kind: str
    object: str | None = None
    sound: str | None = None
    occurrence: int | None = None
    area: str | None = None
    point: tuple[float, float, float] | None = None
    box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    relation: str | None = None
    of: tuple[Truth, ...] = ()

    def describe(self) -> str:
        if self.kind == "object":
            return f"object {self.object}"
        if self.kind == "sound":
            occ = "" if self.occurrence is None else f" #{self.occurrence}"
            return f"sound {self.sound}{occ}"
        if self.kind == "area":
            return f"area {self.area!r}"
        if self.kind == "relation":
            return f"{self.relation}(" + ", ".join(t.describe() for t in self.of) + ")"
        if self.kind == "absent":
            return "absent (not in the scene)"
        return f"{self.kind} {getattr(self, self.kind)}"


@dataclass(frozen=True)
class Landmark:
    """One map query: modality -> text (or an :class:`ImageView` for ``img``)."""

    parts: tuple[tuple[str, object], ...]
    primary: str

    @property
    def as_dict(self) -> dict:
        return dict(self.parts)

    def describe(self) -> str:
        out = []
        for k, v in self.parts:
            text = "an image" if k == "img" else repr(v)
            out.append(f"{k}={text}" + ("*" if k == self.primary and len(self.parts) > 1 else ""))
        return ", ".join(out)


@dataclass(frozen=True)
class Goal:
    """One goal of a task file."""

    id: str
    type: str
    text: str
    truth: Truth
    query: Landmark | None = None
    relation: str | None = None
    landmarks: tuple[Landmark, ...] = ()
    instruction: str | None = None

    @property
    def needs_image(self) -> bool:
        qs = [self.query] if self.query else list(self.landmarks)
        return any(k == "img" for q in qs for k, _ in q.parts)


@dataclass(frozen=True)
class SceneRef:
    """Which scene: a shipped scene ``name``, a spec ``path``, or a generator draw ``random``
    (a dict of :class:`tabletop.sim.scene.RandomSpec` fields)."""

    name: str | None = None
    path: Path | None = None
    random: dict | None = None

    def describe(self) -> str:
        if self.name:
            return f"shipped scene {self.name!r}"
        if self.path:
            return f"scene spec {self.path}"
        return "generated scene " + ", ".join(f"{k}={v}" for k, v in self.random.items())

    def load(self):
        """The :class:`tabletop.sim.scene.SceneSpec`."""
        from tabletop.sim.scene import SceneSpec, load_scene_spec

        if self.name:
            return load_scene_spec(self.name)
        if self.path:
            return load_scene_spec(self.path)
        seed = self.random.get("seed", 0)
        return SceneSpec.from_dict(
            {"scene": {"name": f"random-{seed}"}, "random": dict(self.random)},
            source=f"random-{seed}",
        )


@dataclass(frozen=True)
class RoomRef:
    """Which room (a mobile base's task file): a shipped room ``name``, a spec ``path``, or a
    generator draw ``random`` (``{"seed": N}``)."""

    name: str | None = None
    path: Path | None = None
    random: dict | None = None

    def describe(self) -> str:
        if self.name:
            return f"shipped room {self.name!r}"
        if self.path:
            return f"room spec {self.path}"
        return f"generated room, seed {self.random['seed']}"

    def load(self):
        """The :class:`tabletop.sim.room.RoomSpec`."""
        from tabletop.sim.room import generate_room, load_room_spec

        if self.name:
            return load_room_spec(self.name)
        if self.path:
            return load_room_spec(self.path)
        return generate_room(self.random["seed"])


@dataclass(frozen=True)
class RobotRef:
    """The robot a task file's goals are for (``[robot]``)."""

    kind: str = "arm"
    """A registered robot (:mod:`tabletop.embodiments`): "arm" (the Panda over a table),
    "mobile" (a wheeled base in a room), or one added since."""
    success_radius: float = 0.10
    """A goal is reached within this distance [m]: of the TCP (arm), of the base's centre on
    the floor, in x and y (mobile)."""
    embodiment: str | None = None
    """Its obstacle embodiment, of those it declares (a mobile base's "ground" or "flyer",
    :mod:`tabletop.robot.wheeled`); None for a robot with none to choose."""

    @property
    def body(self):
        """Its :class:`~tabletop.embodiments.Embodiment`."""
        from tabletop.embodiments import embodiment

        return embodiment(self.kind)


@dataclass(frozen=True)
class TaskFile:
    """A parsed task file."""

    path: Path | None
    name: str
    scene: SceneRef | RoomRef
    """The arm's scene, or a mobile base's room (:attr:`robot` says which)."""
    scan: dict
    map: dict
    goals: tuple[Goal, ...]
    sequences: tuple[tuple[str, tuple[str, ...]], ...]
    description: str = ""
    extra: dict = field(default_factory=dict)
    noise: dict = field(default_factory=dict)
    """The ``[noise]`` section: :class:`~tabletop.sim.noise.NoiseConfig` fields applied to the
    clean scan before mapping (empty: a clean run)."""
    robot: RobotRef = field(default_factory=RobotRef)
    """The ``[robot]`` section."""

    def goal(self, goal_id: str) -> Goal:
        for g in self.goals:
            if g.id == goal_id:
                return g
        raise KeyError(goal_id)

    def runs(self) -> list[tuple[str, list[Goal]]]:
        """Goals in execution order, grouped: each declared sequence, then every other goal as
        a sequence of its own (the arm starts from home at the start of each)."""
        out = [(sid, [self.goal(g) for g in ids]) for sid, ids in self.sequences]
        seen = {g for _, ids in self.sequences for g in ids}
        out += [(g.id, [g]) for g in self.goals if g.id not in seen]
        return out


# ---------------------------------------------------------------------------- parsing
def _err(where: str, msg: str) -> TaskFileError:
    return TaskFileError(f"{where}: {msg}")


def _keys(d: object, where: str, required: tuple, optional: tuple = ()) -> dict:
    if not isinstance(d, dict):
        raise _err(where, f"must be a table/object, got {type(d).__name__}")
    valid = (*required, *optional)
    unknown = sorted(set(d) - set(valid))
    if unknown:
        raise _err(where, f"unknown keys {unknown}; valid: {list(valid)}")
    missing = [k for k in required if k not in d]
    if missing:
        raise _err(where, f"missing required keys {missing}")
    return d


def _vec(v: object, where: str, n: int = 3) -> tuple[float, ...]:
    if (
        not isinstance(v, (list, tuple))
        or len(v) != n
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
        or not all(math.isfinite(x) for x in v)
    ):
        raise _err(where, f"must be a list of {n} finite numbers [m], got {v!r}")
    return tuple(float(x) for x in v)


def _text(v: object, where: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise _err(where, f"must be a non-empty string, got {v!r}")
    return v


def _view(v: object, where: str) -> ImageView:
    d = _keys(v, where, ("eye", "look_at"), ("up",))
    view = ImageView(
        _vec(d["eye"], f"{where}.eye"),
        _vec(d["look_at"], f"{where}.look_at"),
        _vec(d.get("up", (1.0, 0.0, 0.0)), f"{where}.up"),
    )
    if view.eye == view.look_at:
        raise _err(where, "eye and look_at must differ")
    return view


def _landmark(d: object, where: str, primary: object = None) -> Landmark:
    if not isinstance(d, dict) or not d:
        raise _err(where, f"must be a table of query parts, some of {list(MODALITIES)}; got {d!r}")
    unknown = sorted(set(d) - set(MODALITIES))
    if unknown:
        raise _err(where, f"unknown query parts {unknown}; valid: {list(MODALITIES)}")
    parts = []
    for k in MODALITIES:  # the robot API's order: the first given is the default primary
        if k not in d:
            continue
        parts.append(
            (k, _view(d[k], f"{where}.img") if k == "img" else _text(d[k], f"{where}.{k}"))
        )
    given = [k for k, _ in parts]
    if primary is None:
        primary = given[0]
    elif primary not in given:
        raise _err(where, f"primary {primary!r} is not one of the query's parts {given}")
    return Landmark(tuple(parts), primary)


def _truth(d: object, where: str, nested: bool = False) -> Truth:
    if not isinstance(d, dict):
        raise _err(where, f"must be a table with one of {list(_TRUTH_KINDS)}, got {d!r}")
    kinds = [k for k in _TRUTH_KINDS if k in d]
    if len(kinds) != 1:
        raise _err(where, f"give exactly one of {list(_TRUTH_KINDS)}, got {sorted(d)}")
    kind = kinds[0]
    if kind == "absent":
        _keys(d, where, ("absent",))
        if d["absent"] is not True:
            raise _err(
                where,
                f"absent must be true, got {d['absent']!r}; a thing that is there names its "
                "truth (object, sound, area, ...)",
            )
        if nested:
            raise _err(where, "a relation's landmark cannot be absent: it names a place")
        return Truth("absent")
    if kind == "object":
        _keys(d, where, ("object",))
        return Truth("object", object=_text(d["object"], f"{where}.object"))
    if kind == "sound":
        _keys(d, where, ("sound",), ("occurrence",))
        occ = d.get("occurrence")
        if occ is not None and (not isinstance(occ, int) or isinstance(occ, bool) or occ < 0):
            raise _err(where, f"occurrence must be an integer >= 0, got {occ!r}")
        return Truth("sound", sound=_text(d["sound"], f"{where}.sound"), occurrence=occ)
    if kind == "area":
        _keys(d, where, ("area",))
        return Truth("area", area=_text(d["area"], f"{where}.area"))
    if kind in ("point", "camera"):
        _keys(d, where, (kind,))
        return Truth(kind, point=_vec(d[kind], f"{where}.{kind}"))
    if kind == "box":
        _keys(d, where, ("box",))
        b = d["box"]
        if not isinstance(b, list) or len(b) != 2:
            raise _err(where, f"box must be [[x0, y0, z0], [x1, y1, z1]] [m], got {b!r}")
        lo, hi = _vec(b[0], f"{where}.box[0]"), _vec(b[1], f"{where}.box[1]")
        if any(a > c for a, c in zip(lo, hi, strict=True)):
            raise _err(where, f"box lower corner {lo} exceeds its upper corner {hi}")
        return Truth("box", box=(lo, hi))
    _keys(d, where, ("relation", "of"))
    rel, of = _relation(d["relation"], d["of"], where, "truths in 'of'")
    return Truth(
        "relation",
        relation=rel,
        of=tuple(_truth(t, f"{where}.of[{i}]", nested=True) for i, t in enumerate(of)),
    )


_GOAL_COMMON = ("id", "type", "text", "truth")


def _relation(rel: object, items: object, where: str, what: str) -> tuple[str, list]:
    """A known relation and a list of as many items as it takes."""
    if not isinstance(rel, str) or rel not in RELATIONS:
        raise _err(where, f"unknown relation {rel!r}; valid: {list(RELATIONS)}")
    if not isinstance(items, list) or len(items) != RELATIONS[rel]:
        raise _err(where, f"relation {rel!r} takes {RELATIONS[rel]} {what}, got {items!r}")
    return rel, items


def _goal(d: object, where: str) -> Goal:
    if not isinstance(d, dict):
        raise _err(where, f"must be a table, got {d!r}")
    gtype = d.get("type")
    if gtype not in GOAL_TYPES:
        raise _err(where, f"unknown goal type {gtype!r}; valid: {list(GOAL_TYPES)}")
    gid = d.get("id")
    where = f"{where} ({gid!r})" if isinstance(gid, str) else where
    if gtype in ("spatial", "multimodal_spatial"):
        _keys(d, where, (*_GOAL_COMMON, "relation", "landmarks"))
    elif gtype == "instruction":
        _keys(d, where, (*_GOAL_COMMON, "instruction"))
    elif gtype == "absent":  # one query part: no primary to choose
        _keys(d, where, (*_GOAL_COMMON, "query"))
    else:
        _keys(d, where, (*_GOAL_COMMON, "query"), ("primary",))
    gid = _text(d["id"], f"{where}.id")
    truth = _truth(d["truth"], f"{where}.truth")
    if (gtype == "absent") != (truth.kind == "absent"):
        raise _err(
            where,
            f"an 'absent' goal's truth is {{ absent = true }}, got {truth.describe()}"
            if gtype == "absent"
            else f"truth {{ absent = true }} belongs to type 'absent' goals (one obj= or "
            f"sound= query part); a {gtype!r} goal names where its goal is",
        )
    common = dict(id=gid, type=gtype, text=_text(d["text"], f"{where}.text"), truth=truth)
    if gtype == "instruction":
        return Goal(**common, instruction=_text(d["instruction"], f"{where}.instruction"))
    if gtype in ("spatial", "multimodal_spatial"):
        rel, lms = _relation(d["relation"], d["landmarks"], where, "landmarks")
        marks = tuple(_landmark(x, f"{where}.landmarks[{i}]") for i, x in enumerate(lms))
        multimodal = any(len(m.parts) > 1 or m.primary != "obj" for m in marks)
        if gtype == "spatial" and multimodal:
            raise _err(
                where,
                "a 'spatial' goal's landmarks are objects (obj=...) only; use "
                "type 'multimodal_spatial' for sounds, images, areas or combinations",
            )
        if gtype == "multimodal_spatial" and not multimodal:
            raise _err(
                where,
                "a 'multimodal_spatial' goal needs a landmark with a sound, an "
                "image, an area or several parts; use type 'spatial' for objects only",
            )
        if truth.kind == "relation" and truth.relation != rel:
            raise _err(where, f"truth relation {truth.relation!r} differs from relation {rel!r}")
        return Goal(**common, relation=rel, landmarks=marks)
    query = _landmark(d["query"], f"{where}.query", d.get("primary"))
    given = [k for k, _ in query.parts]
    expect = {"object": "obj", "sound": "sound", "image": "img", "area": "area"}
    if gtype in expect and given != [expect[gtype]]:
        raise _err(
            where,
            f"a {gtype!r} goal queries {expect[gtype]}= alone, got {given}; "
            "use type 'ambiguous' for a query with several parts",
        )
    if gtype == "ambiguous" and len(given) < 2:
        raise _err(where, f"an 'ambiguous' goal needs two or more query parts, got {given}")
    if gtype == "absent" and (len(given) != 1 or given[0] not in ABSENT_MODALITIES):
        raise _err(
            where,
            f"an 'absent' goal asks for one thing, one of {list(ABSENT_MODALITIES)}, got {given}",
        )
    return Goal(**common, query=query)


def _place(sc: object, section: str, source: str, base_dir: Path | None) -> tuple[str, object]:
    """(which, value) of a ``[scene]`` or ``[room]`` section: ("name", str), ("path", Path
    relative to ``base_dir``) or ("random", its table, unchecked)."""
    where = f"{source} [{section}]"
    sc = _keys(sc, where, (), ("name", "path", "random"))
    given = [k for k in ("name", "path", "random") if k in sc]
    if len(given) != 1:
        raise _err(where, f"give exactly one of name, path, random; got {given}")
    if "name" in sc:
        return "name", _text(sc["name"], f"{where}.name")
    if "path" in sc:
        p = Path(_text(sc["path"], f"{where}.path"))
        return "path", p if p.is_absolute() or base_dir is None else base_dir / p
    return "random", sc["random"]


def scene_ref(sc: object, source: str = "<tasks>", base_dir: Path | None = None) -> SceneRef:
    """A task file's ``[scene]`` section as a :class:`SceneRef`."""
    which, value = _place(sc, "scene", source, base_dir)
    if which != "random":
        return SceneRef(**{which: value})
    r = _keys(
        value, f"{source} [scene].random", ("seed",), ("count", "duplicates", "kinds", "profile")
    )
    return SceneRef(random=dict(r))


def room_ref(sc: object, source: str = "<tasks>", base_dir: Path | None = None) -> RoomRef:
    """A task file's ``[room]`` section as a :class:`RoomRef`."""
    which, value = _place(sc, "room", source, base_dir)
    if which != "random":
        return RoomRef(**{which: value})
    r = _keys(value, f"{source} [room].random", ("seed",))
    seed = r["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise _err(f"{source} [room].random.seed", f"must be an integer >= 0, got {seed!r}")
    return RoomRef(random={"seed": seed})


def robot_ref(d: object, source: str = "<tasks>") -> RobotRef:
    """A task file's ``[robot]`` section as a :class:`RobotRef`: its kind is a registered
    robot (:mod:`tabletop.embodiments`), whose success radius and obstacle embodiments are the
    defaults and the valid choices."""
    from tabletop.embodiments import EMBODIMENTS

    where = f"{source} [robot]"
    d = _keys(d, where, (), ("kind", "success_radius", "embodiment"))
    kind = d.get("kind", "arm")
    if not isinstance(kind, str) or kind not in EMBODIMENTS:
        raise _err(where, f"kind must be one of {list(EMBODIMENTS)}, got {kind!r}")
    body = EMBODIMENTS[kind]
    r = d.get("success_radius", body.success_radius_m)
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not 0 < r < math.inf:
        raise _err(where, f"success_radius must be a number > 0 [m], got {r!r}")
    if "embodiment" in d and not body.obstacles:
        raise _err(where, f"embodiment: the {kind} robot has no obstacle embodiments to choose")
    emb = d.get("embodiment", body.default_obstacles)
    if body.obstacles and emb not in body.obstacles:
        raise _err(where, f"embodiment must be one of {list(body.obstacles)}, got {emb!r}")
    return RobotRef(kind, float(r), emb)


def parse_tasks(data: dict, source: str = "<tasks>", base_dir: Path | None = None) -> TaskFile:
    """Validate parsed TOML/JSON and build a :class:`TaskFile`.

    Raises:
        TaskFileError: naming the file, the goal or section, and the valid options.
    """
    d = _keys(
        data,
        source,
        ("format", "version", "goals"),
        (
            "name",
            "description",
            "scene",
            "room",
            "robot",
            "scan",
            "map",
            "noise",
            "sequences",
            "generator",
        ),
    )
    if d["format"] != FORMAT_NAME:
        raise _err(source, f"format is {d['format']!r}; expected {FORMAT_NAME!r}")
    if d["version"] != FORMAT_VERSION:
        raise _err(
            source, f"version {d['version']!r} is not supported; supported: {FORMAT_VERSION}"
        )
    robot = robot_ref(d.get("robot", {}), source)
    place = robot.body.workspace
    other = "scene" if place == "room" else "room"
    if place not in d or other in d:
        raise _err(
            source,
            f"a task file for the {robot.kind} robot needs a [{place}] section and no "
            f"[{other}] (a robot works at a table [scene] or in a [room], as its embodiment "
            "declares)",
        )
    if place == "room":
        scene = room_ref(d["room"], source, base_dir)
    else:
        scene = scene_ref(d["scene"], source, base_dir)
    scan = dict(_keys(d.get("scan", {}), f"{source} [scan]", (), _scan_fields(robot.kind)))
    mapcfg = dict(_keys(d.get("map", {}), f"{source} [map]", (), _MAP_FIELDS))
    goals_raw = d["goals"]
    if not isinstance(goals_raw, list) or not goals_raw:
        raise _err(source, "goals must be a non-empty list of [[goals]] tables")
    goals = tuple(_goal(g, f"{source} goals[{i}]") for i, g in enumerate(goals_raw))
    ids = [g.id for g in goals]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise _err(source, f"goal ids must be unique; repeated: {dup}")
    seqs = []
    placed: dict[str, str] = {}
    for i, s in enumerate(d.get("sequences", [])):
        w = f"{source} sequences[{i}]"
        s = _keys(s, w, ("id", "goals"))
        sid = _text(s["id"], f"{w}.id")
        if not isinstance(s["goals"], list) or not s["goals"]:
            raise _err(w, "goals must be a non-empty list of goal ids")
        for g in s["goals"]:
            if g not in ids:
                raise _err(w, f"unknown goal id {g!r}; goal ids: {ids}")
            if g in placed:
                raise _err(w, f"goal {g!r} is already in sequence {placed[g]!r}")
            placed[g] = sid
        seqs.append((sid, tuple(s["goals"])))
    try:
        _check_scan(scan, robot.kind)
    except ConfigError as e:
        raise _err(f"{source} [scan]", str(e)) from None
    from tabletop.sim.noise import NoiseConfig

    noise = d.get("noise", {})
    try:
        NoiseConfig.from_dict(noise, "[noise]")
    except ConfigError as e:
        raise _err(source, str(e)) from None
    for k in ("name", "description"):
        if k in d and not isinstance(d[k], str):
            raise _err(source, f"{k} must be a string, got {d[k]!r}")
    return TaskFile(
        path=None,
        name=str(d.get("name", Path(source).stem)),
        scene=scene,
        scan=scan,
        map=mapcfg,
        goals=goals,
        sequences=tuple(seqs),
        description=str(d.get("description", "")),
        extra={"generator": d.get("generator", {})},
        noise=dict(noise),
        robot=robot,
    )


def _scan_fields(kind: str) -> tuple[str, ...]:
    """The ``[scan]`` keys a task file for robot ``kind`` may set."""
    from dataclasses import fields

    from tabletop.embodiments import embodiment

    body = embodiment(kind)
    names = tuple(f.name for f in fields(body.load("scan_config")))
    return names if body.scan_fields is None else tuple(n for n in names if n in body.scan_fields)


def _check_scan(scan: dict, kind: str = "arm") -> None:
    from tabletop.embodiments import embodiment

    try:
        embodiment(kind).load("scan_config")(**scan)
    except TypeError as e:
        raise ConfigError(str(e)) from None


def load_tasks(path: str | Path) -> TaskFile:
    """Load and validate a task file (``.toml`` or ``.json``), or a shipped suite by name
    (``tabletop/data/tasks/<name>.toml``)."""
    p = Path(path)
    if not p.exists() and p.suffix == "":
        shipped = shipped_task_path(str(p))
        if shipped is not None:
            p = shipped
    if not p.is_file():
        from tabletop.paths import input_file_problem

        problem = input_file_problem(p) or "is not a regular file"
        raise TaskFileError(
            f"task file {str(p)!r} {problem}; give a .toml or .json task file, or a shipped "
            f"suite: {list_shipped_tasks()}"
        )
    try:
        if p.suffix == ".toml":
            data = tomllib.loads(p.read_text())
        elif p.suffix == ".json":
            data = json.loads(p.read_text())
        else:
            raise TaskFileError(f"task file {p}: unknown format {p.suffix!r}; valid: .toml, .json")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as e:
        raise TaskFileError(f"task file {p} is not valid {p.suffix[1:].upper()}: {e}") from None
    except UnicodeDecodeError:
        raise TaskFileError(
            f"task file {p} is not UTF-8 text (a binary file?); give a .toml or .json task file"
        ) from None
    tf = parse_tasks(data, source=str(p), base_dir=p.parent)
    return TaskFile(**{**tf.__dict__, "path": p})


def _tasks_dir() -> Path:
    from tabletop.paths import DATA_DIR

    return DATA_DIR / "tasks"


def list_shipped_tasks() -> list[str]:
    """Names of the task files shipped in ``tabletop/data/tasks``."""
    return sorted(p.stem for p in _tasks_dir().glob("*.toml"))


def shipped_task_path(name: str) -> Path | None:
    p = _tasks_dir() / f"{name}.toml"
    return p if p.is_file() else None

"""The simulator's ground truth of a scan, as a typed value.

A simulated scan knows what a real one cannot: where every object stands, the table's named
areas, and where and when each sound was inserted. A room scan by the wheeled base
(:mod:`tabletop.sim.room_scan`) has no single table: its ground truth has ``table = None``, the
room's furniture (:class:`FurnitureTruth`: tables, shelves, walls... with categories and boxes),
each object's ``table`` (the furniture it stands on) and each sound event's ``place``; those
fields are left out of the arm's ground truth, which reads and writes as before.
:class:`GroundTruth` holds it; :meth:`GroundTruth.to_dict` is its on-disk form
(``Recording.ground_truth``, JSON), and :meth:`GroundTruth.from_dict` / :meth:`GroundTruth.of`
read it back, checked, naming a missing or malformed field. Every position is in the world
frame (the arm: the robot base frame, table top at z = 0; a room: the room frame, floor at
z = 0), in metres; arrays are read-only float64.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from tabletop.errors import RecordingError, TabletopError

if TYPE_CHECKING:
    from tabletop.recording import Recording

__all__ = [
    "AreaTruth",
    "FurnitureTruth",
    "GroundTruth",
    "GroundTruthError",
    "NotInGroundTruth",
    "ObjectTruth",
    "SoundEventTruth",
    "TableTruth",
]


class GroundTruthError(RecordingError):
    """A recording's ground truth is missing or malformed (the message names the field)."""


class NotInGroundTruth(TabletopError, LookupError):
    """A name (object, area, sound category) the scene's ground truth does not have; the
    message names the valid ones."""


# ---------------------------------------------------------------------------- validation
def _frozen(value: Any, shape: tuple[int, ...], where: str) -> np.ndarray:
    """A read-only float64 copy of ``value`` with ``shape``, or a :class:`GroundTruthError`."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise GroundTruthError(
            f"{where}: expected numbers of shape {shape}, got {value!r}"
        ) from None
    if a.shape != shape:
        raise GroundTruthError(f"{where}: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise GroundTruthError(f"{where}: expected finite numbers, got {value!r}")
    a.setflags(write=False)
    return a


def _range(value: Any, where: str) -> tuple[float, float]:
    """A (lower, upper) pair of floats."""
    lo, hi = _frozen(value, (2,), where)
    return (float(lo), float(hi))


def _fields(d: Any, names: tuple[str, ...], where: str, optional: tuple[str, ...] = ()) -> None:
    """``d`` is a mapping with the fields ``names``, and perhaps some of ``optional``."""
    if not isinstance(d, Mapping):
        raise GroundTruthError(f"{where}: expected a mapping, got {type(d).__name__}")
    missing = [n for n in names if n not in d]
    if missing:
        raise GroundTruthError(
            f"{where}: missing field {missing[0]!r}; expected fields: {list(names)}"
        )
    extra = sorted(str(k) for k in d if k not in names and k not in optional)
    if extra:
        raise GroundTruthError(
            f"{where}: unknown field {extra[0]!r}; expected fields: {list(names)}"
            + (f", optional: {list(optional)}" if optional else "")
        )


def _opt_str(d: Mapping, key: str, where: str) -> str | None:
    """An optional string field (absent or null: None)."""
    if d.get(key) is None:
        return None
    return _str(d, key, where)


def _str(d: Mapping, key: str, where: str) -> str:
    v = d[key]
    if not isinstance(v, str):
        raise GroundTruthError(f"{where}.{key}: expected a string, got {v!r}")
    return v


def _int(d: Mapping, key: str, where: str) -> int:
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise GroundTruthError(f"{where}.{key}: expected an integer, got {v!r}")
    return int(v)


def _float(d: Mapping, key: str, where: str) -> float:
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise GroundTruthError(f"{where}.{key}: expected a number, got {v!r}")
    return float(v)


def _list(d: Mapping, key: str, where: str) -> list:
    v = d[key]
    if not isinstance(v, (list, tuple)):
        raise GroundTruthError(f"{where}.{key}: expected a list, got {type(v).__name__}")
    return list(v)


class _Value:
    """Equality of the values below is equality of their dicts (arrays compare by value)."""

    def to_dict(self) -> dict:  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


# ---------------------------------------------------------------------------- values
@dataclass(frozen=True, eq=False)
class ObjectTruth(_Value):
    """One object of the scene, where the simulator put it."""

    name: str
    """Unique name in the scene, e.g. ``"red_mug"``."""
    kind: str
    """Catalog kind, e.g. ``"mug"`` (:data:`tabletop.sim.catalog.OBJECT_KINDS`)."""
    label: str
    """What a person calls it, e.g. ``"red mug"``."""
    category: str
    """The kind's label, e.g. ``"mug"`` (what duplicates of a kind share)."""
    color: str
    """Colour name (:data:`tabletop.sim.catalog.COLORS`)."""
    instance_id: int
    """Its id in the recording's segmentation images."""
    position: np.ndarray
    """(2,) float64 [m], world frame: (x, y) of the object frame's origin on the table top
    (z = 0), as the scene spec places it; in a room, on its table's top (the height is in
    ``T_world_obj``)."""
    yaw_deg: float
    """Rotation [deg] about the world z axis."""
    T_world_obj: np.ndarray
    """(4, 4) float64 [m], pose of the object frame in the world frame."""
    aabb_min: np.ndarray
    """(3,) float64 [m], world frame: lower corner of the axis-aligned bounding box."""
    aabb_max: np.ndarray
    """(3,) float64 [m], world frame: upper corner of the axis-aligned bounding box."""
    center: np.ndarray
    """(3,) float64 [m], world frame: centre of the bounding box."""
    table: str | None = None
    """The furniture it stands on (a room's ``"dining_table"``); None on the arm's table."""

    _ARRAYS = (
        ("position", (2,)),
        ("T_world_obj", (4, 4)),
        ("aabb_min", (3,)),
        ("aabb_max", (3,)),
        ("center", (3,)),
    )
    _FIELDS = (
        "name",
        "kind",
        "label",
        "category",
        "color",
        "instance_id",
        "position",
        "yaw_deg",
        "T_world_obj",
        "aabb_min",
        "aabb_max",
        "center",
    )

    def __post_init__(self) -> None:
        for name, shape in self._ARRAYS:
            object.__setattr__(self, name, _frozen(getattr(self, name), shape, f"object.{name}"))
        object.__setattr__(self, "instance_id", int(self.instance_id))
        object.__setattr__(self, "yaw_deg", float(self.yaw_deg))

    @classmethod
    def from_dict(cls, d: Any, where: str = "object") -> ObjectTruth:
        _fields(d, cls._FIELDS, where, optional=("table",))
        return cls(
            **{k: _str(d, k, where) for k in ("name", "kind", "label", "category", "color")},
            instance_id=_int(d, "instance_id", where),
            yaw_deg=_float(d, "yaw_deg", where),
            **{k: _frozen(d[k], s, f"{where}.{k}") for k, s in cls._ARRAYS},
            table=_opt_str(d, "table", where),
        )

    def to_dict(self) -> dict:
        extra = {} if self.table is None else {"table": self.table}
        return extra | {
            "name": self.name,
            "kind": self.kind,
            "label": self.label,
            "category": self.category,
            "color": self.color,
            "instance_id": self.instance_id,
            "position": self.position.tolist(),
            "yaw_deg": self.yaw_deg,
            "T_world_obj": self.T_world_obj.tolist(),
            "aabb_min": self.aabb_min.tolist(),
            "aabb_max": self.aabb_max.tolist(),
            "center": self.center.tolist(),
        }


@dataclass(frozen=True, eq=False)
class AreaTruth(_Value):
    """A named rectangle of the table top."""

    name: str
    """E.g. ``"left side of the table"``."""
    aliases: tuple[str, ...]
    """Other names it answers to, e.g. ``("left",)``."""
    x: tuple[float, float]
    """(lower, upper) extent along x [m], world frame."""
    y: tuple[float, float]
    """(lower, upper) extent along y [m], world frame."""
    center: np.ndarray
    """(3,) float64 [m], world frame: its centre on the table top (z = 0)."""

    _FIELDS = ("name", "aliases", "x", "y", "center")

    def __post_init__(self) -> None:
        object.__setattr__(self, "aliases", tuple(self.aliases))
        object.__setattr__(self, "x", _range(self.x, "area.x"))
        object.__setattr__(self, "y", _range(self.y, "area.y"))
        object.__setattr__(self, "center", _frozen(self.center, (3,), "area.center"))

    @classmethod
    def from_dict(cls, d: Any, where: str = "area") -> AreaTruth:
        _fields(d, cls._FIELDS, where)
        aliases = _list(d, "aliases", where)
        for i, a in enumerate(aliases):
            if not isinstance(a, str):
                raise GroundTruthError(f"{where}.aliases[{i}]: expected a string, got {a!r}")
        return cls(
            name=_str(d, "name", where),
            aliases=tuple(aliases),
            x=_range(d["x"], f"{where}.x"),
            y=_range(d["y"], f"{where}.y"),
            center=_frozen(d["center"], (3,), f"{where}.center"),
        )

    def answers_to(self, name: str) -> bool:
        """Whether ``name`` is the area's name or one of its aliases."""
        return name == self.name or name in self.aliases

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "aliases": list(self.aliases),
            "x": list(self.x),
            "y": list(self.y),
            "center": self.center.tolist(),
        }


@dataclass(frozen=True, eq=False)
class SoundEventTruth(_Value):
    """One sound-bank clip inserted into the scan's audio track during an episode."""

    episode: str
    """Name of the recording segment it was inserted in, e.g. ``"episode_2"``."""
    category: str
    """Sound-bank category, e.g. ``"dog"``."""
    caption: str
    """The category's caption, the query a person would say, e.g. ``"the dog barking"``."""
    clip_id: str
    """Sound-bank clip id."""
    onset_s: float
    """Start [s] of the clip on the recording's clock."""
    offset_s: float
    """End [s] of the clip on the recording's clock."""
    frames: tuple[int, ...]
    """(first, last) frame index during which it sounded, inclusive; ``()`` when noise
    dropped every one of those frames (:func:`tabletop.sim.noise.apply_noise`)."""
    tcp_mean: np.ndarray
    """(3,) float64 [m], world frame: mean tool-centre-point (microphone) position while it
    sounded."""
    table_point: np.ndarray
    """(3,) float64 [m], world frame: where it was heard on the table (``tcp_mean`` at z = 0)."""
    region_center: np.ndarray
    """(3,) float64 [m], world frame: centre of the table region the episode visited (a
    room: the centre of the visited table's top)."""
    place: str | None = None
    """A room scan: the furniture the base stopped at (``tcp_mean`` is then the mean
    microphone position on its mast, ``table_point`` the base's position on the floor)."""

    _ARRAYS = ("tcp_mean", "table_point", "region_center")
    _FIELDS = (
        "episode",
        "category",
        "caption",
        "clip_id",
        "onset_s",
        "offset_s",
        "frames",
        "tcp_mean",
        "table_point",
        "region_center",
    )

    def __post_init__(self) -> None:
        for name in self._ARRAYS:
            object.__setattr__(self, name, _frozen(getattr(self, name), (3,), f"sound.{name}"))
        frames = tuple(int(f) for f in self.frames)
        if len(frames) not in (0, 2):
            raise GroundTruthError(f"sound.frames: expected [first, last] or [], got {frames}")
        object.__setattr__(self, "frames", frames)
        object.__setattr__(self, "onset_s", float(self.onset_s))
        object.__setattr__(self, "offset_s", float(self.offset_s))

    @classmethod
    def from_dict(cls, d: Any, where: str = "sound_event") -> SoundEventTruth:
        _fields(d, cls._FIELDS, where, optional=("place",))
        frames = _list(d, "frames", where)
        if len(frames) not in (0, 2) or any(
            isinstance(f, bool) or not isinstance(f, (int, np.integer)) for f in frames
        ):
            raise GroundTruthError(
                f"{where}.frames: expected [first, last] frame indices or [], got {frames!r}"
            )
        return cls(
            **{k: _str(d, k, where) for k in ("episode", "category", "caption", "clip_id")},
            onset_s=_float(d, "onset_s", where),
            offset_s=_float(d, "offset_s", where),
            frames=tuple(frames),
            **{k: _frozen(d[k], (3,), f"{where}.{k}") for k in cls._ARRAYS},
            place=_opt_str(d, "place", where),
        )

    def to_dict(self) -> dict:
        extra = {} if self.place is None else {"place": self.place}
        return extra | {
            "episode": self.episode,
            "category": self.category,
            "caption": self.caption,
            "clip_id": self.clip_id,
            "onset_s": self.onset_s,
            "offset_s": self.offset_s,
            "frames": list(self.frames),
            "tcp_mean": self.tcp_mean.tolist(),
            "table_point": self.table_point.tolist(),
            "region_center": self.region_center.tolist(),
        }


@dataclass(frozen=True, eq=False)
class TableTruth(_Value):
    """The table top."""

    x: tuple[float, float]
    """(lower, upper) extent along x [m], world frame."""
    y: tuple[float, float]
    """(lower, upper) extent along y [m], world frame."""
    top_z: float
    """Height [m] of the top surface in the world frame (0: the world frame sits on it)."""
    height: float
    """Height [m] of the top surface above the floor."""

    _FIELDS = ("x", "y", "top_z", "height")

    def __post_init__(self) -> None:
        object.__setattr__(self, "x", _range(self.x, "table.x"))
        object.__setattr__(self, "y", _range(self.y, "table.y"))
        object.__setattr__(self, "top_z", float(self.top_z))
        object.__setattr__(self, "height", float(self.height))

    @classmethod
    def from_dict(cls, d: Any, where: str = "table") -> TableTruth:
        _fields(d, cls._FIELDS, where)
        return cls(
            x=_range(d["x"], f"{where}.x"),
            y=_range(d["y"], f"{where}.y"),
            top_z=_float(d, "top_z", where),
            height=_float(d, "height", where),
        )

    def to_dict(self) -> dict:
        return {"x": list(self.x), "y": list(self.y), "top_z": self.top_z, "height": self.height}


@dataclass(frozen=True, eq=False)
class FurnitureTruth(_Value):
    """A piece of a room's furniture (tables, shelves, cabinets...) or one of its walls."""

    name: str
    """Unique name in the room, e.g. ``"dining_table"``, ``"wall_north"``."""
    category: str
    """What it is, in words: ``"table"``, ``"shelf"``, ``"cabinet"``, ``"sofa"``, ``"wall"``."""
    model: str
    """The model it was built from (:data:`tabletop.sim.room.FURNITURE_MODELS`, ``"wall"``)."""
    instance_id: int
    """Its id in the recording's segmentation images."""
    T_world_item: np.ndarray
    """(4, 4) float64 [m]: its frame (footprint centre on the floor, turned by its yaw)."""
    aabb_min: np.ndarray
    """(3,) float64 [m], world frame: lower corner of its axis-aligned bounding box."""
    aabb_max: np.ndarray
    """(3,) float64 [m], world frame: upper corner."""
    top_z: float | None = None
    """Height [m] of the flat top objects stand on (tables, cabinets); None: none."""

    _ARRAYS = (("T_world_item", (4, 4)), ("aabb_min", (3,)), ("aabb_max", (3,)))
    _FIELDS = (
        "name",
        "category",
        "model",
        "instance_id",
        "T_world_item",
        "aabb_min",
        "aabb_max",
        "top_z",
    )

    def __post_init__(self) -> None:
        for name, shape in self._ARRAYS:
            object.__setattr__(self, name, _frozen(getattr(self, name), shape, f"furniture.{name}"))
        object.__setattr__(self, "instance_id", int(self.instance_id))
        if self.top_z is not None:
            object.__setattr__(self, "top_z", float(self.top_z))

    @property
    def center(self) -> np.ndarray:
        """(3,) float64 [m]: centre of its bounding box."""
        return (self.aabb_min + self.aabb_max) / 2

    @classmethod
    def from_dict(cls, d: Any, where: str = "furniture") -> FurnitureTruth:
        _fields(d, cls._FIELDS, where)
        return cls(
            **{k: _str(d, k, where) for k in ("name", "category", "model")},
            instance_id=_int(d, "instance_id", where),
            **{k: _frozen(d[k], s, f"{where}.{k}") for k, s in cls._ARRAYS},
            top_z=None if d["top_z"] is None else _float(d, "top_z", where),
        )

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "category": self.category,
            "model": self.model,
            "instance_id": self.instance_id,
            "T_world_item": self.T_world_item.tolist(),
            "aabb_min": self.aabb_min.tolist(),
            "aabb_max": self.aabb_max.tolist(),
            "top_z": self.top_z,
        }


@dataclass(frozen=True, eq=False)
class GroundTruth(_Value):
    """Everything a benchmark knows about a simulated scan: the scene, where its objects and
    areas are, and the sounds inserted into its audio track.

    Build it with :meth:`SimWorld.ground_truth <tabletop.sim.world.SimWorld.ground_truth>`
    (no sound events yet; :func:`~tabletop.sim.scan.run_scan` adds them) or read it from a
    recording with :meth:`of`.
    """

    scene: dict
    """The scene spec it was built from (:meth:`SceneSpec.to_dict
    <tabletop.sim.scene.SceneSpec.to_dict>`); a private copy, not to be modified."""
    frame: str
    """A sentence naming the frame and units of every position."""
    table: TableTruth | None
    """The arm's table; None in a room (its tables are among the ``furniture``)."""
    objects: tuple[ObjectTruth, ...]
    """In the scene's order."""
    areas: tuple[AreaTruth, ...]
    """In the scene's order."""
    instances: dict[int, str] = field(default_factory=dict)
    """Segmentation instance id -> name (``"none"``, ``"floor"``, ``"table"``, ``"robot"``
    and every object); a private copy, not to be modified."""
    sound_events: tuple[SoundEventTruth, ...] = ()
    """In insertion (episode) order; :meth:`sound_events_of` sorts by onset."""
    furniture: tuple[FurnitureTruth, ...] = ()
    """A room's furniture and walls, in the room spec's order then the walls; empty for the
    arm's scenes."""

    _FIELDS = ("scene", "frame", "table", "objects", "areas", "instances", "sound_events")

    def __post_init__(self) -> None:
        object.__setattr__(self, "scene", copy.deepcopy(dict(self.scene)))
        object.__setattr__(self, "objects", tuple(self.objects))
        object.__setattr__(self, "areas", tuple(self.areas))
        object.__setattr__(self, "sound_events", tuple(self.sound_events))
        object.__setattr__(self, "furniture", tuple(self.furniture))
        items = [f.name for f in self.furniture]
        dup = sorted({n for n in items if items.count(n) > 1})
        if dup:
            raise GroundTruthError(f"furniture: names must be unique; repeated: {dup}")
        object.__setattr__(self, "instances", {int(k): str(v) for k, v in self.instances.items()})
        names = [o.name for o in self.objects]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise GroundTruthError(f"objects: names must be unique; repeated: {dup}")

    # ------------------------------------------------------------------ reading, writing
    @classmethod
    def from_dict(cls, d: Any) -> GroundTruth:
        """The ground truth written by :meth:`to_dict` (``Recording.ground_truth``).

        Raises:
            GroundTruthError: a missing, unknown or malformed field, named by its path
                (e.g. ``ground_truth.objects[2].aabb_min``).
        """
        where = "ground_truth"  # the path into the recording: Recording.ground_truth
        _fields(d, cls._FIELDS, where, optional=("furniture",))
        if not isinstance(d["scene"], Mapping):
            raise GroundTruthError(f"{where}.scene: expected a mapping, got {d['scene']!r}")
        instances = d["instances"]
        if not isinstance(instances, Mapping):
            raise GroundTruthError(f"{where}.instances: expected a mapping, got {instances!r}")
        inst: dict[int, str] = {}
        for k, v in instances.items():
            try:
                key = int(k)
            except (TypeError, ValueError):
                raise GroundTruthError(
                    f"{where}.instances: keys must be instance ids, got {k!r}"
                ) from None
            if not isinstance(v, str):
                raise GroundTruthError(f"{where}.instances[{k!r}]: expected a name, got {v!r}")
            inst[key] = v
        return cls(
            scene=d["scene"],
            frame=_str(d, "frame", where),
            table=None
            if d["table"] is None
            else TableTruth.from_dict(d["table"], f"{where}.table"),
            objects=tuple(
                ObjectTruth.from_dict(o, f"{where}.objects[{i}]")
                for i, o in enumerate(_list(d, "objects", where))
            ),
            areas=tuple(
                AreaTruth.from_dict(a, f"{where}.areas[{i}]")
                for i, a in enumerate(_list(d, "areas", where))
            ),
            instances=inst,
            sound_events=tuple(
                SoundEventTruth.from_dict(e, f"{where}.sound_events[{i}]")
                for i, e in enumerate(_list(d, "sound_events", where))
            ),
            furniture=tuple(
                FurnitureTruth.from_dict(f, f"{where}.furniture[{i}]")
                for i, f in enumerate(_list(d, "furniture", where) if "furniture" in d else ())
            ),
        )

    @classmethod
    def of(cls, recording: Recording) -> GroundTruth:
        """The ground truth of a (simulated) recording.

        Raises:
            GroundTruthError: the recording has none (a real robot's recording) or it is
                malformed.
        """
        if recording.ground_truth is None:
            source = (recording.meta or {}).get("source", "unknown")
            raise GroundTruthError(
                f"the recording has no ground truth (source: {source!r}); only simulated "
                "scans (tabletop.sim.run_scan) carry one, a real robot's recording does not"
            )
        return cls.from_dict(recording.ground_truth)

    def to_dict(self) -> dict:
        """The JSON-serialisable dict a recording stores (``Recording.ground_truth``)."""
        d = {
            "scene": copy.deepcopy(self.scene),
            "frame": self.frame,
            "table": None if self.table is None else self.table.to_dict(),
            "objects": [o.to_dict() for o in self.objects],
            "areas": [a.to_dict() for a in self.areas],
            "instances": {str(k): v for k, v in self.instances.items()},
            "sound_events": [e.to_dict() for e in self.sound_events],
        }
        if self.furniture:
            d["furniture"] = [f.to_dict() for f in self.furniture]
        return d

    # ------------------------------------------------------------------ lookups
    @property
    def object_names(self) -> tuple[str, ...]:
        """Names of the objects, in the scene's order."""
        return tuple(o.name for o in self.objects)

    @property
    def area_names(self) -> tuple[str, ...]:
        """Names of the areas (not their aliases), in the scene's order."""
        return tuple(a.name for a in self.areas)

    @property
    def categories_heard(self) -> tuple[str, ...]:
        """Sorted sound categories inserted in the scan (each once)."""
        return tuple(sorted({e.category for e in self.sound_events}))

    @property
    def sound_events_by_onset(self) -> tuple[SoundEventTruth, ...]:
        """Every sound event in time order (ties keep insertion order)."""
        return tuple(sorted(self.sound_events, key=lambda e: e.onset_s))

    @property
    def duplicated_kinds(self) -> tuple[str, ...]:
        """Sorted kinds of which the scene has more than one object."""
        kinds = [o.kind for o in self.objects]
        return tuple(sorted({k for k in kinds if kinds.count(k) > 1}))

    def objects_of_kind(self, kind: str) -> tuple[ObjectTruth, ...]:
        """The objects of a catalog kind, in the scene's order (empty when there are none)."""
        return tuple(o for o in self.objects if o.kind == kind)

    def object(self, name: str) -> ObjectTruth:
        """The object called ``name``.

        Raises:
            NotInGroundTruth: no such object (the message lists the objects).
        """
        for o in self.objects:
            if o.name == name:
                return o
        raise NotInGroundTruth(
            f"no object {name!r} in the scene; objects: {list(self.object_names)}"
        )

    def area(self, name: str) -> AreaTruth:
        """The first area whose name or one of whose aliases is ``name``.

        Raises:
            NotInGroundTruth: no such area (the message lists the areas' names).
        """
        for a in self.areas:
            if a.answers_to(name):
                return a
        raise NotInGroundTruth(f"no area {name!r}; areas: {list(self.area_names)}")

    def item(self, name: str) -> FurnitureTruth:
        """The piece of furniture (or wall) called ``name``.

        Raises:
            NotInGroundTruth: no such item (the message lists the furniture).
        """
        for f in self.furniture:
            if f.name == name:
                return f
        raise NotInGroundTruth(
            f"no furniture {name!r}; furniture: {[f.name for f in self.furniture]}"
        )

    def furniture_of(self, category: str) -> tuple[FurnitureTruth, ...]:
        """The furniture of a category (``"table"``, ``"wall"``...), in order (may be empty)."""
        return tuple(f for f in self.furniture if f.category == category)

    def objects_on(self, table: str) -> tuple[ObjectTruth, ...]:
        """The objects standing on the furniture called ``table``, in order."""
        return tuple(o for o in self.objects if o.table == table)

    def sound_events_of(self, category: str) -> tuple[SoundEventTruth, ...]:
        """The sound events of ``category`` in time order (one per place it was inserted).

        Raises:
            NotInGroundTruth: the category was not inserted (the message lists those that were).
        """
        events = tuple(e for e in self.sound_events_by_onset if e.category == category)
        if not events:
            raise NotInGroundTruth(
                f"sound {category!r} was not inserted in this scan; "
                f"inserted: {list(self.categories_heard)}"
            )
        return events

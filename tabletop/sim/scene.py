"""Scene specs: a table, the Panda on it, objects and named table areas, as data.

A spec is a TOML (or JSON) file. Objects are listed explicitly, drawn by the seeded generator
(:func:`tabletop.sim.generator.generate_objects`) from a ``[random]`` section, or both. World
frame = robot base frame: the Panda's base sits at the origin on the table top (z = 0), x
points away from the robot across the table, y to the robot's left, z up.

Example::

    [scene]
    name = "two mugs"

    [[objects]]
    name = "red_mug"
    kind = "mug"
    color = "red"
    position = [0.45, 0.20]     # x, y on the table top [m]
    yaw_deg = 30.0

    [random]                   # optional: more objects drawn with this seed
    seed = 3
    count = 6
    duplicates = 2

Areas default to the table's named regions (see :func:`default_areas`); a spec may add its own
``[[areas]]`` with ``name`` and ``x = [lo, hi]``, ``y = [lo, hi]`` bounds, or ``around = "tray"``
with a ``margin`` [m].
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Generic, TypeVar

import numpy as np

from tabletop.errors import SceneError
from tabletop.paths import DATA_DIR
from tabletop.sim.catalog import COLORS, load_mesh_geometry, object_kind
from tabletop.transforms import make_transform, rotation_about

__all__ = [
    "AreaSpec",
    "ObjectSpec",
    "RandomSpec",
    "SceneSpec",
    "SpecFiles",
    "TableSpec",
    "default_areas",
    "default_scene_path",
    "list_default_scenes",
    "load_scene_spec",
]

SpecT = TypeVar("SpecT")

#: The robot base's footprint on the table top [m], world frame: the Panda's ``link0``
#: (collision mesh bounds x -0.154..0.072, y -0.095..0.095), rounded out. No object may stand on it.
ROBOT_BASE_FOOTPRINT = {"x": (-0.16, 0.08), "y": (-0.10, 0.10)}

#: The fields of one ``[[objects]]`` entry.
OBJECT_FIELDS = ("name", "kind", "color", "position", "yaw_deg")


@dataclass(frozen=True)
class TableSpec:
    """The table top, in the world (= robot base) frame. Its top surface is z = 0."""

    x: tuple[float, float] = (-0.20, 0.80)
    """Extent along x [m] (the robot base is at x = 0, near the back edge)."""
    y: tuple[float, float] = (-0.60, 0.60)
    """Extent along y [m]."""
    thickness: float = 0.05
    """Table-top thickness [m]."""
    height: float = 0.75
    """Height of the table top above the floor [m]."""
    color: tuple[float, float, float] = (0.62, 0.47, 0.33)
    """RGB [0, 1] of the table top."""

    def __post_init__(self) -> None:
        for name in ("x", "y"):
            lo, hi = getattr(self, name)
            if not lo < hi:
                raise SceneError(f"table {name} extent must be [lo, hi] with lo < hi, got {lo, hi}")
        if self.thickness <= 0 or self.height <= 0:
            raise SceneError("table thickness and height must be positive [m]")


@dataclass(frozen=True)
class ObjectSpec:
    """One object instance on the table."""

    name: str
    """Unique instance name, e.g. ``"red_mug"``."""
    kind: str
    """Catalog kind, see :data:`tabletop.sim.catalog.OBJECT_KINDS`."""
    color: str
    """Colour name, see :data:`tabletop.sim.catalog.COLORS`."""
    position: tuple[float, float]
    """(x, y) of the object's bottom centre on the table top [m], world frame."""
    yaw_deg: float = 0.0
    """Rotation about the world z axis [deg]."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise SceneError(
                f"object name must be a non-empty string, got {self.name!r} "
                f"(a {self.kind!r} at {list(self.position)})"
            )
        if not _is_number(self.yaw_deg) or not np.isfinite(self.yaw_deg):
            raise SceneError(
                f"object {self.name!r}: yaw_deg must be a finite number [deg], got {self.yaw_deg!r}"
            )
        kind = object_kind(self.kind)
        if self.color not in COLORS:
            raise SceneError(
                f"object {self.name!r}: unknown colour {self.color!r}; valid: {sorted(COLORS)}"
            )
        if not kind.keep_texture and self.color not in kind.colors:
            raise SceneError(
                f"object {self.name!r}: a {self.kind} may be {list(kind.colors)}, "
                f"not {self.color!r}"
            )
        if (
            len(self.position) != 2
            or not all(_is_number(v) for v in self.position)
            or not np.all(np.isfinite(self.position))
        ):
            raise SceneError(f"object {self.name!r}: position must be finite [x, y] in metres")

    @property
    def label(self) -> str:
        """Natural-language label with colour, e.g. ``"red mug"``."""
        return f"{self.color} {object_kind(self.kind).label}"

    def to_dict(self) -> dict:
        """The object as a spec file writes it (position [m] and yaw [deg] as plain floats),
        in a table's scene and on a room's furniture alike."""
        return {
            "name": self.name,
            "kind": self.kind,
            "color": self.color,
            "position": [float(v) for v in self.position],
            "yaw_deg": float(self.yaw_deg),
        }

    @property
    def T_world_obj(self) -> np.ndarray:
        """(4, 4) pose of the object frame (bottom centre) in the world."""
        return make_transform(rotation_about("z", np.deg2rad(self.yaw_deg)), (*self.position, 0.0))

    def vertices_world(self) -> np.ndarray:
        """(N, 3) mesh vertices [m] in the world frame."""
        T = self.T_world_obj
        return load_mesh_geometry(self.kind).vertices @ T[:3, :3].T + T[:3, 3]

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (min, max) [m] of the mesh in the world frame."""
        v = self.vertices_world()
        return v.min(axis=0), v.max(axis=0)


def _is_number(v: object) -> bool:
    """Whether ``v`` is a real number (an int or float, numpy's included; not a bool)."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
        v, (bool, np.bool_)
    )


def _object_from_dict(o: object, i: int, source: str) -> ObjectSpec:
    """The ``i``-th ``[[objects]]`` entry, its fields and their types checked."""
    if not isinstance(o, dict):
        raise SceneError(
            f"{source}: objects[{i}] is a {type(o).__name__}, not a table of an object's "
            f"fields {list(OBJECT_FIELDS)}"
        )
    label = f"object {o['name']!r}" if isinstance(o.get("name"), str) else f"objects[{i}]"
    unknown = sorted(set(o) - set(OBJECT_FIELDS))
    if unknown:
        raise SceneError(
            f"{source}: {label}: unknown keys {unknown}; valid keys: {list(OBJECT_FIELDS)}"
        )
    missing = [k for k in OBJECT_FIELDS[:4] if k not in o]
    if missing:
        raise SceneError(
            f"{source}: {label}: missing required field {missing[0]!r}; an object has "
            f"{list(OBJECT_FIELDS)} (yaw_deg optional)"
        )
    for k in ("name", "kind", "color"):
        if not isinstance(o[k], str):
            raise SceneError(
                f"{source}: {label}: {k} must be a string, got {type(o[k]).__name__} {o[k]!r}"
            )
    pos = o["position"]
    if not isinstance(pos, (list, tuple)) or len(pos) != 2 or not all(map(_is_number, pos)):
        raise SceneError(
            f"{source}: {label}: position must be [x, y], two numbers in metres, got {pos!r}"
        )
    yaw = o.get("yaw_deg", 0.0)
    if not _is_number(yaw):
        raise SceneError(
            f"{source}: {label}: yaw_deg must be a number [deg], got {type(yaw).__name__} {yaw!r}"
        )
    return ObjectSpec(
        name=o["name"],
        kind=o["kind"],
        color=o["color"],
        position=(float(pos[0]), float(pos[1])),
        yaw_deg=float(yaw),
    )


@dataclass(frozen=True)
class AreaSpec:
    """A named rectangular region of the table top, world frame [m]."""

    name: str
    x: tuple[float, float]
    y: tuple[float, float]
    aliases: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not (self.x[0] < self.x[1] and self.y[0] < self.y[1]):
            raise SceneError(f"area {self.name!r}: bounds must be [lo, hi] with lo < hi")

    @property
    def center(self) -> np.ndarray:
        """(3,) centre of the area on the table top [m]."""
        return np.array([(self.x[0] + self.x[1]) / 2, (self.y[0] + self.y[1]) / 2, 0.0])

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Boolean mask of which (N, 2) points [m] lie inside the area."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        return (
            (xy[:, 0] >= self.x[0])
            & (xy[:, 0] <= self.x[1])
            & (xy[:, 1] >= self.y[0])
            & (xy[:, 1] <= self.y[1])
        )


@dataclass(frozen=True)
class RandomSpec:
    """Seeded draw of extra objects (see :mod:`tabletop.sim.generator`)."""

    seed: int = 0
    count: int = 8
    """How many objects to draw."""
    duplicates: int = 2
    """How many kinds appear twice, in different colours."""
    kinds: tuple[str, ...] = ()
    """Kinds to draw from (empty = every catalog kind the profile draws)."""
    profile: str = "table"
    """Placement profile (:data:`tabletop.sim.generator.PROFILES`): ``table`` spreads the
    objects over the table; ``clutter`` packs them densely, tall kinds beside low ones."""

    def __post_init__(self) -> None:
        from tabletop.sim.generator import PROFILES

        if self.profile not in PROFILES:
            raise SceneError(
                f"random.profile: unknown profile {self.profile!r}; valid profiles: "
                f"{sorted(PROFILES)}"
            )
        if self.count < 0 or self.duplicates < 0 or 2 * self.duplicates > self.count:
            raise SceneError(
                f"random: need count >= 0 and 0 <= 2*duplicates <= count, got "
                f"count={self.count}, duplicates={self.duplicates}"
            )
        for k in self.kinds:
            object_kind(k)


def default_areas(table: TableSpec, objects: tuple[ObjectSpec, ...] = ()) -> tuple[AreaSpec, ...]:
    """The table's named regions, from the robot's point of view (it faces +x).

    ``front`` is the far half (in front of the robot), ``back`` the strip nearest the robot,
    ``left``/``right`` the robot's left (+y) and right (-y) thirds, ``center`` the middle, and
    one ``<kind> area`` around each tray.
    """
    x0, x1 = 0.20, table.x[1] - 0.05
    y0, y1 = table.y[0] + 0.05, table.y[1] - 0.05
    xm = (x0 + x1) / 2
    w = (y1 - y0) / 3
    areas = [
        AreaSpec("left side of the table", (x0, x1), (y1 - w, y1), ("left", "left side")),
        AreaSpec("right side of the table", (x0, x1), (y0, y0 + w), ("right", "right side")),
        AreaSpec("front of the table", (xm, x1), (y0, y1), ("front", "far side")),
        AreaSpec("back of the table", (x0, xm), (y0, y1), ("back", "near side")),
        AreaSpec(
            "center of the table",
            (xm - 0.12, xm + 0.12),
            (-0.15, 0.15),
            ("center", "middle of the table"),
        ),
    ]
    for obj in objects:
        if obj.kind == "tray":
            lo, hi = obj.aabb()
            areas.append(
                AreaSpec(
                    f"{obj.name.replace('_', ' ')} area",
                    (lo[0] - 0.03, hi[0] + 0.03),
                    (lo[1] - 0.03, hi[1] + 0.03),
                    ("tray area",),
                )
            )
    return tuple(areas)


@dataclass(frozen=True)
class SceneSpec:
    """A whole scene: table, objects (explicit and drawn), areas."""

    name: str = "scene"
    table: TableSpec = field(default_factory=TableSpec)
    objects: tuple[ObjectSpec, ...] = ()
    areas: tuple[AreaSpec, ...] = ()

    def __post_init__(self) -> None:
        names = [o.name for o in self.objects]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise SceneError(f"object names must be unique; repeated: {dupes}")
        for o in self.objects:
            lo, hi = o.aabb()
            if (
                lo[0] < self.table.x[0]
                or hi[0] > self.table.x[1]
                or lo[1] < self.table.y[0]
                or hi[1] > self.table.y[1]
            ):
                raise SceneError(
                    f"object {o.name!r} at {list(o.position)} overhangs the table "
                    f"(x {list(self.table.x)}, y {list(self.table.y)})"
                )
            bx, by = ROBOT_BASE_FOOTPRINT["x"], ROBOT_BASE_FOOTPRINT["y"]
            if lo[0] < bx[1] and hi[0] > bx[0] and lo[1] < by[1] and hi[1] > by[0]:
                raise SceneError(
                    f"object {o.name!r} at {list(o.position)} stands on the robot's base "
                    f"(x {list(bx)}, y {list(by)} [m]); place it on the table in front of the "
                    f"robot (x up to {self.table.x[1]}, y {list(self.table.y)}, its footprint "
                    f"clear of the base, e.g. x >= {bx[1] + 0.1:.2f})"
                )
        boxes = [(o.name, *o.aabb()) for o in self.objects]
        for i, (na, la, ha) in enumerate(boxes):
            for nb, lb, hb in boxes[i + 1 :]:
                if np.all(la[:2] < hb[:2]) and np.all(lb[:2] < ha[:2]):
                    raise SceneError(f"objects {na!r} and {nb!r} overlap on the table")

    def object(self, name: str) -> ObjectSpec:
        for o in self.objects:
            if o.name == name:
                return o
        raise SceneError(f"no object {name!r}; objects: {[o.name for o in self.objects]}")

    def area(self, name: str) -> AreaSpec:
        for a in self.areas:
            if a.name == name or name in a.aliases:
                return a
        raise SceneError(f"no area {name!r}; areas: {[a.name for a in self.areas]}")

    @classmethod
    def from_dict(cls, data: dict, source: str = "<dict>") -> SceneSpec:
        """Build a spec from parsed TOML/JSON, drawing ``[random]`` objects if present."""
        from tabletop.sim.generator import generate_objects

        known = {"scene", "table", "objects", "random", "areas"}
        unknown = set(data) - known
        if unknown:
            raise SceneError(
                f"{source}: unknown sections {sorted(unknown)}; valid: {sorted(known)}"
            )
        import dataclasses

        _check_table_keys(data.get("scene"), "[scene]", ("name",), source)
        _check_table_keys(
            data.get("table"), "[table]", [f.name for f in dataclasses.fields(TableSpec)], source
        )
        _check_table_keys(
            data.get("random"), "[random]", [f.name for f in dataclasses.fields(RandomSpec)], source
        )
        areas_raw = data.get("areas", [])
        if isinstance(areas_raw, list):
            for i, a in enumerate(areas_raw):
                _check_table_keys(a, f"[[areas]] #{i + 1}", ("name", "x", "y", "aliases"), source)
        try:
            meta = data.get("scene", {})
            table = TableSpec(
                **{
                    k: tuple(v) if isinstance(v, list) else v
                    for k, v in data.get("table", {}).items()
                }
            )
            raw_objects = data.get("objects", [])
            if not isinstance(raw_objects, list):
                raise SceneError(
                    f"{source}: objects must be a list of tables ([[objects]] entries with "
                    f"{list(OBJECT_FIELDS)}), got {type(raw_objects).__name__} {raw_objects!r}"
                )
            objects = tuple(_object_from_dict(o, i, source) for i, o in enumerate(raw_objects))
            if "random" in data:
                r = data["random"]
                rnd = RandomSpec(
                    **{k: tuple(v) if isinstance(v, list) else v for k, v in r.items()}
                )
                drawn = generate_objects(rnd, table, existing=objects)
                objects = objects + tuple(ObjectSpec(*o) for o in drawn)
            areas = tuple(
                AreaSpec(
                    name=a["name"],
                    x=tuple(a["x"]),
                    y=tuple(a["y"]),
                    aliases=tuple(a.get("aliases", ())),
                )
                for a in data.get("areas", [])
            )
        except KeyError as e:
            raise SceneError(f"{source}: missing required field {e.args[0]!r}") from None
        except TypeError as e:
            raise SceneError(f"{source}: {e}") from None
        areas = default_areas(table, objects) + areas
        return cls(
            name=meta.get("name", Path(source).stem), table=table, objects=objects, areas=areas
        )

    def to_dict(self) -> dict:
        """The explicit spec (drawn objects written out), loadable by :meth:`from_dict`."""
        t = self.table
        return {
            "scene": {"name": self.name},
            "table": {
                "x": list(t.x),
                "y": list(t.y),
                "thickness": t.thickness,
                "height": t.height,
                "color": list(t.color),
            },
            "objects": [o.to_dict() for o in self.objects],
            "areas": [
                {"name": a.name, "x": list(a.x), "y": list(a.y), "aliases": list(a.aliases)}
                for a in self.areas
                if a not in default_areas(t, self.objects)
            ],
        }


def shipped_specs(folder: str) -> list[str]:
    """Names of the spec files shipped in ``tabletop/data/<folder>`` ("scenes", "rooms")."""
    return sorted(p.stem for p in (DATA_DIR / folder).glob("*.toml"))


def shipped_spec_path(folder: str, what: str, name: str) -> Path:
    """Path of the ``what`` spec ("scene", "room") shipped as ``name`` in ``folder``."""
    path = DATA_DIR / folder / f"{name}.toml"
    if not path.is_file():
        raise SceneError(f"no shipped {what} {name!r}; shipped: {shipped_specs(folder)}")
    return path


def read_spec_file(path: str | Path, folder: str, what: str) -> tuple[dict, Path]:
    """(parsed data, path) of a ``what`` spec ("scene", "room") from a ``.toml`` or ``.json``
    file, or of one shipped in ``tabletop/data/<folder>`` by name."""
    if not isinstance(path, (str, Path)):
        raise SceneError(
            f"{what} spec must be a file path or a shipped {what}'s name, got "
            f"{type(path).__name__}; shipped {folder}: {shipped_specs(folder)}"
        )
    if str(path) == "":
        raise SceneError(f"{what} spec is empty: give a file or one of the shipped {folder}")
    path = Path(path)
    try:
        found = path.exists()
    except OSError as e:  # a name too long, a loop of links
        raise SceneError(
            f"{what} spec {str(path)[:80]!r}{'...' if len(str(path)) > 80 else ''} "
            f"({len(str(path))} characters) cannot be looked "
            f"up ({e.strerror or e}); give a file path or one of the shipped {folder}: "
            f"{shipped_specs(folder)}"
        ) from None
    if not found and path.suffix == "":
        path = shipped_spec_path(folder, what, str(path))
    if not path.is_file():
        from tabletop.paths import input_file_problem

        problem = input_file_problem(path) or "not found"
        raise SceneError(
            f"{what} spec {str(path)!r} {problem}; shipped {folder}: {shipped_specs(folder)}"
        )
    try:
        if path.suffix == ".toml":
            data = tomllib.loads(path.read_text())
        elif path.suffix == ".json":
            data = json.loads(path.read_text())
        else:
            raise SceneError(f"{what} spec {path}: unknown format; valid: .toml, .json")
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as e:
        raise SceneError(
            f"{what} spec {path} is not valid {path.suffix[1:].upper()}: {e}"
        ) from None
    except UnicodeDecodeError:
        raise SceneError(f"{what} spec {path} is not text (not UTF-8): not a {what} spec") from None
    if not isinstance(data, dict):
        raise SceneError(
            f"{what} spec {path} holds a {type(data).__name__}, not a table of a {what}'s fields"
        )
    if not data:  # an empty file is no spec, not a spec of nothing
        raise SceneError(
            f"{what} spec {path} is empty (no fields); a {what} spec is written like the "
            f"shipped {folder} in {DATA_DIR / folder}: {shipped_specs(folder)}"
        )
    return data, path


@dataclass(frozen=True)
class SpecFiles(Generic[SpecT]):
    """One kind of spec file ("scene", "room"): the specs shipped in
    ``tabletop/data/<folder>`` and how a file's data becomes a spec (``parse(data, source)``,
    the spec class's ``from_dict``). The table's scenes and the rooms load through one."""

    folder: str
    what: str
    parse: Callable[..., SpecT]

    def load(self, path: str | Path) -> SpecT:
        """Load a spec from a ``.toml`` or ``.json`` file, or a shipped one by name."""
        data, path = read_spec_file(path, self.folder, self.what)
        return self.parse(data, source=str(path))

    def names(self) -> list[str]:
        """Names of the specs shipped in ``tabletop/data/<folder>``."""
        return shipped_specs(self.folder)

    def path(self, name: str = "default") -> Path:
        """Path of a shipped spec by name."""
        return shipped_spec_path(self.folder, self.what, name)


#: The scene specs: those shipped in ``tabletop/data/scenes``, read by :meth:`SceneSpec.from_dict`.
SCENE_FILES = SpecFiles("scenes", "scene", SceneSpec.from_dict)
#: Load a scene spec from a ``.toml`` or ``.json`` file, or a shipped scene by name.
load_scene_spec = SCENE_FILES.load
#: Names of the scene specs shipped in ``tabletop/data/scenes``.
list_default_scenes = SCENE_FILES.names
#: Path of a shipped scene spec by name (default: ``"default"``).
default_scene_path = SCENE_FILES.path


def _check_table_keys(table, where: str, valid, source: str) -> None:
    """Refuse unknown keys in one table of a spec, naming them, the table and the valid keys
    (they reached a dataclass as "unexpected keyword argument")."""
    if not isinstance(table, dict):
        return  # not a table: the build below names what it is
    unknown = sorted(set(table) - set(valid))
    if unknown:
        raise SceneError(
            f"{source}: unknown key{'s' if len(unknown) > 1 else ''} {unknown} in {where}; "
            f"valid keys: {sorted(valid)}"
        )

"""Room specs: a floor with walls, furniture with categories, objects on the tables, and the
wheeled base's start pose, as data.

A spec is a TOML (or JSON) file, or drawn by :func:`generate_room`. World frame = room
frame: z up, the floor at z = 0, the room's floor spanning ``[0, size[0]] x [0, size[1]]``
[m]; walls stand outside that rectangle. Furniture comes from :data:`FURNITURE_MODELS`:
``pybullet_data`` models (``table``, ``table_square``, ``kiva_shelf``; zlib licence, see
``docs/assets.md``) and boxes of our own (``box``, e.g. a cabinet; ``sofa``). Every item has a
free-text ``category`` ("table", "shelf", "cabinet", "sofa", ...), the word a map's
open-vocabulary obstacle lists use. Objects come from the same catalog as the arm's scenes
(:mod:`tabletop.sim.catalog`) and stand on furniture with a flat top; their ``position`` is
(x, y) in the top's frame: its centre, x along the item's length, turned with the item.

Example::

    [room]
    name = "kitchen"
    size = [6.0, 5.0]          # floor x, y [m]

    [start]
    position = [0.7, 0.7]      # the base's x, y [m]
    yaw_deg = 45.0

    [[furniture]]
    name = "dining_table"
    category = "table"
    model = "table"            # pybullet_data table/table.urdf: 1.5 x 1.0 m, top at 0.625 m
    position = [2.0, 3.6]
    yaw_deg = 0.0

    [[furniture.objects]]
    name = "red_mug"
    kind = "mug"
    color = "red"
    position = [0.2, -0.1]     # on the table top, from its centre [m]
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.base import TABLETOP_BASE
from tabletop.errors import SceneError
from tabletop.sim.catalog import OBJECT_KINDS, load_mesh_geometry, object_kind
from tabletop.sim.scene import ObjectSpec, SpecFiles
from tabletop.transforms import make_transform, rotation_about, transform_points

__all__ = [
    "FURNITURE_MODELS",
    "FurnitureModel",
    "FurnitureSpec",
    "RoomSpec",
    "StartPose",
    "WallBox",
    "default_room_path",
    "generate_room",
    "list_default_rooms",
    "load_room_spec",
]


@dataclass(frozen=True)
class FurnitureModel:
    """A kind of furniture the room can hold."""

    name: str
    """Identifier used in room specs (``model = "table"``)."""
    source: str
    """Where it comes from: a ``pybullet_data`` path, or ``"primitive"`` (boxes of our own)."""
    size: tuple[float, float, float] | None
    """(length x, depth y, height z) [m] of its bounding box in its own frame; None: the spec
    gives it (``size = [...]``)."""
    top_z: float | None
    """Height [m] of its flat top above the floor, where objects may stand (None: no top;
    boxes: their height)."""
    base_z: float = 0.0
    """Height [m] at which PyBullet's base position puts the model on the floor."""
    licence: str = "Apache-2.0 (ours)"


#: The furniture models. Sizes of the ``pybullet_data`` models were measured from their
#: collision shapes and meshes (``docs/assets.md``).
FURNITURE_MODELS: dict[str, FurnitureModel] = {
    m.name: m
    for m in (
        FurnitureModel("table", "table/table.urdf", (1.5, 1.0, 0.625), 0.625, 0.0, "zlib"),
        FurnitureModel(
            "table_square", "table_square/table_square.urdf", (0.6, 0.6, 0.64), 0.64, 0.0, "zlib"
        ),
        FurnitureModel(
            "kiva_shelf", "kiva_shelf/model.sdf", (0.91, 0.88, 2.32), None, 1.2045, "zlib"
        ),
        FurnitureModel("box", "primitive", None, None),
        FurnitureModel("sofa", "primitive", None, None),
    )
}
#: Surfaces objects are placed on keep them this far [m] from the top's edge.
TOP_MARGIN = 0.05


def _pair(v: object, where: str) -> tuple[float, float]:
    try:
        a = np.array(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"{where} must be two numbers, got {v!r}") from None
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise SceneError(f"{where} must be two finite numbers [m], got {v!r}")
    return (float(a[0]), float(a[1]))


def _num(v: object, where: str, lo: float | None = None, hi: float | None = None) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise SceneError(f"{where} must be a finite number, got {v!r}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise SceneError(f"{where} must be in [{lo}, {hi}], got {v}")
    return float(v)


def _rect_corners(center, half, yaw: float) -> np.ndarray:
    """(4, 2) corners of a rectangle of half sizes ``half`` turned by ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s], [s, c]])
    local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * np.asarray(half)
    return local @ R.T + np.asarray(center)


def _separated(a: np.ndarray, b: np.ndarray, gap: float = 0.0) -> bool:
    """Whether convex polygons ``a`` and ``b`` (K, 2) are at least ``gap`` [m] apart along
    one of their edge normals (the separating axis test, widened by ``gap``)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for e in edges:
            n = np.array([-e[1], e[0]]) / np.linalg.norm(e)
            pa, pb = a @ n, b @ n
            if pa.max() + gap <= pb.min() or pb.max() + gap <= pa.min():
                return True
    return False


@dataclass(frozen=True)
class FurnitureSpec:
    """One piece of furniture standing on the floor."""

    name: str
    """Unique name in the room, e.g. ``"dining_table"``."""
    category: str
    """What it is, in words: ``"table"``, ``"shelf"``, ``"cabinet"``, ``"sofa"``, ..."""
    model: str
    """One of :data:`FURNITURE_MODELS`."""
    position: tuple[float, float]
    """(x, y) [m], room frame: the centre of its footprint."""
    yaw_deg: float = 0.0
    """Rotation [deg] about the room's z axis."""
    size: tuple[float, float, float] | None = None
    """(length, depth, height) [m] of a ``box`` or ``sofa``; the others have a fixed size."""
    color: tuple[float, float, float] = (0.55, 0.40, 0.28)
    """RGB [0, 1] of a ``box`` or ``sofa``."""
    objects: tuple[ObjectSpec, ...] = ()
    """Objects on its top; their positions are (x, y) [m] from the top's centre, in the
    item's frame."""

    def __post_init__(self) -> None:
        where = f"furniture {self.name!r}"
        if not isinstance(self.name, str) or not self.name:
            raise SceneError(f"furniture name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.category, str) or not self.category:
            raise SceneError(
                f"{where}: category must be a word such as 'table', got {self.category!r}"
            )
        if self.model not in FURNITURE_MODELS:
            raise SceneError(
                f"{where}: unknown model {self.model!r}; valid: {sorted(FURNITURE_MODELS)}"
            )
        object.__setattr__(self, "position", _pair(self.position, f"{where}: position"))
        object.__setattr__(self, "yaw_deg", _num(self.yaw_deg, f"{where}: yaw_deg"))
        m = FURNITURE_MODELS[self.model]
        if m.size is None:
            if self.size is None:
                raise SceneError(f"{where}: a {self.model!r} needs size = [length, depth, height]")
            try:
                size = np.array(self.size, dtype=np.float64)
            except (TypeError, ValueError):
                size = np.zeros(0)
            if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0.05):
                raise SceneError(
                    f"{where}: size must be [length, depth, height] > 0.05 m, got {self.size!r}"
                )
            object.__setattr__(self, "size", tuple(float(v) for v in size))
        elif self.size is not None and not np.allclose(self.size, m.size):
            raise SceneError(
                f"{where}: a {self.model!r} has the fixed size {list(m.size)}; leave size out"
            )
        else:
            object.__setattr__(self, "size", None)
        col = np.asarray(self.color, dtype=np.float64)
        if col.shape != (3,) or np.any(col < 0) or np.any(col > 1):
            raise SceneError(f"{where}: color must be RGB in [0, 1], got {self.color!r}")
        object.__setattr__(self, "color", tuple(float(v) for v in col))
        object.__setattr__(self, "objects", tuple(self.objects))
        if self.objects and self.top_z is None:
            raise SceneError(
                f"{where}: a {self.model!r} has no flat top to hold objects; models with one: "
                f"{sorted(n for n, m in FURNITURE_MODELS.items() if m.top_z or n == 'box')}"
            )
        hx, hy = self.dims[0] / 2 - TOP_MARGIN, self.dims[1] / 2 - TOP_MARGIN
        boxes = []
        for o in self.objects:
            lo, hi = o.aabb()
            if lo[0] < -hx or hi[0] > hx or lo[1] < -hy or hi[1] > hy:
                raise SceneError(
                    f"object {o.name!r} at {list(o.position)} overhangs {where} (its top spans "
                    f"x [{-hx:.2f}, {hx:.2f}], y [{-hy:.2f}, {hy:.2f}] from the centre)"
                )
            for name, a, b in boxes:
                if np.all(a[:2] < hi[:2]) and np.all(lo[:2] < b[:2]):
                    raise SceneError(f"objects {name!r} and {o.name!r} overlap on {where}")
            boxes.append((o.name, lo, hi))

    # ------------------------------------------------------------------ geometry
    @property
    def dims(self) -> tuple[float, float, float]:
        """(length, depth, height) [m] in its own frame."""
        return self.size or FURNITURE_MODELS[self.model].size

    @property
    def top_z(self) -> float | None:
        """Height [m] of the flat top objects stand on (None: no such top)."""
        if self.model == "box":
            return self.dims[2]
        return FURNITURE_MODELS[self.model].top_z

    @property
    def yaw(self) -> float:
        """[rad]"""
        return math.radians(self.yaw_deg)

    def footprint(self) -> np.ndarray:
        """(4, 2) [m] corners of its footprint on the floor, room frame."""
        return _rect_corners(self.position, (self.dims[0] / 2, self.dims[1] / 2), self.yaw)

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) (3,) [m] of its axis-aligned bounding box in the room frame."""
        f = self.footprint()
        return np.array([*f.min(axis=0), 0.0]), np.array([*f.max(axis=0), self.dims[2]])

    @property
    def T_world_top(self) -> np.ndarray:
        """(4, 4) the frame of its top: centred, z up at ``top_z`` (0 without a top)."""
        return make_transform(rotation_about("z", self.yaw), (*self.position, self.top_z or 0.0))

    def T_world_obj(self, obj: ObjectSpec) -> np.ndarray:
        """(4, 4) pose of an object on it (its bottom centre) in the room frame."""
        return self.T_world_top @ obj.T_world_obj

    def object_aabb(self, obj: ObjectSpec) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) (3,) [m] of an object's mesh on it, room frame."""
        v = transform_points(self.T_world_obj(obj), load_mesh_geometry(obj.kind).vertices)
        return v.min(axis=0), v.max(axis=0)

    def to_dict(self) -> dict:
        d = {
            "name": self.name,
            "category": self.category,
            "model": self.model,
            "position": list(self.position),
            "yaw_deg": self.yaw_deg,
        }
        if self.size is not None:
            d["size"] = list(self.size)
            d["color"] = list(self.color)
        if self.objects:
            d["objects"] = [o.to_dict() for o in self.objects]
        return d


@dataclass(frozen=True)
class StartPose:
    """Where the base starts: (x, y) [m] and heading [deg], room frame."""

    position: tuple[float, float]
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _pair(self.position, "start.position"))
        object.__setattr__(self, "yaw_deg", _num(self.yaw_deg, "start.yaw_deg"))


@dataclass(frozen=True)
class WallBox:
    """One wall: a box standing on the floor."""

    name: str
    center: tuple[float, float, float]  # [m], room frame
    half_extents: tuple[float, float, float]  # [m]

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        c, h = np.array(self.center), np.array(self.half_extents)
        return c - h, c + h


@dataclass(frozen=True)
class RoomSpec:
    """A whole room: floor, walls, furniture (with the objects on it), the base's start."""

    name: str = "room"
    size: tuple[float, float] = (6.0, 5.0)
    """Floor extent [m] along x and y; the floor spans [0, size[0]] x [0, size[1]]."""
    wall_height: float = 2.4
    """[m]"""
    wall_thickness: float = 0.1
    """[m]"""
    floor_color: tuple[float, float, float] = (0.70, 0.66, 0.60)
    wall_color: tuple[float, float, float] = (0.88, 0.87, 0.83)
    furniture: tuple[FurnitureSpec, ...] = ()
    start: StartPose = field(default_factory=lambda: StartPose((0.6, 0.6), 45.0))
    robot_radius: float = TABLETOP_BASE.radius
    """The base's footprint radius [m]: its start must leave it this far from everything."""

    def __post_init__(self) -> None:
        size = _pair(self.size, "room.size")
        if not (2.0 <= size[0] <= 30.0 and 2.0 <= size[1] <= 30.0):
            raise SceneError(f"room.size must be in [2, 30] m on each side, got {list(size)}")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "wall_height", _num(self.wall_height, "room.wall_height", 0.5, 10))
        object.__setattr__(
            self, "wall_thickness", _num(self.wall_thickness, "room.wall_thickness", 0.01, 1.0)
        )
        for name in ("floor_color", "wall_color"):
            col = np.asarray(getattr(self, name), dtype=np.float64)
            if col.shape != (3,) or np.any(col < 0) or np.any(col > 1):
                raise SceneError(f"room.{name} must be RGB in [0, 1], got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(v) for v in col))
        object.__setattr__(self, "furniture", tuple(self.furniture))
        for i, f in enumerate(self.furniture):
            if not isinstance(f, FurnitureSpec):
                raise SceneError(f"room.furniture[{i}] must be a FurnitureSpec, got {f!r}")
        if not isinstance(self.start, StartPose):
            raise SceneError(f"room.start must be a StartPose, got {self.start!r}")
        names = [f.name for f in self.furniture] + [
            o.name for f in self.furniture for o in f.objects
        ]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise SceneError(f"furniture and object names must be unique; repeated: {dupes}")
        for f in self.furniture:
            lo, hi = f.aabb()
            if lo[0] < 0 or lo[1] < 0 or hi[0] > size[0] or hi[1] > size[1]:
                raise SceneError(
                    f"furniture {f.name!r} at {list(f.position)} pokes through a wall: its "
                    f"footprint spans x [{lo[0]:.2f}, {hi[0]:.2f}], y [{lo[1]:.2f}, {hi[1]:.2f}], "
                    f"the floor [0, {size[0]}] x [0, {size[1]}]"
                )
        for i, a in enumerate(self.furniture):
            for b in self.furniture[i + 1 :]:
                if not _separated(a.footprint(), b.footprint()):
                    raise SceneError(f"furniture {a.name!r} and {b.name!r} overlap")
        r = _num(self.robot_radius, "room.robot_radius", 0.0, 2.0)
        sx, sy = self.start.position
        if not (r <= sx <= size[0] - r and r <= sy <= size[1] - r):
            raise SceneError(
                f"start.position {list(self.start.position)} leaves the base (radius {r} m) "
                f"outside the floor [0, {size[0]}] x [0, {size[1]}]"
            )
        disc = _rect_corners((sx, sy), (r, r), 0.0)
        for f in self.furniture:
            if not _separated(disc, f.footprint(), 0.02):
                raise SceneError(
                    f"start.position {list(self.start.position)} puts the base (radius {r} m) "
                    f"on furniture {f.name!r}"
                )

    # ------------------------------------------------------------------ lookups
    def item(self, name: str) -> FurnitureSpec:
        for f in self.furniture:
            if f.name == name:
                return f
        raise SceneError(f"no furniture {name!r}; furniture: {[f.name for f in self.furniture]}")

    @property
    def tables(self) -> tuple[FurnitureSpec, ...]:
        """The furniture of category ``"table"``, in the spec's order."""
        return tuple(f for f in self.furniture if f.category == "table")

    @property
    def objects(self) -> tuple[tuple[FurnitureSpec, ObjectSpec], ...]:
        """Every object with the furniture it stands on."""
        return tuple((f, o) for f in self.furniture for o in f.objects)

    def walls(self) -> tuple[WallBox, ...]:
        """The four walls, their inner faces on the floor's edges."""
        X, Y = self.size
        t, h = self.wall_thickness, self.wall_height
        return (
            WallBox("wall_south", (X / 2, -t / 2, h / 2), (X / 2 + t, t / 2, h / 2)),
            WallBox("wall_north", (X / 2, Y + t / 2, h / 2), (X / 2 + t, t / 2, h / 2)),
            WallBox("wall_west", (-t / 2, Y / 2, h / 2), (t / 2, Y / 2, h / 2)),
            WallBox("wall_east", (X + t / 2, Y / 2, h / 2), (t / 2, Y / 2, h / 2)),
        )

    def occupancy(self, cell: float = 0.05, inflate: float = 0.0) -> np.ndarray:
        """(nx, ny) bool grid over the floor, True where furniture or a wall is within
        ``inflate`` [m]; cell (i, j) is centred at ((i + 0.5) cell, (j + 0.5) cell)."""
        return _occupancy(self.size, self.furniture, cell, inflate)

    # ------------------------------------------------------------------ reading, writing
    @classmethod
    def from_dict(cls, data: dict, source: str = "<dict>") -> RoomSpec:
        """Build a spec from parsed TOML/JSON (see the module docstring)."""
        if not isinstance(data, dict):
            raise SceneError(f"{source}: a room spec is a table of sections, got {data!r}")
        known = {"room", "start", "furniture"}
        unknown = set(data) - known
        if unknown:
            raise SceneError(
                f"{source}: unknown sections {sorted(unknown)}; valid: {sorted(known)}"
            )
        room = data.get("room", {})
        room_keys = {
            "name",
            "size",
            "wall_height",
            "wall_thickness",
            "floor_color",
            "wall_color",
            "robot_radius",
        }
        _known_keys(room, room_keys, f"{source}: [room]")
        furniture = []
        for i, f in enumerate(data.get("furniture", [])):
            where = f"{source}: furniture[{i}]"
            _known_keys(
                f,
                {"name", "category", "model", "position", "yaw_deg", "size", "color", "objects"},
                where,
            )
            try:
                objects = []
                for j, o in enumerate(f.get("objects", [])):
                    _known_keys(
                        o, {"name", "kind", "color", "position", "yaw_deg"}, f"{where}.objects[{j}]"
                    )
                    objects.append(
                        ObjectSpec(
                            name=o["name"],
                            kind=o["kind"],
                            color=o["color"],
                            position=_pair(o["position"], f"{where}.objects[{j}].position"),
                            yaw_deg=_num(o.get("yaw_deg", 0.0), f"{where}.objects[{j}].yaw_deg"),
                        )
                    )
                furniture.append(
                    FurnitureSpec(
                        name=f["name"],
                        category=f["category"],
                        model=f["model"],
                        position=f["position"],
                        yaw_deg=f.get("yaw_deg", 0.0),
                        size=None if f.get("size") is None else tuple(f["size"]),
                        color=tuple(f.get("color", (0.55, 0.40, 0.28))),
                        objects=tuple(objects),
                    )
                )
            except KeyError as e:
                raise SceneError(f"{where}: missing required field {e.args[0]!r}") from None
            except TypeError as e:
                raise SceneError(f"{where}: {e}") from None
        start = data.get("start", {})
        _known_keys(start, {"position", "yaw_deg"}, f"{source}: [start]")
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in room.items()}
        kw.setdefault("name", Path(source).stem)
        if "position" in start:
            kw["start"] = StartPose(start["position"], start.get("yaw_deg", 0.0))
        try:
            return cls(furniture=tuple(furniture), **kw)
        except TypeError as e:
            raise SceneError(f"{source}: {e}") from None

    def to_dict(self) -> dict:
        """The spec as plain data, loadable by :meth:`from_dict` (and writable as TOML)."""
        return {
            "room": {
                "name": self.name,
                "size": list(self.size),
                "wall_height": self.wall_height,
                "wall_thickness": self.wall_thickness,
                "floor_color": list(self.floor_color),
                "wall_color": list(self.wall_color),
                "robot_radius": self.robot_radius,
            },
            "start": {"position": list(self.start.position), "yaw_deg": self.start.yaw_deg},
            "furniture": [f.to_dict() for f in self.furniture],
        }

    def to_toml(self) -> str:
        """The spec as TOML text (:func:`load_room_spec` reads it back)."""
        return _to_toml(self.to_dict())


def _occupancy(size, furniture, cell: float, inflate: float) -> np.ndarray:
    """See :meth:`RoomSpec.occupancy`."""
    if not (cell > 0 and inflate >= 0):
        raise SceneError(f"need cell > 0 and inflate >= 0 [m], got {cell}, {inflate}")
    X, Y = size
    nx, ny = math.ceil(X / cell), math.ceil(Y / cell)
    xs, ys = (np.arange(nx) + 0.5) * cell, (np.arange(ny) + 0.5) * cell
    px, py = np.meshgrid(xs, ys, indexing="ij")
    occ = (px < inflate) | (py < inflate) | (px > X - inflate) | (py > Y - inflate)
    for f in furniture:
        # distance to a turned rectangle: in its frame, the excess over the half sizes
        c, s = math.cos(f.yaw), math.sin(f.yaw)
        dx, dy = px - f.position[0], py - f.position[1]
        lx, ly = np.abs(c * dx + s * dy), np.abs(-s * dx + c * dy)
        ex = np.maximum(lx - f.dims[0] / 2, 0.0)
        ey = np.maximum(ly - f.dims[1] / 2, 0.0)
        occ |= np.hypot(ex, ey) <= inflate
    return occ


def _known_keys(d: object, valid: set[str], where: str) -> None:
    if not isinstance(d, dict):
        raise SceneError(f"{where}: expected a table of fields, got {d!r}")
    unknown = sorted(set(d) - valid)
    if unknown:
        raise SceneError(f"{where}: unknown field {unknown[0]!r}; valid: {sorted(valid)}")


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise SceneError(f"cannot write {v!r} as TOML")


def _to_toml(d: dict) -> str:
    lines = []
    for section in ("room", "start"):
        lines.append(f"[{section}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in d[section].items()]
        lines.append("")
    for f in d["furniture"]:
        lines.append("[[furniture]]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in f.items() if k != "objects"]
        lines.append("")
        for o in f.get("objects", []):
            lines.append("[[furniture.objects]]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in o.items()]
            lines.append("")
    return "\n".join(lines)


#: The room specs: those shipped in ``tabletop/data/rooms``, read by :meth:`RoomSpec.from_dict`.
ROOM_FILES = SpecFiles("rooms", "room", RoomSpec.from_dict)
#: Load a room spec from a ``.toml`` or ``.json`` file, or a shipped room by name.
load_room_spec = ROOM_FILES.load
#: Names of the room specs shipped in ``tabletop/data/rooms``.
list_default_rooms = ROOM_FILES.names
#: Path of a shipped room spec by name (default: ``"default"``).
default_room_path = ROOM_FILES.path


# ---------------------------------------------------------------------------- generator
#: Free corridor [m] the generator keeps around every table (and between any two items). The
#: room scan's planner keeps the base's centre 0.375 m (its radius and a margin) from
#: everything, so a corridor of 0.8 m still leaves it a passage; at 0.6 m, some of the
#: generated rooms had tables the scan could not reach.
CORRIDOR = 0.8
_OTHER_FURNITURE = (
    ("shelf", "kiva_shelf", None, None),
    ("cabinet", "box", (0.8, 0.45, 0.9), (0.45, 0.30, 0.20)),
    ("sofa", "sofa", (1.8, 0.85, 0.85), (0.30, 0.35, 0.55)),
    ("cabinet", "box", (0.5, 0.5, 0.75), (0.85, 0.85, 0.80)),
)


def _draw_objects(rng: np.random.Generator, table: FurnitureSpec, n: int, taken: set[str]):
    """``n`` catalog objects on a table's top, apart from each other, names not in ``taken``."""
    kinds = [k for k in sorted(OBJECT_KINDS) if k != "tray"]
    hx, hy = table.dims[0] / 2 - TOP_MARGIN, table.dims[1] / 2 - TOP_MARGIN
    placed: list[ObjectSpec] = []
    boxes = []
    for _ in range(200 * n):
        if len(placed) == n:
            break
        kind = object_kind(str(rng.choice(kinds)))
        color = str(rng.choice(kind.colors))
        base = f"{color}_{kind.name}"
        name = base
        k = 2
        while name in taken:
            name, k = f"{base}_{k}", k + 1
        pos = (round(float(rng.uniform(-hx, hx)), 3), round(float(rng.uniform(-hy, hy)), 3))
        o = ObjectSpec(name, kind.name, color, pos, round(float(rng.uniform(-180, 180)), 1))
        lo, hi = o.aabb()
        if lo[0] < -hx or hi[0] > hx or lo[1] < -hy or hi[1] > hy:
            continue
        if any(np.all(a[:2] - 0.04 < hi[:2]) and np.all(lo[:2] - 0.04 < b[:2]) for a, b in boxes):
            continue
        placed.append(o)
        boxes.append((lo, hi))
        taken.add(name)
    return tuple(placed)


def generate_room(
    seed: int,
    *,
    size: tuple[float, float] = (6.0, 5.0),
    tables: int = 3,
    others: int = 3,
    objects_per_table: tuple[int, int] = (3, 5),
) -> RoomSpec:
    """A seeded valid room: ``tables`` tables (``table`` or ``table_square``) with 3-5 catalog
    objects each, ``others`` further items (shelf, cabinets, sofa), none overlapping, every
    item at least :data:`CORRIDOR` from every other item and from the walls, and the base's
    start in the free space.

    Raises:
        SceneError: the room is too small for that much furniture (no layout found).
    """
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SceneError(f"seed must be an integer >= 0, got {seed!r}")
    if not 1 <= tables <= 8 or not 0 <= others <= 8:
        raise SceneError(f"need 1 <= tables <= 8 and 0 <= others <= 8, got {tables}, {others}")
    rng = np.random.default_rng([seed, 0x500])
    X, Y = size
    for _attempt in range(50):
        items: list[FurnitureSpec] = []
        taken: set[str] = set()
        wants = [("table", None)] * tables + [
            ("other", _OTHER_FURNITURE[int(i)])
            for i in rng.choice(
                len(_OTHER_FURNITURE), size=others, replace=others > len(_OTHER_FURNITURE)
            )
        ]
        ok = True
        for i, (what, other) in enumerate(wants):
            for _ in range(300):
                yaw = float(rng.choice([0.0, 90.0, 180.0, 270.0]))
                if what == "table":
                    model = "table" if rng.random() < 0.6 else "table_square"
                    proto = FurnitureSpec(f"table_{i}", "table", model, (X / 2, Y / 2), yaw)
                else:
                    category, model, dims, color = other
                    proto = FurnitureSpec(
                        f"{category}_{i}",
                        category,
                        model,
                        (X / 2, Y / 2),
                        yaw,
                        dims,
                        color or (0.55, 0.40, 0.28),
                    )
                # tables keep a corridor to the walls; the others may stand against one
                wall_gap = CORRIDOR if what == "table" else 0.02
                lo, hi = proto.aabb()
                half = (hi[:2] - lo[:2]) / 2
                if np.any(2 * (half + wall_gap) >= (X, Y)):
                    break
                pos = (  # to the centimetre, as a person writes a spec
                    round(float(rng.uniform(half[0] + wall_gap, X - half[0] - wall_gap)), 2),
                    round(float(rng.uniform(half[1] + wall_gap, Y - half[1] - wall_gap)), 2),
                )
                cand = FurnitureSpec(
                    proto.name, proto.category, proto.model, pos, yaw, proto.size, proto.color
                )
                if all(_separated(cand.footprint(), f.footprint(), CORRIDOR) for f in items):
                    items.append(cand)
                    break
            else:
                ok = False
                break
        if not ok or len(items) != len(wants):
            continue
        final = []
        for f in items:
            objects = ()
            if f.category == "table":
                n = int(rng.integers(objects_per_table[0], objects_per_table[1] + 1))
                objects = _draw_objects(rng, f, n, taken)
            final.append(
                FurnitureSpec(
                    f.name, f.category, f.model, f.position, f.yaw_deg, f.size, f.color, objects
                )
            )
        # the start: a free cell with room to turn, away from everything
        free = np.argwhere(~_occupancy(size, final, 0.1, 0.45))
        if not len(free):
            continue
        i, j = free[int(rng.integers(len(free)))]
        start = StartPose(
            (round((i + 0.5) * 0.1, 2), round((j + 0.5) * 0.1, 2)),
            round(float(rng.uniform(-180, 180))),
        )
        return RoomSpec(name=f"room_{seed}", size=size, furniture=tuple(final), start=start)
    raise SceneError(
        f"no layout of {tables} tables and {others} other items with {CORRIDOR} m corridors "
        f"fits a {X} x {Y} m room; use fewer items or a larger room"
    )

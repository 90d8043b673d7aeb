"""The robot API shared by every embodiment (the paper's API tables), on top of an AVLMap.

Queries (implemented once, here): :meth:`RobotAPI.load_image`, :meth:`RobotAPI.get_major_map`,
:meth:`RobotAPI.get_map`, :meth:`RobotAPI.get_max_pos_3d`, :meth:`RobotAPI.get_pos`. Spatial
primitives compute a target in the base frame from the map, then call :meth:`RobotAPI.move_to`,
the one method (with :meth:`RobotAPI.current_position`) an embodiment implements.

Conventions (world frame = robot base frame, metres, z up): north = +x (away from the robot,
across the table), south = -x, west = left = +y, east = right = -y. "In front of" an object is
its +x side (further along the robot's forward direction), "behind" its -x side.

A query part that matches nothing raises :class:`GoalNotFound` before anything moves. Queries
return :class:`~tabletop.mapping.heatmaps.Heatmap` values; ``a * b`` fuses two of them, and the
one target selector (:mod:`tabletop.mapping.targets`) turns them into points. A spatial
primitive's landmark is an object name or a heatmap (a place found by any query).
"""

from __future__ import annotations

import abc
import functools
import inspect
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError, GoalNotFound, TabletopError
from tabletop.mapping.heatmaps import Heatmap, fuse
from tabletop.mapping.targets import max_position, region_box, surface_z
from tabletop.paths import input_file_problem
from tabletop.reader.reading import DEFAULT_READER, get_reader
from tabletop.relations import relation, side_point

__all__ = [
    "GoalNotFound",
    "ImageGoalUnavailable",
    "PrimitiveArgumentError",
    "RobotAPI",
    "RobotClosed",
    "RobotError",
    "SpatialConfig",
    "TargetOffMap",
    "check_axis",
    "check_compass_distance",
    "check_on_map",
    "check_primitive_args",
]


class RobotError(TabletopError):
    """Base class of the robot API's errors."""


class ImageGoalUnavailable(ConfigError):
    """An image goal was asked of a map without the visual localization module."""


class PrimitiveArgumentError(RobotError, ConfigError, TypeError):
    """A primitive was called with an argument of the wrong type or value (``move_north("5")``):
    a :class:`TypeError` and a :class:`ValueError` alike, naming the argument and its valid
    form."""


class RobotClosed(RobotError, RuntimeError):
    """A primitive was called on a robot after its ``close()``."""


class TargetOffMap(RobotError, ConfigError):
    """A motion's target lies off the map: x, y outside its grid, or more than the success
    radius below its floor; no robot on the map goes there (:func:`check_on_map`)."""


def check_axis(method: str, direction) -> np.ndarray:
    """``direction`` as a (3,) horizontal unit axis, or :class:`PrimitiveArgumentError`
    naming the call: two or three finite numbers whose horizontal part has length 1 (a zero,
    NaN or text direction picks no side)."""
    try:
        d = np.asarray(direction, np.float64).reshape(-1)
    except (TypeError, ValueError):
        d = np.array([np.nan])
    if d.shape in ((2,), (3,)) and np.all(np.isfinite(d)):
        d = np.append(d, 0.0) if len(d) == 2 else d
        if abs(float(np.hypot(d[0], d[1])) - 1.0) < 1e-6 and abs(float(d[2])) < 1e-9:
            return d
    raise PrimitiveArgumentError(
        f"{method}(direction=...): direction must be a horizontal unit axis of 2 or 3 numbers, "
        f"e.g. (0, 1, 0) for the robot's left (left_of, right_of, in_front_of and behind take "
        f"none); got {_shown(direction)}"
    )


def check_on_map(grid, method: str, target) -> None:
    """The one check of a target against a map's grid: :class:`TargetOffMap` naming the point
    and the map's bounds when ``target`` (3,) [m] lies outside the grid in x or y, or more
    than the success radius below its floor. Dry runs (the tracer) and robots without their
    own honest result for such a point (``PointRobot``) refuse with it."""
    from tabletop.arm.success import SUCCESS_RADIUS_M

    t = np.asarray(target, np.float64)
    lo, hi = np.asarray(grid.lower, np.float64), np.asarray(grid.upper, np.float64)
    if np.all((t[:2] >= lo[:2]) & (t[:2] <= hi[:2])) and t[2] >= lo[2] - SUCCESS_RADIUS_M:
        return
    raise TargetOffMap(
        f"{method}: the target ({t[0]:.3g}, {t[1]:.3g}, {t[2]:.3g}) m lies "
        f"outside the map (x {lo[0]:g} .. {hi[0]:g}, y {lo[1]:g} .. {hi[1]:g} m, z at least "
        f"{lo[2] - SUCCESS_RADIUS_M:g} m): no robot on this map goes there"
    )


def compass_limit_m(robot_kind: str) -> float:
    """The longest compass move [m] of a robot kind: its embodiment's
    (:attr:`~tabletop.embodiments.Embodiment.max_move_m`: a table about a metre across
    for the arm, a room for a mobile base), which the reader holds instructions to as well."""
    from tabletop.embodiments import embodiment

    return embodiment(robot_kind).max_move_m


def check_compass_distance(name: str, distance_m, robot_kind: str, *, limit: bool = True) -> None:
    """A compass move's distance must be a number of metres in (0, limit]: the direction is
    the call's (``move_south``, not ``move_north`` of a negative distance).
    :class:`PrimitiveArgumentError` names the call, the argument and the valid range."""
    bad = _number(distance_m)
    top = compass_limit_m(robot_kind)
    d = None if bad else float(distance_m)
    if bad or d <= 0 or (limit and d > top):
        raise PrimitiveArgumentError(
            f"{name}(distance_m=...): distance_m must be a number of metres in (0, {top:g}] "
            f"(greater than 0; the direction is the call's: move_south, not move_north of a "
            f"negative distance); got {_shown(distance_m)}"
        )


def check_offset_distance(name: str, dx, dy, robot_kind: str) -> None:
    """A relative move (``offset``) is held to the compass moves' limit: its horizontal length
    ``hypot(dx, dy)`` at most :func:`compass_limit_m` of the robot kind."""
    if _number(dx) or _number(dy):
        return  # named by the argument check
    top = compass_limit_m(robot_kind)
    length = float(np.hypot(float(dx), float(dy)))
    if length > top:
        raise PrimitiveArgumentError(
            f"{name}(dx=..., dy=...): a relative move is at most {top:g} m long (as a compass "
            f"move), got dx {_shown(dx)}, dy {_shown(dy)} ({length:g} m)"
        )


def _is_real(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def _number(v) -> str | None:
    if not _is_real(v):
        return "a number"
    if not np.isfinite(float(v)):
        return "a finite number"
    return None


#: "between" two things named apart whose best matches are one thing: the other name's next
#: instance must score at least this share of its best to be taken for the second thing (a
#: floor against a thing with no evidence at all; not tuned on any suite).
APART_MIN_RATIO = 0.1


def _landmark_arg(v) -> str | None:
    if isinstance(v, Heatmap):
        return None
    if isinstance(v, str) and v.strip():
        return None
    return "an object name (a non-empty str) or a heatmap from get_major_map / get_map"


def _point_arg(v) -> str | None:
    want = "a finite 3-vector [m] (x, y, z numbers), e.g. (0.4, 0.0, 0.1)"
    if isinstance(v, (str, bytes, dict, set)):
        return want
    if isinstance(v, (list, tuple)) and any(isinstance(x, (bool, np.bool_)) for x in v):
        return want  # a truth value is no coordinate (numpy would read True as 1)
    try:
        a = np.asarray(v)
    except (TypeError, ValueError):
        return want
    if a.shape != (3,) or a.dtype.kind not in "iuf" or not np.all(np.isfinite(a)):
        return want
    return None


def _text_arg(v) -> str | None:
    return None if v is None or (isinstance(v, str) and v.strip()) else "a non-empty str"


def _image_arg(v) -> str | None:
    if v is None or isinstance(v, (str, Path, np.ndarray)):
        return None
    return "an image file path (str) or an (H, W, 3) uint8 RGB array"


#: The valid form of each primitive parameter (by its declared name,
#: :data:`tabletop.robot.primitives.PRIMITIVES`): a check returning what is expected, or None.
_PARAM_CHECKS = {
    "distance_m": lambda v: _number(v) and f"{_number(v)} of metres, e.g. 0.1",
    "dx": lambda v: _number(v) and f"{_number(v)} of metres",
    "dy": lambda v: _number(v) and f"{_number(v)} of metres",
    "angle_deg": lambda v: _number(v) and f"{_number(v)} of degrees, e.g. 90",
    "name": _landmark_arg,
    "a": _landmark_arg,
    "b": _landmark_arg,
    "pos": _point_arg,
    "heatmap": lambda v: (
        None
        if isinstance(v, Heatmap)
        else "a Heatmap (expected a heatmap from get_major_map / get_map, or their product)"
    ),
    "obj": _text_arg,
    "sound": _text_arg,
    "area": _text_arg,
    "img": _image_arg,
    "primary": lambda v: (
        None
        if v is None or (isinstance(v, str) and v in ("obj", "sound", "img", "area"))
        else "None or one of 'obj', 'sound', 'img', 'area'"
    ),
    "path": lambda v: None if isinstance(v, (str, Path)) else "an image file path (str)",
}


def _shown(v) -> str:
    r = repr(v)
    return f"{type(v).__name__} {r if len(r) <= 60 else r[:57] + '...'}"


def check_primitive_args(name: str, params: tuple[str, ...], arguments: dict) -> None:
    """The one check of every primitive's arguments: each given parameter of ``params`` must
    have its valid form (:data:`_PARAM_CHECKS`); :class:`PrimitiveArgumentError` names the
    call, the argument, its valid form and what it got."""
    for param in params:
        if param not in arguments:
            continue
        check = _PARAM_CHECKS.get(param)
        want = None if check is None else check(arguments[param])
        if want:
            raise PrimitiveArgumentError(
                f"{name}({param}=...): {param} must be {want}; got {_shown(arguments[param])}"
            )


def _checked(fn, params: tuple[str, ...], compass: bool = False):
    """``fn`` (a primitive's method) behind :func:`check_primitive_args` and the closed
    check; its signature unchanged."""
    sig = inspect.signature(fn)

    @functools.wraps(fn)
    def method(self, *args, **kwargs):
        if getattr(self, "closed", False):
            raise RobotClosed(
                f"{fn.__name__}: this {type(self).__name__} was closed; make a new one"
            )
        # a missing or extra argument is Python's TypeError, as for any call (the sandbox names
        # its line); what is given is checked first
        try:
            given = sig.bind_partial(self, *args, **kwargs)
        except TypeError as e:
            raise TypeError(f"{fn.__name__}({', '.join(params)}): {e}") from None
        check_primitive_args(fn.__name__, params, given.arguments)
        if compass and "distance_m" in given.arguments:
            check_compass_distance(
                fn.__name__, given.arguments["distance_m"], getattr(self, "robot_kind", "arm")
            )
        if fn.__name__ == "offset" and {"dx", "dy"} <= set(given.arguments):
            check_offset_distance(
                fn.__name__,
                given.arguments["dx"],
                given.arguments["dy"],
                getattr(self, "robot_kind", "arm"),
            )
        if (
            fn.__name__ == "move_to"
            and getattr(self, "refuses_off_map", False)
            and getattr(self, "map", None) is not None
            and "pos" in given.arguments
        ):
            check_on_map(self.map.grid, "move_to", _point(given.arguments["pos"]))
        try:
            sig.bind(self, *args, **kwargs)
        except TypeError as e:
            raise TypeError(f"{fn.__name__}({', '.join(params)}): {e}") from None
        return fn(self, *args, **kwargs)

    method._checked_primitive = True
    return method


def _check_primitives_of(cls: type) -> None:
    """Put every declared primitive ``cls`` itself defines behind :func:`_checked`."""
    from tabletop.robot.primitives import PRIMITIVES

    for p in PRIMITIVES:
        attr = cls.__dict__.get(p.name)
        if isinstance(attr, staticmethod):
            fn = attr.__func__
            if not getattr(fn, "_checked_static", False):

                def static(*args, _fn=fn, _p=p, **kwargs):
                    bound = inspect.signature(_fn).bind(*args, **kwargs)
                    check_primitive_args(_p.name, _p.params, bound.arguments)
                    return _fn(*args, **kwargs)

                functools.update_wrapper(static, fn)
                static._checked_static = True
                setattr(cls, p.name, staticmethod(static))
        elif inspect.isfunction(attr) and not getattr(attr, "_checked_primitive", False):
            setattr(cls, p.name, _checked(attr, p.params, compass=p.direction is not None))


@dataclass(frozen=True)
class SpatialConfig:
    """Offsets of the spatial primitives."""

    side_offset: float = 0.10
    """Distance [m] from an object's centre to a target beside it (left, right, front, behind)."""
    side_gap: float = 0.03
    """A side target is at least this far [m] beyond the object's extent (large objects)."""
    above_gap: float = 0.04
    """``move_to_object`` aims this far [m] above the object's top (a mug's centre is in its
    cavity; a gripper approaches from above)."""

    def __post_init__(self) -> None:
        if not (self.side_offset > 0 and self.side_gap >= 0 and self.above_gap >= 0):
            raise ConfigError(
                "side_offset must be > 0, side_gap and above_gap >= 0 [m], got "
                f"{self.side_offset}, {self.side_gap}, {self.above_gap}"
            )


def _point(pos, name: str = "pos") -> np.ndarray:
    """A finite (3,) float64 copy of ``pos`` [m]."""
    try:
        p = np.array(pos, dtype=np.float64)
    except (TypeError, ValueError):
        p = None
    if p is None or p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"{name} must be a finite 3-vector [m] (x, y, z numbers), got {pos!r}")
    return p


class RobotAPI(abc.ABC):
    """Map queries and spatial primitives for a robot; subclasses implement :meth:`move_to`
    and :meth:`current_position`.

    Args:
        avlmap: the map every query goes to (:class:`tabletop.mapping.avlmap.AVLMap`).
        spatial: offsets of the spatial primitives.
    """

    robot_kind = "arm"
    """Which robot it is (an :mod:`~tabletop.embodiments` name: "arm", the shared API
    with the table's conventions; "mobile", a base in a room,
    :class:`~tabletop.robot.wheeled.MobileRobot`): its primitives, prompt and limits."""

    reader = DEFAULT_READER
    """The reader (:data:`tabletop.reader.READERS`) that reads each ``obj=``/``sound=``/
    ``area=`` reference before the map scores it; set it on an instance to compare readers."""

    refuses_off_map = True
    """Whether ``move_to`` refuses a target off the map's grid with :class:`TargetOffMap`
    (:func:`check_on_map`) before the embodiment's own ``move_to`` runs: an embodiment that
    answers such a target with an honest result of its own (the arm's ``outside_workspace``,
    the base's ``outside_map``) sets it False; any other (``PointRobot``, which would jump
    anywhere) keeps the check."""

    closed = False
    """True once :meth:`close` ran: every primitive then raises :class:`RobotClosed`."""

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        _check_primitives_of(cls)  # one argument check for every embodiment's primitives

    def close(self) -> None:
        """Release what the robot holds (a simulator, a driver); primitives called after it
        raise :class:`RobotClosed`."""
        self.closed = True

    #: Whether the embodiment needs a map (its obstacles come from it); a mapless robot (None)
    #: serves only tracing and tests.
    needs_map = False

    def __init__(self, avlmap, spatial: SpatialConfig | None = None) -> None:
        if avlmap is None and self.needs_map:
            raise ConfigError(
                f"{type(self).__name__} needs a map: an AVLMap "
                "(tabletop.mapping.AVLMap.load(path)), got None"
            )
        if avlmap is not None and not all(hasattr(avlmap, a) for a in ("grid", "query", "config")):
            raise ConfigError(
                f"{type(self).__name__} needs an AVLMap (tabletop.mapping.AVLMap.load(path)), got "
                f"{type(avlmap).__name__}"
            )
        self.map = avlmap
        self.spatial = spatial or SpatialConfig()
        self.last_heatmaps: tuple = ()
        """The per-part heatmaps (with confidence and reason) of the last map query."""

    # ------------------------------------------------------------------ embodiment
    @abc.abstractmethod
    def move_to(self, pos):
        """Move to ``pos`` (3,) [m], base frame; return the embodiment's result value."""

    @abc.abstractmethod
    def current_position(self) -> np.ndarray:
        """(3,) [m] base frame: the TCP for an arm, the base's point for a mobile base."""

    # ------------------------------------------------------------------ queries
    @staticmethod
    def load_image(path) -> np.ndarray:
        """(H, W, 3) uint8 RGB image read from ``path`` (PNG, JPEG, ...)."""
        import cv2

        if not isinstance(path, (str, Path)):
            raise ConfigError(f"path must be an image file path (str), got {type(path).__name__}")
        problem = input_file_problem(path)
        if problem:
            raise ConfigError(f"image {str(path)!r} {problem}")
        p = Path(path)
        bgr = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ConfigError(f"image {str(p)!r} could not be decoded (not an image file?)")
        return np.ascontiguousarray(bgr[:, :, ::-1])

    def _image_heatmap(self, img, major: bool) -> Heatmap:
        rgb = self.load_image(img) if isinstance(img, (str, Path)) else np.asarray(img)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ConfigError(
                f"img must be an (H, W, 3) uint8 RGB array or a path, got {rgb.shape} {rgb.dtype}"
            )
        if self.map.visual is None:
            raise ImageGoalUnavailable(
                "image goals need the map's visual localization module; this map was built "
                "without it (MapConfig.visual=None)"
            )
        return self.map.image_heatmap(rgb, major=major)

    def _part(self, kind: str, value, major: bool) -> Heatmap:
        if kind == "img":
            return self._image_heatmap(value, major)
        # the words of a reference are read by the one reader every caller asks
        ref = get_reader(self.reader).reference(kind, value)
        if kind == "obj":  # "the nearest mug": nearest where the robot is
            return self.map.object_heatmap(ref, major=major, viewpoint=self._viewpoint())
        return self.map.query(kind, ref, major)

    def _viewpoint(self):
        """(x, y) [m] from which "the nearest" and "the farthest" thing are ranked: None, the
        map frame's origin (an arm's base); a mobile base ranks from where it stands."""
        return None

    def _heatmap(self, parts: dict, majors: dict) -> Heatmap:
        given = {k: v for k, v in parts.items() if v is not None}
        if not given:
            raise ConfigError("give at least one of obj=, sound=, img=, area=")
        for k, v in given.items():
            if k != "img" and (not isinstance(v, str) or not v.strip()):
                raise ConfigError(f"{k}= must be a non-empty string, got {v!r}")
        heatmaps = []
        for k, v in given.items():
            h = self._part(k, v, majors[k])
            if not h.found:
                label = f"{k}={v!r}" if k != "img" else "img"
                raise GoalNotFound(label, h.reason or "no match")
            heatmaps.append(h)
        self.last_heatmaps = tuple(heatmaps)
        out = fuse(*heatmaps)
        if not out.found:
            desc = ", ".join(f"{k}={v!r}" if k != "img" else "img" for k, v in given.items())
            raise GoalNotFound(desc, out.reason)
        return out

    def get_major_map(self, obj=None, sound=None, img=None, area=None, *, primary=None) -> Heatmap:
        """A sharp heatmap (major decay): "where exactly". A :class:`Heatmap` on the map's grid.

        With several parts, the ``primary`` one (default: the first given of obj, img, sound,
        area) is sharp and the others are broad constraints (auxiliary decay), multiplied: the
        paper's ``get_major_map(obj="mug") * get_map(sound="cat meowing")`` in one call, which
        peaks on the mug nearest the sound, not between the two.

        Raises:
            GoalNotFound: a part matches nothing (its reason is in the message).
            ImageGoalUnavailable: ``img=`` on a map without visual localization.
        """
        parts = {"obj": obj, "img": img, "sound": sound, "area": area}
        given = [k for k, v in parts.items() if v is not None]
        if primary is None:
            primary = given[0] if given else None
        elif primary not in given:
            raise ConfigError(f"primary={primary!r} is not one of the given parts {given}")
        return self._heatmap(parts, {k: k == primary for k in parts})

    def get_map(self, obj=None, sound=None, img=None, area=None) -> Heatmap:
        """A broad heatmap (auxiliary decay): "near". Several parts are multiplied."""
        parts = {"obj": obj, "img": img, "sound": sound, "area": area}
        return self._heatmap(parts, dict.fromkeys(parts, False))

    def _check_heatmap(self, heatmap) -> Heatmap:
        if not isinstance(heatmap, Heatmap):
            raise ConfigError(
                "expected a heatmap from get_major_map / get_map (or their product), got "
                f"{type(heatmap).__name__}"
            )
        if heatmap.grid != self.map.grid:
            raise ConfigError(f"heatmap grid {heatmap.grid} is not the map's {self.map.grid}")
        return heatmap

    def get_max_pos_3d(self, heatmap) -> np.ndarray:
        """(3,) [m] base frame: the point of maximal heat (the one target selector,
        :func:`tabletop.mapping.targets.max_position`).

        Raises:
            GoalNotFound: the heatmap found nothing or is zero everywhere.
        """
        h = self._check_heatmap(heatmap)
        return max_position(h, self.map.voxels.occupancy())

    def _landmark(self, landmark) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(centre, lower, upper) [m] of a landmark: an object name (the map's best instance)
        or a heatmap (its hottest region; a top-down place is a point level with the highest
        surface around it)."""
        if isinstance(landmark, str):
            h = self.get_major_map(obj=landmark)
        else:
            h = self._check_heatmap(landmark)
        return region_box(h, self.map.voxels.occupancy())

    def get_pos(self, name) -> np.ndarray:
        """(3,) [m] base frame: the centre of landmark ``name`` (an object name: the map's best
        instance of it; or a heatmap)."""
        return self._landmark(name)[0]

    # ------------------------------------------------------------------ spatial targets
    def side_target(self, name, direction) -> np.ndarray:
        """(3,) [m]: the point beside landmark ``name`` (an object name or a heatmap) along the
        horizontal ``direction`` (a unit axis), ``side_offset`` from its centre and at least
        ``side_gap`` beyond its extent, level with its top."""
        direction = check_axis("side_target", direction)
        c, lo, hi = self._landmark(name)
        s = self.spatial
        return side_point(direction, c, (hi - lo) / 2, hi[2], s.side_offset, s.side_gap)

    def above(self, name) -> np.ndarray:
        """(3,) [m]: ``above_gap`` above the top of object ``name``, over its centre."""
        c, _, hi = self._landmark(name)
        return np.array([c[0], c[1], hi[2] + self.spatial.above_gap])

    def left_of(self, name) -> np.ndarray:
        return self.side_target(name, relation("left_of").axis)

    def right_of(self, name) -> np.ndarray:
        return self.side_target(name, relation("right_of").axis)

    def in_front_of(self, name) -> np.ndarray:
        return self.side_target(name, relation("in_front_of").axis)

    def behind(self, name) -> np.ndarray:
        return self.side_target(name, relation("behind").axis)

    def between(self, a, b) -> np.ndarray:
        """(3,) [m]: midway between landmarks ``a`` and ``b`` (object names or heatmaps)
        horizontally, on the surface there (the table, or the top of what stands midway).

        Not the mean of the two centres in 3D: a place where a sound was heard lies on top of
        what stood there, so the mean of it and an object's centre floats above the table, and
        an arm approaching that point from above would stop a gripper's gap over it."""
        pa, pb = self.get_pos(a), self.get_pos(b)
        same = type(a) is type(b) and np.allclose(pa, pb, rtol=0.0, atol=1e-6)
        if same and isinstance(a, str) and " ".join(a.split()) != " ".join(b.split()):
            # two things named apart: the one whose next match is nearer its best takes it
            apart = self._apart(a, b, pa)
            if apart is not None:
                (pa, pb), same = apart, False
        # two names (or two heatmaps) that find the same place are one thing; a heatmap and
        # a name may well be (a sound heard on the object is a place beside it, not it)
        if same:
            raise PrimitiveArgumentError(
                f"between(a=..., b=...): a {_shown(a)} and b {_shown(b)} are the same thing "
                f"(both at ({pa[0]:.3f}, {pa[1]:.3f}, {pa[2]:.3f}) m): there is no place between "
                "a thing and itself; give two different landmarks"
            )
        p = (pa + pb) / 2
        p[2] = surface_z(self.map.grid, self.map.voxels.occupancy(), p[:2])
        return p

    def _apart(self, a: str, b: str, shared) -> tuple[np.ndarray, np.ndarray] | None:
        """Centres of two different things for the names ``a`` and ``b``, whose best matches
        are the one thing at ``shared``: "between" two things said differently means two
        things, so the name whose next-best instance scores nearer its best moves to that
        instance. None where the map holds no instances or neither name matches another
        thing at :data:`APART_MIN_RATIO` of its best."""
        objects = getattr(self.map, "objects", None)
        if objects is None or not getattr(objects, "uses_instances", False):
            return None
        items = objects.instances.items
        if len(items) < 2:
            return None
        centres = np.array([it.center for it in items])
        i = int(np.argmin(np.linalg.norm(centres[:, :2] - np.asarray(shared)[:2], axis=1)))
        best = []
        for name in (a, b):
            r = np.asarray(objects.match(name).ranked, dtype=float).copy()
            top, r[i] = r[i], 0.0
            j = int(np.argmax(r))
            best.append((r[j] / top if top > 0 else 0.0, j))
        (qa, ja), (qb, jb) = best
        if max(qa, qb) < APART_MIN_RATIO:
            return None
        if qa >= qb:
            return centres[ja].copy(), centres[i].copy()
        return centres[i].copy(), centres[jb].copy()

    def offset(self, dx: float, dy: float) -> np.ndarray:
        for v in (dx, dy):
            if not np.isfinite(v):
                raise ConfigError(f"distance must be finite [m], got {v}")
        return self.current_position() + np.array([dx, dy, 0.0])

    # ------------------------------------------------------------------ spatial primitives
    def move_to_object(self, name):
        """Move to object ``name``: to ``above_gap`` over its top (a base stops beside it)."""
        return self.move_to(self.above(name))

    def move_to_left(self, name):
        """Move to the left (+y) of object ``name``."""
        return self.move_to(self.left_of(name))

    def move_to_right(self, name):
        """Move to the right (-y) of object ``name``."""
        return self.move_to(self.right_of(name))

    def move_in_front_of(self, name):
        """Move in front of (+x, away from the robot) object ``name``."""
        return self.move_to(self.in_front_of(name))

    def move_behind(self, name):
        """Move behind (-x, towards the robot) object ``name``."""
        return self.move_to(self.behind(name))

    def move_in_between(self, a, b):
        """Move to the midpoint of objects ``a`` and ``b``."""
        return self.move_to(self.between(a, b))

    def move_north(self, distance_m: float):
        """Move ``distance_m`` [m] along +x from the current position."""
        return self.move_to(self.offset(distance_m, 0.0))

    def move_south(self, distance_m: float):
        """Move ``distance_m`` [m] along -x from the current position."""
        return self.move_to(self.offset(-distance_m, 0.0))

    def move_west(self, distance_m: float):
        """Move ``distance_m`` [m] along +y (left) from the current position."""
        return self.move_to(self.offset(0.0, distance_m))

    def move_east(self, distance_m: float):
        """Move ``distance_m`` [m] along -y (right) from the current position."""
        return self.move_to(self.offset(0.0, -distance_m))


_check_primitives_of(RobotAPI)

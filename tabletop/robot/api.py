"""The robot API shared by every embodiment (the paper's API tables), on top of an AVLMap.

Queries (implemented once, here): :meth:`RobotAPI.load_image`, :meth:`RobotAPI.get_major_map`,
:meth:`RobotAPI.get_map`, :meth:`RobotAPI.get_max_pos_3d`, :meth:`RobotAPI.get_pos`. Spatial
primitives compute a target in the base frame from the map, then call :meth:`RobotAPI.move_to`,
the one method (with :meth:`RobotAPI.current_position`) an embodiment implements.

Conventions (world frame = robot base frame, metres, z up): north = +x (away from the robot,
across the table), south = -x, west = left = +y, east = right = -y. "In front of" an object is
its +x side (further along the robot's forward direction), "behind" its -x side.

A query part that matches nothing raises :class:`GoalNotFound` before anything moves.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError, TabletopError

__all__ = [
    "GoalNotFound",
    "ImageGoalUnavailable",
    "RobotAPI",
    "RobotError",
    "SpatialConfig",
]


class RobotError(TabletopError):
    """Base class of the robot API's errors."""


class GoalNotFound(RobotError, LookupError):
    """A query (object, sound, image or area) matches nothing in the map; nothing moved."""

    def __init__(self, query: str, reason: str) -> None:
        super().__init__(f"{query}: not found ({reason})")
        self.query = query
        self.reason = reason


class ImageGoalUnavailable(ConfigError):
    """An image goal was asked of a map without the visual localization module."""


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
    p = np.array(pos, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"{name} must be a finite 3-vector [m], got {np.asarray(pos).tolist()}")
    return p


class RobotAPI(abc.ABC):
    """Map queries and spatial primitives for a robot; subclasses implement :meth:`move_to`
    and :meth:`current_position`.

    Args:
        avlmap: the map every query goes to (:class:`tabletop.mapping.avlmap.AVLMap`).
        spatial: offsets of the spatial primitives.
    """

    def __init__(self, avlmap, spatial: SpatialConfig | None = None) -> None:
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

        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"image {str(p)!r} does not exist")
        bgr = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ConfigError(f"image {str(p)!r} could not be decoded (not an image file?)")
        return np.ascontiguousarray(bgr[:, :, ::-1])

    def _image_heatmap(self, img, major: bool):
        rgb = self.load_image(img) if isinstance(img, (str, Path)) else np.asarray(img)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ConfigError(
                f"img must be an (H, W, 3) uint8 RGB array or a path, got {rgb.shape} {rgb.dtype}"
            )
        fn = getattr(self.map, "image_heatmap", None)
        if fn is None:
            raise ImageGoalUnavailable(
                "image goals need AVLMap.image_heatmap(rgb, major=...) from the visual "
                "localization module (tabletop/mapping/visual_localization.py); this map has no "
                "such method"
            )
        return fn(rgb, major=major)

    def _part(self, kind: str, value, major: bool):
        m = self.map
        if kind == "obj":
            return m.object_heatmap(value, major=major)
        if kind == "sound":
            return m.sound_heatmap(value, major=major)
        if kind == "area":
            return m.area_heatmap(value, major=major)
        return self._image_heatmap(value, major)

    def _heatmap(self, parts: dict, majors: dict) -> np.ndarray:
        given = {k: v for k, v in parts.items() if v is not None}
        if not given:
            raise ConfigError("give at least one of obj=, sound=, img=, area=")
        for k, v in given.items():
            if k != "img" and (not isinstance(v, str) or not v.strip()):
                raise ConfigError(f"{k}= must be a non-empty string, got {v!r}")
        heatmaps = []
        for k, v in given.items():
            h = self._part(k, v, majors[k])
            values = np.asarray(getattr(h, "values", h), dtype=np.float32)
            if values.shape != self.map.grid.shape:
                raise ConfigError(f"{k} heatmap {values.shape} is not on the map's grid")
            if not getattr(h, "found", True):
                label = f"{k}={v!r}" if k != "img" else "img"
                raise GoalNotFound(label, getattr(h, "reason", "") or "no match")
            heatmaps.append((k, v, h, values))
        self.last_heatmaps = tuple(h for _, _, h, _ in heatmaps)
        out = heatmaps[0][3].copy()
        for _, _, _, values in heatmaps[1:]:
            out *= values
        if not out.max() > 0:
            desc = ", ".join(f"{k}={v!r}" if k != "img" else "img" for k, v, _, _ in heatmaps)
            raise GoalNotFound(desc, "no place in the map has heat from every part")
        return out

    def get_major_map(self, obj=None, sound=None, img=None, area=None, *, primary=None):
        """A sharp heatmap (major decay): "where exactly". grid-shaped float32 in [0, 1].

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

    def get_map(self, obj=None, sound=None, img=None, area=None) -> np.ndarray:
        """A broad heatmap (auxiliary decay): "near". Several parts are multiplied."""
        parts = {"obj": obj, "img": img, "sound": sound, "area": area}
        return self._heatmap(parts, dict.fromkeys(parts, False))

    def get_max_pos_3d(self, heatmap) -> np.ndarray:
        """(3,) [m] base frame: the point of maximal heat (ties: see AVLMap.get_max_pos_3d)."""
        values = np.asarray(getattr(heatmap, "values", heatmap), dtype=np.float32)
        if values.shape != self.map.grid.shape:
            raise ConfigError(f"heatmap {values.shape} is not on the map's grid {self.map.grid}")
        if not values.max() > 0:
            raise GoalNotFound("heatmap", "it is zero everywhere")
        return np.asarray(self.map.get_max_pos_3d(values), dtype=np.float64)

    def _object(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(centre, lower, upper) [m] of the map's best instance of ``name``."""
        values = self.get_major_map(obj=name)
        tied = values >= values.max() - 1e-6
        labels, n = ndimage.label(tied, structure=np.ones((3, 3, 3)))
        if n > 1:  # the same instance AVLMap.get_max_pos_3d picks: the heaviest tied region
            weights = ndimage.sum(values, labels, index=np.arange(1, n + 1))
            tied = labels == (int(np.argmax(weights)) + 1)
        centers = self.map.grid.centers(np.argwhere(tied))
        h = self.map.grid.voxel_size / 2
        return centers.mean(axis=0), centers.min(axis=0) - h, centers.max(axis=0) + h

    def get_pos(self, name: str) -> np.ndarray:
        """(3,) [m] base frame: the centre of the map's best instance of object ``name``."""
        return self._object(name)[0]

    # ------------------------------------------------------------------ spatial targets
    def side_target(self, name: str, direction) -> np.ndarray:
        """(3,) [m]: the point beside object ``name`` along the horizontal ``direction`` (a
        unit axis), ``side_offset`` from its centre and at least ``side_gap`` beyond its extent,
        level with its top."""
        d = np.asarray(direction, np.float64)
        c, lo, hi = self._object(name)
        half = float(np.abs(d[:2]) @ ((hi - lo)[:2] / 2))
        dist = max(self.spatial.side_offset, half + self.spatial.side_gap)
        p = c + dist * d
        p[2] = hi[2]  # level with the object's top: a gripper beside it clears its neighbours
        return p

    def above(self, name: str) -> np.ndarray:
        """(3,) [m]: ``above_gap`` above the top of object ``name``, over its centre."""
        c, _, hi = self._object(name)
        return np.array([c[0], c[1], hi[2] + self.spatial.above_gap])

    def left_of(self, name: str) -> np.ndarray:
        return self.side_target(name, (0.0, 1.0, 0.0))

    def right_of(self, name: str) -> np.ndarray:
        return self.side_target(name, (0.0, -1.0, 0.0))

    def in_front_of(self, name: str) -> np.ndarray:
        return self.side_target(name, (1.0, 0.0, 0.0))

    def behind(self, name: str) -> np.ndarray:
        return self.side_target(name, (-1.0, 0.0, 0.0))

    def between(self, a: str, b: str) -> np.ndarray:
        return (self.get_pos(a) + self.get_pos(b)) / 2

    def offset(self, dx: float, dy: float) -> np.ndarray:
        for v in (dx, dy):
            if not np.isfinite(v):
                raise ConfigError(f"distance must be finite [m], got {v}")
        return self.current_position() + np.array([dx, dy, 0.0])

    # ------------------------------------------------------------------ spatial primitives
    def move_to_object(self, name: str):
        """Move to object ``name``: to ``above_gap`` over its top (a base stops beside it)."""
        return self.move_to(self.above(name))

    def move_to_left(self, name: str):
        """Move to the left (+y) of object ``name``."""
        return self.move_to(self.left_of(name))

    def move_to_right(self, name: str):
        """Move to the right (-y) of object ``name``."""
        return self.move_to(self.right_of(name))

    def move_in_front_of(self, name: str):
        """Move in front of (+x, away from the robot) object ``name``."""
        return self.move_to(self.in_front_of(name))

    def move_behind(self, name: str):
        """Move behind (-x, towards the robot) object ``name``."""
        return self.move_to(self.behind(name))

    def move_in_between(self, a: str, b: str):
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

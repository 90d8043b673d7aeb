"""Obstacles in the world frame: boxes, upright cylinders and convex vertex sets.

These are plain values. The collision checker (python-fcl) and the MuJoCo model of the mink
controller both build their own geometry from them, so the two always see the same scene.
Occupied map voxels enter as boxes (:func:`boxes_from_voxels`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tabletop.errors import ConfigError

__all__ = [
    "TABLE_THICKNESS",
    "TABLE_X",
    "TABLE_Y",
    "Box",
    "ConvexObstacle",
    "Cylinder",
    "Obstacle",
    "boxes_from_voxels",
    "obstacle_aabb",
    "table_box",
]

TABLE_X = (-0.2, 0.8)  # [m] table extent along world x
TABLE_Y = (-0.6, 0.6)  # [m] table extent along world y
TABLE_THICKNESS = 0.05  # [m]; the table top is the plane z = 0


def _vec3(v: object, name: str) -> np.ndarray:
    a = np.array(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} must be a finite 3-vector, got {np.asarray(v).tolist()}")
    a.setflags(write=False)
    return a


def _rotation(R: object, name: str) -> np.ndarray:
    a = np.eye(3) if R is None else np.array(R, dtype=np.float64)
    if a.shape != (3, 3) or not np.allclose(a.T @ a, np.eye(3), atol=1e-6):
        raise ConfigError(f"{name} must be a (3, 3) rotation matrix")
    if np.linalg.det(a) < 0:
        raise ConfigError(f"{name} must be a proper rotation (det = +1)")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Box:
    """An oriented box: ``center`` (3,) [m] world, ``half_extents`` (3,) [m] along its own axes,
    ``rotation`` (3, 3) R_world_box (identity by default)."""

    center: np.ndarray
    half_extents: np.ndarray
    rotation: np.ndarray | None = None
    name: str = "box"

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "Box.center"))
        he = _vec3(self.half_extents, "Box.half_extents")
        if np.any(he <= 0):
            raise ConfigError(f"Box.half_extents must be positive, got {he.tolist()}")
        object.__setattr__(self, "half_extents", he)
        object.__setattr__(self, "rotation", _rotation(self.rotation, "Box.rotation"))

    def vertices(self) -> np.ndarray:
        """(8, 3) corners [m], world frame."""
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        return (signs * self.half_extents) @ self.rotation.T + self.center

    def contains(self, p: np.ndarray) -> bool:
        local = self.rotation.T @ (np.asarray(p, dtype=np.float64) - self.center)
        return bool(np.all(np.abs(local) <= self.half_extents + 1e-12))


@dataclass(frozen=True, eq=False)
class Cylinder:
    """An upright cylinder (axis along world z): ``center`` (3,) [m] of its middle,
    ``radius`` and ``height`` [m]."""

    center: np.ndarray
    radius: float
    height: float
    name: str = "cylinder"

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "Cylinder.center"))
        if not (self.radius > 0 and self.height > 0):
            raise ConfigError(
                f"Cylinder radius and height must be positive, got {self.radius}, {self.height}"
            )

    def vertices(self, n: int = 16) -> np.ndarray:
        """(2 n, 3) points of the circumscribed prism [m], world frame (covers the cylinder)."""
        a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
        r = self.radius / np.cos(np.pi / n)
        ring = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
        h = self.height / 2
        top = np.column_stack([ring, np.full(n, h)])
        bot = np.column_stack([ring, np.full(n, -h)])
        return np.vstack([top, bot]) + self.center

    def contains(self, p: np.ndarray) -> bool:
        d = np.asarray(p, dtype=np.float64) - self.center
        return bool(np.hypot(d[0], d[1]) <= self.radius and abs(d[2]) <= self.height / 2)


@dataclass(frozen=True, eq=False)
class ConvexObstacle:
    """The convex hull of ``vertices`` (N, 3) [m], world frame (N >= 4, not coplanar)."""

    vertices: np.ndarray = field(repr=False)
    name: str = "convex"

    def __post_init__(self) -> None:
        v = np.array(self.vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 4 or not np.all(np.isfinite(v)):
            raise ConfigError(f"ConvexObstacle.vertices must be (N >= 4, 3) finite, got {v.shape}")
        if np.linalg.matrix_rank(v - v.mean(axis=0), tol=1e-9) < 3:
            raise ConfigError("ConvexObstacle.vertices are coplanar; the hull has no volume")
        v.setflags(write=False)
        object.__setattr__(self, "vertices", v)

    def contains(self, p: np.ndarray) -> bool:
        from scipy.spatial import Delaunay

        return bool(Delaunay(self.vertices).find_simplex(np.asarray(p, dtype=np.float64)) >= 0)


Obstacle = Box | Cylinder | ConvexObstacle


def obstacle_aabb(ob: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) corners [m] of the world-axis-aligned bounding box of an obstacle."""
    if isinstance(ob, Cylinder):
        ext = np.array([ob.radius, ob.radius, ob.height / 2])
        return ob.center - ext, ob.center + ext
    if isinstance(ob, Box):
        ext = np.abs(ob.rotation) @ ob.half_extents
        return ob.center - ext, ob.center + ext
    return ob.vertices.min(axis=0), ob.vertices.max(axis=0)


def table_box(
    x: tuple[float, float] = TABLE_X,
    y: tuple[float, float] = TABLE_Y,
    thickness: float = TABLE_THICKNESS,
    top_z: float = 0.0,
) -> Box:
    """The table slab as a :class:`Box` whose top face is the plane ``z = top_z`` [m]."""
    return Box(
        center=[(x[0] + x[1]) / 2, (y[0] + y[1]) / 2, top_z - thickness / 2],
        half_extents=[(x[1] - x[0]) / 2, (y[1] - y[0]) / 2, thickness / 2],
        name="table",
    )


def boxes_from_voxels(centers: object, voxel_size: float, name: str = "voxel") -> list[Box]:
    """One axis-aligned :class:`Box` per occupied voxel.

    Args:
        centers: (N, 3) voxel centres [m], world frame.
        voxel_size: voxel edge length [m].
    """
    c = np.asarray(centers, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ConfigError(f"voxel centers must have shape (N, 3), got {c.shape}")
    if not voxel_size > 0:
        raise ConfigError(f"voxel_size must be positive [m], got {voxel_size}")
    h = np.full(3, voxel_size / 2)
    return [Box(center=p, half_extents=h, name=f"{name}{i}") for i, p in enumerate(c)]

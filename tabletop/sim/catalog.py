"""The object catalog: which meshes of ``pybullet_data`` a scene can place, at what size and colour.

Each :class:`ObjectKind` names a mesh shipped with PyBullet (``pybullet_data``, zlib licence
for the package; see ``docs/assets.md``), the scale and upright rotation that make it a
plausible tabletop object, and the colours it may take. Meshes are re-centred so that an
object's frame sits at the bottom centre of its bounding box: placing an object at
``(x, y, 0)`` with a yaw stands it on the table top.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, SceneError
from tabletop.transforms import rotation_about

__all__ = [
    "COLORS",
    "OBJECT_KINDS",
    "MeshGeometry",
    "ObjectKind",
    "load_mesh_geometry",
    "object_kind",
    "pybullet_data_dir",
]

#: Named colours [0, 1] RGB that objects may take; the name is part of the object's label.
COLORS: dict[str, tuple[float, float, float]] = {
    "red": (0.85, 0.12, 0.10),
    "green": (0.15, 0.65, 0.20),
    "blue": (0.12, 0.30, 0.85),
    "yellow": (0.95, 0.85, 0.15),
    "orange": (0.95, 0.50, 0.08),
    "purple": (0.50, 0.20, 0.70),
    "pink": (0.95, 0.55, 0.70),
    "white": (0.93, 0.93, 0.93),
    "black": (0.10, 0.10, 0.10),
    "brown": (0.50, 0.32, 0.16),
    "grey": (0.55, 0.55, 0.55),
}


@dataclass(frozen=True)
class ObjectKind:
    """One kind of object a scene can hold."""

    name: str
    """Identifier used in scene specs (``"mug"``)."""
    label: str
    """English noun used in language queries and ground truth (``"mug"``)."""
    mesh: str
    """Mesh file relative to ``pybullet_data``."""
    scale: tuple[float, float, float]
    """Per-axis mesh scale (mesh units to metres)."""
    upright: tuple[float, float, float]
    """Rotation (roll, pitch, yaw) [rad] about fixed x, y, z that stands the mesh up, z up."""
    colors: tuple[str, ...]
    """Colours this kind may take; the first is its default."""
    keep_texture: bool = False
    """Keep the mesh's texture (tray, ball, domino) instead of painting it a flat colour. Such
    a kind renders the same whatever colour it is given, so it takes one colour: the one its
    texture shows (a label the renders contradict would ask the map for what no camera sees)."""


OBJECT_KINDS: dict[str, ObjectKind] = {
    k.name: k
    for k in (
        ObjectKind(
            "mug",
            "mug",
            "objects/mug.obj",
            (1.0, 1.0, 1.0),
            (0, 0, 0),
            ("red", "blue", "green", "white", "yellow", "black"),
        ),
        ObjectKind(
            "duck",
            "duck",
            "duck.obj",
            (0.06, 0.06, 0.06),
            (np.pi / 2, 0, 0),
            ("yellow", "orange", "white", "pink"),
        ),
        ObjectKind(
            "teddy_bear",
            "teddy bear",
            "teddy2_VHACD_CHs.obj",
            (0.13, 0.13, 0.13),
            (np.pi / 2, 0, 0),
            ("brown", "pink", "white", "grey"),
        ),
        ObjectKind(
            "lego_brick",
            "lego brick",
            "lego/lego.obj",
            (0.15, 0.15, 0.15),
            (np.pi / 2, 0, 0),
            ("red", "blue", "yellow", "green"),
        ),
        ObjectKind(
            "jenga_block",
            "jenga block",
            "jenga/jenga.obj",
            (0.15, 0.05, 0.03),
            (0, 0, 0),
            ("brown",),  # textured: it shows its wood whatever colour it is given
            keep_texture=True,
        ),
        ObjectKind(
            "domino",
            "domino",
            "domino/domino.obj",
            (1.6, 1.6, 1.6),
            (0, 0, 0),
            ("black",),  # textured: its faces render black with white edges
            keep_texture=True,
        ),
        ObjectKind(
            "soccer_ball",
            "soccer ball",
            "soccerball.obj",
            (0.09, 0.09, 0.09),
            (0, 0, 0),
            ("white",),
            keep_texture=True,
        ),
        ObjectKind(
            "tray",
            "tray",
            "tray/tray_textured.obj",
            (0.28, 0.28, 0.28),
            (0, 0, 0),
            ("grey",),
            keep_texture=True,
        ),
        ObjectKind(
            "toy_cube",
            "toy cube",
            "toys/cube.obj",
            (0.7, 0.7, 0.7),
            (np.pi / 2, 0, 0),
            ("green", "red", "blue", "yellow"),
        ),
        ObjectKind(
            "toy_cylinder",
            "toy cylinder",
            "toys/cylinder.obj",
            (0.7, 0.7, 0.7),
            (np.pi / 2, 0, 0),
            ("blue", "red", "green", "yellow"),
        ),
        ObjectKind(
            "toy_prism",
            "toy prism",
            "toys/prism.obj",
            (0.7, 0.7, 0.7),
            (np.pi / 2, 0, 0),
            ("purple", "red", "orange", "blue"),
        ),
        ObjectKind(
            "ball",
            "ball",
            "textured_sphere_smooth.obj",
            (0.03, 0.03, 0.03),
            (0, 0, 0),
            ("red", "blue", "green", "orange", "purple"),
        ),
    )
}


def object_kind(name: str) -> ObjectKind:
    """Look up a kind by name, with an error that lists the valid kinds."""
    try:
        return OBJECT_KINDS[name]
    except KeyError:
        raise SceneError(
            f"unknown object kind {name!r}; valid kinds: {sorted(OBJECT_KINDS)}"
        ) from None


def pybullet_data_dir() -> Path:
    """Directory of the ``pybullet_data`` package (meshes and textures)."""
    import pybullet_data

    return Path(pybullet_data.getDataPath())


@dataclass(frozen=True)
class MeshGeometry:
    """A kind's mesh after scaling, standing up and re-centring.

    ``vertices`` are in the object frame (bottom centre of the bounding box at the origin).
    ``frame_rotation`` and ``frame_offset`` map scaled mesh vertices into that frame:
    ``v_obj = frame_rotation @ (scale * v_mesh) + frame_offset``.
    """

    vertices: np.ndarray  # (N, 3) float64 [m], object frame
    frame_rotation: np.ndarray  # (3, 3)
    frame_offset: np.ndarray  # (3,) [m]
    size: np.ndarray  # (3,) [m], extent of the upright bounding box


def _read_obj_vertices(path: Path) -> np.ndarray:
    verts = []
    with path.open() as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
    if not verts:
        raise AssetError(f"mesh {path} has no vertices")
    return np.asarray(verts, dtype=np.float64)


@cache
def load_mesh_geometry(kind_name: str) -> MeshGeometry:
    """Scaled, upright, re-centred geometry of a kind's mesh (cached; arrays read-only)."""
    kind = object_kind(kind_name)
    path = pybullet_data_dir() / kind.mesh
    if not path.is_file():
        raise AssetError(f"mesh for {kind_name!r} not found at {path}")
    v = _read_obj_vertices(path) * np.asarray(kind.scale)
    roll, pitch, yaw = kind.upright
    R = rotation_about("z", yaw) @ rotation_about("y", pitch) @ rotation_about("x", roll)
    v = v @ R.T
    lo, hi = v.min(axis=0), v.max(axis=0)
    offset = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    v = v + offset
    for arr in (v, R, offset):
        arr.setflags(write=False)
    size = hi - lo
    size.setflags(write=False)
    return MeshGeometry(vertices=v, frame_rotation=R, frame_offset=offset, size=size)

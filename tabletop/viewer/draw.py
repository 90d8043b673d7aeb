"""What the viewer draws, as arrays: colours, heat on voxels, frustums, boxes, the Panda's link
meshes from its URDF. Pure numpy (and cv2, trimesh for the meshes): no viser, no browser, so
each piece is tested on its own.

World frame = robot base frame (metres, z up), as everywhere in tabletop.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "HEAT_FLOOR",
    "LinkMesh",
    "box_segments",
    "distinct_colours",
    "frustum_segments",
    "heat_colours",
    "heat_voxels",
    "height_colours",
    "panda_link_meshes",
    "path_segments",
]

#: Heat below this is not drawn (a heatmap's tail over the whole table would hide the map).
HEAT_FLOOR = 0.02


def heat_colours(values: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 RGB of heat values in [0, 1]: the JET scheme of the report's pictures
    (:mod:`tabletop.mapping.render`: blue = cold, red = hot)."""
    import cv2

    v = np.clip(np.asarray(values, np.float64).reshape(-1), 0.0, 1.0)
    u8 = np.round(v * 255).astype(np.uint8).reshape(-1, 1)
    return cv2.applyColorMap(u8, cv2.COLORMAP_JET).reshape(-1, 3)[:, ::-1].copy()


def height_colours(z: np.ndarray) -> np.ndarray:
    """(N, 3) uint8: occupancy coloured by height (the VIRIDIS scheme, low = dark blue)."""
    import cv2

    z = np.asarray(z, np.float64).reshape(-1)
    if not len(z):
        return np.zeros((0, 3), np.uint8)
    lo, hi = np.percentile(z, 1), np.percentile(z, 99)
    t = np.clip((z - lo) / max(hi - lo, 1e-6), 0, 1)
    u8 = np.round(t * 255).astype(np.uint8).reshape(-1, 1)
    return cv2.applyColorMap(u8, cv2.COLORMAP_VIRIDIS).reshape(-1, 3)[:, ::-1].copy()


def distinct_colours(n: int) -> np.ndarray:
    """(n, 3) uint8: well separated colours (golden-angle hues), one per object instance."""
    import cv2

    if n <= 0:
        return np.zeros((0, 3), np.uint8)
    h = (np.arange(n) * 137.508) % 360 / 2  # OpenCV hue is 0..180
    hsv = np.stack([h, np.full(n, 200), np.full(n, 235)], 1).astype(np.uint8)[None]
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0]


def heat_voxels(
    values: np.ndarray, grid, linear: np.ndarray, floor: float = HEAT_FLOOR
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heat of a heatmap on the map's occupied voxels, where it is at least ``floor``:
    (positions (K, 3) [m], colours (K, 3) uint8, heat (K,)). ``values`` is the heatmap
    (grid.shape), ``linear`` the occupied voxels' linear indices. Heat off the occupied voxels
    (in the air around an object, a sound's column) is not drawn: it lies on what is there."""
    v = np.asarray(values, np.float32).reshape(-1)
    lin = np.asarray(linear, np.int64)
    heat = v[lin] if len(lin) else np.zeros(0, np.float32)
    keep = heat >= floor
    lin, heat = lin[keep], heat[keep]
    pos = grid.centers(grid.unravel(lin)) if len(lin) else np.zeros((0, 3))
    return pos, heat_colours(heat), heat


def box_segments(lo, hi) -> np.ndarray:
    """(12, 2, 3) [m]: the edges of the axis-aligned box ``lo``..``hi``."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64)
    corners = lo + c * (hi - lo)
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.abs(c[a] - c[b]).sum() == 1]
    return np.stack([corners[[a, b]] for a, b in edges])


def path_segments(points) -> np.ndarray:
    """(N-1, 2, 3): consecutive points joined (a path drawn as one node)."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if len(p) < 2:
        return np.zeros((0, 2, 3))
    return np.stack([p[:-1], p[1:]], axis=1)


def frustum_segments(
    T_world_cam: np.ndarray, K: np.ndarray, image_size: tuple[int, int], depth: float
) -> np.ndarray:
    """(8 * N, 2, 3) [m]: the pyramids of N cameras (OpenCV optical frames ``T_world_cam``,
    intrinsics ``K``, ``image_size`` = (width, height)) out to ``depth``: four edges from the
    centre and the four sides of the far rectangle."""
    T = np.asarray(T_world_cam, np.float64).reshape(-1, 4, 4)
    w, h = image_size
    Kinv = np.linalg.inv(np.asarray(K, np.float64))
    px = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], np.float64)
    rays = (Kinv @ px.T).T
    corners_cam = rays / rays[:, 2:3] * depth  # (4, 3)
    R, t = T[:, :3, :3], T[:, :3, 3]
    corners = np.einsum("nij,kj->nki", R, corners_cam) + t[:, None, :]  # (N, 4, 3)
    segs = []
    for k in range(4):
        segs.append(np.stack([t, corners[:, k]], axis=1))
        segs.append(np.stack([corners[:, k], corners[:, (k + 1) % 4]], axis=1))
    return np.concatenate(segs, axis=0) if len(T) else np.zeros((0, 2, 3))


@dataclass(frozen=True)
class LinkMesh:
    """One link's geometry from the URDF: ``vertices`` (V, 3) [m] and ``faces`` (F, 3) in the
    link's frame (the URDF's geometry origin applied)."""

    link: str
    vertices: np.ndarray
    faces: np.ndarray


def _origin(el) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    if el is None:
        return T
    xyz = [float(v) for v in el.get("xyz", "0 0 0").split()]
    rpy = [float(v) for v in el.get("rpy", "0 0 0").split()]
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T[:3, 3] = xyz
    return T


@functools.cache
def panda_link_meshes(
    urdf_path: str | None = None, kind: str = "collision"
) -> tuple[LinkMesh, ...]:
    """Every link of the Panda URDF (``urdf/panda/panda.urdf``, the one the arm model, PyBullet
    and MuJoCo load) with a mesh of ``kind`` ("collision": light, a few hundred triangles a
    link; "visual": the detailed meshes), read with trimesh."""
    import trimesh

    from tabletop.paths import panda_urdf_path

    path = Path(urdf_path) if urdf_path is not None else panda_urdf_path()
    root = ET.parse(path).getroot()
    out = []
    for link in root.findall("link"):
        geom = link.find(f"{kind}/geometry/mesh")
        if geom is None:
            continue
        rel = geom.get("filename", "").removeprefix("package://")
        mesh = trimesh.load(path.parent / rel, force="mesh", process=False)
        T = _origin(link.find(f"{kind}/origin"))
        v = np.asarray(mesh.vertices, np.float64) @ T[:3, :3].T + T[:3, 3]
        out.append(LinkMesh(link.get("name"), v.astype(np.float32), np.asarray(mesh.faces)))
    return tuple(out)

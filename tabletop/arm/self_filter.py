"""Robot self-filter: drop the points of a frame that lie on the robot itself.

A wrist camera sees the gripper's fingers in every frame and other links now and then; fused
into the map they would leave a trail of "robot" voxels wherever the arm went. Each link's
collision mesh from the one URDF is boxed in its link frame (inflated by a margin); for a frame
the link poses come from the recorded joint positions (forward kinematics), and points inside
any box are dropped. This works the same on a real Panda: it needs only the joint positions.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET

import numpy as np

from tabletop.arm.model import PandaModel
from tabletop.paths import panda_urdf_path
from tabletop.transforms import invert, make_transform, rotation_about

__all__ = ["RobotSelfFilter"]

HAND_FRAME = "panda_hand"
"""The frame whose pose a recording stores (``T_world_hand``)."""


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    return rotation_about("z", y) @ rotation_about("y", p) @ rotation_about("x", r)


@functools.cache
def _link_boxes() -> tuple[tuple[str, np.ndarray, np.ndarray], ...]:
    """(link, lo (3,), hi (3,)) boxes of each link's collision mesh, in the link frame [m]."""
    urdf = panda_urdf_path()
    root = ET.parse(urdf).getroot()
    boxes = []
    for link in root.iter("link"):
        pts = []
        for col in link.iter("collision"):
            mesh = col.find("geometry/mesh")
            if mesh is None:
                continue
            fname = mesh.get("filename").replace("package://", "")
            verts = [
                list(map(float, ln.split()[1:4]))
                for ln in (urdf.parent / fname).read_text().splitlines()
                if ln.startswith("v ")
            ]
            origin = col.find("origin")
            xyz = [
                float(v)
                for v in (origin.get("xyz", "0 0 0").split() if origin is not None else [0, 0, 0])
            ]
            rpy = [
                float(v)
                for v in (origin.get("rpy", "0 0 0").split() if origin is not None else [0, 0, 0])
            ]
            T = make_transform(_rpy(*rpy), xyz)
            v = np.asarray(verts)
            pts.append(v @ T[:3, :3].T + T[:3, 3])
        if pts:
            v = np.concatenate(pts)
            boxes.append((link.get("name"), v.min(axis=0), v.max(axis=0)))
    return tuple(boxes)


class RobotSelfFilter:
    """Tests points against the Panda's link boxes at a given joint configuration (what
    :meth:`tabletop.mapping.avlmap.AVLMap.add_frame` takes as its ``self_filter``)."""

    def __init__(self, margin: float = 0.01) -> None:
        self.model = PandaModel()
        self.margin = float(margin)
        boxes = [b for b in _link_boxes() if b[0] in self.model.frame_names]
        self.links = [b[0] for b in boxes]
        self.lo = np.stack([b[1] for b in boxes]) - self.margin
        self.hi = np.stack([b[2] for b in boxes]) + self.margin
        self.center = (self.lo + self.hi) / 2  # (L, 3) box centres in the link frames
        self.radius = np.linalg.norm(self.hi - self.lo, axis=1) / 2  # bounding spheres

    def mask(
        self, points_world: np.ndarray, q: np.ndarray, T_world_hand: np.ndarray | None = None
    ) -> np.ndarray:
        """Boolean (P,) mask of the points (world frame [m]) on the robot at joints ``q``.

        ``T_world_hand``: the hand pose the points were projected with (the recorded one). When
        given, the links are placed relative to it rather than where forward kinematics puts
        them, so an error in the recorded pose moves the robot's boxes with its points: the
        gripper seen by the wrist camera is filtered however wrong the pose is."""
        poses = self.model.fk_frames(q, [*self.links, HAND_FRAME])
        if T_world_hand is not None:
            anchor = np.asarray(T_world_hand, np.float64) @ invert(poses[HAND_FRAME])
            poses = {k: anchor @ v for k, v in poses.items()}
        on = np.zeros(len(points_world), bool)
        for k, link in enumerate(self.links):
            T_world_link = poses[link]
            c = T_world_link[:3, :3] @ self.center[k] + T_world_link[:3, 3]
            near = np.nonzero(np.sum((points_world - c) ** 2, axis=1) <= self.radius[k] ** 2)[0]
            if not len(near):
                continue
            T = invert(T_world_link)
            p = points_world[near] @ T[:3, :3].T + T[:3, 3]
            on[near[np.all((p >= self.lo[k]) & (p <= self.hi[k]), axis=1)]] = True
        return on

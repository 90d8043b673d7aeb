"""The Panda's kinematics and geometry for importing a user's recording (``tabletop import``):
hand poses from joint states (Pinocchio forward kinematics of the one URDF) and the link that
contains a point (the camera-inside-the-arm check of :mod:`tabletop.ingest.checks`)."""

from __future__ import annotations

import numpy as np

from tabletop.arm.model import ARM_JOINT_NAMES, PandaModel
from tabletop.arm.self_filter import HAND_FRAME, _link_boxes
from tabletop.transforms import invert

__all__ = ["PandaRecordingKinematics"]


class PandaRecordingKinematics:
    """Forward kinematics of recorded joint states and the Panda's link boxes (no margin)."""

    joint_names = ARM_JOINT_NAMES
    hand_frame = HAND_FRAME

    def __init__(self) -> None:
        self.model = PandaModel()
        boxes = [b for b in _link_boxes() if b[0] in self.model.frame_names]
        self.links = [b[0] for b in boxes]
        self.lo = np.stack([b[1] for b in boxes])
        self.hi = np.stack([b[2] for b in boxes])

    def hand_poses(self, q: np.ndarray) -> np.ndarray:
        """(N, 7) joint positions [rad] -> (N, 4, 4) ``T_world_hand`` (world = ``panda_link0``)."""
        q = np.asarray(q, np.float64)
        return (
            np.stack([self.model.fk(qi, HAND_FRAME) for qi in q]) if len(q) else np.zeros((0, 4, 4))
        )

    def link_containing(
        self, point_world: np.ndarray, q: np.ndarray, T_world_hand: np.ndarray
    ) -> str | None:
        """The first link whose collision box holds ``point_world`` with the arm at ``q`` (the
        links placed relative to the recorded hand pose), or None."""
        poses = self.model.fk_frames(np.asarray(q, np.float64)[:7], [*self.links, HAND_FRAME])
        anchor = np.asarray(T_world_hand, np.float64) @ invert(poses[HAND_FRAME])
        p = np.append(np.asarray(point_world, np.float64), 1.0)
        for k, link in enumerate(self.links):
            local = invert(anchor @ poses[link]) @ p
            if np.all(local[:3] >= self.lo[k]) and np.all(local[:3] <= self.hi[k]):
                return link
        return None

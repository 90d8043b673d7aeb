"""Query images for image goals: rendered in the scene from a camera pose a task file gives."""

from __future__ import annotations

import numpy as np

from tabletop.errors import ConfigError
from tabletop.eval.tasks import ImageView

__all__ = ["render_view", "view_pose"]


def view_pose(view: ImageView) -> np.ndarray:
    """(4, 4) ``T_world_cam`` (OpenCV optical frame: z forward, y down) of a camera at
    ``view.eye`` looking at ``view.look_at``, the image's top towards ``view.up``."""
    eye = np.asarray(view.eye, np.float64)
    z = np.asarray(view.look_at, np.float64) - eye
    z /= np.linalg.norm(z)
    up = np.asarray(view.up, np.float64)
    up = up - (up @ z) * z
    n = np.linalg.norm(up)
    if n < 1e-6:
        raise ConfigError(f"image view: 'up' {list(view.up)} is parallel to the viewing direction")
    y = -up / n  # image y points down, away from 'up'
    x = np.cross(y, z)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


def render_view(world, view: ImageView) -> np.ndarray:
    """(H, W, 3) uint8 RGB of ``view`` rendered by a :class:`tabletop.sim.SimWorld` or
    :class:`tabletop.sim.room_world.RoomWorld` (with the recording's camera model and
    renderer, so the query looks like the scan's frames). The robot is out of the picture:
    a query image shows the scene, the same whatever the robot did before."""
    from tabletop.sim.views import render_without_robot

    return np.ascontiguousarray(render_without_robot(world, view_pose(view)).rgb)

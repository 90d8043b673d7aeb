"""Views of a world without its robot: query pictures that do not depend on where the robot is.

An image goal is a picture of the scene taken from a pose the task file gives. Rendered in
the robot's own world, the picture would show the robot wherever the previous goal left it,
so the same goal would look different (and be found or not) depending on the order goals run
in. :func:`render_without_robot` moves the robot out of sight for the one render and puts
the simulator back exactly as it was (positions, velocities, contacts), without stepping.

Scans never use this module (the scan's frames see what the robot's camera sees).
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from tabletop.errors import ConfigError
from tabletop.sim.world import CameraImage

__all__ = ["FAR_AWAY", "render_without_robot", "robot_hidden"]

#: [m] where the robot waits while a view renders: far below the floor, out of every frustum.
FAR_AWAY = (0.0, 0.0, -1000.0)


@contextmanager
def robot_hidden(world):
    """Within the block the world's robot (``world.robot_id``) is out of sight; on leaving,
    the simulator's state is restored exactly. Nothing may step the physics inside."""
    robot = getattr(world, "robot_id", None)
    pb, cid = getattr(world, "_pb", None), getattr(world, "_client", None)
    if robot is None or pb is None or cid is None:
        raise ConfigError(
            f"{type(world).__name__} has no robot to hide (valid: a RoomWorld or SimWorld "
            "that is open)"
        )
    state = pb.saveState(physicsClientId=cid)
    try:
        _, quat = pb.getBasePositionAndOrientation(robot, physicsClientId=cid)
        pb.resetBasePositionAndOrientation(robot, FAR_AWAY, quat, physicsClientId=cid)
        yield
    finally:
        pb.restoreState(stateId=state, physicsClientId=cid)
        pb.removeState(state, physicsClientId=cid)


def render_without_robot(world, T_world_cam: np.ndarray) -> CameraImage:
    """:meth:`world.render` from ``T_world_cam`` (4x4, OpenCV optical frame) with the robot
    out of sight; the world is left as it was."""
    with robot_hidden(world):
        return world.render(np.asarray(T_world_cam, np.float64))

"""Query pictures do not show the robot, and rendering them leaves the simulator as it was."""

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.eval.images import render_view, view_pose
from tabletop.eval.tasks import ImageView
from tabletop.sim.room import load_room_spec
from tabletop.sim.room_world import INSTANCE_ROBOT, RoomWorld, mast_camera_config
from tabletop.sim.views import render_without_robot, robot_hidden

SMALL = {"width": 320, "height": 240}


def _look_at_base(world) -> ImageView:
    x, y = world.T_world_base()[:2, 3]
    # from inside the room (the default start is in its corner), looking back at the base
    return ImageView(eye=(x + 1.5, y + 0.4, 1.2), look_at=(x, y, 0.3), up=(0.0, 0.0, 1.0))


def test_a_view_of_the_base_does_not_show_it_and_leaves_the_world_as_it_was():
    with RoomWorld(load_room_spec("default"), mast_camera_config(**SMALL)) as world:
        world.driver.command_wheels(0.4, 0.4, 0.5)  # moving: velocities to keep
        view = _look_at_base(world)
        T = view_pose(view)
        seen = world.render(T)
        assert np.count_nonzero(seen.segmentation == INSTANCE_ROBOT) > 50  # in the frustum
        pb, cid, rid = world._pb, world._client, world.robot_id
        pose0 = pb.getBasePositionAndOrientation(rid, physicsClientId=cid)
        vel0 = pb.getBaseVelocity(rid, physicsClientId=cid)
        hidden = render_without_robot(world, T)
        assert not np.any(hidden.segmentation == INSTANCE_ROBOT)
        assert pb.getBasePositionAndOrientation(rid, physicsClientId=cid) == pose0
        assert pb.getBaseVelocity(rid, physicsClientId=cid) == vel0
        # the picture is the same wherever the base went before it was taken
        first = render_view(world, view)
        before = world.T_world_base()
        world.driver.command_wheels(-0.5, 0.5, 1.0)
        assert not np.allclose(world.T_world_base(), before, atol=1e-2)  # (the base turned)
        assert np.array_equal(render_view(world, view), first)


def test_hiding_needs_an_open_world_with_a_robot():
    world = RoomWorld(load_room_spec("default"), mast_camera_config(**SMALL))
    world.close()
    with pytest.raises(ConfigError, match="no robot to hide"):
        with robot_hidden(world):
            pass
    with pytest.raises(ConfigError, match="no robot to hide"):
        with robot_hidden(object()):
            pass

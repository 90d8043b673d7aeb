"""The simulated world: building from a spec, ground truth, and the camera geometry."""

import numpy as np
import pytest
from helpers import assert_on_table

from tabletop.errors import ConfigError
from tabletop.sim.scene import load_scene_spec
from tabletop.sim.world import HOME_Q, INSTANCE_TABLE, SimWorld
from tabletop.transforms import backproject, transform_points

# Arm configurations that look at the table from different heights and angles.
VIEW_QS = [
    HOME_Q,
    np.array([0.45, -0.2, 0.0, -2.0, 0.0, 1.9, 0.785]),
    np.array([-0.5, 0.1, 0.0, -1.9, 0.0, 2.1, 0.3]),
    np.array([0.0, 0.3, 0.0, -1.6, 0.0, 2.2, 1.2]),
]


@pytest.fixture(scope="module")
def world():
    w = SimWorld(load_scene_spec("default"))
    yield w
    w.close()


def test_depth_backprojects_onto_ground_truth_boxes_within_5mm(world):
    gt = {o.instance_id: o for o in world.ground_truth().objects}
    K = world.intrinsics.K
    seen = set()
    for q in VIEW_QS:
        world.set_arm(q)
        T_world_cam = world.T_world_hand() @ world.camera.T_hand_cam
        img = world.render(T_world_cam)
        for inst, obj in gt.items():
            mask = img.segmentation == inst
            if mask.sum() < 20:
                continue
            seen.add(obj.name)
            pts = transform_points(T_world_cam, backproject(img.depth, K, mask))
            lo, hi = obj.aabb_min, obj.aabb_max
            outside = np.maximum(lo - pts, 0) + np.maximum(pts - hi, 0)
            dist = np.linalg.norm(outside, axis=1)
            assert dist.max() <= 0.005, (obj.name, dist.max())
        # the table top is the plane z = 0
        table = transform_points(
            T_world_cam, backproject(img.depth, K, img.segmentation == INSTANCE_TABLE)
        )
        assert len(table) > 1000
        assert_on_table(table)
    assert len(seen) >= 8, seen


def test_geometry_check_would_catch_a_wrong_extrinsic(world):
    # The same check with a camera pose off by 2 cm fails: the test above can fail.
    world.set_arm(HOME_Q)
    T = world.T_world_hand() @ world.camera.T_hand_cam
    img = world.render(T)
    T_wrong = T.copy()
    T_wrong[0, 3] += 0.02
    mask = img.segmentation == INSTANCE_TABLE
    pts = transform_points(T_wrong, backproject(img.depth, world.intrinsics.K, mask))
    good = transform_points(T, backproject(img.depth, world.intrinsics.K, mask))
    assert np.abs(good[:, 2]).max() <= 0.005
    assert np.abs(pts[:, 0] - good[:, 0]).min() > 0.019


def test_render_outputs_have_documented_types(world):
    world.set_arm(HOME_Q)
    img = world.render(world.T_world_cam())
    assert img.rgb.shape == (240, 320, 3) and img.rgb.dtype == np.uint8
    assert img.depth.shape == (240, 320) and img.depth.dtype == np.float32
    assert img.segmentation.dtype == np.uint16
    assert (img.segmentation[img.depth == 0] == 0).all()
    valid = img.depth[img.depth > 0]
    assert valid.min() >= world.camera.near and valid.max() <= world.camera.far
    # quantised to the sensor resolution (0.1 mm)
    steps = valid.astype(np.float64) / world.camera.depth_resolution
    assert np.abs(steps - np.round(steps)).max() < 1e-2


def test_ground_truth_lists_objects_areas_and_instances(world):
    gt = world.ground_truth()
    assert "red_mug" in gt.object_names and "blue_mug" in gt.object_names
    assert {m.color for m in gt.objects_of_kind("mug")} == {"red", "blue"}
    for o in gt.objects:
        assert o.aabb_min[2] == pytest.approx(0.0, abs=1e-9)
        assert np.all(o.aabb_min < o.aabb_max)
        assert gt.instances[o.instance_id] == o.name
    assert {"left side of the table", "right side of the table", "tray area"} <= set(gt.area_names)
    assert gt.sound_events == ()  # a scan adds the sounds it inserts


def test_link_pose_is_link_frame_and_errors_name_links(world):
    world.set_arm(HOME_Q)
    T_hand = world.link_pose("panda_hand")
    T_tcp = world.link_pose("panda_grasptarget")
    # The TCP is 0.105 m along the hand's z axis.
    np.testing.assert_allclose(T_tcp[:3, 3], T_hand[:3, 3] + 0.105 * T_hand[:3, 2], atol=1e-6)
    with pytest.raises(ConfigError, match="panda_hand"):
        world.link_pose("hnd")
    with pytest.raises(ConfigError, match=r"shape \(7,\)"):
        world.set_arm(np.zeros(6))


def test_tiny_renderer_gives_the_same_geometry(world):
    world.set_arm(HOME_Q)
    T = world.T_world_cam()
    ref = world.render(T)
    with SimWorld(world.spec, renderer="tiny") as tiny:
        img = tiny.render(T)
    both = (ref.depth > 0) & (img.depth > 0) & (ref.segmentation == img.segmentation)
    assert both.mean() > 0.95
    assert np.median(np.abs(ref.depth[both] - img.depth[both])) < 1e-3

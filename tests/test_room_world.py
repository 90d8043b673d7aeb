"""The simulated room and the physics base driver: the build, the mast camera, ground truth,
the follower on wheel motors, wheel odometry (with and without drift), collision counting."""

import json
import math

import numpy as np
import pytest

from tabletop.base import BaseDriver, FollowConfig, OdometryDrift, follow_path, turn_to
from tabletop.sim.ground_truth import GroundTruth
from tabletop.sim.room import load_room_spec
from tabletop.sim.room_world import INSTANCE_ROBOT, RoomWorld
from tabletop.sim.teleop import look_at

#: A free route through the default room from its start (0.7, 0.7): 2.3 m up the west side,
#: then 2.7 m east between the dining and the work table.
ROUTE = [[1.0, 3.0], [3.6, 2.4]]
ROUTE_M = math.dist((0.7, 0.7), ROUTE[0]) + math.dist(*ROUTE)
#: Stated accuracy of the drift-free wheel odometry on this floor (measured: under 1 mm and
#: 0.05 deg over the route): the tyres touch the floor at a point of their mid-plane, so the
#: effective wheel radius and track are the nominal ones, and the casters slide freely.
ODOMETRY_ERROR_PER_M = 0.005
ODOMETRY_YAW_ERROR = math.radians(0.5)


@pytest.fixture(scope="module")
def spec():
    return load_room_spec("default")


def test_the_room_renders_from_the_mast_with_metric_depth(spec):
    with RoomWorld(spec) as w:
        assert isinstance(w.driver, BaseDriver) and w.driver.collisions == 0
        img = w.render()
        assert img.rgb.shape == (240, 320, 3) and img.depth.dtype == np.float32
        seen = {w.instance_names[i] for i in np.unique(img.segmentation)}
        assert "floor" in seen and len(seen) >= 3
        # a camera 3 m from the east wall, looking straight at it: depth 3 m at the centre
        T = look_at(np.array([3.0, 2.5, 1.8]), np.array([6.0, 2.5, 1.8]))
        img = w.render(T)
        assert img.depth[119:121, 159:161] == pytest.approx(3.0, abs=0.005)
        assert w.instance_names[int(img.segmentation[120, 160])] == "wall_east"
        # the mast camera is the URDF's camera link, 1.1 m above the floor
        assert np.allclose(w.T_world_cam(), w.link_pose("camera_optical"), atol=1e-6)
        assert w.T_world_cam()[2, 3] == pytest.approx(1.1, abs=0.01)
        assert INSTANCE_ROBOT not in np.unique(w.render().segmentation)


def test_ground_truth_is_in_the_room_frame(spec):
    with RoomWorld(spec, renderer="tiny") as w:
        gt = w.ground_truth()
    assert GroundTruth.from_dict(json.loads(json.dumps(gt.to_dict()))) == gt
    assert gt.table is None
    assert {f.category for f in gt.furniture} == {"table", "shelf", "cabinet", "sofa", "wall"}
    assert len(gt.furniture_of("wall")) == 4
    for o in gt.objects:
        table = gt.item(o.table)
        assert o.aabb_min[2] == pytest.approx(table.top_z, abs=1e-6)
        assert np.all(o.aabb_min[:2] >= table.aabb_min[:2])
        assert np.all(o.aabb_max[:2] <= table.aabb_max[:2])
    assert [o.name for o in gt.objects_on("coffee_table")] == [
        "red_ball",
        "purple_toy_prism",
        "brown_jenga_block",
    ]
    assert gt.area("dining table").center[2] == pytest.approx(0.625)


def drive(spec, drift=None):
    w = RoomWorld(spec, renderer="tiny", drift=drift)
    d = w.driver
    start = d.true_pose()
    turn = turn_to(d, math.atan2(ROUTE[0][1] - start.y, ROUTE[0][0] - start.x))
    res = follow_path(d, ROUTE, final_yaw=0.0)
    return w, turn, res


def test_the_follower_drives_the_physics_base_to_its_goal(spec):
    w, turn, res = drive(spec)
    with w:
        d = w.driver
        assert turn.reached and res.reached and res.reason == "reached"
        odo, true = d.read_odometry(), d.true_pose()
        tol = FollowConfig().goal_tolerance
        assert math.dist(odo.xy, ROUTE[-1]) <= tol + 0.01  # the base stops after the check
        assert math.dist(true.xy, ROUTE[-1]) <= tol + ODOMETRY_ERROR_PER_M * ROUTE_M
        assert abs(odo.yaw) <= FollowConfig().yaw_tolerance + 0.01
        # drift-free odometry stays within its stated error of the simulator's pose
        assert odo.distance_to(true) <= ODOMETRY_ERROR_PER_M * ROUTE_M
        assert abs(odo.yaw - true.yaw) <= ODOMETRY_YAW_ERROR
        assert d.collisions == 0 and d.collision_log == []
        assert res.driven.shape[1] == 3 and res.duration_s > ROUTE_M / 0.6


def test_drift_moves_the_odometry_away_from_the_truth(spec):
    errors = []
    for seed in (3, 3):
        w, _, res = drive(spec, OdometryDrift(wheel_scale_std=0.03, slip_std=0.05, seed=seed))
        with w:
            errors.append(w.driver.read_odometry().distance_to(w.driver.true_pose()))
            assert res.reached  # the follower trusts its odometry: it "reaches" the goal
    w, _, _ = drive(spec)
    with w:
        exact = w.driver.read_odometry().distance_to(w.driver.true_pose())
    assert errors[0] == errors[1]  # seeded
    assert errors[0] > exact + 0.05


def test_collisions_are_counted_and_named(spec):
    with RoomWorld(spec, renderer="tiny") as w:
        d = w.driver
        turn_to(d, 0.0)
        # straight east from the start runs into the work table (x from 1.85 m at y 0.6-1.6)
        r = follow_path(d, [[3.2, 0.7]], FollowConfig(timeout_s=10.0))
        assert d.collisions >= 1
        assert d.collision_log[0].other == "work_table"
        assert d.true_pose().x < 1.85
        assert r.reason in ("timeout", "reached")


def test_the_wheels_carry_the_base_in_any_start_pose():
    """With four rigid contacts the solver once left the wheels unloaded (spinning in place) in
    some start poses; the casters are compliant so the wheels always carry the weight."""
    import pybullet as pb

    from tabletop.sim.room import generate_room

    with RoomWorld(generate_room(0), renderer="tiny") as w:
        loads = {}
        for link in ("left_wheel", "right_wheel", "front_caster", "rear_caster"):
            contacts = pb.getContactPoints(
                bodyA=w.robot_id, linkIndexA=w._link_index[link], physicsClientId=w._client
            )
            loads[link] = sum(c[9] for c in contacts)
        weight = 14.5 * 9.81
        assert loads["left_wheel"] + loads["right_wheel"] > 0.9 * weight
        assert math.degrees(math.acos(w.T_world_base()[2, 2])) < 0.2  # hardly tilted
        r = turn_to(w.driver, w.driver.true_pose().yaw + 2.5)
        assert r.reached and r.duration_s < 6.0

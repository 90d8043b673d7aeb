"""The robot API on a short scan's oracle map: queries, spatial targets, the simulated arm and
the kinematic mobile base."""

import numpy as np
import pytest
from robot_helpers import box_distance, scan_and_map

from tabletop.errors import ConfigError, TabletopError
from tabletop.eval.suites import RELATION_WORDS
from tabletop.eval.tasks import RELATIONS as TASK_RELATIONS
from tabletop.eval.truth import relation_point
from tabletop.language.codegen import plan_to_code
from tabletop.mapping import Heatmap
from tabletop.mapping.targets import surface_z
from tabletop.reader.plan import Above, Between, Side
from tabletop.reader.reading import understand
from tabletop.relations import RELATIONS, relation, relation_by_side
from tabletop.robot import (
    GoalNotFound,
    ImageGoalUnavailable,
    MobileBase,
    RobotAPI,
    SimArm,
    SpatialConfig,
)
from tabletop.robot.primitives import motion_to, primitive


class PointRobot(RobotAPI):
    """An embodiment that only records where it was sent."""

    def __init__(self, avlmap, pos=(0.3, 0.0, 0.2), spatial=None):
        super().__init__(avlmap, spatial)
        self.pos = np.array(pos, float)
        self.sent = []

    def move_to(self, pos):
        self.sent.append(np.array(pos, float))
        self.pos = np.array(pos, float)
        return self.pos

    def current_position(self):
        return self.pos.copy()


@pytest.fixture(scope="module")
def rec_map():
    return scan_and_map()


@pytest.fixture(scope="module")
def gt(rec_map):
    return {o["name"]: o for o in rec_map[0].ground_truth["objects"]}


@pytest.fixture(scope="module")
def arm(rec_map):
    a = SimArm(rec_map[1], "default")
    yield a
    a.close()


def test_spatial_targets_are_on_the_right_side(rec_map, gt):
    robot = PointRobot(rec_map[1])
    mug = gt["red_mug"]
    lo, hi = np.array(mug["aabb_min"]), np.array(mug["aabb_max"])
    c = robot.get_pos("red mug")
    assert box_distance(c, mug) == 0.0  # the centre is inside the mug's box
    left, right = robot.left_of("red mug"), robot.right_of("red mug")
    front, back = robot.in_front_of("red mug"), robot.behind("red mug")
    assert left[1] > hi[1] and lo[0] <= left[0] <= hi[0]  # left = +y
    assert right[1] < lo[1] and lo[0] <= right[0] <= hi[0]  # right = -y
    assert front[0] > hi[0] and lo[1] <= front[1] <= hi[1]  # front = +x, away from the robot
    assert back[0] < lo[0] and lo[1] <= back[1] <= hi[1]
    np.testing.assert_allclose(np.linalg.norm((left - c)[:2]), 0.10, atol=1e-9)  # default offset
    assert left[2] == pytest.approx(hi[2], abs=0.011)  # level with the mug's top
    # A large object: the target clears its extent by side_gap.
    tray = gt["tray"]
    assert robot.left_of("tray")[1] >= tray["aabb_max"][1] + 0.02
    # between: the midpoint of the two objects
    mid = (np.add(mug["center"], gt["blue_mug"]["center"])) / 2
    assert np.linalg.norm(robot.between("red mug", "blue mug")[:2] - mid[:2]) <= 0.02
    # configurable offset
    far = PointRobot(rec_map[1], spatial=SpatialConfig(side_offset=0.2))
    np.testing.assert_allclose((far.left_of("red mug") - c)[:2], [0, 0.2], atol=1e-9)


def test_between_lies_on_the_surface_midway_not_between_the_heights(rec_map, gt):
    """A place heard where an object stands is high; the midpoint between it and an object's
    centre is put on what is midway (the table here), not left floating between the two."""
    avlmap = rec_map[1]
    robot = PointRobot(avlmap)
    tall = max(gt.values(), key=lambda o: o["aabb_max"][2])
    # a one-column place on the tall object's top, as a sound heard there gives
    vals = np.zeros(avlmap.grid.shape, np.float32)
    idx, inside = avlmap.grid.world_to_index(np.array([tall["center"]]))
    assert inside[0]
    vals[idx[0, 0], idx[0, 1], :] = 1.0
    place = robot.get_major_map(obj="red mug").with_values(vals)
    place_pos = robot.get_pos(place)
    assert place_pos[2] > 0.04  # the place is up on the object, well above the table
    occ = avlmap.voxels.occupancy()
    checked = 0
    for o in gt.values():
        if o["name"] == tall["name"]:
            continue
        q = o["name"].replace("_", " ")
        b = robot.between(place, q)
        naive = (place_pos + robot.get_pos(q)) / 2
        assert np.linalg.norm(b[:2] - naive[:2]) < 1e-9
        assert b[2] == pytest.approx(surface_z(avlmap.grid, occ, b[:2]))  # what stands there
        if b[2] <= 0.03:  # the table or the tray midway: low, below the mean of the heights
            assert b[2] < naive[2] - 0.01, (o["name"], b, naive)
            checked += 1
    assert checked >= 2


def test_compass_moves_are_relative_to_the_current_position(rec_map):
    robot = PointRobot(rec_map[1], pos=(0.3, 0.0, 0.2))
    robot.move_north(0.1)
    robot.move_west(0.05)
    robot.move_south(0.02)
    robot.move_east(0.15)
    np.testing.assert_allclose(
        robot.sent, [[0.4, 0, 0.2], [0.4, 0.05, 0.2], [0.38, 0.05, 0.2], [0.38, -0.1, 0.2]]
    )
    robot.move_to_left("red mug")
    np.testing.assert_allclose(robot.sent[-1], robot.left_of("red mug"))
    with pytest.raises(ConfigError, match="finite"):
        robot.move_north(float("nan"))


def test_a_relative_move_is_held_to_the_compass_moves_limit(rec_map):
    from tabletop.robot.api import PrimitiveArgumentError

    robot = PointRobot(rec_map[1], pos=(0.3, 0.0, 0.2))
    np.testing.assert_allclose(robot.offset(0.6, 0.8), [0.9, 0.8, 0.2])  # 1 m: the limit
    for dx, dy in [(100.0, 0.0), (0.0, -100.0), (0.8, 0.8)]:
        too_far = r"offset\(dx=\.\.\., dy=\.\.\.\): .* at most 1 m"
        with pytest.raises(PrimitiveArgumentError, match=too_far):
            robot.offset(dx, dy)
    assert robot.sent == []


def test_boolean_parameters_take_true_or_false_only(rec_map):
    from tabletop.reader.reading import get_reader

    avlmap = rec_map[1]
    area = get_reader().reference("area", "the left side of the table")
    img = np.zeros((240, 320, 3), np.uint8)
    calls = {
        "object_heatmap": lambda v: avlmap.object_heatmap("mug", major=v),
        "sound_heatmap": lambda v: avlmap.sound_heatmap("a dog barking", major=v),
        "area_heatmap": lambda v: avlmap.area_heatmap(area, major=v),
        "image_heatmap": lambda v: avlmap.image_heatmap(img, major=v),
        "query": lambda v: avlmap.query("obj", "mug", major=v),
    }
    for name, call in calls.items():
        for bad in ("yes", "no", 1, 0, None, [True]):
            takes = rf"{name}\(major=...\): major takes True or False"
            with pytest.raises(ConfigError, match=takes):
                call(bad)
    avlmap.object_heatmap("mug", major=np.bool_(False))  # numpy's booleans are booleans
    for bad in ("no", 0):
        takes = r"SimArm\(other_scene=...\): other_scene takes True or False"
        with pytest.raises(ConfigError, match=takes):
            SimArm(avlmap, "default", other_scene=bad)


def test_a_duplicated_category_near_a_sound_picks_the_right_instance(rec_map, gt):
    rec, avlmap = rec_map
    robot = PointRobot(avlmap)
    events = rec.ground_truth["sound_events"]
    cats = [e["category"] for e in events]
    unique = [e for e in events if cats.count(e["category"]) == 1]
    assert unique
    checked = 0
    for kind in ("mug", "duck"):
        instances = [o for o in gt.values() if o["kind"] == kind]
        for e in unique:
            sound_xy = np.array(e["table_point"][:2])
            d = [np.hypot(*(np.array(o["center"][:2]) - sound_xy)) for o in instances]
            nearest = instances[int(np.argmin(d))]
            if sorted(d)[1] - sorted(d)[0] < 0.15:
                continue  # not a clear case
            # one call: obj sharp, sound broad ...
            p = robot.get_max_pos_3d(robot.get_major_map(obj=kind, sound=e["caption"]))
            assert box_distance(p, nearest) <= 0.02, (kind, e["caption"], p)
            # ... equals the paper's product of a major and an auxiliary map
            fused = robot.get_major_map(obj=kind) * robot.get_map(sound=e["caption"])
            np.testing.assert_allclose(robot.get_max_pos_3d(fused), p, atol=1e-9)
            checked += 1
    assert checked >= 1
    # the last query's parts are kept, with their confidence
    robot.get_major_map(obj="mug", sound=unique[0]["caption"])
    assert [h.modality for h in robot.last_heatmaps] == ["object", "sound"]


def test_heatmap_values_and_argument_errors(rec_map, tmp_path):
    robot = PointRobot(rec_map[1])
    h = robot.get_major_map(obj="red mug")
    assert isinstance(h, Heatmap) and h.found and h.grid == rec_map[1].grid
    assert h.values.dtype == np.float32 and h.values.shape == h.grid.shape
    assert 0.0 <= h.values.min() and h.peak == pytest.approx(1.0)
    broad = robot.get_map(obj="red mug")
    assert (broad.values > 0).sum() > (h.values > 0).sum()  # auxiliary decay is broader
    with pytest.raises(ConfigError, match="at least one"):
        robot.get_major_map()
    with pytest.raises(ConfigError, match="primary"):
        robot.get_major_map(obj="mug", primary="sound")
    zero = Heatmap.not_found(h.grid, "nothing", "object", 10.0, "no match")
    with pytest.raises(GoalNotFound, match="no match"):
        robot.get_max_pos_3d(zero)
    with pytest.raises(GoalNotFound, match="zero everywhere"):
        robot.get_max_pos_3d(h.with_values(np.zeros_like(h.values)))
    # a raw array is not a query result: it is refused, not treated as found
    with pytest.raises(ConfigError, match="expected a heatmap"):
        robot.get_max_pos_3d(h.values)
    # the product of two heatmaps is the fused heatmap, and its target is the map's
    fused = h * robot.get_map(obj="blue mug")
    assert fused.modality == "fused" and len(fused.parts) == 2
    # load_image reads RGB (not BGR); img= needs the visual localization module
    import cv2

    img = np.zeros((8, 10, 3), np.uint8)
    img[..., 0] = 200  # red
    cv2.imwrite(str(tmp_path / "q.png"), img[:, :, ::-1])
    got = robot.load_image(tmp_path / "q.png")
    np.testing.assert_array_equal(got, img)
    with pytest.raises(ConfigError, match="does not exist"):
        robot.load_image(tmp_path / "missing.png")
    if rec_map[1].visual is None:
        with pytest.raises(ImageGoalUnavailable, match="visual localization"):
            robot.get_major_map(img=tmp_path / "q.png")


def test_unknown_object_raises_and_nothing_moves(arm):
    arm.reset()
    tcp, n = arm.current_position(), len(arm.history)
    with pytest.raises(GoalNotFound, match="laptop") as e:
        arm.move_to_object("a laptop computer")
    assert isinstance(e.value, TabletopError) and e.value.reason
    with pytest.raises(GoalNotFound):
        arm.move_in_between("red mug", "a laptop computer")
    assert len(arm.history) == n
    np.testing.assert_allclose(arm.current_position(), tcp, atol=1e-9)


@pytest.mark.parametrize(
    "query, name", [("red mug", "red_mug"), ("yellow duck", "yellow_duck"), ("tray", "tray")]
)
def test_sim_arm_reaches_object_goals_without_contact(arm, gt, query, name):
    arm.reset()
    r = arm.move_to_object(query)
    assert r.reached, r.reason
    assert box_distance(r.final_tcp, gt[name]) <= 0.10
    assert arm.contacts[-1] == 0
    assert arm.history[-1] is r


def test_sim_arm_spatial_primitive_without_contact(arm, gt):
    arm.reset()
    r = arm.move_to_left("red mug")
    assert r.reached, r.reason
    assert r.final_tcp[1] > gt["red_mug"]["aabb_max"][1]
    r = arm.move_north(0.05)
    assert r.reached, r.reason
    assert arm.contacts[-2:] == [0, 0]


def test_a_point_beside_a_tall_object_is_approached_within_the_success_radius(arm, gt):
    """On the table 3 cm from the teddy bear (12 cm tall): clearing the highest surface in the
    gripper's disc would put the TCP 4 cm over the bear, 16 cm from the point; the arm goes
    4 cm over the table instead, with the bear an obstacle, and ends within the goal radius
    of the point without touching anything."""
    bear = gt["brown_teddy_bear"]
    point = np.array(
        [bear["aabb_max"][0] + 0.03, (bear["aabb_min"][1] + bear["aabb_max"][1]) / 2, 0]
    )
    goal, ref = arm.approach_goal(point)
    np.testing.assert_allclose(ref, point, atol=0.011)  # nothing stands there: the table top
    np.testing.assert_allclose(goal, ref + np.array([0, 0, arm.spatial.above_gap]), atol=1e-9)
    # the highest surface within the gripper's radius is the bear's top
    assert arm.approach_radius > 0.03
    arm.reset()
    r = arm.move_to(point)
    assert r.reached, r.reason
    assert np.linalg.norm(r.final_tcp - point) <= arm.controller.config.goal_radius + 0.005
    assert arm.contacts[-1] == 0
    # on an object, the reference is its top: the goal stays above_gap over it
    lego = gt["red_lego_brick"]
    centre = (np.array(lego["aabb_min"]) + np.array(lego["aabb_max"])) / 2
    goal, ref = arm.approach_goal(centre)
    assert abs(ref[2] - lego["aabb_max"][2]) <= 0.015 and goal[2] >= ref[2] + 0.039


def test_mobile_base_plans_around_obstacles(rec_map, gt):
    base = MobileBase(rec_map[1], start=(0.30, 0.0))
    tray = gt["tray"]
    # The straight line to the far side of the tray crosses it; the path goes around.
    r = base.move_to([0.76, 0.0, 0.0])
    assert r.reached and r.reason == "reached"
    np.testing.assert_allclose(r.final_position, [0.76, 0.0, 0.0])
    assert r.length_m > 0.46 + 0.1
    lo, hi = np.array(tray["aabb_min"][:2]), np.array(tray["aabb_max"][:2])
    inside = np.all((r.path[:, :2] >= lo) & (r.path[:, :2] <= hi), axis=1)
    assert not inside.any()
    cells = np.array([base.blocked.to_cell(p)[0] for p in r.path[1:-1]])
    assert not base.blocked.occupied[cells[:, 0], cells[:, 1]].any()
    # An object goal ends beside the object; the same API, another embodiment.
    r = base.move_to_object("red mug")
    assert r.reached and r.goal_shifted
    assert box_distance(np.r_[r.final_position[:2], 0.05], gt["red_mug"]) <= 0.10
    with pytest.raises(GoalNotFound):
        base.move_to_object("a laptop computer")
    r = base.move_to([2.0, 0.0, 0.0])
    assert not r.reached and r.reason == "outside_map"


def test_move_to_refuses_what_is_not_a_point(arm):
    n = len(arm.history)
    for bad in (["a", "b", "c"], [1.0, 2.0], [0.0, float("nan"), 0.0], None):
        with pytest.raises(ConfigError, match="finite 3-vector"):
            arm.move_to(bad)
    assert len(arm.history) == n  # nothing moved


@pytest.mark.parametrize("rel", [r.name for r in RELATIONS])
def test_a_relation_is_declared_once_and_every_layer_agrees(rec_map, gt, rel):
    """One spec per relation (tabletop.relations): the robot API's target and motion
    primitives, the evaluation's truth point, task files' landmark count, code generation, the
    suites' wording and the reader's plan all follow it."""
    r = relation(rel)
    names = ["red mug", "blue mug"][: r.landmarks]
    # robot API: a target primitive named as the relation, and a motion declared to move there
    target = primitive(rel)
    assert target.kind == "target" and len(target.params) == r.landmarks
    assert motion_to(rel).target == rel
    robot = PointRobot(rec_map[1])
    point = getattr(robot, rel)(*names)
    # the evaluation's truth: the same point from the landmarks' boxes
    anchors = []
    for n in names:
        c, lo, hi = robot._landmark(n)
        anchors.append((c, (hi - lo) / 2))
    truth = relation_point(rel, anchors, robot.spatial)
    np.testing.assert_allclose(point[:2], truth[:2], atol=1e-9)
    if r.axis is not None:  # a side: beyond the landmark's box along the axis
        mug = gt["red_mug"]
        lo, hi = np.array(mug["aabb_min"]), np.array(mug["aabb_max"])
        axis = np.array(r.axis)
        assert (point - robot.get_pos("red mug")) @ axis > np.abs(axis) @ (hi - lo) / 2
    # task files take exactly its landmarks
    assert TASK_RELATIONS[rel] == r.landmarks
    # the suites' wording, read by the default reader, is the plan that calls its motion
    text = (
        f"go {r.wording} the red mug and the blue mug"
        if r.landmarks == 2
        else f"go {r.wording} the red mug"
    )
    (step,) = understand(text).steps
    action = step.action
    want = {"between": Between, "above": Above}.get(rel, Side)
    assert isinstance(action, want)
    if r.side is not None:
        assert action.side == r.side and relation_by_side(action.side) is r
    if rel != "above":  # above an object is the object's own motion (move_to_object)
        assert f"robot.{motion_to(rel).name}(" in plan_to_code((step,))
    if rel != "above":
        assert RELATION_WORDS[rel] == r.wording


def test_an_unknown_relation_or_side_is_named_with_the_valid_ones():
    with pytest.raises(ConfigError, match="valid: .*left_of"):
        relation("next_to")
    with pytest.raises(ConfigError, match="valid: .*front"):
        relation_by_side("up")

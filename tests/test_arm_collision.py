"""Convex-hull collision checking: clearances, filtered pairs, motions refused before contact."""

import numpy as np
import pybullet as pb
import pytest

from tabletop.arm.bench import cluttered_scene
from tabletop.arm.collision import CollisionChecker
from tabletop.arm.ik import solve_ik
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, table_box
from tabletop.errors import ConfigError
from tabletop.transforms import make_transform


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def checker(model):
    return CollisionChecker(model, [table_box()])


def test_home_is_clear_of_table_and_itself(checker):
    c = checker.clearance(HOME_Q)
    assert c.environment == pytest.approx(checker.max_distance)  # table far below the hand
    assert 0.03 < c.self_distance < checker.max_distance
    assert c.distance == min(c.environment, c.self_distance)


def test_adjacent_and_rigid_pairs_are_filtered(checker):
    names = {
        frozenset((checker.link_names[i], checker.link_names[j])) for i, j in checker.self_pairs
    }
    assert frozenset(("panda_link6", "panda_link7")) not in names
    assert frozenset(("panda_hand", "panda_leftfinger")) not in names
    assert frozenset(("panda_link1", "panda_hand")) in names


def test_clearance_matches_a_box_just_below_the_fingers(model):
    T = model.fk(HOME_Q)
    # The fingertips end ~7 mm beyond the TCP; a box top 3 cm below the TCP.
    box = Box(T[:3, 3] - [0, 0, 0.03 + 0.05], [0.05, 0.05, 0.05], name="below")
    ch = CollisionChecker(model, [box], self_collision=False)
    c = ch.clearance(HOME_Q)
    assert c.closest_pair[1] == "below"
    assert 0.015 < c.environment < 0.03


def test_penetration_is_negative(model):
    T = model.fk(HOME_Q)
    # 12 cm wide: wider than the open fingers (8 cm apart), so both fingers sink into it.
    ch = CollisionChecker(model, [Box(T[:3, 3], [0.06, 0.06, 0.03], name="inside")])
    c = ch.clearance(HOME_Q)
    assert c.environment < 0
    assert c.closest_pair[1] == "inside"


def test_hull_distance_agrees_with_pybullet_hulls(model):
    # PyBullet also collides with the convex hull of each OBJ mesh.
    from tabletop.paths import panda_urdf_path

    cid = pb.connect(pb.DIRECT)
    try:
        robot = pb.loadURDF(str(panda_urdf_path()), useFixedBase=True, physicsClientId=cid)
        box = Box([0.55, 0.05, 0.05], [0.05, 0.05, 0.05], name="b")
        col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=cid)
        body = pb.createMultiBody(0, col, -1, box.center.tolist(), physicsClientId=cid)
        ch = CollisionChecker(model, [box], self_collision=False, max_distance=0.3)
        rng = np.random.default_rng(5)
        for _ in range(10):
            p = rng.uniform([0.45, -0.05, 0.14], [0.65, 0.15, 0.25])
            q = solve_ik(model, make_transform(np.diag([1.0, -1.0, -1.0]), p), HOME_Q).q
            for j in range(7):
                pb.resetJointState(robot, j, float(q[j]), physicsClientId=cid)
            for j in (9, 10):
                pb.resetJointState(robot, j, 0.04, physicsClientId=cid)
            d_pb = min(c[8] for c in pb.getClosestPoints(robot, body, 0.3, physicsClientId=cid))
            # PyBullet pads its hulls with a ~4 mm collision margin.
            assert abs(ch.clearance(q).environment - d_pb) < 0.006
    finally:
        pb.disconnect(cid)


def test_motion_into_a_box_is_refused_before_contact(model):
    T = model.fk(HOME_Q)
    box = Box(T[:3, 3] - [0, 0, 0.12], [0.05, 0.05, 0.05], name="obstacle")  # top 7 cm below
    ch = CollisionChecker(model, [box])
    q_down = solve_ik(model, make_transform(T[:3, :3], T[:3, 3] - [0, 0, 0.09]), HOME_Q).q
    assert ch.clearance(q_down).environment < 0  # the end configuration penetrates
    mc = ch.check_motion(HOME_Q, q_down, margin=0.01)
    assert not mc.ok and mc.swept_lower_bound < 0.01
    # A small step away from the box is fine.
    q_up = solve_ik(model, make_transform(T[:3, :3], T[:3, 3] + [0, 0, 0.01]), HOME_Q).q
    assert ch.check_motion(HOME_Q, q_up, margin=0.01).ok


def test_displacement_bound_covers_the_real_motion(model, checker):
    rng = np.random.default_rng(0)
    for _ in range(20):
        q0 = model.random_q(rng, margin=0.2)
        q1 = q0 + rng.normal(0, 0.02, 7)
        moved = np.linalg.norm(model.fk(q1)[:3, 3] - model.fk(q0)[:3, 3])
        assert moved <= checker.max_displacement(q0, q1)


def test_invalid_arguments(model):
    with pytest.raises(ConfigError, match="max_distance must be positive"):
        CollisionChecker(model, max_distance=0.0)
    with pytest.raises(ConfigError, match="unsupported obstacle type str"):
        CollisionChecker(model, ["table"])
    ch = CollisionChecker(model, [table_box()])
    for bad in (np.array([*HOME_Q[:6], np.nan]), np.array([*HOME_Q[:6], np.inf]), HOME_Q[:6]):
        with pytest.raises(ConfigError, match="non-finite|shape"):
            ch.clearance(bad)
    # a float64 array that is not (7,), another dtype, a list: the same answers as before
    q32 = HOME_Q.astype(np.float32)
    assert ch.clearance(q32) == ch.clearance_all_pairs(q32)
    assert ch.clearance(HOME_Q.tolist()) == ch.clearance_all_pairs(HOME_Q)


def _both_queries(ch, q):
    """(every pair's clearance, narrow calls of the pruned query, of every pair's), asserting
    that the pruned query gives the same clearance."""
    n0 = ch.narrow_queries
    fast = ch.clearance(q)
    n1 = ch.narrow_queries
    slow = ch.clearance_all_pairs(q)
    assert fast == slow
    return slow, n1 - n0, ch.narrow_queries - n1


def test_pruned_query_matches_every_pair_on_random_configurations(model):
    # Spatial bounds: random configurations, far apart, many of them inside the table or
    # an object (penetrations deeper than a link's bounding sphere must not be pruned).
    ch = CollisionChecker(model, cluttered_scene(np.random.default_rng(0), 6))
    rng = np.random.default_rng(1)
    pruned = every = negative = 0
    for _ in range(150):
        slow, n_fast, n_every = _both_queries(ch, model.random_q(rng))
        pruned, every = pruned + n_fast, every + n_every
        negative += slow.distance < 0
    assert negative > 10
    assert pruned < every / 4


def test_pruned_query_matches_every_pair_along_small_motions(model):
    # Temporal bounds: walks of small steps (as the controller makes), near the table and the
    # objects, through contact and out again.
    obstacles = cluttered_scene(np.random.default_rng(0), 6)
    ch = CollisionChecker(model, obstacles)
    temporal = [0]
    bounds = ch._temporal_bounds

    def counted_bounds(q):
        b = bounds(q)
        temporal[0] += b is not None
        return b

    ch._temporal_bounds = counted_bounds
    rng = np.random.default_rng(2)
    pruned = every = near = 0
    for start in ([0.45, 0.0, 0.05], [0.6, -0.2, 0.12], [0.35, 0.3, 0.02]):
        q = solve_ik(model, make_transform(np.diag([1.0, -1.0, -1.0]), start), HOME_Q).q
        for _ in range(200):
            q = model.clip(q + rng.normal(0.0, 0.003, 7))
            slow, n_fast, n_every = _both_queries(ch, q)
            pruned, every = pruned + n_fast, every + n_every
            near += slow.environment < ch.max_distance
    assert temporal[0] > 500  # of 600: the bounds carried over from the previous query
    assert near > 100
    assert pruned < every / 4


def test_set_obstacles_forgets_the_previous_query(model):
    ch = CollisionChecker(model, [table_box()])
    q = HOME_Q.copy()
    ch.clearance(q)
    T = model.fk(q)
    ch.set_obstacles([table_box(), Box(T[:3, 3] - [0, 0, 0.05], [0.05, 0.05, 0.02], name="new")])
    assert ch.clearance(q) == ch.clearance_all_pairs(q)
    assert ch.clearance(q).closest_pair[1] == "new"


def test_self_collision_can_be_switched_between_queries(model):
    ch = CollisionChecker(model, [table_box()])
    q = HOME_Q.copy()
    assert ch.clearance(q).self_distance < ch.max_distance
    ch.self_collision = False
    q = q + 0.001
    off = ch.clearance(q)
    assert off.self_distance == ch.max_distance and off == ch.clearance_all_pairs(q)
    ch.self_collision = True
    q = q + 0.001
    on = ch.clearance(q)
    assert on.self_distance < ch.max_distance and on == ch.clearance_all_pairs(q)


def test_hulls_placed_on_their_joint_are_where_the_urdf_puts_them(model):
    # The hand's and the fingers' hulls are stored in joint 7's frame; the same distances as
    # the mesh-frame hulls moved by the URDF's placement (to FCL's GJK precision).
    import fcl
    import pinocchio as pin

    from tabletop.arm.collision import _fcl_convex

    box = Box([0.5, 0.0, 0.1], [0.05, 0.05, 0.05], name="b")
    ch = CollisionChecker(model, [box], max_distance=1.0)
    ob = ch._obs_objs[0]
    data = model.model.createData()
    rng = np.random.default_rng(3)
    placed = [i for i, lk in enumerate(ch._links) if lk.name in ("panda_hand", "panda_leftfinger")]
    worst = 0.0
    for _ in range(30):
        q = model.random_q(rng)
        pin.forwardKinematics(model.model, data, q)
        for i in placed:
            lk = ch._links[i]
            M = data.oMi[lk.joint] * lk.placement
            ref = fcl.CollisionObject(
                _fcl_convex(*ch.hull(lk.name)), fcl.Transform(M.rotation, M.translation)
            )
            want = fcl.distance(ref, ob, ch._req, fcl.DistanceResult())
            got = ch._distance(ch._set_tf(i, data.oMi, set()), ob)
            worst = max(worst, abs(got - want))
    assert worst < 1e-3

"""The mink controller: convergence, velocity limits, collision-avoidance limits."""

import numpy as np
import pytest

from tabletop.arm.bench import cluttered_scene
from tabletop.arm.collision import CollisionChecker
from tabletop.arm.diffik import DiffIKConfig, MinkDiffIK, top_down_rotation
from tabletop.arm.ik import solve_ik
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, obstacle_aabb, table_box
from tabletop.errors import ConfigError
from tabletop.transforms import make_transform

BOX = Box([0.5, 0.0, 0.06], [0.04, 0.04, 0.06], name="box")


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def ik(model):
    return MinkDiffIK(model, [table_box(), BOX])


def test_top_down_rotation_points_the_tcp_down():
    R = top_down_rotation(0.3)
    np.testing.assert_allclose(R[:, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


def test_steps_converge_with_decreasing_error_and_bounded_velocity(model, ik):
    q = HOME_Q.copy()
    T = make_transform(top_down_rotation(0.0), [0.45, -0.25, 0.2])
    errs = []
    for _ in range(300):
        st = ik.step(q, T)
        assert st.solved
        v = (st.q - q) / ik.config.dt
        assert np.all(np.abs(v) <= model.v_max * ik.config.velocity_scale + 1e-3)
        q = st.q
        errs.append(np.linalg.norm(model.fk(q)[:3, 3] - T[:3, 3]))
    assert errs[-1] < 1e-3
    assert errs[50] < errs[0] and errs[150] < errs[50]
    assert model.within_limits(q)


def test_collision_limit_keeps_the_hand_above_a_box(model, ik):
    # Target inside the box: the QP must stop the fingers above its top.
    checker = CollisionChecker(model, [table_box(), BOX])
    q = HOME_Q.copy()
    T = make_transform(top_down_rotation(0.0), [0.5, 0.0, 0.06])
    for _ in range(400):
        q = ik.step(q, T).q
    assert checker.clearance(q).environment > 0.01
    assert model.fk(q)[2, 3] > 0.12


def test_config_is_validated():
    with pytest.raises(ConfigError, match=r"velocity_scale must be in \(0, 1\]"):
        DiffIKConfig(velocity_scale=2.0)
    with pytest.raises(ConfigError, match="collision_min_distance < collision_detection"):
        DiffIKConfig(collision_min_distance=0.2, collision_detection_distance=0.1)


def test_fast_step_matches_mink_solve_ik(model):
    # The QP assembled and solved in step() (box bounds, pruned collision rows, unconstrained /
    # warm / daqp) against mink.solve_ik on the same problem, along moves that hit the
    # velocity limits, the joint limits and the collision rows.
    scene = cluttered_scene(np.random.default_rng(0), 6)
    fast, ref = MinkDiffIK(model, scene), MinkDiffIK(model, scene)
    rng = np.random.default_rng(4)
    moves = []  # (start q, target point)
    for ob in scene[1:]:
        # onto each object from 15 cm above it: the collision rows bind, on the way down (with
        # the velocity limits) and at the end (alone: the TCP 2 cm above the top is too close)
        p = np.array([*ob.center[:2], obstacle_aabb(ob)[1][2] + 0.02])
        R = top_down_rotation(float(np.arctan2(p[1], p[0])))
        above = make_transform(R, p + np.array([0.0, 0.0, 0.15]))
        moves.append((solve_ik(model, above, HOME_Q).q, p, 150))
    # to points in the open and on until the error is small: velocity limits, then none bind
    moves += [(HOME_Q, rng.uniform([0.3, -0.3, 0.1], [0.6, 0.3, 0.35]), 250) for _ in range(2)]
    moves.append((HOME_Q, np.array([0.9, 0.6, 0.9]), 100))  # out of reach: joint limits
    worst, steps, bound_rows = 0.0, 0, 0
    for q, p, n in moves:
        T = make_transform(top_down_rotation(float(np.arctan2(p[1], p[0]))), p)
        for _ in range(n):
            a, b = fast.step(q, T), ref.step_reference(q, T)
            assert a.solved == b.solved
            worst = max(worst, float(np.abs(a.q - b.q).max()))
            bound_rows += bool(fast._active and fast._active[2])
            q = a.q
            steps += 1
    assert worst < 1e-9
    assert bound_rows > 50  # steps whose solution had a collision row tight
    paths = fast.qp_paths
    assert paths["unconstrained"] > 0 and paths["warm"] > 0 and paths["daqp"] > 0
    assert sum(paths.values()) == steps and ref.qp_paths["mink"] == steps


def test_step_checks_the_target_pose_like_as_transform(model, ik):
    T = make_transform(top_down_rotation(0.0), [0.45, 0.0, 0.2])
    assert ik.step(HOME_Q, T.tolist()).solved  # a nested list goes through as_transform
    off_last_row = T.copy()
    off_last_row[3, 0] = 1e-6
    bad = [
        ("rotation block is not a proper rotation", T @ np.diag([1.0, 1.0, 1.0 + 1e-3, 1.0])),
        ("rotation block is not a proper rotation", T @ np.diag([-1.0, 1.0, 1.0, 1.0])),
        ("last row must be", off_last_row),
        ("non-finite", np.where(np.eye(4, dtype=bool), np.nan, T)),
        ("must be a \\(4, 4\\)", T[:3]),
    ]
    for message, pose in bad:
        with pytest.raises(ConfigError, match=message):
            ik.step(HOME_Q, pose)
    # within as_transform's tolerances: accepted, as before
    assert ik.step(HOME_Q, T @ np.diag([1.0, 1.0, 1.0 + 4e-6, 1.0])).solved
    # a pose with the rotation of the step before skips the rotation checks, not the others
    assert ik.step(HOME_Q, T).solved
    for message, change in [
        ("non-finite", (0, 3, np.nan)),
        ("non-finite", (2, 3, np.inf)),
        ("last row must be", (3, 2, 1e-6)),
        ("last row must be", (3, 3, 1.0 + 1e-3)),
    ]:
        pose = T.copy()
        pose[change[:2]] = change[2]
        with pytest.raises(ConfigError, match=message):
            ik.step(HOME_Q, pose)
    with pytest.raises(ConfigError, match="non-finite"):
        ik.step(np.array([*HOME_Q[:6], np.nan]), T)
    # the target follows the pose: each step as from a controller that saw no pose before
    T2 = make_transform(top_down_rotation(0.5), [0.45, 0.05, 0.2])
    q = HOME_Q.copy()
    for pose in [T, T, T2, T2, T, T2]:
        fresh = MinkDiffIK(model, ik.obstacles).step(q, pose).q
        step = ik.step(q, pose).q
        np.testing.assert_allclose(step, fresh, rtol=0, atol=1e-12)  # (warm starts differ)
        q = step


def test_collision_rows_match_minks(model):
    # The pairs the broad phase keeps give exactly the rows of mink's CollisionAvoidanceLimit
    # (which queries every pair its bounding spheres cannot rule out).
    ik = MinkDiffIK(model, cluttered_scene(np.random.default_rng(0), 6))
    limit = ik.limits[2]
    rng = np.random.default_rng(6)
    n_rows = 0
    for _ in range(300):
        q = model.random_q(rng)
        ik.configuration.update(q)
        _, _, G, h, rows = ik._constraints(q)
        ref = limit.compute_qp_inequalities(ik.configuration, ik.config.dt)
        kept = np.nonzero(np.isfinite(ref.h))[0]
        assert sorted(rows) == kept.tolist()
        if rows:
            order = np.argsort(rows)
            np.testing.assert_allclose(G[order], ref.G[kept], atol=1e-12)
            np.testing.assert_allclose(h[order], ref.h[kept], atol=1e-12)
        n_rows += len(rows)
    assert n_rows > 300

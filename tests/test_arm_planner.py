"""The global planner: certified edges, a path around a wall, typed failures."""

import itertools

import numpy as np
import pytest

from tabletop.arm.collision import CollisionChecker
from tabletop.arm.diffik import top_down_rotation
from tabletop.arm.ik import solve_ik
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, table_box
from tabletop.arm.planner import JointPlanner, PlannerConfig, PlanReason
from tabletop.arm.trajectory import PANDA_LIMITS, check_trajectory, time_parametrize
from tabletop.errors import ConfigError
from tabletop.transforms import make_transform

# A wall 30 cm tall across the table between the two goals: the arm must go over it.
WALL = Box([0.5, 0.0, 0.15], [0.15, 0.01, 0.15], name="wall")
SCENE = [table_box(), WALL]


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def checker(model):
    return CollisionChecker(model, SCENE)


@pytest.fixture(scope="module")
def ends(model):
    out = []
    for y in (-0.2, 0.2):
        T = make_transform(top_down_rotation(float(np.arctan2(y, 0.5))), [0.5, y, 0.05])
        res = solve_ik(model, T, HOME_Q)
        assert res.success
        out.append(res.q)
    return out


def _dense_clearance(checker, path, per_segment=40):
    """Smallest clearance over many configurations along the path (an independent check)."""
    worst = np.inf
    for a, b in itertools.pairwise(path):
        for s in np.linspace(0.0, 1.0, per_segment):
            worst = min(worst, checker.clearance(a + s * (b - a)).distance)
    return worst


def test_segment_clearance_is_a_lower_bound_of_the_sampled_clearance(model, checker):
    planner = JointPlanner(model, checker)
    rng = np.random.default_rng(1)
    certified = 0
    for _ in range(25):
        a = HOME_Q + rng.normal(0.0, 0.4, 7)
        b = a + rng.normal(0.0, 0.3, 7)
        a = np.clip(a, PANDA_LIMITS.q_lower, PANDA_LIMITS.q_upper)
        b = np.clip(b, PANDA_LIMITS.q_lower, PANDA_LIMITS.q_upper)
        bound = planner.segment_clearance(a, b)
        if bound >= planner.config.margin:
            certified += 1
            assert _dense_clearance(checker, [a, b], 30) >= bound - 1e-9
    assert certified >= 5  # the property was exercised


def test_plan_goes_around_the_wall_and_every_piece_keeps_the_margin(model, checker, ends):
    planner = JointPlanner(model, checker)
    qa, qb = ends
    assert planner.segment_clearance(qa, qb) < planner.config.margin  # straight line is blocked
    res = planner.plan(qa, qb)
    assert res.ok and res.reason == PlanReason.PLANNED
    np.testing.assert_array_equal(res.path[0], qa)
    np.testing.assert_array_equal(res.path[-1], qb)
    assert len(res.path) >= 3 and len(res.path) <= res.raw_waypoints
    assert res.min_clearance_m >= planner.config.margin
    assert _dense_clearance(checker, res.path) >= planner.config.margin
    # The TCP goes over the wall on the way.
    tops = [model.fk(q)[2, 3] for q in res.path]
    assert max(tops) > 0.30
    assert res.planning_time_s < 10.0 and res.clearance_queries > 0
    traj = time_parametrize(res.path)
    assert check_trajectory(traj).ok
    # Reproducible: the same seed gives the same path.
    again = JointPlanner(model, checker).plan(qa, qb)
    np.testing.assert_array_equal(again.path, res.path)


def test_failures_are_typed(model, checker, ends):
    planner = JointPlanner(model, checker)
    qa, qb = ends
    low = np.array([0.0, 1.7, 0.0, -0.2, 0.0, 2.0, 0.8])  # the hand under the table top
    assert planner.plan(low, qb).reason == PlanReason.START_IN_COLLISION
    assert planner.plan(qa, low).reason == PlanReason.GOAL_IN_COLLISION
    outside = HOME_Q.copy()
    outside[3] = -0.03  # inside the URDF's limit, outside the Panda's published one
    res = planner.plan(outside, qb)
    assert res.reason == PlanReason.OUTSIDE_LIMITS and not res.ok and res.path is None
    tight = JointPlanner(model, checker, PlannerConfig(max_iterations=1, step=0.05))
    res = tight.plan(qa, qb)
    assert res.reason == PlanReason.NO_PATH and res.iterations == 1
    with pytest.raises(ConfigError, match="PlannerConfig.step must be positive"):
        PlannerConfig(step=0.0)
    with pytest.raises(ConfigError, match="PlannerConfig.max_iterations must be >= 1"):
        PlannerConfig(max_iterations=0)

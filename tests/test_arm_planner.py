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


def _slot(model, q, margin):
    """Two walls either side of the hand at ``q``, as close as the clearance ``margin`` (plus
    a hair) allows: the hand sits in a slot on the margin, where a reach that pushed into it
    would have stalled."""
    T = model.fk(q)
    opening = T[:3, 1] / np.linalg.norm(T[:2, 1])  # the fingers' axis, horizontal
    k = int(np.argmax(np.abs(opening[:2])))

    def walls(w):
        out = [table_box()]
        for s in (1.0, -1.0):
            c = np.array([T[0, 3], T[1, 3], 0.06]) + s * (w + 0.01) * opening
            half = [0.1, 0.1, 0.06]
            half[k] = 0.01
            out.append(Box(c.tolist(), half, name=f"slot{s:+.0f}"))
        return out

    lo, hi = 0.0, 0.3
    for _ in range(40):
        w = (lo + hi) / 2
        if CollisionChecker(model, walls(w)).clearance(q).distance >= margin + 2e-5:
            hi = w
        else:
            lo = w
    return CollisionChecker(model, walls(hi))


def test_an_end_on_the_margin_is_moved_off_it_first(model, ends):
    """From a configuration on the margin no tree step certifies (the swept bound of every step
    is below the margin), so the planner first moves the end off the margin along a short
    segment that keeps half its clearance, then plans from there."""
    qb = ends[1]
    m = PlannerConfig().margin
    q0 = solve_ik(
        model,
        make_transform(top_down_rotation(float(np.arctan2(-0.2, 0.5))), [0.5, -0.2, 0.06]),
        HOME_Q,
    ).q
    slot = _slot(model, q0, m)
    c0 = slot.clearance(q0).distance
    assert m <= c0 < m + 1e-3
    stuck = JointPlanner(model, slot, PlannerConfig(escape_band=0.0, max_time_s=2.0))
    assert stuck.plan(q0, qb).reason == PlanReason.NO_PATH
    res = JointPlanner(model, slot).plan(q0, qb)
    assert res.ok, res.reason
    np.testing.assert_array_equal(res.path[0], q0)
    np.testing.assert_array_equal(res.path[-1], qb)
    assert slot.clearance(res.path[1]).distance >= m + PlannerConfig().escape_band
    assert res.min_clearance_m >= 0.5 * c0
    assert _dense_clearance(slot, res.path[:2]) >= 0.5 * c0
    assert _dense_clearance(slot, res.path[1:]) >= m
    assert check_trajectory(time_parametrize(res.path)).ok
    # A goal on the margin likewise: the same query reversed.
    back = JointPlanner(model, slot).plan(qb, q0)
    assert back.ok and np.array_equal(back.path[-1], q0)
    assert _dense_clearance(slot, back.path[-2:]) >= 0.5 * c0


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
    with pytest.raises(ConfigError, match="PlannerConfig.escape_band must be >= 0"):
        PlannerConfig(escape_band=-0.01)
    with pytest.raises(ConfigError, match="PlannerConfig.step must be positive"):
        PlannerConfig(step=0.0)
    with pytest.raises(ConfigError, match="PlannerConfig.max_iterations must be >= 1"):
        PlannerConfig(max_iterations=0)

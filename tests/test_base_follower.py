"""The path follower on the kinematic driver (the physics driver: test_room_world.py)."""

import math

import numpy as np
import pytest

from tabletop.base import (
    TABLETOP_BASE,
    BasePose,
    FollowConfig,
    KinematicBaseDriver,
    PathError,
    follow_path,
    turn_to,
)
from tabletop.errors import ConfigError


@pytest.mark.parametrize(
    "path",
    [
        [[2.0, 0.0]],
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.5]],
        [[0.0, 0.0], [-1.0, 0.2], [-1.5, -1.0]],  # behind the start: turns in place first
    ],
)
def test_follower_reaches_the_last_waypoint(path):
    d = KinematicBaseDriver(TABLETOP_BASE)
    r = follow_path(d, path, final_yaw=0.5)
    assert r.reached and r.reason == "reached"
    assert np.hypot(*(d.true_pose().xy - path[-1])) <= FollowConfig().goal_tolerance
    assert abs(d.true_pose().yaw - 0.5) <= FollowConfig().yaw_tolerance
    assert r.driven.shape[1] == 3 and len(r.driven) > 10
    assert r.duration_s == pytest.approx(d.true_pose().t)
    # the base stays near the polyline (pure pursuit cuts corners by less than the lookahead)
    dense = np.concatenate(
        [np.linspace(a, b, 50) for a, b in zip([[0.0, 0.0], *path[:-1]], path, strict=True)]
    )
    dist = np.linalg.norm(r.driven[:, None, :2] - dense[None], axis=2).min(axis=1)
    assert dist.max() < FollowConfig().lookahead


def test_speed_limits_hold():
    d = KinematicBaseDriver(TABLETOP_BASE)
    c = FollowConfig(max_linear=0.3, max_angular=0.8, control_dt=0.1)
    r = follow_path(d, [[3.0, 0.0], [3.0, 2.0]], c)
    steps = np.diff(r.driven, axis=0)
    speed = np.linalg.norm(steps[:, :2], axis=1) / c.control_dt
    turn = np.abs((steps[:, 2] + np.pi) % (2 * np.pi) - np.pi) / c.control_dt
    assert r.reached and speed.max() <= 0.3 + 1e-9 and turn.max() <= 0.8 + 1e-9


def test_turn_to_and_stop_and_timeout():
    d = KinematicBaseDriver(TABLETOP_BASE, BasePose(0.0, 0.0, 3.0))
    r = turn_to(d, -3.0)  # the short way, through pi
    assert r.reached and abs(d.true_pose().yaw + 3.0) < 0.05
    assert np.allclose(d.true_pose().xy, 0.0)
    seen = []
    r = follow_path(d, [[2.0, 0.0]], on_step=lambda p: seen.append(p) or len(seen) < 5)
    assert not r.reached and r.reason == "stopped" and len(seen) == 5
    r = follow_path(d, [[20.0, 0.0]], FollowConfig(timeout_s=1.0))
    assert not r.reached and r.reason == "timeout" and r.duration_s == pytest.approx(1.0)


def test_bad_input_is_named():
    d = KinematicBaseDriver(TABLETOP_BASE)
    with pytest.raises(PathError, match=r"shape \(K, 2\)"):
        follow_path(d, [[1.0, 2.0, 3.0]])
    with pytest.raises(PathError, match=r"path_xy\[1\] is not finite"):
        follow_path(d, [[1.0, 2.0], [math.nan, 0.0]])
    with pytest.raises(ConfigError, match="final_yaw must be a finite angle"):
        follow_path(d, [[1.0, 2.0]], final_yaw=math.inf)
    with pytest.raises(ConfigError, match="FollowConfig.lookahead must be > 0"):
        FollowConfig(lookahead=0.0)
    with pytest.raises(ConfigError, match="min_linear .* must not exceed max_linear"):
        FollowConfig(min_linear=1.0, max_linear=0.5)

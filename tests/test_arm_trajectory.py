"""Time-parametrised trajectories: limits and continuity on every sample, straight segments."""

import numpy as np
import pytest

from tabletop.arm.driver import KinematicDriver
from tabletop.arm.errors import DriverError
from tabletop.arm.model import HOME_Q
from tabletop.arm.trajectory import (
    PANDA_LIMITS,
    JointLimits,
    JointTrajectory,
    TrajectoryConfig,
    check_trajectory,
    time_parametrize,
)
from tabletop.errors import ConfigError

CFG = TrajectoryConfig()
USED = PANDA_LIMITS.scaled(CFG.velocity_scale, CFG.acceleration_scale, CFG.jerk_scale)


def _random_paths(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    lo, hi = PANDA_LIMITS.q_lower + 0.05, PANDA_LIMITS.q_upper - 0.05
    for _ in range(n):
        m = int(rng.integers(2, 6))
        yield np.clip(HOME_Q + rng.normal(0.0, 0.6, (m, 7)), lo, hi)


def _assert_every_sample_within(traj: JointTrajectory, lim: JointLimits, slack: float = 1e-6):
    """Independent of check_trajectory: the limits and continuity, sample by sample."""
    h = traj.period
    assert np.all(traj.q >= lim.q_lower) and np.all(traj.q <= lim.q_upper)
    assert np.all(np.abs(traj.dq) <= lim.v_max * (1 + slack))
    assert np.all(np.abs(traj.ddq) <= lim.a_max * (1 + slack))
    jerk = np.diff(traj.ddq, axis=0) / h
    assert np.all(np.abs(jerk) <= lim.j_max * (1 + slack))
    # Continuity: no sample jumps further than the velocity (acceleration) limit allows.
    assert np.all(np.abs(np.diff(traj.q, axis=0)) <= lim.v_max * h * (1 + slack))
    assert np.all(np.abs(np.diff(traj.dq, axis=0)) <= lim.a_max * h * (1 + slack))
    # Velocity is the derivative of position (trapezoid rule over each period).
    fd = np.diff(traj.q, axis=0) / h
    mid = (traj.dq[1:] + traj.dq[:-1]) / 2
    assert np.abs(fd - mid).max() <= 0.01 * lim.v_max.max()
    np.testing.assert_array_equal(traj.dq[[0, -1]], 0.0)
    np.testing.assert_array_equal(traj.ddq[[0, -1]], 0.0)


def test_every_sample_keeps_the_configured_and_published_limits():
    worst = 0.0
    for path in _random_paths(15):
        traj = time_parametrize(path)
        _assert_every_sample_within(traj, USED)
        _assert_every_sample_within(traj, PANDA_LIMITS)
        check = check_trajectory(traj, USED)
        assert check.ok, check.violations
        worst = max(worst, check.velocity_ratio, check.acceleration_ratio, check.jerk_ratio)
        np.testing.assert_allclose(traj.q[0], path[0])
        np.testing.assert_allclose(traj.q[-1], path[-1])
        assert traj.duration == pytest.approx((len(traj) - 1) * CFG.period)
    # Time-optimal within the scaled limits: some limit is reached, not left far below.
    assert worst > 0.99


def test_segments_are_straight_and_every_waypoint_is_a_sample():
    a = HOME_Q
    b = HOME_Q + np.array([0.5, 0.3, -0.2, 0.4, 0.1, -0.3, 0.6])
    c = HOME_Q + 0.1
    traj = time_parametrize([a, b, b, c])  # the repeated waypoint is dropped
    assert len(traj.waypoints) == 3
    hits = [int(np.argmin(np.abs(traj.q - w).max(axis=1))) for w in traj.waypoints]
    for w, k in zip(traj.waypoints, hits, strict=True):
        np.testing.assert_array_equal(traj.q[k], w)
        np.testing.assert_array_equal(traj.dq[k], 0.0)  # at rest at every waypoint
    for (p, q), (k0, k1) in zip([(a, b), (b, c)], [hits[:2], hits[1:]], strict=True):
        seg = traj.q[k0 : k1 + 1]
        u = q - p
        s = (seg - p) @ u / (u @ u)
        assert np.abs(seg - p - np.outer(s, u)).max() < 1e-9  # on the segment
        assert np.all(np.diff(s) >= -1e-12)  # monotone, no overshoot
        assert s.min() >= -1e-12 and s.max() <= 1 + 1e-12


def test_check_trajectory_names_the_broken_limit_joint_and_sample():
    traj = time_parametrize([HOME_Q, HOME_Q + 0.3])
    q = traj.q.copy()
    q[40, 2] += 0.01  # a 0.01 rad jump at one sample of joint 3
    bad = JointTrajectory(traj.period, q, traj.dq, traj.ddq, traj.waypoints)
    check = check_trajectory(bad)
    assert not check.ok
    assert any("position step of joint 3 at sample" in v for v in check.violations)
    ddq = traj.ddq.copy()
    ddq[100, 5] = 25.0  # above joint 6's 20 rad/s^2
    check = check_trajectory(JointTrajectory(traj.period, traj.q, traj.dq, ddq, traj.waypoints))
    assert any("acceleration of joint 6 at sample 100" in v for v in check.violations)
    assert any("jerk of joint 6" in v for v in check.violations)
    fast = time_parametrize(
        [HOME_Q, HOME_Q + 0.5], config=TrajectoryConfig(velocity_scale=1, acceleration_scale=1)
    )
    assert check_trajectory(fast).ok
    assert not check_trajectory(fast, USED).ok  # too fast for the scaled limits


def test_bad_input_is_a_typed_error_naming_the_field():
    out = HOME_Q.copy()
    out[3] = 0.0  # joint 4 must stay below -0.0698 rad
    with pytest.raises(ConfigError, match=r"waypoint 1: joint 4 = 0.0000 rad outside"):
        time_parametrize([HOME_Q, out])
    with pytest.raises(ConfigError, match=r"path must be \(M, 7\)"):
        time_parametrize(np.zeros((3, 6)))
    with pytest.raises(ConfigError, match="TrajectoryConfig.jerk_scale must be in"):
        TrajectoryConfig(jerk_scale=0.0)
    with pytest.raises(ConfigError, match="velocity scale must be in"):
        PANDA_LIMITS.scaled(1.5, 1, 1)
    single = time_parametrize([HOME_Q])
    assert len(single) == 1 and single.duration == 0.0


def test_kinematic_driver_records_and_lands_on_the_last_sample():
    traj = time_parametrize([HOME_Q, HOME_Q + 0.2])
    d = KinematicDriver(HOME_Q)
    d.execute_trajectory(traj)
    assert d.trajectories == [traj]
    np.testing.assert_array_equal(d.read_state().q, traj.q[-1])
    assert d.read_state().time_s == pytest.approx(traj.duration)
    with pytest.raises(
        DriverError, match=r"starts 0.2000 rad from the arm.s configuration \(allowed 0.01"
    ):
        d.execute_trajectory(traj)  # the arm is at the end now

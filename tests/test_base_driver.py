"""The kinematic base driver: ideal motion, wheel odometry, seeded drift."""

import math

import numpy as np
import pytest

from tabletop.base import (
    TABLETOP_BASE,
    BaseDriver,
    BasePose,
    KinematicBaseDriver,
    OdometryDrift,
    WheelOdometry,
)
from tabletop.errors import ConfigError

#: Turn rate [rad/s] of the wheels at -4, +4 rad/s.
W4 = 2 * TABLETOP_BASE.wheel_radius * 4.0 / TABLETOP_BASE.wheel_separation


def drive_square(driver):
    for _ in range(4):
        driver.command_wheels(8.0, 8.0, 2.5)  # 1 m straight
        driver.command_wheels(-4.0, 4.0, math.pi / 2 / W4)  # quarter turn


def test_kinematic_driver_moves_exactly_and_its_odometry_agrees():
    d = KinematicBaseDriver(TABLETOP_BASE, BasePose(1.0, 1.0, 0.0))
    assert isinstance(d, BaseDriver)
    drive_square(d)
    assert d.true_pose().as_array() == pytest.approx([1.0, 1.0, 0.0], abs=1e-9)
    assert d.read_odometry().as_array() == pytest.approx(d.true_pose().as_array(), abs=1e-9)
    assert d.read_odometry().t == pytest.approx(4 * 2.5 + 4 * math.pi / 2 / W4)


def test_wheel_speeds_saturate_at_the_limit():
    d = KinematicBaseDriver(TABLETOP_BASE)
    d.command_wheels(100.0, 50.0, 0.1)
    assert d.wheel_speeds == pytest.approx((12.0, 6.0))
    with pytest.raises(ConfigError, match="duration must be > 0"):
        d.command_wheels(1.0, 1.0, 0.0)
    with pytest.raises(ConfigError, match="left must be a finite number"):
        d.command_wheels(float("nan"), 1.0, 0.1)


def test_drift_is_seeded_and_moves_the_odometry_away():
    poses = []
    for seed in (0, 0, 1):
        drift = OdometryDrift(wheel_scale_std=0.02, slip_std=0.05, seed=seed)
        d = KinematicBaseDriver(TABLETOP_BASE, drift=drift)
        drive_square(d)
        err = d.read_odometry().distance_to(d.true_pose())
        assert err > 0.01  # 4 m of driving with 2 % wheel error: centimetres off
        poses.append(d.read_odometry().as_array())
    assert np.array_equal(poses[0], poses[1])
    assert not np.allclose(poses[0], poses[2])
    with pytest.raises(ConfigError, match="slip_std must be in"):
        OdometryDrift(slip_std=-0.1)


def test_wheel_odometry_integrates_increments_as_arcs():
    odo = WheelOdometry(TABLETOP_BASE, BasePose(0.0, 0.0, 0.0), (5.0, 5.0))
    p = odo.update(5.0 + 20.0, 5.0 + 20.0, 1.0)  # 20 rad * 5 cm = 1 m straight
    assert p.as_array() == pytest.approx([1.0, 0.0, 0.0])
    # each wheel's angle for a quarter turn in place
    turn = math.pi / 2 * (TABLETOP_BASE.wheel_separation / 2) / TABLETOP_BASE.wheel_radius
    p = odo.update(25.0 - turn, 25.0 + turn, 2.0)
    assert p.as_array() == pytest.approx([1.0, 0.0, math.pi / 2])

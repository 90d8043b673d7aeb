"""Differential-drive kinematics: twist <-> wheels, limits, exact arc integration."""

import math

import numpy as np
import pytest

from tabletop.base import (
    BasePose,
    DiffDriveParams,
    integrate,
    limit_wheels,
    twist_from_wheels,
    wheels_from_twist,
)
from tabletop.errors import ConfigError

P = DiffDriveParams(wheel_radius=0.05, wheel_separation=0.3, max_wheel_speed=10.0, radius=0.2)


def test_twist_and_wheels_are_inverse():
    rng = np.random.default_rng(0)
    for v, w in rng.uniform(-1, 1, (20, 2)):
        left, right = wheels_from_twist(P, v, w)
        assert np.allclose(twist_from_wheels(P, left, right), (v, w))
    assert wheels_from_twist(P, 0.5, 0.0) == (10.0, 10.0)
    left, right = wheels_from_twist(P, 0.0, 1.0)  # turning left: the right wheel forward
    assert right == -left > 0


def test_limits_keep_the_curvature():
    left, right = limit_wheels(P, 30.0, 15.0)
    assert max(abs(left), abs(right)) == pytest.approx(10.0)
    assert left / right == pytest.approx(2.0)
    assert limit_wheels(P, 3.0, -4.0) == (3.0, -4.0)
    assert P.max_linear_speed == pytest.approx(0.5)
    assert P.max_angular_speed == pytest.approx(2 * 0.5 / 0.3)


def test_integration_is_exact_on_arcs_and_lines():
    p = integrate(BasePose(1.0, 2.0, 0.3), 0.4, 0.0, 2.5)
    assert (p.x, p.y, p.yaw, p.t) == pytest.approx((1 + math.cos(0.3), 2 + math.sin(0.3), 0.3, 2.5))
    # a full circle of radius v / w comes back to the start
    v, w = 0.3, 0.6
    p = integrate(BasePose(0.0, 0.0, 0.0), v, w, 2 * math.pi / w)
    assert (p.x, p.y) == pytest.approx((0.0, 0.0), abs=1e-12)
    # a quarter circle: from (0, 0) facing +x to (R, R) facing +y
    p = integrate(BasePose(0.0, 0.0, 0.0), v, w, math.pi / 2 / w)
    assert (p.x, p.y, p.yaw) == pytest.approx((v / w, v / w, math.pi / 2))
    # many small steps agree with one big one
    q = BasePose(0.0, 0.0, 0.0)
    for _ in range(100):
        q = integrate(q, v, w, math.pi / 2 / w / 100)
    assert q.as_array() == pytest.approx(p.as_array())


def test_pose_matrix_round_trips_and_wraps_yaw():
    p = BasePose(1.0, -2.0, 3.0 * math.pi)
    assert -math.pi <= p.yaw < math.pi
    T = p.as_matrix()
    assert T[2, 3] == 0.0 and np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3))
    assert BasePose.from_matrix(T).as_array() == pytest.approx(p.as_array())


@pytest.mark.parametrize(
    "field, value, needle",
    [
        ("wheel_radius", 0.0, "wheel_radius must be > 0"),
        ("wheel_separation", float("nan"), "wheel_separation must be a finite"),
        ("max_wheel_speed", "fast", "max_wheel_speed must be a finite"),
        ("radius", 0.1, "radius .* must hold the wheels"),
    ],
)
def test_bad_params_name_the_field(field, value, needle):
    kw = dict(wheel_radius=0.05, wheel_separation=0.3, max_wheel_speed=10.0, radius=0.2)
    with pytest.raises(ConfigError, match=needle):
        DiffDriveParams(**{**kw, field: value})
    with pytest.raises(ConfigError, match="dt must be >= 0"):
        integrate(BasePose(0, 0, 0), 1.0, 0.0, -1.0)
    with pytest.raises(ConfigError, match="BasePose.yaw must be finite"):
        BasePose(0.0, 0.0, float("inf"))

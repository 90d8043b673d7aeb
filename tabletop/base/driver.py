"""Base drivers: what the path follower talks to, simulated or real, behind one protocol.

A driver reports the base's odometry (its own pose estimate, as a real base's wheel encoders
give it), holds wheel angular velocities for a duration of (simulated) time, and stops.
Here: :class:`KinematicBaseDriver`, an ideal unicycle for planning and tests; the physics
driver lives in :mod:`tabletop.sim.room_world` (``PyBulletBaseDriver``).
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

from tabletop.base.kinematics import DiffDriveParams, integrate, limit_wheels, twist_from_wheels
from tabletop.base.odometry import OdometryDrift, WheelOdometry
from tabletop.base.pose import BasePose
from tabletop.errors import ConfigError

__all__ = ["BaseDriver", "BasePose", "KinematicBaseDriver", "check_command"]


def check_command(
    params: DiffDriveParams, left: float, right: float, duration: float
) -> tuple[float, float, float]:
    """Validated (left, right, duration): finite wheel speeds [rad/s] saturated at
    ``params.max_wheel_speed`` (curvature kept), a positive finite duration [s]."""
    for name, v in (("left", left), ("right", right), ("duration", duration)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"wheel command {name} must be a finite number, got {v!r}")
    if duration <= 0:
        raise ConfigError(f"wheel command duration must be > 0 [s], got {duration}")
    left, right = limit_wheels(params, left, right)
    return left, right, float(duration)


@runtime_checkable
class BaseDriver(Protocol):
    """What the path follower needs from a wheeled base, simulated or real."""

    params: DiffDriveParams

    def read_odometry(self) -> BasePose:
        """The base's own pose estimate (wheel odometry), time-stamped on the driver clock."""
        ...

    def command_wheels(self, left: float, right: float, duration: float) -> None:
        """Hold wheel angular velocities (left, right) [rad/s] for ``duration`` [s] of
        (simulated) time, then return. Speeds beyond ``params.max_wheel_speed`` are scaled
        down together."""
        ...

    def stop(self) -> None:
        """Bring the wheels to rest."""
        ...


class KinematicBaseDriver(BaseDriver):
    """An ideal unicycle: the commanded wheel speeds happen exactly (exact arc integration).

    Its odometry equals the true pose unless ``drift`` is given; then the wheel angles are
    read through :class:`OdometryDrift`'s errors, integrated in ``odometry_dt`` steps.

    Args:
        params: the base's geometry and limits.
        start: the initial (true and estimated) pose.
        drift: odometry errors (None: exact odometry).
        odometry_dt: step [s] at which the odometry reads the wheels.
    """

    def __init__(
        self,
        params: DiffDriveParams,
        start: BasePose | None = None,
        *,
        drift: OdometryDrift | None = None,
        odometry_dt: float = 0.01,
    ) -> None:
        if not (isinstance(odometry_dt, (int, float)) and 0 < odometry_dt <= 1.0):
            raise ConfigError(f"odometry_dt must be in (0, 1] s, got {odometry_dt!r}")
        self.params = params
        self._true = start or BasePose(0.0, 0.0, 0.0)
        self._wheels = [0.0, 0.0]  # wheel angles [rad]
        self._odometry = WheelOdometry(params, self._true, (0.0, 0.0), drift)
        self._odometry_dt = float(odometry_dt)
        self.wheel_speeds = (0.0, 0.0)
        """The last commanded (left, right) [rad/s], after saturation."""

    @property
    def time(self) -> float:
        """The driver clock [s]."""
        return self._true.t

    @property
    def wheel_angles(self) -> tuple[float, float]:
        """(left, right) accumulated wheel angles [rad]."""
        return self._wheels[0], self._wheels[1]

    def true_pose(self) -> BasePose:
        """Where the base really is."""
        return self._true

    def read_odometry(self) -> BasePose:
        return self._odometry.pose

    def command_wheels(self, left: float, right: float, duration: float) -> None:
        left, right, duration = check_command(self.params, left, right, duration)
        self.wheel_speeds = (left, right)
        v, w = twist_from_wheels(self.params, left, right)
        n = max(1, math.ceil(duration / self._odometry_dt - 1e-9))
        dt = duration / n
        for _ in range(n):
            self._true = integrate(self._true, v, w, dt)
            self._wheels[0] += left * dt
            self._wheels[1] += right * dt
            self._odometry.update(self._wheels[0], self._wheels[1], self._true.t)

    def stop(self) -> None:
        self.wheel_speeds = (0.0, 0.0)

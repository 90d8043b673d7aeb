"""Wheel odometry: the base's own pose estimate, integrated from its wheel angles.

A real base counts encoder ticks; :class:`WheelOdometry` takes the wheel angles [rad] it
reads and integrates each increment as an arc. :class:`OdometryDrift` models what makes
odometry drift on a real floor: a wheel radius that is not quite the nominal one (each wheel
off by a fixed fraction, drawn once) and slip (a random fraction of every increment lost or
gained), both seeded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tabletop.base.kinematics import DiffDriveParams, integrate, twist_from_wheels
from tabletop.base.pose import BasePose
from tabletop.errors import ConfigError

__all__ = ["OdometryDrift", "WheelOdometry"]


@dataclass(frozen=True)
class OdometryDrift:
    """How wrong the odometry is (0 everywhere = exact)."""

    wheel_scale_std: float = 0.0
    """Standard deviation of each wheel's fixed radius error, as a fraction (0.01 = 1 %):
    the odometry believes the nominal radius, the floor sees another."""
    slip_std: float = 0.0
    """Standard deviation of the random fraction of each wheel increment that slips [1]."""
    seed: int = 0
    """Seed of both draws."""

    def __post_init__(self) -> None:
        for name in ("wheel_scale_std", "slip_std"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 0.5:
                raise ConfigError(f"OdometryDrift.{name} must be in [0, 0.5), got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"OdometryDrift.seed must be an integer >= 0, got {self.seed!r}")

    @property
    def any(self) -> bool:
        return self.wheel_scale_std > 0 or self.slip_std > 0


class WheelOdometry:
    """Integrates wheel angle readings [rad] into a :class:`BasePose`.

    Args:
        params: the base's nominal geometry (what the odometry believes).
        start: the pose at the first reading.
        wheel_angles: (left, right) [rad] at ``start``.
        drift: errors to add to every increment (None: exact).
    """

    def __init__(
        self,
        params: DiffDriveParams,
        start: BasePose,
        wheel_angles: tuple[float, float] = (0.0, 0.0),
        drift: OdometryDrift | None = None,
    ) -> None:
        self.params = params
        self.drift = drift or OdometryDrift()
        self._rng = np.random.default_rng([self.drift.seed, 7])
        self._scale = 1.0 + self._rng.normal(0.0, self.drift.wheel_scale_std, 2)
        self._pose = start
        self._last = (float(wheel_angles[0]), float(wheel_angles[1]))

    @property
    def pose(self) -> BasePose:
        """The current estimate."""
        return self._pose

    def update(self, left: float, right: float, t: float) -> BasePose:
        """Take a reading: wheel angles (left, right) [rad] at time ``t`` [s]."""
        if not (math.isfinite(left) and math.isfinite(right) and math.isfinite(t)):
            raise ConfigError(f"wheel readings must be finite, got {left}, {right} at t={t}")
        dl, dr = left - self._last[0], right - self._last[1]
        self._last = (float(left), float(right))
        if self.drift.any:
            slip = 1.0 + self._rng.normal(0.0, self.drift.slip_std, 2)
            dl, dr = dl * self._scale[0] * slip[0], dr * self._scale[1] * slip[1]
        # An increment over one reading is an arc: a twist held for a unit of time.
        v, w = twist_from_wheels(self.params, dl, dr)
        p = integrate(self._pose, v, w, 1.0)
        self._pose = BasePose(p.x, p.y, p.yaw, t)
        return self._pose

    def reset(self, pose: BasePose, wheel_angles: tuple[float, float]) -> None:
        """Set the estimate (e.g. from a localisation) at the given wheel angles [rad]."""
        self._pose = pose
        self._last = (float(wheel_angles[0]), float(wheel_angles[1]))

"""Differential-drive kinematics: wheel speeds and body twists, and exact arc integration.

A differential-drive base has two driven wheels on one axle. With wheel radius ``r``, wheel
separation ``L`` and wheel angular velocities ``left``, ``right`` [rad/s] (positive = rolling
forward), the body twist is ``v = r (left + right) / 2`` [m/s] forward and
``w = r (right - left) / L`` [rad/s] counter-clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tabletop.base.pose import BasePose
from tabletop.errors import ConfigError

__all__ = [
    "DiffDriveParams",
    "integrate",
    "limit_wheels",
    "twist_from_wheels",
    "wheels_from_twist",
]


def _number(v: object, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigError(f"{where} must be a finite number, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class DiffDriveParams:
    """The geometry and limits of a differential-drive base."""

    wheel_radius: float
    """Radius of the driven wheels [m]."""
    wheel_separation: float
    """Distance between the two wheels' contact points [m] (the track width)."""
    max_wheel_speed: float
    """Largest wheel angular velocity [rad/s] either way."""
    radius: float
    """Radius [m] of the disc that holds the whole base seen from above (its footprint):
    obstacles are inflated by it when planning."""

    def __post_init__(self) -> None:
        for name in ("wheel_radius", "wheel_separation", "max_wheel_speed", "radius"):
            v = _number(getattr(self, name), f"DiffDriveParams.{name}")
            if v <= 0:
                raise ConfigError(f"DiffDriveParams.{name} must be > 0, got {v}")
            object.__setattr__(self, name, v)
        if self.radius < self.wheel_separation / 2:
            raise ConfigError(
                f"DiffDriveParams.radius ({self.radius} m) must hold the wheels: at least half "
                f"the wheel_separation ({self.wheel_separation / 2} m)"
            )

    @property
    def max_linear_speed(self) -> float:
        """Top forward speed [m/s], both wheels at ``max_wheel_speed``."""
        return self.wheel_radius * self.max_wheel_speed

    @property
    def max_angular_speed(self) -> float:
        """Top turning rate [rad/s] in place, the wheels at ``max_wheel_speed`` in opposition."""
        return 2.0 * self.wheel_radius * self.max_wheel_speed / self.wheel_separation


def wheels_from_twist(params: DiffDriveParams, v: float, w: float) -> tuple[float, float]:
    """Wheel angular velocities (left, right) [rad/s] for a forward speed ``v`` [m/s] and a
    turn rate ``w`` [rad/s]. Not limited: see :func:`limit_wheels`."""
    v, w = _number(v, "v"), _number(w, "w")
    half = params.wheel_separation / 2
    return (v - w * half) / params.wheel_radius, (v + w * half) / params.wheel_radius


def twist_from_wheels(params: DiffDriveParams, left: float, right: float) -> tuple[float, float]:
    """Forward speed ``v`` [m/s] and turn rate ``w`` [rad/s] of wheel angular velocities
    (left, right) [rad/s]."""
    left, right = _number(left, "left"), _number(right, "right")
    r = params.wheel_radius
    return r * (left + right) / 2, r * (right - left) / params.wheel_separation


def limit_wheels(params: DiffDriveParams, left: float, right: float) -> tuple[float, float]:
    """Scale (left, right) [rad/s] down together so neither exceeds ``max_wheel_speed``: the
    path's curvature is kept, only the speed drops."""
    left, right = _number(left, "left"), _number(right, "right")
    peak = max(abs(left), abs(right))
    if peak <= params.max_wheel_speed:
        return left, right
    k = params.max_wheel_speed / peak
    return left * k, right * k


def integrate(pose: BasePose, v: float, w: float, dt: float) -> BasePose:
    """The pose after holding a constant twist (``v`` [m/s], ``w`` [rad/s]) for ``dt`` [s]:
    exact integration along the circular arc (a straight line when ``w`` is 0)."""
    v, w, dt = _number(v, "v"), _number(w, "w"), _number(dt, "dt")
    if dt < 0:
        raise ConfigError(f"dt must be >= 0 [s], got {dt}")
    dyaw = w * dt
    if abs(dyaw) < 1e-9:
        # second-order expansion about the straight line
        mid = pose.yaw + dyaw / 2
        dx, dy = v * dt * math.cos(mid), v * dt * math.sin(mid)
    else:
        R = v / w
        dx = R * (math.sin(pose.yaw + dyaw) - math.sin(pose.yaw))
        dy = -R * (math.cos(pose.yaw + dyaw) - math.cos(pose.yaw))
    return BasePose(pose.x + dx, pose.y + dy, pose.yaw + dyaw, pose.t + dt)

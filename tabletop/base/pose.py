"""The planar pose of a wheeled base on the floor, as a value."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["BasePose", "wrap_angle"]


def wrap_angle(a: float) -> float:
    """``a`` [rad] wrapped into [-pi, pi)."""
    return float((a + math.pi) % (2.0 * math.pi) - math.pi)


@dataclass(frozen=True)
class BasePose:
    """Where a base stands: the world (room) frame, z up, the floor at z = 0."""

    x: float
    """Position of the base frame's origin (between the wheels, on the floor) [m]."""
    y: float
    """[m]"""
    yaw: float
    """Heading [rad] about the world z axis, 0 = facing +x; kept in [-pi, pi)."""
    t: float = 0.0
    """Time [s] on the driver's clock (simulated time for simulators)."""

    def __post_init__(self) -> None:
        for name in ("x", "y", "yaw", "t"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ConfigError(f"BasePose.{name} must be a number, got {v!r}")
            if not math.isfinite(v):
                raise ConfigError(f"BasePose.{name} must be finite, got {v!r}")
            object.__setattr__(self, name, float(v))
        object.__setattr__(self, "yaw", wrap_angle(self.yaw))

    @property
    def xy(self) -> np.ndarray:
        """(2,) float64 [m] position."""
        return np.array([self.x, self.y])

    def as_array(self) -> np.ndarray:
        """(3,) float64: x [m], y [m], yaw [rad]."""
        return np.array([self.x, self.y, self.yaw])

    def as_matrix(self) -> np.ndarray:
        """(4, 4) float64 ``T_world_base``: the base frame on the floor (z = 0)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        T = np.eye(4)
        T[:2, :2] = [[c, -s], [s, c]]
        T[0, 3], T[1, 3] = self.x, self.y
        return T

    @classmethod
    def from_matrix(cls, T_world_base: np.ndarray, t: float = 0.0) -> BasePose:
        """The planar pose of a (4, 4) transform (its z and tilt are dropped)."""
        T = np.asarray(T_world_base, dtype=np.float64)
        if T.shape != (4, 4):
            raise ConfigError(f"T_world_base must be (4, 4), got shape {T.shape}")
        return cls(float(T[0, 3]), float(T[1, 3]), math.atan2(T[1, 0], T[0, 0]), t)

    def distance_to(self, other: BasePose) -> float:
        """Planar distance [m] between two poses."""
        return math.hypot(self.x - other.x, self.y - other.y)

"""The box in which the TCP may be commanded (world frame), shared by controller and drivers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["Workspace"]


@dataclass(frozen=True)
class Workspace:
    """An axis-aligned box of allowed TCP positions [m], world frame.

    The default covers the table (x in [-0.2, 0.8], y in [-0.6, 0.6]) from its top (z = 0) up
    to 0.8 m.
    """

    lower: tuple[float, float, float] = (-0.2, -0.6, 0.0)
    """(3,) lower corner [m]."""
    upper: tuple[float, float, float] = (0.8, 0.6, 0.8)
    """(3,) upper corner [m]."""

    def __post_init__(self) -> None:
        lo = np.asarray(self.lower, dtype=np.float64)
        hi = np.asarray(self.upper, dtype=np.float64)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(lo < hi):
            raise ConfigError(f"workspace needs lower < upper, 3 values each; got {lo}, {hi}")

    def contains(self, p: object, tol: float = 0.0) -> bool:
        """True when the point ``p`` (3,) [m] is inside the box grown by ``tol`` [m]."""
        p = np.asarray(p, dtype=np.float64)
        lo = np.asarray(self.lower) - tol
        hi = np.asarray(self.upper) + tol
        return bool(np.all(p >= lo) and np.all(p <= hi))

    def clip(self, p: object) -> np.ndarray:
        """The point ``p`` (3,) [m] clipped into the box."""
        return np.clip(np.asarray(p, dtype=np.float64), self.lower, self.upper)

"""The evaluation criterion: a reach succeeds when the TCP ends within 10 cm of the truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.arm.obstacles import Box
from tabletop.errors import ConfigError

__all__ = ["SUCCESS_RADIUS_M", "ReachSuccess", "distance_to_box", "reach_success"]

SUCCESS_RADIUS_M = 0.10  # [m], the paper's table-top goal-reaching criterion


@dataclass(frozen=True)
class ReachSuccess:
    """Distance from the final TCP to the ground truth, and whether it is within the radius."""

    success: bool
    distance_m: float  # [m]; 0 when the TCP is inside the ground-truth box
    threshold_m: float  # [m]


def distance_to_box(p: np.ndarray, box: Box) -> float:
    """Euclidean distance [m] from a point (3,) to an oriented box (0 inside)."""
    local = box.rotation.T @ (np.asarray(p, dtype=np.float64) - box.center)
    return float(np.linalg.norm(np.maximum(np.abs(local) - box.half_extents, 0.0)))


def reach_success(
    tcp: object,
    *,
    point: object | None = None,
    box: Box | None = None,
    threshold: float = SUCCESS_RADIUS_M,
) -> ReachSuccess:
    """Score a final TCP position (3,) [m] against a ground-truth point or box (world frame).

    Exactly one of ``point`` and ``box`` is given. Success when the distance <= ``threshold``.
    """
    p = np.asarray(tcp, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"tcp must be a finite (3,) point [m], got {np.asarray(tcp).tolist()}")
    if (point is None) == (box is None):
        raise ConfigError("give exactly one ground truth: point=... or box=...")
    if not threshold > 0:
        raise ConfigError(f"threshold must be positive [m], got {threshold}")
    if box is not None:
        d = distance_to_box(p, box)
    else:
        gt = np.asarray(point, dtype=np.float64)
        if gt.shape != (3,):
            raise ConfigError(f"point must have shape (3,), got {gt.shape}")
        d = float(np.linalg.norm(p - gt))
    return ReachSuccess(success=d <= threshold, distance_m=d, threshold_m=float(threshold))

"""Checks of the images and intrinsics that enter visual localization: malformed input raises
:class:`~tabletop.errors.ConfigError` naming what is wrong."""

from __future__ import annotations

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["check_rgb"]


def check_rgb(rgb: object, name: str = "rgb") -> np.ndarray:
    """``rgb`` as a contiguous (H, W, 3) uint8 array, or :class:`ConfigError` naming what is
    wrong."""
    if not isinstance(rgb, np.ndarray):
        raise ConfigError(f"{name} must be a numpy array (H, W, 3) uint8, got {type(rgb).__name__}")
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ConfigError(f"{name} must have shape (H, W, 3), got {rgb.shape}")
    if rgb.dtype != np.uint8:
        raise ConfigError(f"{name} must be uint8 (0..255), got dtype {rgb.dtype}")
    if rgb.shape[0] < 32 or rgb.shape[1] < 32:
        raise ConfigError(f"{name} is too small to localise: {rgb.shape[1]}x{rgb.shape[0]} px")
    return np.ascontiguousarray(rgb)


def _check_K(K: object) -> np.ndarray:
    given = K
    try:
        K = np.array(K, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"K must be a (3, 3) matrix of numbers, got {given!r:.80}") from None
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ConfigError(f"K must be a finite (3, 3) pinhole matrix with fx, fy > 0, got {K}")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]):
        raise ConfigError(f"K's last row must be [0, 0, 1], got {K[2].tolist()}")
    return K

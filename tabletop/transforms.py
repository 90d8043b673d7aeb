"""Rigid transforms as 4x4 float64 matrices.

Naming: ``T_a_b`` is the pose of frame b in frame a; it maps points in b to points in a, so
``T_a_c = T_a_b @ T_b_c``. Quaternions are ``(x, y, z, w)`` like PyBullet's.
"""

from __future__ import annotations

import numpy as np

from tabletop.errors import ConfigError

__all__ = [
    "aabb_distance",
    "as_transform",
    "backproject",
    "invert",
    "make_transform",
    "pixel_rays",
    "quat_from_matrix",
    "quat_to_matrix",
    "rotation_about",
    "transform_points",
]


def as_transform(T: object, name: str = "T") -> np.ndarray:
    """Validate a homogeneous transform; return a float64 (4, 4) copy."""
    arr = np.array(T, dtype=np.float64)
    if arr.shape != (4, 4):
        raise ConfigError(f"{name} must be a (4, 4) homogeneous transform, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} contains non-finite values")
    if not np.allclose(arr[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise ConfigError(f"{name} last row must be [0, 0, 0, 1], got {arr[3].tolist()}")
    R = arr[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
        raise ConfigError(f"{name} rotation block is not a proper rotation matrix")
    return arr


def make_transform(R: object | None = None, t: object | None = None) -> np.ndarray:
    """Build a (4, 4) transform from a (3, 3) rotation and a (3,) translation [m]."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = np.asarray(R, dtype=np.float64).reshape(3, 3)
    if t is not None:
        T[:3, 3] = np.asarray(t, dtype=np.float64).reshape(3)
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform (or a stack (..., 4, 4) of them)."""
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    Ti = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    Ti[..., :3, :3] = Rt
    Ti[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)
    Ti[..., 3, 3] = 1.0
    return Ti


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map (N, 3) points from frame b to frame a."""
    points_b = np.asarray(points_b, dtype=np.float64)
    return points_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def quat_to_matrix(q_xyzw: object) -> np.ndarray:
    """(3, 3) rotation from a unit quaternion (x, y, z, w)."""
    x, y, z, w = np.asarray(q_xyzw, dtype=np.float64) / np.linalg.norm(q_xyzw)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_from_matrix(R: object) -> np.ndarray:
    """Unit quaternion (x, y, z, w), w >= 0, of a (3, 3) rotation."""
    R = np.asarray(R, dtype=np.float64)
    tr = np.trace(R)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s]
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s, (R[1, 0] - R[0, 1]) / s]
    q = np.asarray(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def rotation_about(axis: str, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` [rad] about the x, y or z axis."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=np.float64)
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=np.float64)
    if axis == "z":
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=np.float64)
    raise ConfigError(f"unknown axis {axis!r}; valid: 'x', 'y', 'z'")


def aabb_distance(p: object, lo: object, hi: object) -> float:
    """Euclidean distance [m] from point ``p`` to the axis-aligned box ``[lo, hi]`` (0 inside)."""
    p = np.asarray(p, dtype=np.float64)
    return float(np.linalg.norm(np.maximum(np.subtract(lo, p), 0) + np.maximum(p - hi, 0)))


def pixel_rays(K: np.ndarray, T_world_cam: np.ndarray, u: object, v: object) -> np.ndarray:
    """(N, 3) unit world-frame directions of the rays through pixels ``(u, v)`` [px] of a
    pinhole camera with intrinsics ``K`` (3, 3) at ``T_world_cam`` (OpenCV optical frame)."""
    K = np.asarray(K, np.float64)
    u, v = np.ravel(u).astype(np.float64), np.ravel(v).astype(np.float64)
    d = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(len(u))], axis=1)
    d = d @ np.asarray(T_world_cam, np.float64)[:3, :3].T
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def backproject(depth: np.ndarray, K: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) points [m] in the camera frame from valid (> 0) depth pixels (and ``mask``)."""
    depth = np.asarray(depth)
    valid = depth > 0
    if mask is not None:
        valid &= mask
    v, u = np.nonzero(valid)
    z = depth[v, u].astype(np.float64)
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], axis=1)

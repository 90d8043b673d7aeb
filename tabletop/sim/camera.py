"""The wrist RGB-D camera: intrinsics, the hand-camera extrinsic, and OpenGL conversions.

Camera frame = OpenCV optical frame (x right, y down, z forward). PyBullet's view and
projection matrices are OpenGL (camera looks down -z, y up) and column-major; this module is
the one place that converts between the two. Pixel (u, v) = (column, row) with integer
coordinates at pixel centres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tabletop.errors import ConfigError
from tabletop.transforms import as_transform, invert, make_transform, rotation_about

__all__ = [
    "CameraIntrinsics",
    "WristCameraConfig",
    "default_T_hand_cam",
    "depth_from_gl_buffer",
    "gl_projection_matrix",
    "gl_view_matrix",
]

# OpenCV camera frame -> OpenGL camera frame (flip y and z).
_CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of an image of ``width`` x ``height`` pixels."""

    width: int
    height: int
    K: np.ndarray  # (3, 3) float64 [px], read-only

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ConfigError(f"image size must be positive, got {self.width}x{self.height}")
        K = np.array(self.K, dtype=np.float64)
        if K.shape != (3, 3) or K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
            raise ConfigError(
                f"K must be a (3, 3) pinhole matrix with fx, fy > 0, got {K.tolist()}"
            )
        K.setflags(write=False)
        object.__setattr__(self, "K", K)

    @classmethod
    def from_fov(cls, width: int, height: int, fov_y_deg: float) -> CameraIntrinsics:
        """Square pixels, principal point at the image centre, vertical field of view [deg]."""
        if not 1.0 < fov_y_deg < 170.0:
            raise ConfigError(f"fov_y_deg must be in (1, 170), got {fov_y_deg}")
        f = 0.5 * height / np.tan(np.deg2rad(fov_y_deg) / 2)
        K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
        return cls(width, height, K)

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])


def default_T_hand_cam() -> np.ndarray:
    """Calibrated pose of the wrist camera in ``panda_hand`` (a D405-like mount).

    The camera sits 6.5 cm off the hand's axis and 3 cm up, looking along the gripper
    (hand +z) with a small tilt toward the fingertips, and its image x along the hand's
    y axis (the finger opening). The small off-axis angles are deliberate: nothing may
    assume a trivial extrinsic.
    """
    R = rotation_about("z", np.pi / 2) @ rotation_about("x", np.deg2rad(-1.0))
    R = rotation_about("y", np.deg2rad(-8.0)) @ R
    T = make_transform(R, (0.065, 0.0, 0.03))
    T.setflags(write=False)
    return T


@dataclass(frozen=True)
class WristCameraConfig:
    """The wrist camera: image size, field of view, range, extrinsic, sensor model."""

    MIN_SIZE = (320, 240)
    """Smallest image (width, height) [px]: the maps' and the encoders' working resolution."""
    MAX_SIZE = (1920, 1440)
    """Largest image (width, height) [px], six times the smallest on each side: a frame's
    colour, depth and labels are then some 25 MB, and a scan holds all its frames in memory."""

    width: int = 320
    """Image width [px]."""
    height: int = 240
    """Image height [px]."""
    fov_y_deg: float = 58.0
    """Vertical field of view [deg]."""
    near: float = 0.07
    """Minimum valid depth [m]; nearer returns 0 (invalid), like a real stereo camera."""
    far: float = 3.0
    """Maximum valid depth [m]."""
    depth_resolution: float = 1e-4
    """Depth quantisation step [m] (0.1 mm); the recording stores depth in these units."""
    T_hand_cam: np.ndarray = field(default_factory=default_T_hand_cam)
    """(4, 4) pose of the camera optical frame in ``panda_hand``."""

    def __post_init__(self) -> None:
        (w_min, h_min), (w_max, h_max) = self.MIN_SIZE, self.MAX_SIZE
        if self.width < w_min or self.height < h_min:
            raise ConfigError(
                f"wrist camera needs at least {w_min}x{h_min} (width x height, at most "
                f"{w_max}x{h_max}), got {self.width}x{self.height}"
            )
        if self.width > w_max or self.height > h_max:
            raise ConfigError(
                f"wrist camera takes at most {w_max}x{h_max} (width x height, at least "
                f"{w_min}x{h_min}), got {self.width}x{self.height}"
            )
        if not 0 < self.near < self.far:
            raise ConfigError(f"need 0 < near < far [m], got near={self.near}, far={self.far}")
        if self.far / self.depth_resolution > 65535:
            raise ConfigError(
                f"far={self.far} m at depth_resolution={self.depth_resolution} m exceeds 16 bits"
            )
        T = as_transform(self.T_hand_cam, "T_hand_cam")
        T.setflags(write=False)
        object.__setattr__(self, "T_hand_cam", T)

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return CameraIntrinsics.from_fov(self.width, self.height, self.fov_y_deg)


def gl_view_matrix(T_world_cam: np.ndarray) -> list[float]:
    """PyBullet view matrix (column-major 16 floats) of an OpenCV camera pose."""
    T_cam_world_gl = invert(np.asarray(T_world_cam, dtype=np.float64) @ _CV_TO_GL)
    return T_cam_world_gl.flatten(order="F").tolist()


def gl_projection_matrix(intr: CameraIntrinsics, near: float, far: float) -> list[float]:
    """PyBullet projection matrix (column-major 16 floats) that reproduces ``K`` exactly."""
    W, H = intr.width, intr.height
    P = np.zeros((4, 4))
    P[0, 0] = 2 * intr.fx / W
    P[0, 2] = 1 - 2 * (intr.cx + 0.5) / W
    P[1, 1] = 2 * intr.fy / H
    P[1, 2] = 2 * (intr.cy + 0.5) / H - 1
    P[2, 2] = -(far + near) / (far - near)
    P[2, 3] = -2 * far * near / (far - near)
    P[3, 2] = -1.0
    return P.flatten(order="F").tolist()


def depth_from_gl_buffer(buffer: np.ndarray, near: float, far: float) -> np.ndarray:
    """Metric depth along the optical axis [m] from a non-linear depth buffer; 0 = invalid."""
    d = np.asarray(buffer, dtype=np.float64)
    z = far * near / (far - (far - near) * d)
    z[(d >= 1.0) | (z < near) | (z > far)] = 0.0
    return z

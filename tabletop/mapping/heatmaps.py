"""Heatmaps: dense float32 arrays in [0, 1] over the workspace grid, as in the paper.

Object module (3D, Euclidean):  H_o(p) = max(1 - eps * d_min(p), 0), d_min = distance from p to
the nearest target voxel, computed with a Euclidean distance transform (not an O(N*M) loop).
Area/audio modules (top-down):  H(p) = max(max_i (s_i - eps * d_xy(p, p_i)), 0).
Visual module:                  H_v(p) = max(1 - eps * d_xy(p, p_v), 0).
Fusion is the element-wise product; :func:`argmax_world` is ``get_max_pos_3d``.

Decay rates ``eps`` are in 1/m, so a heatmap means the same at any voxel size. Presets, tuned for
a tabletop: ``MAJOR_DECAY`` = 10 /m (heat reaches 0 at 10 cm: "where exactly"), and
``AUX_DECAY`` = 2.5 /m (0 at 40 cm: "near", a broad constraint). The paper used 2 /m and
0.2 /m for rooms (0.1 and 0.01 per 5 cm voxel).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError
from tabletop.mapping.grid import VoxelGrid

__all__ = [
    "AUX_DECAY",
    "MAJOR_DECAY",
    "argmax_world",
    "fuse",
    "point_heatmap_3d",
    "scored_points_heatmap_xy",
]

MAJOR_DECAY = 10.0  # [1/m]
AUX_DECAY = 2.5  # [1/m]


def _check_decay(decay: float) -> float:
    if not (np.isfinite(decay) and decay > 0):
        raise ConfigError(f"decay must be a positive rate in 1/m, got {decay}")
    return float(decay)


def point_heatmap_3d(grid: VoxelGrid, target_mask: np.ndarray, decay: float) -> np.ndarray:
    """H(p) = max(1 - decay * d_min(p), 0) with d_min the distance [m] to the nearest target
    voxel centre; ``target_mask`` is a boolean array of the grid's shape."""
    decay = _check_decay(decay)
    target_mask = np.asarray(target_mask, bool)
    if target_mask.shape != grid.shape:
        raise ConfigError(f"target mask {target_mask.shape} is not the grid's {grid.shape}")
    if not target_mask.any():
        return np.zeros(grid.shape, np.float32)
    # Only voxels within 1/decay of a target get heat: work in that sub-box.
    r = int(np.ceil(1.0 / decay / grid.voxel_size)) + 1
    idx = np.argwhere(target_mask)
    lo = np.maximum(idx.min(axis=0) - r, 0)
    hi = np.minimum(idx.max(axis=0) + r + 1, grid.shape)
    sub = ~target_mask[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    d = ndimage.distance_transform_edt(sub, sampling=grid.voxel_size)
    out = np.zeros(grid.shape, np.float32)
    out[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] = np.maximum(1.0 - decay * d, 0.0)
    return out


def scored_points_heatmap_xy(
    grid: VoxelGrid, points_xy: np.ndarray, scores: np.ndarray, decay: float
) -> np.ndarray:
    """H(p) = max(max_i (s_i - decay * d_xy(p, p_i)), 0), constant along z.

    ``points_xy`` (M, 2) [m], ``scores`` (M,) in [0, 1].
    """
    decay = _check_decay(decay)
    pts = np.asarray(points_xy, np.float64).reshape(-1, 2)
    s = np.asarray(scores, np.float64).reshape(-1)
    if len(pts) != len(s):
        raise ConfigError(f"{len(pts)} points but {len(s)} scores")
    xs, ys, _ = grid.axes()
    best = np.zeros((len(xs), len(ys)))
    # Points with a score that cannot beat the current floor anywhere are skipped; the rest
    # are applied in chunks, vectorised over the grid.
    order = np.argsort(-s)
    for start in range(0, len(order), 64):
        chunk = order[start : start + 64]
        chunk = chunk[s[chunk] > 0]
        if not len(chunk):
            break
        dx = xs[None, :, None] - pts[chunk, 0, None, None]
        dy = ys[None, None, :] - pts[chunk, 1, None, None]
        best = np.maximum(best, (s[chunk, None, None] - decay * np.hypot(dx, dy)).max(axis=0))
    return np.repeat(np.clip(best, 0, 1)[:, :, None], grid.shape[2], axis=2).astype(np.float32)


def fuse(*heatmaps: np.ndarray) -> np.ndarray:
    """Element-wise product of heatmaps of one grid (the paper's cross-modal reasoning)."""
    if not heatmaps:
        raise ConfigError("fuse needs at least one heatmap")
    out = np.array(heatmaps[0], np.float32)
    for h in heatmaps[1:]:
        if h.shape != out.shape:
            raise ConfigError(f"heatmaps of different grids: {out.shape} vs {h.shape}")
        out *= h
    return out


def argmax_world(grid: VoxelGrid, heatmap: np.ndarray) -> np.ndarray:
    """World point [m] (3,) of the hottest voxel (ties: the mean of the tied voxels' centres)."""
    if heatmap.shape != grid.shape:
        raise ConfigError(f"heatmap {heatmap.shape} is not on the grid {grid.shape}")
    m = heatmap.max()
    ties = np.argwhere(heatmap >= m - 1e-6 * max(m, 1e-12))
    return grid.centers(ties).mean(axis=0)

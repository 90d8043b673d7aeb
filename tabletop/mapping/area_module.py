"""The area module: one global image embedding per frame, tied to where the camera looked.

A query's text embedding is scored against every frame's embedding; the best-matching views
(min-max normalised score >= ``top_score``) put heat where their optical axes meet the table
plane, decaying top-down (:func:`~tabletop.mapping.heatmaps.scored_points_heatmap_xy`). The
evidence is the best score's margin over the median frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.heatmaps import Heatmap, Judge, scored_points_heatmap_xy

__all__ = ["AreaConfig", "AreaModule", "look_at_table", "normalize_scores"]


@dataclass(frozen=True)
class AreaConfig:
    """Which views carry an area."""

    top_score: float = 0.8
    """Frames whose min-max normalised score reaches this carry the area."""

    def __post_init__(self) -> None:
        if not 0 < self.top_score <= 1:
            raise ConfigError(f"top_score must be in (0, 1], got {self.top_score}")


def normalize_scores(s: np.ndarray) -> np.ndarray:
    """Scores min-max normalised to [0, 1] (all ones when they are all equal)."""
    lo, hi = float(s.min()), float(s.max())
    if hi - lo < 1e-9:
        return np.ones_like(s, dtype=np.float64)
    return (s - lo) / (hi - lo)


def look_at_table(T_world_cam: np.ndarray) -> np.ndarray:
    """(N, 2) [m] xy where each camera's optical axis meets the table plane z = 0 (0.5 m along
    the axis for a camera not looking down)."""
    o = T_world_cam[:, :3, 3]
    d = T_world_cam[:, :3, 2]
    t = np.where(d[:, 2] < -1e-3, -o[:, 2] / np.minimum(d[:, 2], -1e-3), 0.5)
    return (o + t[:, None] * d)[:, :2]


class AreaModule:
    """Per-frame global embeddings (``embeddings``: list of (dim,) float32) and camera poses
    (``poses``: list of (4, 4) ``T_world_cam``)."""

    def __init__(self, grid: VoxelGrid, config: AreaConfig | None = None) -> None:
        self.grid = grid
        self.config = config or AreaConfig()
        self.embeddings: list[np.ndarray] = []
        self.poses: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.embeddings)

    def add(self, embedding: np.ndarray, T_world_cam: np.ndarray) -> None:
        """Keep one frame's global embedding (dim,) and its camera pose (4, 4)."""
        self.embeddings.append(np.asarray(embedding, np.float32))
        self.poses.append(np.array(T_world_cam, np.float64))

    def heatmap(self, query: str, decay: float, text, judge: Judge) -> Heatmap:
        """Heat where the frames that best match ``query`` looked."""
        if not self.embeddings:
            return Heatmap.not_found(
                self.grid, query, "area", decay, "the map has no frame embeddings"
            )
        s = np.stack(self.embeddings) @ text.encode_text([query])[0]
        scores = normalize_scores(s)
        pts = look_at_table(np.stack(self.poses))
        top = scores >= self.config.top_score
        values = scored_points_heatmap_xy(self.grid, pts[top], scores[top], decay)
        margin = float(s.max()) - float(np.median(s))
        conf, found = judge("area", margin)
        reason = "" if found else f"no view matches {query!r} well (confidence {conf:.2f})"
        return Heatmap(self.grid, values, query, "area", decay, conf, found, reason, margin)

"""The object module: a text query scored against the map's fused voxel features.

Each occupied voxel holds the mean of the dense image features of every pixel fused into it.
A query's text embedding is scored (cosine) against every voxel and against the background
concepts; the voxels where the query beats the background and scores within
``select_margin`` of the best are the target, and the heat decays from them in 3D
(:func:`~tabletop.mapping.heatmaps.point_heatmap_3d`). The evidence is the best score's margin
over the median voxel score, which the map's calibration turns into a confidence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError
from tabletop.mapping.heatmaps import Heatmap, Judge, point_heatmap_3d
from tabletop.mapping.voxel_map import VoxelMap

__all__ = ["BACKGROUND", "ObjectConfig", "ObjectModule"]

#: Concepts every object query competes against: what a tabletop map holds besides objects.
BACKGROUND = ("table", "floor", "robot arm", "other")


@dataclass(frozen=True)
class ObjectConfig:
    """How the object module picks a query's target voxels."""

    select_margin: float = 0.1
    """Target voxels score within this fraction of (best - median) of the best."""
    background: tuple[str, ...] = BACKGROUND
    """Concepts a query must beat at a voxel for the voxel to be a candidate."""

    def __post_init__(self) -> None:
        if not 0 <= self.select_margin <= 1:
            raise ConfigError(f"select_margin must be in [0, 1], got {self.select_margin}")
        if not self.background or not all(isinstance(b, str) and b for b in self.background):
            raise ConfigError(f"background must be non-empty strings, got {self.background!r}")
        object.__setattr__(self, "background", tuple(self.background))


class ObjectModule:
    """Object queries on a :class:`~tabletop.mapping.voxel_map.VoxelMap`.

    Args:
        voxels: the map's voxels (read at query time; the module caches their normalised
            features until the voxels change).
        text: the text encoder (``encode_text(list[str]) -> (n, dim)``, unit rows).
        config: the module's parameters.
    """

    def __init__(self, voxels: VoxelMap, text, config: ObjectConfig | None = None) -> None:
        self.voxels = voxels
        self.text = text
        self.config = config or ObjectConfig()
        self._key: tuple[int, int] | None = None
        self._features: np.ndarray | None = None
        self._background: np.ndarray | None = None

    def _refresh(self) -> None:
        key = (self.voxels.n, self.voxels.version)
        if self._key != key:
            self._features = self.voxels.mean_features()
            bg = self.text.encode_text(list(self.config.background))
            self._background = (self._features @ bg.T).max(axis=1)
            self._key = key

    def features(self) -> np.ndarray:
        """(n, dim) float32: the normalised mean feature of each occupied voxel."""
        self._refresh()
        return self._features

    def scores(self, query: str) -> tuple[np.ndarray, np.ndarray]:
        """Per occupied voxel: the query's cosine score, and whether the query beats the
        background concepts there."""
        self._refresh()
        s = self._features @ self.text.encode_text([query])[0]
        return s, s > self._background

    def heatmap(self, query: str, decay: float, judge: Judge) -> Heatmap:
        """Heat around the voxels that best match ``query``; not found (with the reason) when
        no voxel beats the background or the calibrated confidence says so."""
        grid = self.voxels.grid
        if self.voxels.n == 0:
            return Heatmap.not_found(grid, query, "object", decay, "the map is empty")
        s, beats = self.scores(query)
        cand = np.nonzero(beats)[0]
        if not len(cand):
            return Heatmap.not_found(
                grid,
                query,
                "object",
                decay,
                f"no voxel matches {query!r} better than the background",
            )
        best = float(s[cand].max())
        margin = best - float(np.median(s))
        keep = cand[s[cand] >= best - self.config.select_margin * margin]
        mask = np.zeros(grid.size, bool)
        mask[self.voxels.linear_indices[keep]] = True
        values = point_heatmap_3d(grid, mask.reshape(grid.shape), decay)
        conf, found = judge("object", margin)
        reason = "" if found else f"best match {best:.2f} is weak (confidence {conf:.2f})"
        return Heatmap(grid, values, query, "object", decay, conf, found, reason, margin)

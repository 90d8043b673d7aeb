"""Sparse voxel fusion of pixel features: scatter-mean into the occupied voxels of a grid.

Only occupied voxels store a feature row, so a 1 m x 1.2 m table at 1 cm with 384-d features
takes a few tens of MB. Fusion is vectorised: each point finds its voxel's row through one
grid-sized lookup (only voxels seen for the first time are sorted), counts, colours and heights
are summed with ``bincount``, and the features of a few frames at a time with one sparse-matrix
product; there is no per-point Python loop. Frames can be added one at a time (online) or in any
batches: the sums, and so the means, do not depend on how the frames were grouped (up to float32
rounding). The arrays given to :meth:`VoxelMap.integrate` are read until the next flush: a
caller must not change them in place afterwards.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.transforms import transform_points

__all__ = ["VoxelMap", "frame_points"]

#: Feature sums are added to the map every this many points (about eight frames at 320x240 and
#: a pixel step of 3), or once the pending frames' feature tables reach this many bytes, and
#: before anything reads them.
PENDING_POINTS = 1 << 16
PENDING_BYTES = 32 << 20


def frame_points(depth: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray, step: int = 1):
    """World points (P, 3) [m] of the valid depth pixels on every ``step``-th row and column,
    and their pixel coordinates (P, 2) as (row, column)."""
    sub = np.asarray(depth)[::step, ::step]  # a view: only the fused pixels are read
    v, u = np.nonzero(sub > 0)
    z = sub[v, u].astype(np.float64)
    rows, cols = v * step, u * step
    pts_cam = np.empty((len(z), 3))
    pts_cam[:, 0] = (cols - K[0, 2]) * z / K[0, 0]
    pts_cam[:, 1] = (rows - K[1, 2]) * z / K[1, 1]
    pts_cam[:, 2] = z
    return transform_points(T_world_cam, pts_cam), np.stack([rows, cols], axis=1)


class VoxelMap:
    """Occupied voxels with feature sums, point counts, colour sums and height sums (the mean
    height of a voxel's points places a surface within its voxel: a flat object lying in a
    table top's voxel layer still stands above the table's own voxels)."""

    def __init__(self, grid: VoxelGrid, dim: int, capacity: int = 4096) -> None:
        if dim < 0:
            raise ConfigError(f"feature dim must be >= 0, got {dim}")
        self.grid = grid
        self.dim = int(dim)
        self._row_of = np.full(grid.size, -1, dtype=np.int32)  # linear index -> row
        self._lin = np.zeros(capacity, np.int64)  # row -> linear index
        self._feat = np.zeros((capacity, self.dim), np.float32)  # feature sums
        self._count = np.zeros(capacity, np.int64)  # points per voxel
        self._rgb = np.zeros((capacity, 3), np.float64)  # colour sums
        self._z = np.zeros(capacity, np.float64)  # point height sums [m]
        self.has_heights = True
        """Whether the point heights are known (a map restored from a file that lacks them
        is not)."""
        self._pending: list[tuple] = []
        """Frames integrated but not yet in the sums: (rows, heights, colours or None,
        feature rows or None, feature table or None) each (:meth:`_flush`)."""
        self._pending_points = 0
        self._pending_bytes = 0
        self._pending_tables: set[int] = set()
        self.n = 0
        self.version = 0
        """Counts the integrations: a cache of anything derived from the voxels keys on it."""

    # ------------------------------------------------------------------ building
    def _grow(self, need: int) -> None:
        cap = len(self._lin)
        if need <= cap:
            return
        new = max(need, 2 * cap)
        self._lin = np.resize(self._lin, new)
        feat = np.zeros((new, self.dim), np.float32)
        feat[:cap] = self._feat
        self._feat = feat
        self._count = np.concatenate([self._count, np.zeros(new - cap, np.int64)])
        self._rgb = np.concatenate([self._rgb, np.zeros((new - cap, 3))])
        self._z = np.concatenate([self._z, np.zeros(new - cap)])

    def integrate(
        self,
        points: np.ndarray,
        features: np.ndarray | None = None,
        colors: np.ndarray | None = None,
        feature_index: np.ndarray | None = None,
    ) -> int:
        """Add (P, 3) world points [m] with their features and (P, 3) uint8 colours.

        ``features`` is (P, dim), one row per point, or — with ``feature_index`` (P,) — a table
        (C, dim) whose row ``feature_index[i]`` belongs to point i (a dense encoder's cells:
        many pixels share a cell, and the table is never expanded per point). Points outside
        the grid are dropped. Returns how many points were added.
        """
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ConfigError(f"points must be (P, 3), got {points.shape}")
        if features is not None:
            features = np.asarray(features)
            if feature_index is None:
                if features.shape != (len(points), self.dim):
                    raise ConfigError(
                        f"features must be ({len(points)}, {self.dim}), got {features.shape}"
                    )
                feature_index = np.arange(len(points))
            elif features.ndim != 2 or features.shape[1] != self.dim:
                raise ConfigError(f"features must have {self.dim} columns, got {features.shape}")
            elif len(feature_index) != len(points):
                raise ConfigError("feature_index must have one entry per point")
        idx, inside = self.grid.world_to_index(points)
        every = bool(inside.all())
        if not every:
            if not inside.any():
                return 0
            idx, points = idx[inside], points[inside]
        lin = self.grid.linear(idx)
        # each point's row through the grid-sized lookup: no sort of the frame's points; only
        # the voxels seen for the first time are sorted (to give them rows in voxel order)
        rows = self._row_of[lin]
        new = rows < 0
        if new.any():
            fresh = np.unique(lin[new])
            k = len(fresh)
            self._grow(self.n + k)
            self._row_of[fresh] = np.arange(self.n, self.n + k, dtype=np.int32)
            self._lin[self.n : self.n + k] = fresh
            self.n += k
            rows = self._row_of[lin]
        self.version += 1
        if colors is not None:
            colors = np.asarray(colors)
            colors = colors.copy() if every else colors[inside]
        fi = table = None
        if features is not None:
            fi = np.asarray(feature_index)
            fi, table = (fi.copy() if every else fi[inside]), features
            if id(table) not in self._pending_tables:
                self._pending_tables.add(id(table))
                self._pending_bytes += table.nbytes
        self._pending.append((rows, points[:, 2].copy(), colors, fi, table))
        self._pending_points += len(rows)
        if self._pending_points >= PENDING_POINTS or self._pending_bytes >= PENDING_BYTES:
            self._flush()
        return len(rows)

    def _flush(self) -> None:
        """Add the frames integrated since the last flush to the sums, in one pass over the
        voxels they touched: counts, heights and colours by ``bincount``, features by one
        sparse product of every (voxel, feature row) pair with the frames' tables stacked (a
        frame's voxels are mostly the last frame's: adding each frame's sums on its own moved
        every touched voxel's whole feature row each time)."""
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        self._pending_points = self._pending_bytes = 0
        self._pending_tables = set()
        rows = np.concatenate([p[0] for p in pending])
        counts = np.bincount(rows, minlength=self.n)
        touched = np.flatnonzero(counts)
        local = np.empty(self.n, np.int32)
        local[touched] = np.arange(len(touched), dtype=np.int32)
        inv = local[rows]
        m = len(touched)
        self._count[touched] += counts[touched]
        self._z[touched] += np.bincount(inv, weights=np.concatenate([p[1] for p in pending]),
                                        minlength=m)  # fmt: skip
        coloured = [p for p in pending if p[2] is not None]
        if coloured:
            at = inv if len(coloured) == len(pending) else local[
                np.concatenate([p[0] for p in coloured])]  # fmt: skip
            c = np.concatenate([p[2] for p in coloured]).astype(np.float64)
            for k in range(3):
                self._rgb[touched, k] += np.bincount(at, weights=c[:, k], minlength=m)
        with_features = [p for p in pending if p[4] is not None]
        if not with_features:
            return
        offset: dict[int, int] = {}
        tables = []
        for p in with_features:
            if id(p[4]) not in offset:
                offset[id(p[4])] = sum(len(t) for t in tables)
                tables.append(p[4])
        at = inv if len(with_features) == len(pending) else local[
            np.concatenate([p[0] for p in with_features])]  # fmt: skip
        cols = np.concatenate([p[3].astype(np.int64) + offset[id(p[4])] for p in with_features])
        table = tables[0] if len(tables) == 1 else np.concatenate(tables)
        # (voxel, feature row) pair counts; duplicates are summed by the sparse format
        F = sp.csr_matrix((np.ones(len(at), np.float32), (at, cols)), shape=(m, len(table)))
        self._feat[touched] += F @ np.asarray(table, np.float32)

    # ------------------------------------------------------------------ reading
    @property
    def linear_indices(self) -> np.ndarray:
        """(n,) linear grid index of each occupied voxel (row order)."""
        return self._lin[: self.n].copy()

    @property
    def indices(self) -> np.ndarray:
        """(n, 3) voxel indices of the occupied voxels."""
        return self.grid.unravel(self._lin[: self.n])

    @property
    def centers(self) -> np.ndarray:
        """(n, 3) world coordinates [m] of the occupied voxels' centres."""
        return self.grid.centers(self.indices)

    @property
    def counts(self) -> np.ndarray:
        self._flush()
        return self._count[: self.n].copy()

    def mean_features(self, normalize: bool = True) -> np.ndarray:
        """(n, dim) float32 mean feature per occupied voxel (L2-normalised by default)."""
        self._flush()
        f = self._feat[: self.n] / np.maximum(self._count[: self.n, None], 1)
        if normalize:
            f /= np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-12)
        return f.astype(np.float32)

    def mean_colors(self) -> np.ndarray:
        """(n, 3) uint8 mean colour per occupied voxel."""
        self._flush()
        c = self._rgb[: self.n] / np.maximum(self._count[: self.n, None], 1)
        return np.clip(np.round(c), 0, 255).astype(np.uint8)

    def mean_heights(self) -> np.ndarray | None:
        """(n,) [m] the mean height of the points fused into each occupied voxel; None when
        they are not known (:attr:`has_heights`)."""
        if not self.has_heights:
            return None
        self._flush()
        return self._z[: self.n] / np.maximum(self._count[: self.n], 1)

    def occupancy(self) -> np.ndarray:
        """Dense boolean occupancy over the grid's shape."""
        occ = np.zeros(self.grid.size, bool)
        occ[self._lin[: self.n]] = True
        return occ.reshape(self.grid.shape)

    def state(self) -> dict[str, np.ndarray]:
        """Arrays that fully describe the map (for saving); copies trimmed to ``n``
        (``height_sums`` only where the heights are known)."""
        self._flush()
        st = {
            "linear": self._lin[: self.n].copy(),
            "feature_sums": self._feat[: self.n].copy(),
            "counts": self._count[: self.n].copy(),
            "color_sums": self._rgb[: self.n].copy(),
        }
        if self.has_heights:
            st["height_sums"] = self._z[: self.n].copy()
        return st

    @classmethod
    def from_state(cls, grid: VoxelGrid, dim: int, state: dict[str, np.ndarray]) -> VoxelMap:
        m = cls(grid, dim, capacity=max(1, len(state["linear"])))
        m.restore(state)
        return m

    def restore(self, state: dict[str, np.ndarray]) -> None:
        """Fill this empty map with a :meth:`state` (in place: whatever holds the map sees it).
        A state without ``height_sums`` (an older file) leaves the heights unknown."""
        if self.n:
            raise ConfigError(f"restore needs an empty voxel map, this one holds {self.n} voxels")
        n = len(state["linear"])
        if state["feature_sums"].shape != (n, self.dim) or len(state["counts"]) != n:
            raise ConfigError("voxel map arrays disagree in length or feature dim")
        heights = state.get("height_sums")
        if heights is not None and np.shape(heights) != (n,):
            raise ConfigError(f"voxel height sums have shape {np.shape(heights)}, expected ({n},)")
        if n and (state["linear"].min() < 0 or state["linear"].max() >= self.grid.size):
            raise ConfigError("voxel map indices lie outside its grid")
        self._grow(n)
        self._lin[:n] = state["linear"]
        self._feat[:n] = state["feature_sums"]
        self._count[:n] = state["counts"]
        self._rgb[:n] = state["color_sums"]
        self.has_heights = heights is not None
        if heights is not None:
            self._z[:n] = heights
        self._row_of[state["linear"]] = np.arange(n, dtype=np.int32)
        self.n = n
        self.version += 1

    @property
    def nbytes(self) -> int:
        """Memory held by the map's arrays [bytes]."""
        arrays = (self._row_of, self._lin, self._feat, self._count, self._rgb, self._z)
        return sum(a.nbytes for a in arrays)

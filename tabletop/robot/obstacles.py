"""Obstacles per embodiment, from one map (the paper's open-vocabulary obstacle maps).

Each occupied voxel of an :class:`~tabletop.mapping.avlmap.AVLMap` is scored against an
embodiment's obstacle concepts and free concepts (cosine similarity of the voxel's mean feature
with each concept's text embedding) and takes the concept with the highest score. Voxels labelled
with an obstacle concept are the embodiment's obstacles. Sound or image heat above a threshold
adds keep-out regions (places that are hard to name as objects: "where the glass broke").

Two exports, one per kind of robot:

- :func:`arm_obstacles`: :class:`~tabletop.arm.obstacles.Box` values for the arm's collision
  checker and controller. Obstacle voxel columns are filled down to the table top (a camera sees
  an object's top and sides, never its inside), then merged greedily into axis-aligned boxes
  (runs along z, then y, then x); a surface concept ("table") becomes one slab.
- :func:`occupancy_grid`: a 2D :class:`OccupancyGrid` for a mobile base, the obstacle voxels in
  the embodiment's height band projected top-down.

World frame = robot base frame; metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from tabletop.arm.obstacles import TABLE_THICKNESS, Box
from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid

__all__ = [
    "ARM",
    "MOBILE_BASE",
    "Embodiment",
    "ObstacleVoxels",
    "OccupancyGrid",
    "arm_obstacles",
    "label_voxels",
    "merge_boxes",
    "obstacle_voxels",
    "occupancy_grid",
]


@dataclass(frozen=True)
class Embodiment:
    """What one robot must not touch, in words.

    Every occupied voxel takes the best-scoring concept of ``obstacles + slabs + free``.
    """

    name: str
    obstacles: tuple[str, ...]
    """Concepts that block this robot (objects, "other", ...)."""
    free: tuple[str, ...]
    """Concepts that do not block it (the surface a base drives on, the floor, ...)."""
    slabs: tuple[str, ...] = ()
    """Blocking concepts that are a horizontal surface (the table): exported as one slab box
    under their voxels instead of many voxel boxes (arm export only)."""
    z_range: tuple[float, float] = (-np.inf, np.inf)
    """Only voxels whose centre z [m] is in this band count (a base's height, say)."""
    fill_down_to: float | None = 0.0
    """Fill each obstacle column down to this height [m] (the table top); None: no filling."""
    unknown_is_obstacle: bool = True
    """Voxels with no feature (all-zero mean) count as obstacles."""
    map_objects: bool = True
    """Every object name of the map's vocabulary (``MapConfig.objects``) blocks this robot too,
    ahead of ``obstacles``."""
    objects_free: bool = False
    """Every object name of the map's vocabulary is free for this robot (a flyer passes over
    what stands on a table); exclusive with ``map_objects``."""
    block_above: float | None = None
    """Every voxel whose centre is at least this high [m] blocks, whatever its concept (a
    flyer cruising at that height cannot pass what reaches above it, named or not); None:
    the concepts alone decide."""

    def __post_init__(self) -> None:
        if not self.obstacles and not self.slabs:
            raise ConfigError(f"embodiment {self.name!r}: give at least one obstacle concept")
        clash = set(self.obstacles + self.slabs) & set(self.free)
        if clash:
            raise ConfigError(f"embodiment {self.name!r}: {sorted(clash)} both obstacle and free")
        if self.map_objects and self.objects_free:
            raise ConfigError(
                f"embodiment {self.name!r}: the map's objects either block it (map_objects) or "
                "not (objects_free), not both"
            )
        lo, hi = self.z_range
        if not lo < hi:
            raise ConfigError(f"embodiment {self.name!r}: z_range must be (lo, hi), lo < hi")

    @property
    def concepts(self) -> tuple[str, ...]:
        return self.obstacles + self.slabs + self.free

    def for_map(self, avlmap) -> Embodiment:
        """This embodiment with the map's object vocabulary among its obstacles (when
        ``map_objects``), ready to label that map's voxels."""
        if not (self.map_objects or self.objects_free):
            return self
        taken = set(self.obstacles + self.slabs + self.free)
        objects = tuple(dict.fromkeys(o for o in avlmap.config.objects if o not in taken))
        if self.objects_free:
            return replace(self, free=(*self.free, *objects), objects_free=False)
        return replace(self, obstacles=(*objects, *self.obstacles), map_objects=False)


#: The Panda on the table: every object and the table itself are obstacles.
ARM = Embodiment(
    name="panda arm",
    obstacles=("other",),
    free=("floor", "robot arm"),
    slabs=("table",),
)

#: A small base driving on the table top: objects block it, the table is where it drives.
MOBILE_BASE = Embodiment(
    name="table-top mobile base",
    obstacles=("robot arm", "other"),
    free=("table", "floor"),
    z_range=(0.003, 0.25),
)


@dataclass(frozen=True)
class ObstacleVoxels:
    """An embodiment's obstacles on a map's grid (a value)."""

    grid: VoxelGrid
    mask: np.ndarray  # grid.shape bool: obstacle voxels (filled columns, keep-out included)
    slab_voxels: np.ndarray  # (S, 3) [m] world centres of voxels labelled with a slab concept
    concepts: tuple[str, ...]
    labels: np.ndarray  # (n,) int index into ``concepts`` per occupied map voxel, -1 unknown
    keep_out_voxels: int  # how many voxels of ``mask`` came from keep-out heat


def label_voxels(avlmap, concepts: Sequence[str]) -> np.ndarray:
    """(n,) index of the best-scoring concept per occupied voxel (-1: the voxel has no feature).

    The score is the cosine similarity of the voxel's mean feature with the concept's text
    embedding (the paper's argmax over a category list).
    """
    concepts = list(concepts)
    if not concepts:
        raise ConfigError("label_voxels needs at least one concept")
    feats = avlmap.voxels.mean_features()
    if not len(feats):
        return np.zeros(0, np.int64)
    emb = avlmap.text.encode_text(concepts)
    labels = np.argmax(feats @ emb.T, axis=1).astype(np.int64)
    labels[np.linalg.norm(feats, axis=1) < 1e-6] = -1
    return labels


def _heat_values(h) -> np.ndarray:
    return np.asarray(getattr(h, "values", h), dtype=np.float32)


def obstacle_voxels(
    avlmap,
    embodiment: Embodiment,
    keep_out: Sequence = (),
    threshold: float = 0.5,
) -> ObstacleVoxels:
    """The embodiment's obstacle voxels on the map's grid.

    Args:
        avlmap: the map.
        embodiment: the concept lists.
        keep_out: heatmaps (arrays of the grid's shape, or ``Heatmap``) whose heat at or above
            ``threshold`` is a keep-out region (e.g. ``get_major_map(sound="glass breaking")``);
            kept to the embodiment's height band and above ``fill_down_to``.
        threshold: heat in [0, 1] at which a keep-out heatmap blocks.
    """
    if not 0.0 < threshold <= 1.0:
        raise ConfigError(f"keep-out threshold must be in (0, 1], got {threshold}")
    grid = avlmap.grid
    embodiment = embodiment.for_map(avlmap)
    concepts = embodiment.concepts
    labels = label_voxels(avlmap, concepts)
    idx = avlmap.voxels.indices
    z = grid.axes()[2]
    zlo, zhi = embodiment.z_range
    band = (z >= zlo) & (z <= zhi)
    n_obs, n_slab = len(embodiment.obstacles), len(embodiment.slabs)
    is_obs = (labels >= 0) & (labels < n_obs)
    if embodiment.unknown_is_obstacle:
        is_obs |= labels < 0
    if embodiment.block_above is not None and len(idx):
        is_obs |= z[idx[:, 2]] >= embodiment.block_above
    is_slab = (labels >= n_obs) & (labels < n_obs + n_slab) & ~is_obs
    mask = np.zeros(grid.shape, bool)
    sel = idx[is_obs]
    sel = sel[band[sel[:, 2]]] if len(sel) else sel
    mask[sel[:, 0], sel[:, 1], sel[:, 2]] = True
    floor_k = 0
    if embodiment.fill_down_to is not None:
        floor_k = int(np.searchsorted(z, embodiment.fill_down_to))  # first centre above it
        mask[:, :, :floor_k] = False
        # Fill each column from the floor up to its highest obstacle voxel.
        above = np.cumsum(mask[:, :, ::-1], axis=2)[:, :, ::-1] > 0
        above[:, :, :floor_k] = False
        mask = above & band[None, None, :]
    n_keep = 0
    for h in keep_out:
        v = _heat_values(h)
        if v.shape != grid.shape:
            raise ConfigError(f"keep-out heatmap {v.shape} is not on the map's grid {grid.shape}")
        ko = (v >= threshold) & band[None, None, :]
        ko[:, :, :floor_k] = False
        n_keep += int((ko & ~mask).sum())
        mask |= ko
    slab_idx = idx[is_slab]
    return ObstacleVoxels(
        grid=grid,
        mask=mask,
        slab_voxels=grid.centers(slab_idx) if len(slab_idx) else np.zeros((0, 3)),
        concepts=concepts,
        labels=labels,
        keep_out_voxels=n_keep,
    )


def _runs(mask: np.ndarray) -> np.ndarray:
    """(R, 6) boxes [i0, i1, j0, j1, k0, k1) (half-open voxel index ranges) covering ``mask``:
    runs along z, merged along y where equal, then along x where equal."""
    p = np.pad(mask, ((0, 0), (0, 0), (1, 1))).astype(np.int8)
    d = np.diff(p, axis=2)
    st, en = np.argwhere(d == 1), np.argwhere(d == -1)  # same (i, j, k) order, paired
    if not len(st):
        return np.zeros((0, 6), np.int64)
    i, j, k0, k1 = st[:, 0], st[:, 1], st[:, 2], en[:, 2]

    def merge(key: np.ndarray, pos: np.ndarray):
        """Group rows with equal ``key`` (M, c) and consecutive ``pos``; return (first rows,
        run starts, run ends (exclusive))."""
        order = np.lexsort((pos, *key.T[::-1]))
        key, pos = key[order], pos[order]
        new = np.ones(len(pos), bool)
        new[1:] = np.any(key[1:] != key[:-1], axis=1) | (pos[1:] != pos[:-1] + 1)
        starts = np.nonzero(new)[0]
        ends = np.r_[starts[1:], len(pos)] - 1
        return key[starts], pos[starts], pos[ends] + 1

    key, j0, j1 = merge(np.stack([i, k0, k1], 1), j)  # along y
    key2, i0, i1 = merge(np.stack([j0, j1, key[:, 1], key[:, 2]], 1), key[:, 0])  # along x
    return np.stack([i0, i1, key2[:, 0], key2[:, 1], key2[:, 2], key2[:, 3]], 1)


def merge_boxes(
    mask: np.ndarray, grid: VoxelGrid, max_boxes: int = 2000, name: str = "map"
) -> list[Box]:
    """Axis-aligned boxes whose union is exactly the occupied voxels of ``mask`` (grid.shape).

    Greedy merging: runs along z, then equal runs side by side along y, then along x. If more
    than ``max_boxes`` result, the mask is coarsened by 2 (a coarse voxel is occupied when any
    of its fine voxels is: the boxes only grow) until they fit.
    """
    if max_boxes < 1:
        raise ConfigError(f"max_boxes must be >= 1, got {max_boxes}")
    mask = np.asarray(mask, bool)
    if mask.shape != grid.shape:
        raise ConfigError(f"mask {mask.shape} is not on the grid {grid.shape}")
    size = grid.voxel_size
    lower = np.asarray(grid.lower, np.float64)
    while True:
        runs = _runs(mask)
        if len(runs) <= max_boxes or max(mask.shape) <= 1:
            break
        pad = [(0, s % 2) for s in mask.shape]
        m = np.pad(mask, pad)
        mask = m.reshape(m.shape[0] // 2, 2, m.shape[1] // 2, 2, m.shape[2] // 2, 2).any((1, 3, 5))
        size *= 2
    lo = lower + runs[:, [0, 2, 4]] * size
    hi = lower + runs[:, [1, 3, 5]] * size
    return [
        Box(center=(a + b) / 2, half_extents=(b - a) / 2, name=f"{name}{n}")
        for n, (a, b) in enumerate(zip(lo, hi, strict=True))
    ]


def _slab(points: np.ndarray, grid: VoxelGrid, name: str) -> Box | None:
    """One slab under voxels of a surface: top at their 95th-percentile top, xy their extent."""
    if len(points) < 10:
        return None
    h = grid.voxel_size / 2
    top = float(np.percentile(points[:, 2], 95)) + h
    lo = points[:, :2].min(axis=0) - h
    hi = points[:, :2].max(axis=0) + h
    c = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, top - TABLE_THICKNESS / 2]
    return Box(center=c, half_extents=[*((hi - lo) / 2), TABLE_THICKNESS / 2], name=name)


def arm_obstacles(
    avlmap,
    embodiment: Embodiment = ARM,
    keep_out: Sequence = (),
    threshold: float = 0.5,
    max_boxes: int = 2000,
) -> list[Box]:
    """The arm's obstacles from the map: one slab per surface concept (the table), then the
    merged boxes of the obstacle voxels (objects, keep-out regions)."""
    embodiment = embodiment.for_map(avlmap)
    ov = obstacle_voxels(avlmap, embodiment, keep_out, threshold)
    out: list[Box] = []
    if embodiment.slabs:
        labels = ov.labels
        first = len(embodiment.obstacles)
        centers = avlmap.voxels.centers
        for s, concept in enumerate(embodiment.slabs):
            pts = centers[labels == first + s]
            slab = _slab(pts, avlmap.grid, concept)
            if slab is not None:
                out.append(slab)
    out.extend(merge_boxes(ov.mask, avlmap.grid, max_boxes=max_boxes))
    return out


@dataclass(frozen=True)
class OccupancyGrid:
    """A top-down occupancy grid (a value): cell (i, j) covers
    ``lower + [i, i+1) * cell_size`` on x and likewise on y, world frame [m]."""

    occupied: np.ndarray  # (nx, ny) bool
    lower: tuple[float, float]  # [m] world x, y of the grid's corner
    cell_size: float  # [m]

    def __post_init__(self) -> None:
        occ = np.array(self.occupied, bool)
        if occ.ndim != 2:
            raise ConfigError(f"occupied must be 2D, got {occ.shape}")
        occ.setflags(write=False)
        object.__setattr__(self, "occupied", occ)

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape

    def to_cell(self, xy: np.ndarray) -> tuple[np.ndarray, bool]:
        """(2,) int cell of a world point [m] and whether it lies on the grid."""
        c = np.floor((np.asarray(xy, float)[:2] - self.lower) / self.cell_size).astype(np.int64)
        return c, bool(np.all(c >= 0) and np.all(c < self.shape))

    def to_world(self, cells: np.ndarray) -> np.ndarray:
        """(N, 2) world xy [m] of (N, 2) cell centres."""
        return np.asarray(self.lower) + (np.asarray(cells) + 0.5) * self.cell_size

    def inflated(self, radius: float) -> OccupancyGrid:
        """Cells within ``radius`` [m] of an occupied cell are occupied (a disc robot)."""
        if radius <= 0 or not self.occupied.any():
            return self
        d = ndimage.distance_transform_edt(~self.occupied, sampling=self.cell_size)
        return OccupancyGrid(d <= radius, self.lower, self.cell_size)


def occupancy_grid(
    avlmap,
    embodiment: Embodiment = MOBILE_BASE,
    keep_out: Sequence = (),
    threshold: float = 0.5,
) -> OccupancyGrid:
    """The embodiment's 2D obstacle grid: its obstacle voxels (height band) seen from above."""
    embodiment = embodiment.for_map(avlmap)
    ov = obstacle_voxels(avlmap, embodiment, keep_out, threshold)
    g = avlmap.grid
    return OccupancyGrid(ov.mask.any(axis=2), (g.lower[0], g.lower[1]), g.voxel_size)

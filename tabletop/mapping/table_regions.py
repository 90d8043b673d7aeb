"""Named table regions from the map's own geometry: "the left side of the table", "the far
right corner", "the middle", "near the robot".

A region named by where it is on the table is geometry, not an image embedding: the table is
fitted from the map (:func:`fit_table`: the dominant horizontal layer of occupied voxels, its
height and its extent), and the phrase is parsed into a lateral and a depth constraint
(by the reader: :mod:`tabletop.reader.places`) in the robot frame: +x points away from
the robot ("front", "far"), +y to its left. Phrases that name what is in an area ("the tray
area", "where the toys are") are not geometric: the reader gives their subject instead, which
the map looks for as a thing or a sound. The map receives an :class:`AreaRef` (what the reader
read) and holds no words of places.

The table's usable part starts :data:`ROBOT_CLEARANCE_M` in front of the robot base (the base
and shoulder stand nearer than that) and keeps :data:`EDGE_MARGIN_M` from the fitted edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.heatmaps import Heatmap

__all__ = [
    "EDGE_MARGIN_M",
    "ROBOT_CLEARANCE_M",
    "AreaRef",
    "TableFit",
    "TableRegion",
    "fit_surfaces",
    "fit_table",
    "raised_surfaces",
    "region_heatmap",
]

#: The usable table starts this far [m] in front of the robot base (x = 0).
ROBOT_CLEARANCE_M = 0.20
#: Regions keep this far [m] inside the fitted table edges.
EDGE_MARGIN_M = 0.05


@dataclass(frozen=True)
class TableRegion:
    """A parsed region: ``lateral`` in {"left", "right", "middle", None} (along y) and
    ``depth`` in {"far", "near", "middle", None} (along x); None = the whole extent."""

    lateral: str | None
    depth: str | None
    text: str


@dataclass(frozen=True)
class AreaRef:
    """A place as the reader read it (:mod:`tabletop.reader.places`): a ``region`` of the
    table's own geometry, or a ``subject`` (what a place is named after: "the area around the
    tray" -> "tray"), or neither (words that name no place here: not found). ``how`` says what
    read it ("grammar", "learned 0.93", ...), for the reason a query reports."""

    text: str
    region: TableRegion | None = None
    subject: str | None = None
    how: str = ""

    def __post_init__(self) -> None:
        if self.region is not None and self.subject is not None:
            raise ConfigError(f"{self.text!r}: an area is a region or a subject, not both")


@dataclass(frozen=True)
class TableFit:
    """The table fitted from a map: its top's height and extent [m], robot frame."""

    z: float
    x: tuple[float, float]
    y: tuple[float, float]
    voxels: int  # voxels of the table layer the fit used

    def usable(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((x0, x1), (y0, y1)) [m]: the part of the table regions divide."""
        x0 = max(self.x[0] + EDGE_MARGIN_M, ROBOT_CLEARANCE_M)
        x1 = self.x[1] - EDGE_MARGIN_M
        y0, y1 = self.y[0] + EDGE_MARGIN_M, self.y[1] - EDGE_MARGIN_M
        if not (x0 < x1 and y0 < y1):
            raise ConfigError(
                f"the fitted table ({self.x}, {self.y}) has no usable part in front of the robot"
            )
        return (x0, x1), (y0, y1)

    def box(self, region: TableRegion) -> tuple[tuple[float, float], tuple[float, float]]:
        """((x0, x1), (y0, y1)) [m] of ``region`` on this table."""
        (x0, x1), (y0, y1) = self.usable()
        xs = {
            None: (x0, x1),
            "near": (x0, (x0 + x1) / 2),
            "far": ((x0 + x1) / 2, x1),
            "middle": (x0 + (x1 - x0) / 3, x1 - (x1 - x0) / 3),
        }[region.depth]
        ys = {
            None: (y0, y1),
            "right": (y0, y0 + (y1 - y0) / 3),
            "left": (y1 - (y1 - y0) / 3, y1),
            "middle": (y0 + (y1 - y0) / 3, y1 - (y1 - y0) / 3),
        }[region.lateral]
        return xs, ys


def fit_table(grid: VoxelGrid, indices: np.ndarray) -> TableFit | None:
    """The table top from the occupied voxels ``indices`` (N, 3): the densest horizontal layer
    (with a neighbour layer holding at least a quarter as many voxels: a surface at a voxel
    boundary fills two), its height (the count-weighted mean of those layers' centres) and the
    1st-99th percentile extent of its largest connected part. None when the map holds no
    horizontal surface of at least 100 voxels."""
    idx = np.asarray(indices)
    if len(idx) < 100:
        return None
    counts = np.bincount(idx[:, 2], minlength=grid.shape[2])
    k = int(np.argmax(counts))
    layers = [k] + [
        j for j in (k - 1, k + 1) if 0 <= j < len(counts) and counts[j] >= counts[k] / 4
    ]
    if counts[layers].sum() < 100:
        return None
    zs = grid.axes()[2]
    z = float(np.average(zs[layers], weights=counts[layers]))
    layer = np.zeros(grid.shape[:2], bool)
    sel = np.isin(idx[:, 2], layers)
    layer[idx[sel, 0], idx[sel, 1]] = True
    labels, n = ndimage.label(layer)
    if n > 1:
        sizes = ndimage.sum(layer, labels, index=np.arange(1, n + 1))
        layer = labels == (int(np.argmax(sizes)) + 1)
    ij = np.argwhere(layer)
    xs, ys, _ = grid.axes()
    px, py = xs[ij[:, 0]], ys[ij[:, 1]]
    h = grid.voxel_size / 2
    return TableFit(
        z,
        (float(np.percentile(px, 1)) - h, float(np.percentile(px, 99)) + h),
        (float(np.percentile(py, 1)) - h, float(np.percentile(py, 99)) + h),
        int(layer.sum()),
    )


def fit_surfaces(
    grid: VoxelGrid,
    indices: np.ndarray,
    min_area_m2: float = 0.04,
    above_m: float = 0.10,
    max_covered: float = 0.5,
    heights: np.ndarray | None = None,
) -> list[TableFit]:
    """Every horizontal surface of the occupied voxels ``indices`` (N, 3), largest first: a
    room's floor, its table tops, a cabinet's top, a shelf's boards.

    A surface is a connected patch of one layer (with the layer above: a surface at a voxel
    boundary fills two) of at least ``min_area_m2`` [m^2] that survives a morphological opening
    by 3 x 3 voxels (a wall cut by the layer is a line one or two voxels thick; a surface is
    not), with at most ``max_covered`` of its cells occupied in the ``above_m`` [m] over it (a
    table top carries objects on part of it; a vertical side cut by the layer is occupied
    above it too). A patch already taken by a surface a layer away is the same surface. Each
    surface's
    height is the count-weighted mean of its two layers' centres, or, given ``heights`` (N,)
    [m] (the mean height of each voxel's points, :meth:`VoxelMap.mean_heights`), the median
    of its voxels' point heights (what stands on it covers at most ``max_covered``); its extent
    is the 1st-99th percentile of its cells (as :func:`fit_table`)."""
    idx = np.asarray(indices)
    if heights is not None:
        heights = np.asarray(heights, np.float64)
        if heights.shape != (len(idx),):
            raise ConfigError(f"heights must be ({len(idx)},), got {heights.shape}")
        height_of = np.full(grid.shape, np.nan)
        height_of[tuple(idx.T)] = heights
    min_cells = max(int(np.ceil(min_area_m2 / grid.voxel_size**2)), 9)
    above_cells = max(round(above_m / grid.voxel_size), 1)
    if len(idx) < min_cells:
        return []
    nz = grid.shape[2]
    counts = np.bincount(idx[:, 2], minlength=nz)
    layers = np.zeros(grid.shape, bool)
    layers[tuple(idx.T)] = True
    xs, ys, zs = grid.axes()
    h = grid.voxel_size / 2
    taken = np.zeros(grid.shape, bool)  # cells (per layer) of accepted surfaces
    out: list[TableFit] = []
    for k in np.argsort(-counts, kind="stable"):
        if counts[k] < min_cells:
            break
        pair = [k] + ([k + 1] if k + 1 < nz else [])
        both = layers[:, :, pair].any(axis=2)
        opened = ndimage.binary_opening(both, structure=np.ones((3, 3), bool))
        labels, n = ndimage.label(opened, structure=np.ones((3, 3), bool))
        for c in range(1, n + 1):
            patch = labels == c
            area = int(patch.sum())
            if area < min_cells:
                continue
            near = taken[:, :, max(k - 1, 0) : min(k + 3, nz)].any(axis=2)
            if (patch & near).sum() > area / 2:
                continue
            # A surface has room above it (what stands on it covers part of it); a wall, a
            # sofa's back or a shelf's side cut by the layer is occupied above as well.
            over = layers[:, :, min(k + 2, nz) : min(k + 2 + above_cells, nz)].any(axis=2)
            if (patch & over).sum() > max_covered * area:
                continue
            if heights is not None:
                z = float(np.nanmedian(height_of[:, :, pair][patch]))
            else:
                per_layer = [(layers[:, :, j] & patch).sum() for j in pair]
                z = float(np.average(zs[pair], weights=np.array(per_layer, np.float64) + 1e-9))
            ij = np.argwhere(patch)
            px, py = xs[ij[:, 0]], ys[ij[:, 1]]
            out.append(
                TableFit(
                    z,
                    (float(np.percentile(px, 1)) - h, float(np.percentile(px, 99)) + h),
                    (float(np.percentile(py, 1)) - h, float(np.percentile(py, 99)) + h),
                    area,
                )
            )
            taken[:, :, pair] |= patch[:, :, None]
    out.sort(key=lambda t: -t.voxels)
    return out


def raised_surfaces(surfaces: list[TableFit], min_height_m: float) -> list[TableFit]:
    """The surfaces at least ``min_height_m`` [m] above the lowest one (a room's table tops
    and shelves, not its floor); all of them when there is only one."""
    if len(surfaces) < 2:
        return list(surfaces)
    floor = min(s.z for s in surfaces)
    return [s for s in surfaces if s.z >= floor + min_height_m]


def region_heatmap(
    grid: VoxelGrid, table: TableFit | None, text: str, region: TableRegion, decay: float
) -> Heatmap:
    """Heat 1 over the region's rectangle (every height), ``max(1 - decay * d_xy, 0)`` around
    it; not found when the map has no fitted table."""
    if table is None:
        return Heatmap.not_found(
            grid, text, "area", decay, "the map holds no table surface to find regions on"
        )
    (x0, x1), (y0, y1) = table.box(region)
    xs, ys, _ = grid.axes()
    dx = np.maximum(np.maximum(x0 - xs, xs - x1), 0.0)[:, None]
    dy = np.maximum(np.maximum(y0 - ys, ys - y1), 0.0)[None, :]
    top = np.maximum(1.0 - decay * np.hypot(dx, dy), 0.0).astype(np.float32)
    values = np.repeat(top[:, :, None], grid.shape[2], axis=2)
    return Heatmap(grid, values, text, "area", decay, 1.0, True, "", None)

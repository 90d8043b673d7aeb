"""The one target selector: from a heatmap to a point in the world (``get_max_pos_3d``), and
the height from which a gripper approaches it.

Every caller (the map, the robot API, the CLI, the evaluation, the calibration) goes through
these functions, so what the benchmark measures is what a user can call.

- :func:`hottest_region`: the voxels at the maximum; ties (plateaus) resolve to the connected
  tied region of largest total heat.
- :func:`max_position`: that region's centroid; when the region spans the grid's whole height
  (a top-down heatmap: sound, area, image) the point is put on the surface beneath it. A fused
  heatmap whose peak lies in the fading halo of its object factor, not on the object (a sound
  whose reach barely overlaps the halo), goes to the object nearest that peak.
- :func:`region_box`: the region as a landmark (centre and extent) for spatial relations.
- :func:`approach_point`: a point raised to ``gap`` above the highest surface within
  ``radius`` of it, so a top-down gripper approaches a goal on or in an object (a mug's cavity,
  the table beside a tall object) from above instead of being driven into it.

A heatmap that found nothing, or is zero everywhere, or the same everywhere (every voxel ties for
the maximum) raises :class:`~tabletop.errors.GoalNotFound`: the robot is never sent to the argmax
of nothing, nor to the middle of a grid no place of which stands out. ``occupancy`` arguments
are the map's dense boolean occupancy (grid-shaped); points are (3,) float64 [m] in the world
(= robot base) frame.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from tabletop.errors import ConfigError, GoalNotFound
from tabletop.grid import VoxelGrid, box_argwhere, mask_box
from tabletop.mapping.heatmaps import Heatmap, sharpest_part

__all__ = [
    "APPROACH_RADIUS_M",
    "approach_point",
    "hottest_region",
    "max_position",
    "region_box",
    "surface_z",
]

#: Horizontal radius [m] of the surface a gripper must clear when it approaches a point from
#: above (about the Panda gripper's half span).
APPROACH_RADIUS_M = 0.05
_TIE = 1e-6


def _check(heatmap: Heatmap) -> Heatmap:
    if not isinstance(heatmap, Heatmap):
        raise ConfigError(
            f"a target needs a Heatmap (from a map query), got {type(heatmap).__name__}"
        )
    if not heatmap.found:
        raise GoalNotFound(heatmap.query, heatmap.reason or "the query found nothing")
    if not heatmap.peak > 0:
        raise GoalNotFound(heatmap.query, "the heatmap is zero everywhere")
    if float(heatmap.values.min()) >= heatmap.peak - _TIE:  # every voxel ties for the maximum
        raise GoalNotFound(
            heatmap.query, f"the heatmap is {heatmap.peak:.3g} everywhere: it singles out no place"
        )
    return heatmap


def _check_occupancy(grid: VoxelGrid, occupancy: np.ndarray) -> np.ndarray:
    occ = np.asarray(occupancy, bool)
    if occ.shape != grid.shape:
        raise ConfigError(f"occupancy {occ.shape} is not on the grid {grid.shape}")
    return occ


def hottest_region(heatmap: Heatmap) -> np.ndarray:
    """Grid-shaped bool mask of the voxels at the maximum; of several disconnected tied
    regions, the one with the largest total heat."""
    return _hottest(heatmap)[0]


def _hottest(heatmap: Heatmap):
    """(:func:`hottest_region`'s mask, the box of slices that holds it)."""
    values = _check(heatmap).values
    tied = values >= heatmap.peak - _TIE
    # the components of the tied voxels lie in their bounding box: label that box alone (a
    # peak is usually a few hundred voxels of a grid of a million), numbered in the same order
    box = mask_box(tied)
    labels, n = ndimage.label(tied[box], structure=np.ones((3, 3, 3)))
    if n > 1:
        weights = ndimage.sum(values[box], labels, index=np.arange(1, n + 1))
        tied = np.zeros_like(tied)
        tied[box] = labels == (int(np.argmax(weights)) + 1)
    return tied, box


def surface_z(grid: VoxelGrid, occupancy: np.ndarray, xy, radius: float = 0.0) -> float:
    """Height [m] of the top of the highest occupied voxel whose centre is within ``radius``
    [m] of ``xy`` horizontally (the voxel column at ``xy`` when ``radius`` is 0); 0, the table
    plane, where there is none."""
    occ = _check_occupancy(grid, occupancy)
    x, y = float(xy[0]), float(xy[1])
    xs, ys, zs = grid.axes()
    if radius > 0:
        near = (xs[:, None] - x) ** 2 + (ys[None, :] - y) ** 2 <= radius**2
        cols = occ[near]  # (K, nz)
    else:
        idx, inside = grid.world_to_index(np.array([[x, y, 0.0]]))
        if not inside[0]:
            return 0.0
        cols = occ[idx[0, 0], idx[0, 1]][None, :]
    if not cols.size or not cols.any():
        return 0.0
    return float(zs[np.nonzero(cols.any(axis=0))[0].max()] + grid.voxel_size / 2)


def _is_column(grid: VoxelGrid, idx: np.ndarray) -> bool:
    return len(np.unique(idx[:, 2])) == grid.shape[2]


def _centroid(grid: VoxelGrid, occupancy: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(3,) [m]: the centroid of the voxels ``idx`` (N, 3), put on the surface beneath when they
    span the grid's whole height."""
    p = grid.centers(idx).mean(axis=0)
    if _is_column(grid, idx):
        p[2] = surface_z(grid, occupancy, p[:2])
    return p


def max_position(heatmap: Heatmap, occupancy: np.ndarray) -> np.ndarray:
    """(3,) [m]: the centroid of the hottest region (:func:`hottest_region`); a region spanning
    the grid's whole height (a top-down heatmap) is placed on the surface beneath it."""
    mask, box = _hottest(heatmap)  # checks the heatmap first
    _, core = _sharp_region(heatmap, mask)
    cells = box_argwhere(mask, box) if core is None else box_argwhere(core)
    return _centroid(heatmap.grid, occupancy, cells)


def _landmark_region(heatmap: Heatmap) -> np.ndarray:
    """Grid-shaped bool mask of the region a landmark occupies: the hottest region, or for a
    fused heatmap whose sharpest factor is a 3D region (an object narrowed by a sound or another
    object: "the mug near the sound of X"), the whole region of that factor the product's
    peak lies on (:func:`_sharp_region`). The product alone peaks at the object's voxel nearest
    the other factor, and a relation to that one voxel would start from the object's edge, not
    its centre."""
    mask = hottest_region(heatmap)
    region, core = _sharp_region(heatmap, mask)
    if region is not None:
        return region
    return mask if core is None else core


def _sharp_region(heatmap: Heatmap, mask: np.ndarray):
    """(region, core) of a fused heatmap's sharpest factor (``heatmaps.sharpest_part``) when
    it is a 3D region (an object, not a place seen from above), else (None, None). With the
    product's peak on that factor's own region (at least half its peak): ``region`` is the whole
    connected region of the factor at the peak's level, ``core`` None. With the peak off it (in
    the factor's fading halo, drawn there by a broad factor whose reach barely overlaps it:
    "the duck near the flute" heard 0.46 m away): ``region`` None, ``core`` the factor's hottest
    connected region nearest the peak — the duck, not a sliver of its halo."""
    if heatmap.modality != "fused" or not heatmap.parts:
        return None, None
    sharp = heatmap.parts[sharpest_part(heatmap.parts)]
    idx = np.argwhere(mask)
    peak = tuple(idx[int(np.argmax(heatmap.values[mask]))])
    level = float(sharp.values[peak])
    box = np.ones((3, 3, 3))
    if level >= 0.5 * sharp.peak:
        labels, _ = ndimage.label(sharp.values >= level - _TIE, structure=box)
        region = labels == labels[peak]
        if _is_column(heatmap.grid, np.argwhere(region)):
            return None, None  # a place seen from above (a sound, an area) has no box to keep
        return region, None
    if not sharp.peak > 0:
        return None, None
    labels, _ = ndimage.label(sharp.values >= sharp.peak - _TIE, structure=box)
    cores = np.argwhere(labels > 0)
    nearest = cores[int(np.argmin(((cores - np.array(peak)) ** 2).sum(axis=1)))]
    core = labels == labels[tuple(nearest)]
    if _is_column(heatmap.grid, np.argwhere(core)):
        return None, None
    return None, core


def region_box(
    heatmap: Heatmap, occupancy: np.ndarray, radius: float = APPROACH_RADIUS_M
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre, lower, upper) [m] of the hottest region as a landmark for spatial relations.

    A 3D region (an object's voxels) gives its centroid and bounds; a top-down region (a place
    where a sound was heard, an image's target) gives the point :func:`max_position` gives
    (on the surface beneath), with no horizontal extent and its top at the highest surface
    within ``radius`` of it (an object's top, else the table): a target level with the
    landmark's top clears what stands there.
    """
    idx = np.argwhere(_landmark_region(heatmap))
    grid = heatmap.grid
    p = _centroid(grid, occupancy, idx)
    if _is_column(grid, idx):
        top = p.copy()
        top[2] = max(p[2], surface_z(grid, occupancy, p[:2], radius))
        return p, p.copy(), top
    centers, h = grid.centers(idx), grid.voxel_size / 2
    return p, centers.min(axis=0) - h, centers.max(axis=0) + h


def approach_point(
    grid: VoxelGrid,
    occupancy: np.ndarray,
    point,
    gap: float,
    radius: float = APPROACH_RADIUS_M,
) -> np.ndarray:
    """(3,) [m]: ``point`` raised to at least ``gap`` [m] above the highest surface within
    ``radius`` [m] of it (horizontally); unchanged when it is already that high."""
    p = np.array(point, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ConfigError(f"point must be a finite 3-vector [m], got {np.asarray(point).tolist()}")
    if not (np.isfinite(gap) and gap >= 0 and np.isfinite(radius) and radius >= 0):
        raise ConfigError(f"gap and radius must be finite and >= 0 [m], got {gap}, {radius}")
    p[2] = max(p[2], surface_z(grid, occupancy, p[:2], radius) + gap)
    return p

"""Heatmaps equal brute-force implementations of the paper's formulas."""

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.mapping.grid import VoxelGrid
from tabletop.mapping.heatmaps import (
    argmax_world,
    fuse,
    point_heatmap_3d,
    scored_points_heatmap_xy,
)

GRID = VoxelGrid(lower=(0.0, -0.2, 0.0), upper=(0.4, 0.2, 0.1), voxel_size=0.01)


def brute_object(grid, points, decay):
    """Paper eq. (obj): H(p) = max(1 - eps * min_i |p - p_i|, 0), one voxel at a time."""
    xs, ys, zs = grid.axes()
    out = np.zeros(grid.shape)
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            for k, z in enumerate(zs):
                d = np.min(np.linalg.norm(points - [x, y, z], axis=1))
                out[i, j, k] = max(1.0 - decay * d, 0.0)
    return out


def brute_scored_xy(grid, pts, scores, decay):
    """Paper eq. (area/sound): H(p) = max(max_i (s_i - eps * d_xy(p, p_i)), 0)."""
    xs, ys, _ = grid.axes()
    out = np.zeros(grid.shape)
    pairs = list(zip(pts, scores, strict=True))
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            v = max(max(s - decay * np.hypot(x - px, y - py) for (px, py), s in pairs), 0)
            out[i, j, :] = v
    return out


@pytest.mark.parametrize("decay", [10.0, 2.5])
def test_object_heatmap_equals_brute_force(decay):
    rng = np.random.default_rng(0)
    idx = np.stack([rng.integers(0, n, 12) for n in GRID.shape], axis=1)
    mask = np.zeros(GRID.shape, bool)
    mask[tuple(idx.T)] = True
    ours = point_heatmap_3d(GRID, mask, decay)
    ref = brute_object(GRID, GRID.centers(np.argwhere(mask)), decay)
    assert ours.dtype == np.float32
    np.testing.assert_allclose(ours, ref, atol=1e-5)
    assert ours.min() >= 0 and ours.max() == pytest.approx(1.0)


@pytest.mark.parametrize("decay", [10.0, 2.5])
def test_scored_xy_heatmap_equals_brute_force(decay):
    rng = np.random.default_rng(1)
    pts = rng.uniform([0.0, -0.2], [0.4, 0.2], size=(150, 2))
    scores = rng.uniform(0, 1, 150)
    ours = scored_points_heatmap_xy(GRID, pts, scores, decay)
    np.testing.assert_allclose(ours, brute_scored_xy(GRID, pts, scores, decay), atol=1e-5)


def test_decay_is_per_metre_so_voxel_size_does_not_change_meaning():
    fine = VoxelGrid(lower=(0, 0, 0), upper=(0.3, 0.02, 0.02), voxel_size=0.005)
    coarse = VoxelGrid(lower=(0, 0, 0), upper=(0.3, 0.02, 0.02), voxel_size=0.01)
    for g in (fine, coarse):
        mask = np.zeros(g.shape, bool)
        mask[0, 0, 0] = True
        h = point_heatmap_3d(g, mask, 10.0)
        xs = g.axes()[0]
        # heat at 5 cm from the target voxel centre is 0.5 at any voxel size
        i = np.argmin(np.abs(xs - (xs[0] + 0.05)))
        assert h[i, 0, 0] == pytest.approx(0.5, abs=1e-6)


def test_fusion_is_the_product_and_argmax_finds_the_peak():
    a = np.zeros(GRID.shape, np.float32)
    b = np.zeros(GRID.shape, np.float32)
    a[5:10, 5:10, 2] = 1.0
    b[7, 8, 2] = 1.0
    b[30, 30, 5] = 2.0  # hot in b alone: the product ignores it
    f = fuse(a, b)
    np.testing.assert_array_equal(f, a * b)
    np.testing.assert_allclose(argmax_world(GRID, f), GRID.centers(np.array([[7, 8, 2]]))[0])
    with pytest.raises(ConfigError, match="different grids"):
        fuse(a, np.zeros((2, 2, 2), np.float32))
    with pytest.raises(ConfigError, match="decay must be a positive rate in 1/m"):
        point_heatmap_3d(GRID, np.zeros(GRID.shape, bool), -1.0)

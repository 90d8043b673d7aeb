"""The one target selector: argmax, ties, surface placement, landmarks and the approach."""

import numpy as np
import pytest

from tabletop.errors import ConfigError, GoalNotFound
from tabletop.grid import VoxelGrid
from tabletop.mapping.heatmaps import Heatmap
from tabletop.mapping.targets import (
    approach_point,
    hottest_region,
    max_position,
    region_box,
    surface_z,
)

GRID = VoxelGrid(lower=(0.0, -0.2, 0.0), upper=(0.4, 0.2, 0.1), voxel_size=0.01)


def _h(values, found=True, modality="object"):
    return Heatmap(GRID, values.astype(np.float32), "q", modality, 10.0, 0.9, found, "why")


def test_zero_nan_and_refused_heatmaps_have_no_target():
    occ = np.zeros(GRID.shape, bool)
    with pytest.raises(GoalNotFound, match="zero everywhere"):
        max_position(_h(np.zeros(GRID.shape)), occ)
    v = np.zeros(GRID.shape)
    v[3, 3, 3] = 1.0
    with pytest.raises(GoalNotFound, match="why"):
        max_position(_h(v, found=False), occ)
    with pytest.raises(ConfigError, match="needs a Heatmap"):
        max_position(v, occ)


def test_ties_resolve_to_the_heaviest_connected_region():
    v = np.zeros(GRID.shape)
    v[2:4, 2:4, 2] = 1.0  # 4 voxels at the max
    v[30, 30, 5] = 1.0  # 1 voxel at the max, elsewhere
    mask = hottest_region(_h(v))
    assert mask.sum() == 4 and mask[2, 2, 2] and not mask[30, 30, 5]
    p = max_position(_h(v), np.zeros(GRID.shape, bool))
    np.testing.assert_allclose(p, GRID.centers(np.array([[2.5, 2.5, 2]]))[0])


def test_a_top_down_heatmap_lands_on_the_surface_beneath():
    v = np.zeros(GRID.shape)
    v[10, 20, :] = 1.0  # a whole column: a sound's or an area's heat
    occ = np.zeros(GRID.shape, bool)
    occ[10, 20, :4] = True  # an object 4 cm tall there
    p = max_position(_h(v, modality="sound"), occ)
    assert p[2] == pytest.approx(0.04)
    assert surface_z(GRID, occ, p[:2]) == pytest.approx(0.04)
    assert surface_z(GRID, np.zeros(GRID.shape, bool), p[:2]) == 0.0


def test_region_box_of_an_object_and_of_a_place():
    v = np.zeros(GRID.shape)
    v[5:8, 5:7, 0:3] = 1.0
    occ = v > 0
    c, lo, hi = region_box(_h(v), occ)
    np.testing.assert_allclose(lo, [0.05, -0.15, 0.0])
    np.testing.assert_allclose(hi, [0.08, -0.13, 0.03])
    col = np.zeros(GRID.shape)
    col[9, 6, :] = 1.0  # 2 cm beside the object: the place is level with its top
    c, lo, hi = region_box(_h(col, modality="sound"), occ)
    assert c[2] == pytest.approx(0.0) and np.array_equal(lo, c)  # the table beneath
    assert hi[2] == pytest.approx(0.03) and np.array_equal(hi[:2], c[:2])  # the object's top


def test_approach_point_clears_the_highest_surface_around():
    occ = np.zeros(GRID.shape, bool)
    occ[10, 20, :6] = True  # a 6 cm object at (0.105, 0.005)
    beside = np.array([0.135, 0.005, 0.0])  # 3 cm away, on the table
    p = approach_point(GRID, occ, beside, gap=0.04, radius=0.05)
    assert p[2] == pytest.approx(0.10) and np.array_equal(p[:2], beside[:2])
    far = np.array([0.3, 0.1, 0.0])
    assert approach_point(GRID, occ, far, gap=0.04)[2] == pytest.approx(0.04)
    high = np.array([0.105, 0.005, 0.2])
    assert approach_point(GRID, occ, high, gap=0.04)[2] == pytest.approx(0.2)
    with pytest.raises(ConfigError, match="finite 3-vector"):
        approach_point(GRID, occ, [0, 0, np.nan], gap=0.04)

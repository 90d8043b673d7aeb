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


def test_a_narrowed_object_is_a_landmark_by_its_whole_box():
    from tabletop.mapping.heatmaps import fuse, point_heatmap_3d, scored_points_heatmap_xy

    duck = np.zeros(GRID.shape, bool)
    duck[10:16, 20:26, 0:5] = True  # a 6 x 6 x 5 cm object
    other = np.zeros(GRID.shape, bool)
    other[30:36, 20:26, 0:5] = True  # one of the same kind, 14 cm away
    obj = Heatmap(GRID, point_heatmap_3d(GRID, duck | other, 10.0), "duck", "object", 10.0,
                  0.9, True)  # fmt: skip
    # a sound heard 10 cm to the duck's right: broad heat, highest at the duck's right edge
    xy = GRID.centers(np.array([[12, 10, 0]]))[:, :2]
    snd = Heatmap(GRID, scored_points_heatmap_xy(GRID, xy, np.ones(1), 2.5), "dog", "sound",
                  2.5, 0.9, True)  # fmt: skip
    fused = fuse(obj, snd)
    occ = duck | other
    # the product peaks on the duck's voxels nearest the sound, but the landmark is the duck
    assert hottest_region(fused).sum() < duck.sum()
    c, lo, hi = region_box(fused, occ)
    np.testing.assert_allclose(lo, GRID.centers(np.array([[10, 20, 0]]))[0] - 0.005, atol=1e-9)
    np.testing.assert_allclose(hi, GRID.centers(np.array([[15, 25, 4]]))[0] + 0.005, atol=1e-9)
    np.testing.assert_allclose(c, GRID.centers(np.argwhere(duck)).mean(axis=0), atol=1e-9)


def test_a_sound_whose_reach_only_grazes_the_halo_leads_to_the_object_itself():
    """The flute was heard 0.46 m from the duck, beyond the sound heatmap's 0.4 m reach but
    within it from the edge of the duck's 10 cm halo: the product peaks on a sliver of the
    halo. The target and the landmark are the duck, not that sliver."""
    from tabletop.mapping.heatmaps import fuse, point_heatmap_3d, scored_points_heatmap_xy

    grid = VoxelGrid(lower=(0.0, -0.4, 0.0), upper=(0.3, 0.4, 0.1), voxel_size=0.01)
    duck = np.zeros(grid.shape, bool)
    duck[10:16, 64:70, 0:5] = True  # centred at y = +0.27
    obj = Heatmap(grid, point_heatmap_3d(grid, duck, 10.0), "duck", "object", 10.0, 0.9, True)
    xy = np.array([[0.125, -0.19]])  # 0.46 m from the duck's centre along y
    snd = Heatmap(grid, scored_points_heatmap_xy(grid, xy, np.ones(1), 2.5), "flute", "sound",
                  2.5, 0.9, True)  # fmt: skip
    fused = fuse(obj, snd)
    peak = np.argwhere(hottest_region(fused))
    assert not duck[tuple(peak.T)].any()  # the plain product peaks in the halo
    centre = grid.centers(np.argwhere(duck)).mean(axis=0)
    p = max_position(fused, duck)
    np.testing.assert_allclose(p[:2], centre[:2], atol=1e-9)
    c, lo, hi = region_box(fused, duck)
    np.testing.assert_allclose(c, centre, atol=1e-9)
    assert hi[1] - lo[1] == pytest.approx(0.06)


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

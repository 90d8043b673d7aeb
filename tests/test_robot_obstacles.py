"""Obstacles per embodiment from the map: arm boxes, a mobile base's grid, keep-out heat."""

import numpy as np
import pytest
from robot_helpers import scan_and_map

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.robot import (
    ARM,
    MOBILE_BASE,
    Embodiment,
    arm_obstacles,
    label_voxels,
    merge_boxes,
    obstacle_voxels,
    occupancy_grid,
)
from tabletop.sim.scene import load_scene_spec


@pytest.fixture(scope="module")
def rec_map():
    return scan_and_map()


@pytest.fixture(scope="module")
def boxes(rec_map):
    return arm_obstacles(rec_map[1])


def _inside(points, boxes):
    inside = np.zeros(len(points), bool)
    for b in boxes:
        inside |= np.all(np.abs(points - b.center) <= b.half_extents + 1e-9, axis=1)
    return inside


def test_arm_boxes_cover_every_object(boxes):
    assert boxes[0].name == "table" and 1 < len(boxes) <= 2000
    lo = np.array([b.center - b.half_extents for b in boxes[1:]])
    hi = np.array([b.center + b.half_extents for b in boxes[1:]])
    for obj in load_scene_spec("default").objects:
        v = obj.vertices_world()
        v = v[v[:, 2] > 0.003]  # the bottom rests on the table slab
        gap = np.maximum(lo[None] - v[:, None], 0) + np.maximum(v[:, None] - hi[None], 0)
        d = np.linalg.norm(gap, axis=2).min(axis=1)  # [m] from each mesh vertex to the boxes
        assert (d == 0).mean() >= 0.95, obj.name
        # what a camera saw least (under a teddy's arm, a duck's tail) is within half a voxel:
        # less than the arm's clearance margin (1 cm)
        assert d.max() <= 0.006, (obj.name, d.max())


def test_table_is_one_slab_at_the_table_top(boxes):
    table = boxes[0]
    top = table.center[2] + table.half_extents[2]
    assert 0.0 <= top <= 0.011  # the voxel layer holding the table surface
    lo, hi = table.center - table.half_extents, table.center + table.half_extents
    assert lo[0] <= 0.05 and hi[0] >= 0.75 and lo[1] <= -0.55 and hi[1] >= 0.55


def test_voxels_are_labelled_by_argmax_over_the_concepts(rec_map):
    avlmap = rec_map[1]
    labels = label_voxels(avlmap, ["mug", "duck", "table"])
    s = avlmap.voxels.mean_features() @ avlmap.text.encode_text(["red mug"])[0]
    red_mug = s > 0.99  # the oracle's "red mug" voxels
    assert red_mug.sum() > 50 and np.all(labels[red_mug] == 0)


def test_embodiments_differ_on_the_same_map(rec_map, boxes):
    avlmap = rec_map[1]
    arm_ov = obstacle_voxels(avlmap, ARM)
    base = occupancy_grid(avlmap, MOBILE_BASE)
    # The table is an obstacle (a slab) for the arm and free for a base driving on it.
    assert len(arm_ov.slab_voxels) > 1000
    assert base.occupied.mean() < 0.3
    for obj in load_scene_spec("default").objects:
        c, on = base.to_cell(obj.position)
        assert on and base.inflated(0.02).occupied[tuple(c)], obj.name
    free = base.to_cell((0.1, -0.45))[0]
    assert not base.occupied[tuple(free)]
    # A base that may drive over the tray: its footprint becomes free.
    rover = Embodiment(
        "rover",
        obstacles=tuple(c for c in MOBILE_BASE.obstacles if c != "tray"),
        free=(*MOBILE_BASE.free, "tray"),
        z_range=MOBILE_BASE.z_range,
    )
    g = occupancy_grid(avlmap, rover)
    c = tuple(g.to_cell((0.45, 0.08))[0])  # on the tray, away from other objects
    assert base.occupied[c] and not g.occupied[c]
    with pytest.raises(ConfigError, match="both obstacle and free"):
        Embodiment("bad", obstacles=("mug",), free=("mug",))


def test_sound_heat_is_a_keep_out_region(rec_map):
    rec, avlmap = rec_map
    e = rec.ground_truth["sound_events"][0]
    heat = avlmap.sound_heatmap(e["caption"], major=True)
    p = np.array(e["table_point"][:2])
    plain = occupancy_grid(avlmap)
    kept = occupancy_grid(avlmap, keep_out=[heat], threshold=0.5)
    c = tuple(kept.to_cell(p)[0])
    assert kept.occupied[c]
    assert kept.occupied.sum() > plain.occupied.sum()
    far = tuple(kept.to_cell(p - [0.25, 0.0])[0])
    assert kept.occupied[far] == plain.occupied[far]
    arm_plain = obstacle_voxels(avlmap, ARM)
    arm_kept = obstacle_voxels(avlmap, ARM, keep_out=[heat.values])
    assert arm_kept.keep_out_voxels > 0 and arm_kept.mask.sum() > arm_plain.mask.sum()
    with pytest.raises(ConfigError, match="grid"):
        occupancy_grid(avlmap, keep_out=[np.zeros((3, 3, 3))])


def test_merge_boxes_is_exact_and_coarsens_to_fit():
    grid = VoxelGrid((0, 0, 0), (0.2, 0.16, 0.1), 0.01)
    rng = np.random.default_rng(0)
    mask = rng.random(grid.shape) < 0.15
    mask[2:9, 3:12, 0:6] = True
    boxes = merge_boxes(mask, grid, max_boxes=100000)
    idx = np.argwhere(np.ones(grid.shape, bool))
    centers = grid.centers(idx)
    covered = _inside(centers, boxes).reshape(grid.shape)
    np.testing.assert_array_equal(covered, mask)  # exact union
    assert len(boxes) < mask.sum()
    few = merge_boxes(mask, grid, max_boxes=40)
    assert len(few) <= 40
    assert _inside(centers[mask.ravel()], few).all()  # coarser boxes still cover
    with pytest.raises(ConfigError):
        merge_boxes(mask[:-1], grid)

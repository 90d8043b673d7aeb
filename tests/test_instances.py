"""Object instances segmented from a map's geometry: one per object, split where objects
touch, the same online as in batch, saved and restored."""

import numpy as np
import pytest
from module_helpers import GRID, box_points, coloured_voxels, text_encoder

from tabletop.errors import ConfigError
from tabletop.mapping.instances import (
    InstanceConfig,
    InstanceSet,
    instances_from_labels,
    segment_instances,
)
from tabletop.mapping.table_regions import fit_table
from tabletop.mapping.voxel_map import VoxelMap

RED, BLUE, YELLOW = (200, 30, 25), (30, 60, 180), (220, 190, 30)
BOXES = {
    "red mug": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.10), RED),
    "yellow duck": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07), YELLOW),
    "blue mug": ((0.30, -0.20, 0.01), (0.36, -0.14, 0.10), BLUE),
}


def _segment(vm, config=None):
    return segment_instances(vm, fit_table(GRID, vm.indices), config)


def _which(inst, boxes):
    """The box each instance's centre lies in."""
    out = []
    for i in inst:
        hit = [
            k
            for k, (lo, hi, _) in boxes.items()
            if np.all(i.center >= lo) and np.all(i.center <= hi)
        ]
        out.append(hit[0] if len(hit) == 1 else None)
    return out


def test_one_instance_per_object_with_its_geometry_and_colour():
    vm = coloured_voxels(BOXES)
    inst = _segment(vm)
    assert sorted(_which(inst, BOXES)) == sorted(BOXES)
    for i, name in zip(inst, _which(inst, BOXES), strict=True):
        lo, hi, rgb = BOXES[name]
        # the extent is the box's above the table layer, to a voxel
        assert np.allclose(i.hi, hi, atol=0.011) and np.allclose(i.lo[:2], lo[:2], atol=0.011)
        assert np.allclose(i.rgb, rgb, atol=1.0)
        assert i.embedding.shape == (vm.dim,) and np.isclose(np.linalg.norm(i.embedding), 1)
        cos = float(i.embedding @ text_encoder().encode_text([name])[0])
        assert cos > 0.99  # every voxel of it carries its label's embedding
    assert [i.id for i in inst] == list(range(len(inst)))
    assert inst[0].voxels >= inst[-1].voxels  # largest first


def test_touching_objects_split_where_colour_and_features_change():
    boxes = {
        "red mug": ((0.10, -0.05, 0.01), (0.16, 0.01, 0.10), RED),
        "blue mug": ((0.16, -0.05, 0.01), (0.22, 0.01, 0.10), BLUE),  # shares a face
    }
    vm = coloured_voxels(boxes)
    assert sorted(_which(_segment(vm), boxes)) == sorted(boxes)
    # with the split disabled they are one component
    merged = _segment(vm, InstanceConfig(split_delta_e=1000.0, split_cos_alone=-1.0))
    assert len(merged) == 1


def test_touching_objects_of_one_colour_split_where_the_features_alone_change():
    boxes = {
        "blue lego brick": ((0.10, -0.05, 0.01), (0.16, 0.01, 0.05), BLUE),
        "blue ball": ((0.16, -0.05, 0.01), (0.22, 0.01, 0.07), BLUE),  # shares a face
    }
    vm = coloured_voxels(boxes)
    assert sorted(_which(_segment(vm), boxes)) == sorted(boxes)
    # colour cannot tell them apart: without the features' own split they are one
    assert len(_segment(vm, InstanceConfig(split_cos_alone=-1.0))) == 1
    # one object of one kind, features alike throughout, stays whole
    one = coloured_voxels({"blue ball": ((0.10, -0.05, 0.01), (0.22, 0.01, 0.07), BLUE)})
    assert len(_segment(one)) == 1


def _brick_and_ball(cos: float, ball_x: float = 0.19):
    """A voxel map of a 6 x 6 x 3 cm brick and a ball of radius 3 cm leaning on its face
    (centre ``ball_x``), one colour, features whose cosine is ``cos``."""
    brick = box_points((0.10, -0.03, 0.01), (0.16, 0.03, 0.04))
    cube = box_points((ball_x - 0.03, -0.03, 0.01), (ball_x + 0.03, 0.03, 0.07))
    ball = cube[np.linalg.norm(cube - (ball_x, 0.0, 0.04), axis=1) <= 0.03]
    table = box_points((0.0, -0.3, 0.0), (0.6, 0.3, 0.01), 0.01)
    dim = 8
    f = np.zeros((3, dim), np.float32)
    f[0, 0] = 1.0  # the table
    f[1, 1] = 1.0  # the brick
    f[2, 1], f[2, 2] = cos, np.sqrt(1 - cos**2)  # the ball: cosine ``cos`` to the brick
    vm = VoxelMap(GRID, dim)
    pts = np.concatenate([table, brick, ball])
    which = np.repeat([0, 1, 2], [len(table), len(brick), len(ball)])
    rgb = np.where(which[:, None] == 0, 128, np.array(BLUE)).astype(np.uint8)
    vm.integrate(pts, f, rgb, feature_index=which)
    boxes = {
        "brick": ((0.10, -0.03, 0.01), (0.16, 0.03, 0.04), BLUE),
        "ball": ((ball_x - 0.03, -0.03, 0.01), (ball_x + 0.03, 0.03, 0.07), BLUE),
    }
    return vm, boxes


def test_touching_objects_of_one_colour_and_alike_features_split_where_their_shapes_fold():
    vm, boxes = _brick_and_ball(cos=0.8)  # too alike for the features alone (0.6)
    assert len(_segment(vm)) == 1  # shape off (the default): one instance
    shape = InstanceConfig(split_crease_m=0.015)
    assert sorted(_which(_segment(vm, shape), boxes)) == ["ball", "brick"]
    # the fold between them is sharp: a crease threshold well above it cuts nothing
    assert len(_segment(vm, InstanceConfig(split_crease_m=0.08))) == 1
    # features that agree keep one object's folds joined (an arm against a belly)
    same, _ = _brick_and_ball(cos=1.0)
    assert len(_segment(same, shape)) == 1
    # one convex object has no crease, whatever its features
    ball_only = coloured_voxels({"blue ball": ((0.16, -0.03, 0.01), (0.22, 0.03, 0.07), BLUE)})
    assert len(_segment(ball_only, InstanceConfig(split_crease_m=0.015, split_cos_shape=1.0))) == 1
    with pytest.raises(ConfigError, match="split_crease_m must be > 0"):
        InstanceConfig(split_crease_m=0.0)


def test_specks_are_dropped_and_no_table_means_no_instances():
    vm = coloured_voxels({"red mug": BOXES["red mug"]})
    vm.integrate(np.array([[0.5, 0.2, 0.05]]), np.zeros((1, vm.dim), np.float32), np.zeros((1, 3)))
    assert len(_segment(vm)) == 1
    assert segment_instances(vm, None) == []
    empty = VoxelMap(GRID, 4)
    assert segment_instances(empty, fit_table(GRID, empty.indices)) == []


def test_online_equals_batch_and_the_set_follows_new_frames():
    text = text_encoder()
    labels = ["table", *BOXES]
    table = text.encode_text(labels)
    parts = [(box_points((0.0, -0.3, 0.0), (0.6, 0.3, 0.01), 0.01), 0, (128, 128, 128))]
    parts += [(box_points(lo, hi), k, rgb) for k, (lo, hi, rgb) in enumerate(BOXES.values(), 1)]
    online = VoxelMap(GRID, text.dim)
    s = InstanceSet(online, lambda: fit_table(GRID, online.indices))
    counts = []
    for pts, k, rgb in parts:  # one "frame" per part
        online.integrate(pts, table, np.tile(rgb, (len(pts), 1)), np.full(len(pts), k))
        counts.append(len(s))
    assert counts == [0, 1, 2, 3]  # the set was segmented again after each frame
    batch = coloured_voxels(BOXES)
    a = sorted((tuple(np.round(i.center, 4)), i.voxels) for i in s)
    b = sorted((tuple(np.round(i.center, 4)), i.voxels) for i in _segment(batch))
    assert a == b


def test_restore_round_trips_and_rejects_bad_labels():
    vm = coloured_voxels(BOXES)
    s = InstanceSet(vm, lambda: fit_table(GRID, vm.indices))
    labels = s.labels()
    assert labels.shape == (vm.n,) and set(np.unique(labels)) == {-1, 0, 1, 2}
    again = InstanceSet(vm, lambda: None)  # no table: only the restored labels can give these
    again.restore(labels)
    assert [(i.voxels, tuple(i.center)) for i in again] == [(i.voxels, tuple(i.center)) for i in s]
    with pytest.raises(ConfigError, match="entries"):
        again.restore(labels[:-1])
    bad = labels.copy()
    bad[bad == 1] = 5
    with pytest.raises(ConfigError, match="skip"):
        instances_from_labels(vm, bad)
    with pytest.raises(ConfigError, match=">= -1"):
        again.restore(np.full(vm.n, -2))


def test_config_is_checked():
    with pytest.raises(ConfigError, match="split_cos_alone"):
        InstanceConfig(split_cos_alone=0.95)
    with pytest.raises(ConfigError, match="min_voxels"):
        InstanceConfig(min_voxels=0)
    with pytest.raises(ConfigError, match="split_cos"):
        InstanceConfig(split_cos=2.0)


def test_the_palette_separates_two_colours_but_not_one_colour_shaded():
    from tabletop.mapping.colors import rgb_to_lab, shaded_lab
    from tabletop.mapping.instances import colour_palette

    black_white = rgb_to_lab(np.array([(20, 20, 20)] * 7 + [(230, 230, 230)] * 3, float))
    pal, share = colour_palette(black_white, np.ones(10))
    assert share == pytest.approx([0.7, 0.3])
    assert pal[0][0] < 10 and pal[1][0] > 85  # black first (the larger share), then white
    # One orange, lit and shaded to 60 % of the light: one colour, no palette.
    orange = shaded_lab(np.array([(230, 110, 20)] * 6, float), [1.0, 0.6]).reshape(-1, 3)
    pal, share = colour_palette(orange, np.ones(12))
    assert pal.shape == (0, 3) and share.shape == (0,)
    assert colour_palette(black_white[:1], np.ones(1))[0].shape == (0, 3)


def _room_voxels():
    """A room at 2 cm: a floor, a wall, two tables (tops at 0.60 and 0.74 m on legs), a mug on
    each, and a board 0.3 m over the second table with a box on it."""
    from tabletop.grid import VoxelGrid

    grid = VoxelGrid(lower=(0.0, 0.0, -0.04), upper=(3.0, 2.0, 1.4), voxel_size=0.02)
    text = text_encoder()
    names = ["floor", "wall", "table", "red mug", "blue mug", "box"]
    emb = text.encode_text(names)
    parts = [
        ("floor", (0.0, 0.0, -0.02), (3.0, 2.0, 0.0), (90, 90, 90)),
        ("wall", (2.97, 0.0, 0.0), (3.0, 2.0, 1.3), (200, 200, 200)),  # its face
        ("table", (0.5, 0.5, 0.58), (1.3, 1.1, 0.60), (150, 110, 60)),
        ("table", (0.5, 0.5, 0.0), (0.56, 0.56, 0.58), (150, 110, 60)),
        ("table", (1.8, 0.8, 0.72), (2.5, 1.5, 0.74), (150, 110, 60)),
        ("table", (1.8, 0.8, 0.0), (1.86, 0.86, 0.72), (150, 110, 60)),
        ("table", (1.8, 0.8, 1.04), (2.5, 1.5, 1.06), (150, 110, 60)),  # the board
        ("red mug", (0.8, 0.7, 0.60), (0.9, 0.8, 0.70), RED),
        ("blue mug", (2.0, 1.0, 0.74), (2.1, 1.1, 0.84), BLUE),
        ("box", (2.2, 1.2, 1.06), (2.3, 1.3, 1.14), YELLOW),
    ]
    vm = VoxelMap(grid, text.dim)
    for name, lo, hi, rgb in parts:
        pts = box_points(lo, hi, 0.01)
        vm.integrate(
            pts,
            emb,
            np.tile(np.array(rgb, np.uint8), (len(pts), 1)),
            feature_index=np.full(len(pts), names.index(name), np.int64),
        )
    return grid, vm


def test_a_room_has_a_floor_table_tops_and_a_board_and_objects_stand_on_each():
    from tabletop.mapping.table_regions import fit_surfaces, raised_surfaces

    grid, vm = _room_voxels()
    surfaces = fit_surfaces(grid, vm.indices)
    heights = sorted(round(s.z, 2) for s in surfaces)
    # the floor, the two table tops and the board; the wall is no surface
    assert len(surfaces) == 4, heights
    assert np.allclose(heights, [-0.01, 0.59, 0.73, 1.05], atol=0.02)
    assert surfaces[0].z < 0.0  # the floor is the largest
    raised = raised_surfaces(surfaces, 0.2)
    assert len(raised) == 3 and min(s.z for s in raised) > 0.5

    inst = segment_instances(vm, raised, InstanceConfig(max_height_m=0.25))
    boxes = {
        "red mug": ((0.8, 0.7, 0.60), (0.9, 0.8, 0.70), RED),
        "blue mug": ((2.0, 1.0, 0.74), (2.1, 1.1, 0.84), BLUE),
        "box": ((2.2, 1.2, 1.06), (2.3, 1.3, 1.14), YELLOW),
    }
    assert sorted(_which(inst, boxes)) == sorted(boxes)  # neither legs, board nor wall
    # the one table of a tabletop scan would have been the floor: everything on it is one blob
    one = segment_instances(vm, surfaces[0])
    assert len(one) < 3 or any(i.extent[2] > 0.5 for i in one)


def test_a_flat_object_in_the_table_tops_voxel_layer_stands_out_by_its_points_heights():
    """3 cm voxels, a table top at 0.636 m and a 1.5 cm thick block lying on it: the block's
    points and the table top's share one voxel layer, so only the points' heights part them."""
    from tabletop.grid import VoxelGrid
    from tabletop.mapping.table_regions import fit_surfaces, raised_surfaces

    grid = VoxelGrid(lower=(0.0, 0.0, -0.06), upper=(2.0, 2.0, 1.2), voxel_size=0.03)
    text = text_encoder()
    names = ["floor", "table", "jenga block"]
    emb = text.encode_text(names)
    top = 0.636
    block = ((0.90, 0.90, top), (1.05, 0.99, top + 0.015))
    parts = [
        ("floor", (0.0, 0.0, -0.01), (2.0, 2.0, 0.0), (90, 90, 90)),
        ("table", (0.6, 0.6, top - 0.02), (1.4, 1.4, top), (150, 110, 60)),
        ("table", (0.6, 0.6, 0.0), (0.65, 0.65, top - 0.02), (150, 110, 60)),
        ("jenga block", *block, (120, 70, 40)),
    ]
    vm = VoxelMap(grid, text.dim)
    for name, lo, hi, rgb in parts:
        pts = box_points(lo, hi, 0.005)
        if name == "table":  # the block hides the table top beneath it
            under = np.all((pts[:, :2] >= block[0][:2]) & (pts[:, :2] <= block[1][:2]), axis=1)
            pts = pts[~under]
        vm.integrate(
            pts,
            emb,
            np.tile(np.array(rgb, np.uint8), (len(pts), 1)),
            feature_index=np.full(len(pts), names.index(name), np.int64),
        )
    assert vm.mean_heights() is not None
    by_points = InstanceConfig(supports="surfaces", heights="points", max_height_m=0.3)
    surfaces = raised_surfaces(fit_surfaces(grid, vm.indices, heights=vm.mean_heights()), 0.2)
    assert len(surfaces) == 1 and surfaces[0].z == pytest.approx(top, abs=0.005)
    inst = segment_instances(vm, surfaces, by_points)
    assert len(inst) == 1
    assert np.all(inst[0].center[:2] >= block[0][:2]) and np.all(inst[0].center[:2] <= block[1][:2])
    # judged by voxel centres, the block is lost in (or is all of) the table top's layer
    by_centres = InstanceConfig(supports="surfaces", max_height_m=0.3)
    centre_surfaces = raised_surfaces(fit_surfaces(grid, vm.indices), 0.2)
    blobs = segment_instances(vm, centre_surfaces, by_centres)
    assert not any(i.extent[0] < 0.3 for i in blobs)
    with pytest.raises(ConfigError, match="heights"):
        InstanceConfig(heights="median")
    with pytest.raises(ConfigError, match="heights"):
        fit_surfaces(grid, vm.indices, heights=np.zeros(3))


def test_a_voxel_map_without_point_heights_says_so():
    vm = coloured_voxels(BOXES)
    st = vm.state()
    h = vm.mean_heights()
    assert st["height_sums"].shape == (vm.n,) and np.all(h > vm.centers[:, 2] - 0.006)
    del st["height_sums"]
    old = VoxelMap.from_state(vm.grid, vm.dim, st)
    assert not old.has_heights and old.mean_heights() is None and "height_sums" not in old.state()
    # segmenting by points falls back to the voxel centres
    table = fit_table(GRID, vm.indices)
    by_points = segment_instances(old, table, InstanceConfig(heights="points"))
    assert len(by_points) == len(segment_instances(old, table)) == len(BOXES)

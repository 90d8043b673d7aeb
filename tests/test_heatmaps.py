"""Heatmaps equal brute-force implementations of the paper's formulas."""

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.heatmaps import (
    Heatmap,
    fuse,
    point_heatmap_3d,
    point_heatmap_3d_at,
    scored_points_heatmap_xy,
)
from tabletop.mapping.targets import max_position

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
    # from the target voxels' indices, with no mask of the grid: the same values
    np.testing.assert_array_equal(point_heatmap_3d_at(GRID, idx, decay), ours)
    assert not point_heatmap_3d_at(GRID, np.zeros((0, 3), int), decay).any()
    with pytest.raises(ConfigError, match="outside the grid"):
        point_heatmap_3d_at(GRID, [[0, 0, GRID.shape[2]]], decay)


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


def _h(values, query="q", found=True, grid=GRID, confidence=0.9):
    return Heatmap(grid, values, query, "object", 10.0, confidence, found)


def test_fusion_is_the_product_and_argmax_finds_the_peak():
    a = np.zeros(GRID.shape, np.float32)
    b = np.zeros(GRID.shape, np.float32)
    a[5:10, 5:10, 2] = 1.0
    b[7, 8, 2] = 1.0
    b[30, 30, 5] = 0.9  # hot in b alone: the product ignores it
    f = fuse(_h(a, "a"), _h(b, "b", confidence=0.7))
    np.testing.assert_array_equal(f.values, a * b)
    assert f.found and f.modality == "fused" and f.confidence == pytest.approx(0.7)
    assert [h.query for h in f.parts] == ["a", "b"]
    assert (_h(a) * _h(b)).values.tolist() == f.values.tolist()
    occ = np.zeros(GRID.shape, bool)
    np.testing.assert_allclose(max_position(f, occ), GRID.centers(np.array([[7, 8, 2]]))[0])
    other = VoxelGrid(lower=(0.0, 0.0, 0.0), upper=(0.02, 0.02, 0.02), voxel_size=0.01)
    with pytest.raises(ConfigError, match="different grids"):
        fuse(_h(a), _h(np.zeros((2, 2, 2), np.float32), grid=other))
    with pytest.raises(ConfigError, match="takes Heatmap values"):
        fuse(a, b)


def test_fused_heatmap_is_found_only_when_every_part_is_and_near_is_relative():
    a = np.zeros(GRID.shape, np.float32)
    b = np.zeros(GRID.shape, np.float32)
    a[1, 1, 1] = a[15, 15, 1] = 1.0  # two mugs
    b[20, 20, 2] = 1.0  # a sound beyond the reach of both: the plain product is zero
    broad = Heatmap(GRID, b, "s", "sound", 2.5, 0.9, True)
    f = fuse(_h(a), broad)
    assert f.found and f.confidence == pytest.approx(0.9)
    occ = np.zeros(GRID.shape, bool)  # the mug nearer the sound, not a place between
    np.testing.assert_allclose(max_position(f, occ), GRID.centers(np.array([[15, 15, 1]]))[0])
    assert f.values[1, 1, 1] < f.values[15, 15, 1] < 0.01  # faint: heat beyond reach
    # a place on the table contains what is in it: a mug outside it is not there
    area = Heatmap(GRID, b, "the left side", "area", 2.5, 1.0, True)
    g = fuse(_h(a), area)
    assert not g.found and "no place in the map has heat from every part" in g.reason
    missing = Heatmap.not_found(GRID, "giraffe", "object", 10.0, "no voxel matches")
    g = fuse(_h(a), missing)
    assert not g.found and "giraffe" in g.reason and "no voxel matches" in g.reason
    assert g.confidence == 0.0


def test_heatmap_values_are_checked_and_read_only():
    with pytest.raises(ConfigError, match="non-finite"):
        _h(np.full(GRID.shape, np.nan, np.float32))
    with pytest.raises(ConfigError, match=r"in \[0, 1\]"):
        _h(np.full(GRID.shape, 2.0, np.float32))
    with pytest.raises(ConfigError, match="not on the grid"):
        _h(np.zeros((3, 3, 3), np.float32))
    with pytest.raises(ConfigError, match="unknown modality"):
        Heatmap(GRID, np.zeros(GRID.shape, np.float32), "q", "smell", 1.0, 0.5, True)
    h = _h(np.zeros(GRID.shape, np.float32))
    assert not h.values.flags.writeable
    with pytest.raises(ConfigError, match="non-finite"):  # one inf among finite values
        v = np.zeros(GRID.shape, np.float32)
        v[3, 4, 5] = np.inf
        _h(v)
    v = np.zeros(GRID.shape, np.float32)
    v[1, 2, 3] = 0.7
    assert _h(v).peak == pytest.approx(0.7) and h.peak == 0.0


def test_the_box_of_a_mask_finds_its_cells_as_argwhere_does():
    from tabletop.grid import box_argwhere, mask_box

    rng = np.random.default_rng(4)
    for _ in range(50):
        mask = np.zeros(tuple(int(n) for n in rng.integers(1, 12, 3)), bool)
        for _ in range(int(rng.integers(0, 5))):
            mask[tuple(int(rng.integers(0, n)) for n in mask.shape)] = True
        cells = np.argwhere(mask)
        np.testing.assert_array_equal(box_argwhere(mask), cells)
        box = mask_box(mask)
        if not len(cells):
            assert box is None
        else:
            assert box == tuple(slice(int(c.min()), int(c.max()) + 1) for c in cells.T)


def test_decay_must_be_positive():
    with pytest.raises(ConfigError, match="decay must be a positive rate in 1/m"):
        point_heatmap_3d(GRID, np.zeros(GRID.shape, bool), -1.0)


def test_two_heatmaps_compare_by_what_they_say_and_hash_alike():
    # == compared identity: two heatmaps of the same values and query were unequal
    v = np.zeros(GRID.shape, np.float32)
    v[3, 4, 5] = 0.75
    a, b = _h(v), _h(v.copy())
    assert a == b and not (a != b) and hash(a) == hash(b) and len({a, b}) == 1
    w = v.copy()
    w[0, 0, 0] = 0.5
    assert a != _h(w)  # other values
    assert a != _h(v, query="other") and a != _h(v, confidence=0.5) and a != _h(v, found=False)
    assert a.with_values(v, target=(0.1, 0.0, 0.05)) != a  # a target
    assert fuse(a, b) == fuse(b.with_values(v), a) and fuse(a, b) != a  # parts compared too
    # a number or an array is refused by name, with what to compare instead
    for other in (0.75, 1, np.float32(0.0), v):
        with pytest.raises(TypeError, match=r"use h.values .* numpy.allclose"):
            a == other  # noqa: B015
        with pytest.raises(TypeError, match="a heatmap equals only another Heatmap"):
            a != other  # noqa: B015
    with pytest.raises(TypeError, match="a heatmap equals only another Heatmap"):
        v == a  # noqa: B015  (numpy defers to the heatmap)
    assert a != None and a != "q" and a in [None, b]  # noqa: E711

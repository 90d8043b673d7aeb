"""Voxel fusion: scatter-mean equals a per-point reference; online equals batch."""

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.voxel_map import VoxelMap

GRID = VoxelGrid(lower=(0.0, 0.0, 0.0), upper=(0.2, 0.2, 0.1), voxel_size=0.01)


def reference_means(points, features):
    """Per-point loop: the mean feature of the points in each voxel (dict of voxel -> mean)."""
    sums, counts = {}, {}
    for p, f in zip(points, features, strict=True):
        idx = tuple(np.floor((p - GRID.lower) / GRID.voxel_size).astype(int))
        if not all(0 <= i < n for i, n in zip(idx, GRID.shape, strict=True)):
            continue
        sums[idx] = sums.get(idx, 0) + f
        counts[idx] = counts.get(idx, 0) + 1
    return {k: sums[k] / counts[k] for k in sums}, counts


def test_world_voxel_world_round_trip():
    rng = np.random.default_rng(0)
    idx = np.stack([rng.integers(0, n, 50) for n in GRID.shape], axis=1)
    back, inside = GRID.world_to_index(GRID.centers(idx))
    assert inside.all()
    np.testing.assert_array_equal(back, idx)
    np.testing.assert_array_equal(GRID.unravel(GRID.linear(idx)), idx)
    _, inside = GRID.world_to_index(np.array([[-0.001, 0.1, 0.05], [0.1, 0.1, 0.1]]))
    assert not inside.any()


def test_scatter_mean_equals_per_point_loop():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.02, 0.22, size=(3000, 3)) * [1, 1, 0.5]
    feats = rng.normal(size=(3000, 8)).astype(np.float32)
    m = VoxelMap(GRID, 8, capacity=4)  # tiny capacity: growth is exercised
    m.integrate(pts[:1000], feats[:1000])
    m.integrate(pts[1000:], feats[1000:])
    ref, counts = reference_means(pts, feats)
    assert m.n == len(ref)
    got = m.mean_features(normalize=False)
    for row, idx in enumerate(map(tuple, m.indices)):
        np.testing.assert_allclose(got[row], ref[idx], rtol=1e-5, atol=1e-6)
        assert m.counts[row] == counts[idx]


def test_online_and_batch_give_the_same_map():
    rng = np.random.default_rng(2)
    frames = [
        (rng.uniform(0, 0.2, (500, 3)) * [1, 1, 0.5], rng.normal(size=(500, 4))) for _ in range(6)
    ]
    online = VoxelMap(GRID, 4)
    for p, f in frames:
        online.integrate(p, f.astype(np.float32))
    batch = VoxelMap(GRID, 4)
    batch.integrate(
        np.concatenate([p for p, _ in frames]),
        np.concatenate([f for _, f in frames]).astype(np.float32),
    )
    order_a = np.argsort(online.linear_indices)
    order_b = np.argsort(batch.linear_indices)
    np.testing.assert_array_equal(online.linear_indices[order_a], batch.linear_indices[order_b])
    np.testing.assert_allclose(
        online.mean_features()[order_a], batch.mean_features()[order_b], atol=1e-6
    )


@pytest.mark.parametrize("pending_points", [1, 700, 1 << 30])
def test_feature_tables_summed_a_few_frames_at_a_time_equal_the_per_point_loop(
    pending_points, monkeypatch
):
    """Frames give their features as a table and each point's row in it (one table shared by
    several frames, or a new one each frame); the map sums them a few frames at a time, and a
    read in between sees every frame given so far."""
    import tabletop.mapping.voxel_map as vm

    monkeypatch.setattr(vm, "PENDING_POINTS", pending_points)
    rng = np.random.default_rng(4)
    shared = rng.normal(size=(5, 6)).astype(np.float32)
    m = VoxelMap(GRID, 6, capacity=4)
    all_pts, all_feats = [], []
    for k in range(9):
        pts = rng.uniform(-0.02, 0.22, size=(300, 3)) * [1, 1, 0.5]
        table = shared if k % 3 else rng.normal(size=(7, 6)).astype(np.float32)
        index = rng.integers(0, len(table), len(pts))
        m.integrate(pts, table, feature_index=index)
        all_pts.append(pts)
        all_feats.append(table[index])
        if k == 4:  # a read mid-way: what has been given so far
            ref, _ = reference_means(np.concatenate(all_pts), np.concatenate(all_feats))
            got = m.mean_features(normalize=False)
            assert m.n == len(ref)
            for row, idx in enumerate(map(tuple, m.indices)):
                np.testing.assert_allclose(got[row], ref[idx], rtol=1e-5, atol=1e-6)
    ref, counts = reference_means(np.concatenate(all_pts), np.concatenate(all_feats))
    got, state = m.mean_features(normalize=False), m.state()
    assert m.n == len(ref) and len(state["feature_sums"]) == m.n
    for row, idx in enumerate(map(tuple, m.indices)):
        np.testing.assert_allclose(got[row], ref[idx], rtol=1e-5, atol=1e-6)
        assert m.counts[row] == counts[idx]


def test_state_round_trip_and_validation():
    rng = np.random.default_rng(3)
    m = VoxelMap(GRID, 4)
    m.integrate(
        rng.uniform(0, 0.1, (200, 3)),
        rng.normal(size=(200, 4)).astype(np.float32),
        rng.integers(0, 255, (200, 3)),
    )
    again = VoxelMap.from_state(GRID, 4, m.state())
    np.testing.assert_array_equal(again.mean_features(), m.mean_features())
    np.testing.assert_array_equal(again.mean_colors(), m.mean_colors())
    np.testing.assert_array_equal(again.occupancy(), m.occupancy())
    bad = m.state()
    bad["linear"] = bad["linear"] + GRID.size
    with pytest.raises(ConfigError, match="outside its grid"):
        VoxelMap.from_state(GRID, 4, bad)
    with pytest.raises(ConfigError, match=r"features must be \(2, 4\)"):
        m.integrate(np.zeros((2, 3)), np.zeros((2, 5), np.float32))


def test_march_stops_at_the_first_occupied_voxel_within_reach():
    occ = np.zeros(GRID.shape, bool)
    occ[10, 10, 2] = True  # the voxel [0.10, 0.11) x [0.10, 0.11) x [0.02, 0.03)
    origin = np.array([0.105, 0.105, 0.095])
    down = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    hit, point = GRID.march(origin, down, occ, 0.2)
    assert hit.tolist() == [True, False]
    assert GRID.world_to_index(point[:1])[0][0].tolist() == [10, 10, 2]  # a sample inside it
    assert point[0, 2] > 0.02 + GRID.voxel_size / 4  # the first such sample: from above
    hit, _ = GRID.march(origin, down, occ, [0.05, 0.2])  # per-ray reach: stops short
    assert not hit.any()


@pytest.mark.parametrize("origin", [(0.1, 0.1, 0.05), (-0.05, 0.1, 0.12), (0.1, 0.0, 0.05)])
def test_march_finds_each_rays_first_occupied_sample_as_a_step_by_step_walk(origin):
    """Rays of many lengths (several of the march's chunks of steps), some hitting, some not,
    some along the grid's axes, from inside the grid, outside it and on its face: the first
    occupied half-voxel sample of each, as a ray walked one sample at a time finds it."""
    rng = np.random.default_rng(7)
    occ = rng.random(GRID.shape) < 0.01
    origin = np.array(origin)
    rays = rng.normal(size=(300, 3))
    rays[:24] = np.repeat(np.vstack([np.eye(3), -np.eye(3)]), 4, axis=0)  # along the axes
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    reach = rng.uniform(0.0, 0.4, len(rays))
    hit, point = GRID.march(origin, rays, occ, reach)
    step = GRID.voxel_size / 2
    assert 0 < hit.sum() < len(rays)
    for r, d, h, p in zip(rays, reach, hit, point, strict=True):
        first = None
        for k in range(int(np.ceil(0.4 / step)) + 1):
            t = k * step
            if t >= 0.4 or t > d:
                break
            q = origin + t * r
            idx, inside = GRID.world_to_index(q[None])
            if inside[0] and occ[tuple(idx[0])]:
                first = q
                break
        assert h == (first is not None)
        if h:
            np.testing.assert_array_equal(p, first)

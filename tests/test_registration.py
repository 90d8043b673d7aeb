"""Table registration: frames whose recorded poses are off in height and tilt are corrected onto
the table the other frames see; exact poses are left exactly as they are."""

import math

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.mapping.registration import RegistrationConfig, table_corrections
from tabletop.transforms import make_transform, rotation_about

K = np.array([[200.0, 0, 80], [0, 200.0, 60], [0, 0, 1]])
H, W = 120, 160


def _look_down(x, y, z, yaw=0.0):
    """A camera at (x, y, z) looking straight down (optical z along world -z)."""
    R = rotation_about("z", yaw) @ np.diag([1.0, -1.0, -1.0])
    return make_transform(R, [x, y, z])


def _render(T_world_cam, box=((0.45, 0.0), 0.04, 0.03)):
    """Depth of a table at z = 0 with a box (centre, half-size, height) on it."""
    v, u = np.mgrid[0:H, 0:W].astype(float)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    R, t = T_world_cam[:3, :3], T_world_cam[:3, 3]
    d_world = rays @ R.T
    depth = -t[2] / d_world[..., 2]  # along the optical axis (rays have z = 1)
    (cx, cy), half, top = box
    hit_top = (top - t[2]) / d_world[..., 2]
    p = t + hit_top[..., None] * d_world
    on_box = (np.abs(p[..., 0] - cx) < half) & (np.abs(p[..., 1] - cy) < half)
    return np.where(on_box, hit_top, depth).astype(np.float32)


def _scan(n=40, seed=0):
    rng = np.random.default_rng(seed)
    poses = [
        _look_down(0.35 + 0.2 * rng.random(), -0.1 + 0.2 * rng.random(), 0.4, rng.uniform(-1, 1))
        for _ in range(n)
    ]
    return np.stack(poses), np.stack([_render(T) for T in poses])


def test_exact_poses_are_left_exactly_as_they_are():
    T, depth = _scan()
    c = table_corrections(depth, K, T)
    assert c.table_frames == len(T) and not c.any
    assert c.height_m == pytest.approx(0.0, abs=1e-4)
    np.testing.assert_array_equal(c.C, np.tile(np.eye(4), (len(T), 1, 1)))


def test_height_and_tilt_errors_are_corrected_onto_the_table():
    T, depth = _scan(n=100)
    rng = np.random.default_rng(1)
    noisy = T.copy()
    for i in range(len(T)):
        err = make_transform(
            rotation_about("x", rng.normal(0, math.radians(1)))
            @ rotation_about("y", rng.normal(0, math.radians(1))),
            rng.normal(0, 0.005, 3),
        )
        noisy[i] = noisy[i] @ err
    c = table_corrections(depth, K, noisy)
    assert c.corrected.mean() > 0.9
    fixed = c.C @ noisy

    def tilt_deg(A):
        return np.degrees(
            np.arccos(np.clip(np.einsum("ni,ni->n", A[:, :3, 2], T[:, :3, 2]), -1, 1))
        )

    before_dz = np.abs(noisy[:, 2, 3] - T[:, 2, 3]).mean()
    after_dz = np.abs(fixed[:, 2, 3] - T[:, 2, 3]).mean()
    assert before_dz > 0.002 and after_dz < 0.0005, (before_dz, after_dz)
    # every frame now agrees on the table (a thin table), and that table is level
    assert tilt_deg(noisy).mean() > 0.7 and tilt_deg(fixed).std() < 0.02
    assert tilt_deg(fixed).mean() < 0.05
    # the correction is rigid
    R = c.C[:, :3, :3]
    np.testing.assert_allclose(
        R @ np.swapaxes(R, 1, 2), np.tile(np.eye(3), (len(T), 1, 1)), atol=1e-9
    )


def test_a_tilt_all_frames_share_is_levelled_unless_the_table_may_be_tilted():
    # a camera extrinsic that is off by a rotation, seen from cameras that all look down alike:
    # every frame sees the table tilted by the same 1 deg
    T, depth = _scan(n=40)
    off = make_transform(rotation_about("x", math.radians(1.0)), [0.0, 0.0, 0.0])
    wrong = off @ T

    def table_tilt_deg(C):  # the table (z = 0 in the true frames) as the corrected frames see it
        n = (C @ wrong @ np.linalg.inv(T))[:, :3, 2]
        return np.degrees(np.arccos(np.clip(n[:, 2], -1, 1)))

    shared = table_corrections(depth, K, wrong, RegistrationConfig(level=False))
    assert not shared.any  # the frames agree with each other: the median keeps their tilt
    assert table_tilt_deg(shared.C).min() > 0.9
    level = table_corrections(depth, K, wrong)
    assert level.corrected.all()
    assert table_tilt_deg(level.C).max() < 0.02


def test_a_frame_whose_dominant_plane_is_another_surface_is_not_moved_onto_it():
    T, depth = _scan(n=30)
    high = _look_down(0.45, 0.0, 0.12)  # close over the box: its top fills the view
    d = _render(high, box=((0.45, 0.0), 0.2, 0.08))
    c = table_corrections(np.concatenate([depth, d[None]]), K, np.concatenate([T, high[None]]))
    assert not c.corrected[-1]  # 8 cm above the table: not the table, not corrected
    assert c.height_m == pytest.approx(0.0, abs=1e-4)


def test_disabled_registration_corrects_nothing_and_bad_settings_are_named():
    T, depth = _scan(n=5)
    noisy = T.copy()
    noisy[:, 2, 3] += 0.01
    c = table_corrections(depth, K, noisy, RegistrationConfig(enabled=False))
    assert not c.any and c.height_m is None
    with pytest.raises(ConfigError, match="min_inlier_fraction must be in"):
        RegistrationConfig(min_inlier_fraction=0)
    with pytest.raises(ConfigError, match="inlier_m must be a number"):
        RegistrationConfig(inlier_m=float("nan"))


BOXES = (((0.42, -0.06), 0.03, 0.10), ((0.50, 0.05), 0.025, 0.14), ((0.36, 0.08), 0.035, 0.07))


def _render_boxes(T_world_cam):
    """Depth of a table at z = 0 with upright boxes (centre, half-size, height) on it."""
    v, u = np.mgrid[0:H, 0:W].astype(float)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
    R, t = T_world_cam[:3, :3], T_world_cam[:3, 3]
    d = rays @ R.T  # world direction per pixel, scaled so that camera depth is the parameter
    best = np.where(d[..., 2] < 0, -t[2] / np.where(d[..., 2] < 0, d[..., 2], -1), np.inf)
    for (cx, cy), half, top in BOXES:
        lo, hi = np.array([cx - half, cy - half, 0.0]), np.array([cx + half, cy + half, top])
        with np.errstate(divide="ignore", invalid="ignore"):
            a, b = (lo - t) / d, (hi - t) / d
        near = np.nanmax(np.minimum(a, b), axis=-1)
        far = np.nanmin(np.maximum(a, b), axis=-1)
        hit = (near <= far) & (near > 0)
        best = np.where(hit & (near < best), near, best)
    return np.where(np.isfinite(best), best, 0.0).astype(np.float32)


def _box_scan(n=60, seed=0):
    """Views from all round the boxes, tilted so that their sides are seen."""
    rng = np.random.default_rng(seed)
    poses = []
    for _ in range(n):
        az = rng.uniform(-math.pi, math.pi)
        eye = np.array([0.43 + 0.3 * math.cos(az), 0.02 + 0.3 * math.sin(az), 0.35])
        z = np.array([0.43, 0.02, 0.03]) - eye + rng.normal(0, 0.02, 3)
        z /= np.linalg.norm(z)
        x = np.cross(z, [0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        poses.append(make_transform(np.stack([x, np.cross(z, x), z], axis=1), eye))
    return np.stack(poses), np.stack([_render_boxes(T) for T in poses])


def test_horizontal_shift_and_yaw_are_registered_on_what_stands_on_the_table():
    T, depth = _box_scan()
    planar = RegistrationConfig(planar=True)
    exact = table_corrections(depth, K, T, planar)
    np.testing.assert_array_equal(exact.C, np.tile(np.eye(4), (len(T), 1, 1)))
    rng = np.random.default_rng(2)
    noisy = np.stack(
        [
            make_transform(rotation_about("z", rng.normal(0, math.radians(0.5))), [*s, 0.0]) @ P
            for P, s in zip(T, rng.normal(0, 0.005, (len(T), 2)), strict=True)
        ]
    )
    probe = np.array([0.43, 0.02, 0.05, 1.0])  # a point among the boxes

    def spread(A):  # how far the frames disagree there, less what they share
        err = (A @ np.linalg.inv(T) @ probe)[:, :2] - probe[:2]
        return float(np.linalg.norm(err - np.median(err, axis=0), axis=1).mean())

    table_only = table_corrections(depth, K, noisy, RegistrationConfig(planar=False))
    fixed = table_corrections(depth, K, noisy, planar)
    assert spread(table_only.C @ noisy) > 0.004  # the table alone cannot see these errors
    assert spread(fixed.C @ noisy) < 0.65 * spread(noisy), (spread(noisy), spread(fixed.C @ noisy))


def test_a_frame_is_not_slid_along_surfaces_it_already_lies_on():
    # exact poses, depth with 1 mm of noise: an alignment without the gain check still finds
    # something to slide; nothing brings the points closer, so nothing is corrected
    T, depth = _box_scan()
    rng = np.random.default_rng(3)
    depth = (depth + (depth > 0) * rng.normal(0, 0.001, depth.shape)).astype(np.float32)
    assert table_corrections(depth, K, T, RegistrationConfig(planar_min_gain_m=0.0)).any
    assert not table_corrections(depth, K, T).any

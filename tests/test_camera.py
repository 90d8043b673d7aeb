import numpy as np
import pybullet as pb
import pytest

from tabletop.errors import ConfigError
from tabletop.sim.camera import (
    CameraIntrinsics,
    WristCameraConfig,
    depth_from_gl_buffer,
    gl_projection_matrix,
    gl_view_matrix,
)
from tabletop.transforms import backproject, invert, make_transform, rotation_about


def test_projection_matches_pybullet_fov_matrix_for_centred_principal_point():
    intr = CameraIntrinsics.from_fov(320, 240, 58.0)
    ours = np.array(gl_projection_matrix(intr, 0.07, 3.0))
    ref = np.array(pb.computeProjectionMatrixFOV(58.0, 320 / 240, 0.07, 3.0))
    np.testing.assert_allclose(ours, ref, atol=1e-6)


def test_projection_and_view_map_a_point_to_its_opencv_pixel():
    # Off-centre principal point: the GL matrices must reproduce K exactly.
    K = np.array([[300.0, 0, 150.3], [0, 290.0, 125.7], [0, 0, 1]])
    intr = CameraIntrinsics(320, 240, K)
    T_world_cam = make_transform(
        rotation_about("x", 2.5) @ rotation_about("z", 0.3), (0.2, -0.1, 0.6)
    )
    p_cam = np.array([0.05, -0.03, 0.45])
    p_world = T_world_cam[:3, :3] @ p_cam + T_world_cam[:3, 3]
    V = np.array(gl_view_matrix(T_world_cam)).reshape(4, 4, order="F")
    P = np.array(gl_projection_matrix(intr, 0.07, 3.0)).reshape(4, 4, order="F")
    clip = P @ V @ np.append(p_world, 1.0)
    ndc = clip[:3] / clip[3]
    u = (ndc[0] + 1) / 2 * 320 - 0.5
    v = 240 - (ndc[1] + 1) / 2 * 240 - 0.5
    u_ref, v_ref, _ = K @ (p_cam / p_cam[2])
    np.testing.assert_allclose([u, v], [u_ref, v_ref], atol=1e-9)
    # and the depth buffer value converts back to the optical-axis depth
    d = (ndc[2] + 1) / 2
    np.testing.assert_allclose(depth_from_gl_buffer(np.array([d]), 0.07, 3.0), [0.45], atol=1e-9)


def test_backproject_inverts_projection():
    intr = CameraIntrinsics.from_fov(320, 240, 60.0)
    depth = np.zeros((240, 320), np.float32)
    depth[100, 200] = 0.5
    depth[10, 5] = 1.25
    pts = backproject(depth, intr.K)
    uv = (intr.K @ (pts / pts[:, 2:]).T).T[:, :2]
    assert sorted(map(tuple, np.round(uv, 6))) == [(5.0, 10.0), (200.0, 100.0)]
    assert sorted(pts[:, 2]) == pytest.approx([0.5, 1.25])


def test_depth_outside_range_is_invalid():
    z = depth_from_gl_buffer(np.array([0.0, 0.5, 1.0]), 0.07, 3.0)
    assert z[0] == pytest.approx(0.07)
    assert 0.07 < z[1] < 3.0
    assert z[2] == 0.0


def test_config_rejects_small_images_and_bad_extrinsic():
    with pytest.raises(ConfigError, match="at least 320x240"):
        WristCameraConfig(width=160, height=120)
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ConfigError, match="T_hand_cam rotation"):
        WristCameraConfig(T_hand_cam=bad)
    with pytest.raises(ConfigError, match="16 bits"):
        WristCameraConfig(far=10.0)


def test_intrinsics_are_read_only():
    intr = CameraIntrinsics.from_fov(320, 240, 60.0)
    with pytest.raises(ValueError):
        intr.K[0, 0] = 1.0
    assert np.allclose(
        invert(invert(WristCameraConfig().T_hand_cam)), WristCameraConfig().T_hand_cam
    )

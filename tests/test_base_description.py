"""The base's URDF: its DiffDriveParams and mast frames are what the code assumes."""

import numpy as np
import pybullet as pb
import pytest

from tabletop.base import TABLETOP_BASE, base_urdf_path, load_base_description
from tabletop.base.description import CAMERA_FRAME, MIC_FRAME, WHEEL_JOINTS
from tabletop.transforms import make_transform, quat_to_matrix


def test_urdf_params_match_the_constant():
    d = load_base_description()
    assert d.params == TABLETOP_BASE
    # the camera looks forward and 20-30 degrees down from about 1.1 m
    T = d.T_base_cam
    assert 1.0 <= T[2, 3] <= 1.2
    pitch = np.degrees(np.arcsin(-T[2, 2]))
    assert 20 <= pitch <= 30 and T[0, 2] > 0.8
    assert T[:3, 0] @ [0, -1, 0] == pytest.approx(1.0)  # image x = the robot's right
    assert 0.5 < d.T_base_mic[2, 3] < 1.2


def test_pybullet_agrees_with_the_parsed_urdf():
    cid = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(base_urdf_path()), [0, 0, 0], physicsClientId=cid)
        links, joints = {}, {}
        for j in range(pb.getNumJoints(body, physicsClientId=cid)):
            info = pb.getJointInfo(body, j, physicsClientId=cid)
            links[info[12].decode()] = j
            joints[info[1].decode()] = info
        d = load_base_description()
        for name, T in ((CAMERA_FRAME, d.T_base_cam), (MIC_FRAME, d.T_base_mic)):
            st = pb.getLinkState(
                body, links[name], computeForwardKinematics=True, physicsClientId=cid
            )
            assert np.allclose(make_transform(quat_to_matrix(st[5]), st[4]), T, atol=1e-6)
        for name in WHEEL_JOINTS:
            info = joints[name]
            assert info[2] == pb.JOINT_REVOLUTE and info[11] == TABLETOP_BASE.max_wheel_speed
            st = pb.getLinkState(body, info[0], computeForwardKinematics=True, physicsClientId=cid)
            assert st[4][2] == pytest.approx(TABLETOP_BASE.wheel_radius)
            assert abs(st[4][1]) == pytest.approx(TABLETOP_BASE.wheel_separation / 2)
        lo, hi = pb.getAABB(body, -1, physicsClientId=cid)
        for j in range(pb.getNumJoints(body, physicsClientId=cid)):
            a, b = pb.getAABB(body, j, physicsClientId=cid)
            lo, hi = np.minimum(lo, a), np.maximum(hi, b)
        assert max(np.abs(lo[:2]).max(), np.abs(hi[:2]).max()) <= TABLETOP_BASE.radius + 0.01
    finally:
        pb.disconnect(cid)

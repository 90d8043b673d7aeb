"""The Pinocchio Panda model: FK against PyBullet, limits, frames, validation."""

import numpy as np
import pybullet as pb
import pytest

from tabletop.arm.errors import FrameError
from tabletop.arm.model import ARM_JOINT_NAMES, HOME_Q, TCP_FRAME, PandaModel
from tabletop.errors import ConfigError
from tabletop.paths import panda_urdf_path
from tabletop.transforms import quat_to_matrix

FRAMES = ("panda_link1", "panda_link4", "panda_link7", "panda_hand", TCP_FRAME)


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def bullet():
    cid = pb.connect(pb.DIRECT)
    robot = pb.loadURDF(str(panda_urdf_path()), [0, 0, 0], useFixedBase=True, physicsClientId=cid)
    joints, links = {}, {}
    for j in range(pb.getNumJoints(robot, physicsClientId=cid)):
        info = pb.getJointInfo(robot, j, physicsClientId=cid)
        joints[info[1].decode()] = j
        links[info[12].decode()] = j
    yield cid, robot, joints, links
    pb.disconnect(cid)


def test_fk_matches_pybullet_to_1e6_over_random_configurations(model, bullet):
    cid, robot, joints, links = bullet
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = model.random_q(rng)
        for name, v in zip(ARM_JOINT_NAMES, q, strict=True):
            pb.resetJointState(robot, joints[name], float(v), physicsClientId=cid)
        poses = model.fk_frames(q, FRAMES)
        for frame in FRAMES:
            st = pb.getLinkState(
                robot, links[frame], computeForwardKinematics=True, physicsClientId=cid
            )
            T_pin = poses[frame]
            assert np.abs(T_pin[:3, 3] - np.array(st[4])).max() < 1e-6, frame
            assert np.abs(T_pin[:3, :3] - quat_to_matrix(st[5])).max() < 1e-6, frame


def test_tcp_is_105mm_beyond_the_hand_along_its_z(model):
    T_hand = model.fk(HOME_Q, "panda_hand")
    T_tcp = model.fk(HOME_Q)
    np.testing.assert_allclose(T_tcp[:3, 3], T_hand[:3, 3] + 0.105 * T_hand[:3, 2], atol=1e-12)


def test_limits_are_frozen_and_match_the_urdf(model):
    assert model.joint_names == ARM_JOINT_NAMES
    assert model.q_lower.shape == model.q_upper.shape == model.v_max.shape == (7,)
    assert model.q_lower[3] == pytest.approx(-3.1416)
    assert model.v_max[0] == pytest.approx(2.175)
    with pytest.raises(ValueError, match="read-only"):
        model.q_lower[0] = 0.0
    assert model.within_limits(HOME_Q)
    assert not model.within_limits(model.q_upper + 0.1)
    np.testing.assert_array_equal(model.clip(model.q_upper + 1.0), model.q_upper)


def test_jacobian_matches_finite_differences(model):
    rng = np.random.default_rng(3)
    q = model.random_q(rng, margin=0.2)
    J = model.jacobian(q)
    T0 = model.fk(q)
    h = 1e-6
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = h
        T1 = model.fk(q + dq)
        np.testing.assert_allclose((T1[:3, 3] - T0[:3, 3]) / h, J[:3, i], atol=1e-5)
        dR = T1[:3, :3] @ T0[:3, :3].T
        w = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / (2 * h)
        np.testing.assert_allclose(w, J[3:, i], atol=1e-5)


def test_unknown_frame_names_the_options(model):
    with pytest.raises(FrameError, match=r"frame 'hnd' not in the Panda model; available: \["):
        model.fk(HOME_Q, "hnd")
    assert "panda_grasptarget" in model.frame_names


def test_bad_configuration_shape_is_refused(model):
    with pytest.raises(ConfigError, match=r"q must have shape \(7,\)"):
        model.fk(np.zeros(9))
    with pytest.raises(ConfigError, match="non-finite"):
        model.fk(np.full(7, np.nan))

"""The MuJoCo model generated from the URDF: joints, geoms, FK identical to Pinocchio."""

import mujoco
import numpy as np
import pytest

from tabletop.arm.mjcf import build_mujoco_model, obstacle_geom_names, urdf_for_mujoco
from tabletop.arm.model import ARM_JOINT_NAMES, PandaModel
from tabletop.arm.obstacles import Box, ConvexObstacle, Cylinder, table_box
from tabletop.errors import ConfigError

OBSTACLES = [
    table_box(),
    Box([0.5, 0.1, 0.05], [0.03, 0.03, 0.05], name="cube"),
    Cylinder([0.4, -0.2, 0.06], 0.03, 0.12, name="can"),
    ConvexObstacle(Box([0.6, 0.3, 0.04], [0.02, 0.02, 0.04]).vertices(), name="hull"),
]


@pytest.fixture(scope="module")
def mj_model():
    return build_mujoco_model(OBSTACLES)


def test_urdf_is_rewritten_for_mujoco():
    text = urdf_for_mujoco()
    assert "package://" not in text
    assert 'fusestatic="false"' in text and 'discardvisual="true"' in text
    assert 'name="panda_finger_joint1" type="fixed"' in text


def test_model_has_the_seven_arm_joints_and_named_obstacles(mj_model):
    assert tuple(mj_model.joint(i).name for i in range(mj_model.njnt)) == ARM_JOINT_NAMES
    for name in obstacle_geom_names(OBSTACLES):
        assert mj_model.geom(name).id >= 0
    assert mj_model.body("panda_grasptarget").id > 0


def test_fk_matches_pinocchio(mj_model):
    model = PandaModel()
    data = mujoco.MjData(mj_model)
    rng = np.random.default_rng(11)
    for _ in range(20):
        q = model.random_q(rng)
        data.qpos[:] = q
        mujoco.mj_kinematics(mj_model, data)
        for frame in ("panda_hand", "panda_grasptarget", "panda_leftfinger"):
            T = model.fk(q, frame)
            np.testing.assert_allclose(data.body(frame).xpos, T[:3, 3], atol=1e-9)
            np.testing.assert_allclose(data.body(frame).xmat.reshape(3, 3), T[:3, :3], atol=1e-9)


def test_unsupported_obstacle_is_refused():
    with pytest.raises(ConfigError, match="cannot hold a str; valid: Box, Cylinder"):
        build_mujoco_model(["table"])

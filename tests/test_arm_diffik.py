"""The mink controller: convergence, velocity limits, collision-avoidance limits."""

import numpy as np
import pytest

from tabletop.arm.collision import CollisionChecker
from tabletop.arm.diffik import DiffIKConfig, MinkDiffIK, top_down_rotation
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, table_box
from tabletop.errors import ConfigError
from tabletop.transforms import make_transform

BOX = Box([0.5, 0.0, 0.06], [0.04, 0.04, 0.06], name="box")


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def ik(model):
    return MinkDiffIK(model, [table_box(), BOX])


def test_top_down_rotation_points_the_tcp_down():
    R = top_down_rotation(0.3)
    np.testing.assert_allclose(R[:, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


def test_steps_converge_with_decreasing_error_and_bounded_velocity(model, ik):
    q = HOME_Q.copy()
    T = make_transform(top_down_rotation(0.0), [0.45, -0.25, 0.2])
    errs = []
    for _ in range(300):
        st = ik.step(q, T)
        assert st.solved
        v = (st.q - q) / ik.config.dt
        assert np.all(np.abs(v) <= model.v_max * ik.config.velocity_scale + 1e-3)
        q = st.q
        errs.append(np.linalg.norm(model.fk(q)[:3, 3] - T[:3, 3]))
    assert errs[-1] < 1e-3
    assert errs[50] < errs[0] and errs[150] < errs[50]
    assert model.within_limits(q)


def test_collision_limit_keeps_the_hand_above_a_box(model, ik):
    # Target inside the box: the QP must stop the fingers above its top.
    checker = CollisionChecker(model, [table_box(), BOX])
    q = HOME_Q.copy()
    T = make_transform(top_down_rotation(0.0), [0.5, 0.0, 0.06])
    for _ in range(400):
        q = ik.step(q, T).q
    assert checker.clearance(q).environment > 0.01
    assert model.fk(q)[2, 3] > 0.12


def test_config_is_validated():
    with pytest.raises(ConfigError, match=r"velocity_scale must be in \(0, 1\]"):
        DiffIKConfig(velocity_scale=2.0)
    with pytest.raises(ConfigError, match="collision_min_distance < collision_detection"):
        DiffIKConfig(collision_min_distance=0.2, collision_detection_distance=0.1)

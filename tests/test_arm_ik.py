"""Damped-least-squares IK: convergence, decreasing error, joint limits, unreachable targets."""

import numpy as np
import pytest

from tabletop.arm.ik import solve_ik
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.errors import ConfigError
from tabletop.transforms import make_transform


@pytest.fixture(scope="module")
def model():
    return PandaModel()


def test_ik_converges_to_nearby_poses_with_decreasing_error(model):
    rng = np.random.default_rng(0)
    n_ok, iters = 0, []
    for _ in range(40):
        q0 = model.random_q(rng, margin=0.3)
        q_goal = model.clip(q0 + rng.normal(0.0, 0.2, 7))
        res = solve_ik(model, model.fk(q_goal), q0)
        n_ok += res.success
        if res.success:
            assert res.pos_error_m <= 1e-4 and res.rot_error_rad <= 1e-3
            np.testing.assert_allclose(model.fk(res.q)[:3, 3], model.fk(q_goal)[:3, 3], atol=1e-4)
            h = np.array(res.error_history)
            assert h[-1] < 1e-3 * h[0] or h[0] < 1e-3
            assert np.all(np.diff(h) < 0)  # strictly decreasing, every iteration
            iters.append(res.iterations)
    assert n_ok >= 38
    assert np.median(iters) <= 10


def test_ik_respects_joint_limits(model):
    rng = np.random.default_rng(1)
    for _ in range(20):
        q_goal = model.random_q(rng)
        res = solve_ik(model, model.fk(q_goal), HOME_Q, max_iters=50)
        assert model.within_limits(res.q)


def test_position_only_ik_reaches_table_points_from_home(model):
    rng = np.random.default_rng(2)
    for _ in range(20):
        p = rng.uniform([0.3, -0.4, 0.05], [0.7, 0.4, 0.3])
        res = solve_ik(model, make_transform(t=p), HOME_Q, position_only=True)
        assert res.success, (p, res.pos_error_m)
        np.testing.assert_allclose(model.fk(res.q)[:3, 3], p, atol=1e-4)


def test_unreachable_target_fails_without_raising(model):
    res = solve_ik(model, make_transform(t=[2.0, 0.0, 0.5]), HOME_Q, max_iters=60)
    assert not res.success
    assert res.iterations <= 60  # stops early at the local minimum
    assert res.pos_error_m > 0.9
    assert model.within_limits(res.q)


def test_already_solved_takes_zero_iterations(model):
    res = solve_ik(model, model.fk(HOME_Q), HOME_Q)
    assert res.success and res.iterations == 0


def test_invalid_arguments_are_refused(model):
    with pytest.raises(ConfigError, match=r"T_target must be a \(4, 4\)"):
        solve_ik(model, np.eye(3), HOME_Q)
    with pytest.raises(ConfigError, match=r"q0 must have shape \(7,\)"):
        solve_ik(model, np.eye(4), np.zeros(6))

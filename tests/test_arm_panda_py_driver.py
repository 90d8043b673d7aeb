"""The panda-py adapter against a recording test double (no robot, no panda-py needed)."""

import sys
from types import SimpleNamespace

import numpy as np
import pytest

from tabletop.arm.errors import DriverError, SafetyError
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.panda_py_driver import PandaPyDriver
from tabletop.arm.trajectory import (
    PANDA_LIMITS,
    JointTrajectory,
    TrajectoryConfig,
    check_trajectory,
    time_parametrize,
)


class FakeController:
    def __init__(self, kind, log):
        self.kind, self.log = kind, log

    def set_control(self, *args):
        self.log.append((self.kind + ".set_control", *[np.array(a) for a in args]))


class FakeControllers:
    def __init__(self, log):
        self.log = log

    def JointPosition(self):  # panda-py's name
        return FakeController("JointPosition", self.log)

    def JointVelocity(self):  # panda-py's name
        return FakeController("JointVelocity", self.log)


class FakeContext:
    """panda-py's control-loop context: ``ok()`` is true for as many ticks as the runtime."""

    def __init__(self, log, frequency, max_runtime):
        self.log, self.ticks = log, round(frequency * max_runtime)
        log.append(("create_context", frequency, max_runtime))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.log.append(("context_exit",))

    def ok(self):
        self.ticks -= 1
        return self.ticks >= 0


class FakePanda:
    """Records calls; its state is whatever the test puts in ``q``."""

    def __init__(self, log, q):
        self.log, self.q = log, np.array(q, dtype=float)

    def create_context(self, frequency, max_runtime):
        return FakeContext(self.log, frequency, max_runtime)

    def get_state(self):
        return SimpleNamespace(q=self.q.copy(), dq=np.zeros(7))

    def start_controller(self, ctrl):
        self.log.append(("start_controller", ctrl.kind))

    def stop_controller(self):
        self.log.append(("stop_controller",))


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture
def rig(model):
    log, sleeps = [], []
    panda = FakePanda(log, HOME_Q)
    drv = PandaPyDriver(
        model=model, panda=panda, controllers=FakeControllers(log), sleep=sleeps.append
    )
    return drv, panda, log, sleeps


def test_position_command_starts_the_controller_once_and_sends_targets(rig):
    drv, _, log, sleeps = rig
    q = HOME_Q + 0.002
    drv.command_positions(q, 0.01)
    drv.command_positions(q + 0.002, 0.01)
    assert [e[0] for e in log] == [
        "start_controller",
        "JointPosition.set_control",
        "JointPosition.set_control",
    ]
    np.testing.assert_allclose(log[1][1], q)
    np.testing.assert_allclose(log[1][2], np.full(7, 0.2))  # feed-forward velocity [rad/s]
    assert sleeps == [0.01, 0.01]


def test_switching_to_velocity_stops_the_position_controller(rig):
    drv, _, log, _ = rig
    drv.command_positions(HOME_Q, 0.01)
    drv.command_velocities(np.full(7, 0.1), 0.01)
    drv.stop()
    kinds = [e[0] if e[0] != "start_controller" else e for e in log]
    assert kinds == [
        ("start_controller", "JointPosition"),
        "JointPosition.set_control",
        "stop_controller",
        ("start_controller", "JointVelocity"),
        "JointVelocity.set_control",
        "JointVelocity.set_control",  # zero velocity on stop
        "stop_controller",
    ]
    np.testing.assert_allclose(log[-2][1], np.zeros(7))


def test_too_fast_commands_are_refused_before_reaching_the_robot(rig):
    drv, _, log, _ = rig
    with pytest.raises(SafetyError, match=r"exceeds the limit .* at joints \[1\]"):
        drv.command_positions(HOME_Q + np.array([0.1, 0, 0, 0, 0, 0, 0]), 0.01)
    with pytest.raises(SafetyError, match="exceeds the limit"):
        drv.command_velocities(np.full(7, 2.0), 0.01)
    assert log == []


def test_commands_leaving_the_workspace_or_limits_are_refused(rig, model):
    drv, panda, log, _ = rig
    q_low = np.array([0.0, 1.7, 0.0, -0.2, 0.0, 2.0, 0.8])  # reaches down below the table top
    assert model.fk(q_low)[2, 3] < 0
    panda.q = q_low.copy()
    with pytest.raises(SafetyError, match="outside the workspace box"):
        drv.command_positions(q_low, 0.01)
    panda.q = model.q_upper.copy()
    with pytest.raises(SafetyError, match="leaves the joint limits"):
        drv.command_positions(model.q_upper + 0.001, 0.01)
    assert log == []


def test_missing_panda_py_names_the_package(monkeypatch, model):
    monkeypatch.setitem(sys.modules, "panda_py", None)
    with pytest.raises(DriverError, match="pip install panda-python"):
        PandaPyDriver("172.16.0.2", model=model)


def _streamed(log, kind="JointPosition.set_control"):
    """The (q, dq) samples the robot received, as (N, 7) arrays."""
    sent = [e for e in log if e[0] == kind]
    return np.array([e[1] for e in sent]), np.array([e[2] for e in sent])


def test_trajectory_is_streamed_sample_by_sample_within_every_limit(rig):
    drv, _, log, sleeps = rig
    goal = HOME_Q + np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.4])
    traj = time_parametrize([HOME_Q, goal, HOME_Q + 0.02])
    drv.execute_trajectory(traj)
    assert log[0] == ("start_controller", "JointPosition")
    assert log[1] == ("create_context", 1000.0, pytest.approx(traj.duration + 1.0))
    assert log[-1] == ("context_exit",)
    q, dq = _streamed(log)
    np.testing.assert_array_equal(q, traj.q)  # exactly the trajectory, every sample
    np.testing.assert_array_equal(dq, traj.dq)
    assert sleeps == []  # paced by the robot's control loop, not by sleeping
    # What reached the robot, checked on every sample: limits and continuity.
    h = traj.period
    assert np.all(q >= PANDA_LIMITS.q_lower) and np.all(q <= PANDA_LIMITS.q_upper)
    assert np.all(np.abs(dq) <= drv.v_limit + 1e-9)
    ddq = np.diff(dq, axis=0) / h
    assert np.all(np.abs(ddq) <= PANDA_LIMITS.a_max * (1 + 1e-6))
    assert np.all(np.abs(np.diff(q, axis=0)) <= PANDA_LIMITS.v_max * h)
    recorded = JointTrajectory(h, q, dq, traj.ddq, traj.waypoints)
    assert check_trajectory(recorded).ok


def test_unsafe_trajectories_never_reach_the_robot(rig, model):
    drv, panda, log, _ = rig
    fast = time_parametrize(
        [HOME_Q, HOME_Q + 0.6], config=TrajectoryConfig(velocity_scale=1, acceleration_scale=1)
    )
    with pytest.raises(SafetyError, match=r"velocity of joint 1 at sample \d+ is .* above"):
        drv.execute_trajectory(fast)
    traj = time_parametrize([HOME_Q, HOME_Q + 0.2])
    jerky = traj.ddq.copy()
    jerky[10, 1] = 7.0  # joint 2: within 7.5 rad/s^2 but a jump of 7 in 1 ms
    with pytest.raises(SafetyError, match="jerk of joint 2 at sample"):
        drv.execute_trajectory(JointTrajectory(traj.period, traj.q, traj.dq, jerky, traj.waypoints))
    low = np.array([0.0, 1.7, 0.0, -0.2, 0.0, 2.0, 0.8])  # TCP below the table top
    assert model.fk(low)[2, 3] < 0
    with pytest.raises(SafetyError, match=r"trajectory sample \d+ puts .* outside the workspace"):
        drv.execute_trajectory(time_parametrize([HOME_Q, low]))
    panda.q = HOME_Q + 0.05
    with pytest.raises(SafetyError, match="starts 0.0500 rad from the measured configuration"):
        drv.execute_trajectory(traj)
    assert log == []


def test_a_control_loop_that_ends_early_is_a_driver_error(rig):
    drv, panda, log, _ = rig
    traj = time_parametrize([HOME_Q, HOME_Q + 0.2])
    panda.create_context = lambda frequency, max_runtime: FakeContext(log, frequency, 0.1)
    with pytest.raises(DriverError, match=r"ended after 100 of \d+ samples"):
        drv.execute_trajectory(traj)

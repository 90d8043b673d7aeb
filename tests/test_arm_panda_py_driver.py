"""The panda-py adapter against a recording test double (no robot, no panda-py needed)."""

import sys
from types import SimpleNamespace

import numpy as np
import pytest

from tabletop.arm.errors import DriverError, SafetyError
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.panda_py_driver import PandaPyDriver


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


class FakePanda:
    """Records calls; its state is whatever the test puts in ``q``."""

    def __init__(self, log, q):
        self.log, self.q = log, np.array(q, dtype=float)

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

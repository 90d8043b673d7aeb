"""Drivers: the protocol, the kinematic driver, and the PyBullet driver on a caller's client."""

import numpy as np
import pybullet as pb
import pytest

from tabletop.arm.driver import ArmDriver, KinematicDriver, PyBulletDriver, touching_points
from tabletop.arm.errors import DriverError
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.obstacles import Box, table_box
from tabletop.arm.reach import ReachController, ReachReason
from tabletop.arm.trajectory import check_trajectory, time_parametrize
from tabletop.errors import ConfigError
from tabletop.paths import panda_urdf_path

CUBE = Box([0.5, 0.1, 0.05], [0.04, 0.04, 0.05], name="cube")


@pytest.fixture(scope="module")
def world():
    """A DIRECT client of our own: a box table, a cube, the Panda under gravity."""
    cid = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, -9.81, physicsClientId=cid)
    bodies = []
    for ob in (table_box(), CUBE):
        col = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=ob.half_extents.tolist(), physicsClientId=cid
        )
        bodies.append(pb.createMultiBody(0, col, -1, ob.center.tolist(), physicsClientId=cid))
    robot = pb.loadURDF(str(panda_urdf_path()), useFixedBase=True, physicsClientId=cid)
    yield cid, robot, bodies
    pb.disconnect(cid)


def _reset(cid, robot, q):
    for j in range(7):
        pb.resetJointState(robot, j, float(q[j]), physicsClientId=cid)


def test_drivers_implement_the_protocol(world):
    cid, robot, _ = world
    assert isinstance(KinematicDriver(), ArmDriver)
    assert isinstance(PyBulletDriver(cid, robot), ArmDriver)


def test_kinematic_driver_reaches_commands_exactly():
    d = KinematicDriver(HOME_Q)
    q = HOME_Q + 0.01
    d.command_positions(q, 0.01)
    st = d.read_state()
    np.testing.assert_allclose(st.q, q)
    np.testing.assert_allclose(st.dq, np.full(7, 1.0))
    assert st.time_s == pytest.approx(0.01)
    with pytest.raises(ConfigError, match="duration must be positive"):
        d.command_positions(q, 0.0)


def test_pybullet_driver_tracks_position_commands_with_physics(world):
    cid, robot, _ = world
    _reset(cid, robot, HOME_Q)
    d = PyBulletDriver(cid, robot)
    goal = HOME_Q + np.array([0.2, 0.1, -0.1, 0.1, 0.0, -0.1, 0.2])
    for k in range(1, 51):
        d.command_positions(HOME_Q + (goal - HOME_Q) * k / 50, 0.01)
    for _ in range(30):
        d.command_positions(goal, 0.01)
    st = d.read_state()
    assert np.abs(st.q - goal).max() < 5e-3
    assert st.time_s == pytest.approx(0.8, abs=0.01)
    assert d.steps == round(0.8 * 240)


def test_pybullet_driver_tracks_a_trajectory_sample_by_sample(world):
    cid, robot, _ = world
    _reset(cid, robot, HOME_Q)
    steps = []
    d = PyBulletDriver(cid, robot, on_step=lambda: steps.append(1))
    mid = HOME_Q + np.array([0.4, 0.2, -0.2, 0.3, 0.1, -0.2, 0.5])
    traj = time_parametrize([HOME_Q, mid, HOME_Q + 0.05])
    assert check_trajectory(traj).ok
    d.execute_trajectory(traj)
    # One physics step per 1/240 s of trajectory, each tracked against its own sample.
    assert len(steps) == len(d.tracking) == int(np.ceil(traj.duration * 240 - 1e-9))
    t, err = np.array(d.tracking).T
    assert t[-1] == pytest.approx(traj.duration, abs=1 / 240)
    assert err.max() < 0.01  # [rad] worst tracking error along the way
    assert np.abs(d.read_state().q - traj.q[-1]).max() < 1e-3
    # Passing the middle waypoint: the arm went there, it did not cut the corner.
    k = int(np.argmin(np.abs(traj.q - mid).max(axis=1)))
    assert np.abs(traj.q[k] - mid).max() == 0.0
    with pytest.raises(DriverError, match="starts .* rad from the arm's configuration"):
        d.execute_trajectory(traj)  # planned from HOME_Q, the arm is elsewhere now


def test_pybullet_driver_velocity_and_stop(world):
    cid, robot, _ = world
    _reset(cid, robot, HOME_Q)
    d = PyBulletDriver(cid, robot)
    dq = np.array([0.3, 0, 0, 0, 0, 0, 0])
    d.command_velocities(dq, 0.2)
    q1 = d.read_state().q
    assert 0.03 < q1[0] - HOME_Q[0] < 0.07
    d.stop()
    for _ in range(20):
        d.stop()
    assert np.abs(d.read_state().dq).max() < 0.05


def test_pybullet_driver_refuses_a_body_that_is_not_a_panda(world):
    cid, _, bodies = world
    with pytest.raises(DriverError, match="is not a Panda: joints"):
        PyBulletDriver(cid, bodies[0])


def test_reach_with_physics_touches_nothing(world):
    cid, robot, bodies = world
    _reset(cid, robot, HOME_Q)
    model = PandaModel()
    driver = PyBulletDriver(cid, robot, finger_opening=model.finger_opening)
    ctrl = ReachController(model, driver, [table_box(), CUBE])
    contacts = 0
    orig = driver.command_positions

    def counted(q, duration):
        nonlocal contacts
        orig(q, duration)
        contacts += sum(len(pb.getContactPoints(robot, b, physicsClientId=cid)) for b in bodies)

    driver.command_positions = counted
    for target in (CUBE.center, [0.35, -0.3, 0.0]):
        res = ctrl.move_to(target)
        assert res.reason == ReachReason.REACHED and res.error_m <= 0.01
    assert contacts == 0


def test_touching_points_count_touches_not_close_passes():
    """PyBullet reports a sphere 0.3 mm above a box as a contact point (positive distance):
    a close pass, not a contact. One that overlaps by 1 mm touches."""
    c = pb.connect(pb.DIRECT)
    try:
        box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.05] * 3, physicsClientId=c)
        ball = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.02, physicsClientId=c)
        table = pb.createMultiBody(0, box, basePosition=[0, 0, 0], physicsClientId=c)
        seen = {}
        for gap in (0.0003, -0.001, 0.01):
            b = pb.createMultiBody(1, ball, basePosition=[0, 0, 0.07 + gap], physicsClientId=c)
            pb.performCollisionDetection(physicsClientId=c)
            reported = len(pb.getContactPoints(table, b, physicsClientId=c))
            seen[gap] = (reported, touching_points(pb, table, b, c))
            pb.removeBody(b, physicsClientId=c)
        assert seen == {0.0003: (1, 0), -0.001: (1, 1), 0.01: (0, 0)}
    finally:
        pb.disconnect(c)

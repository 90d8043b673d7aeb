"""FrankyDriver against franky-sim: a libfranka-protocol server simulating an FR3 in MuJoCo.

The tests start the server themselves (``franky-sim -s mujoco``) on a loopback address nothing
else listens on (libfranka's ports are fixed, so a free address plays the part of a free port),
connect through the real franky client, and kill the server at the end. They skip, saying why,
where franky or franky-sim is not installed or the server does not start.

The simulator runs slower than real time on a busy machine (its clock is the robot's clock), so
durations here are robot time and the motions are short.
"""

import importlib.util
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from tabletop.arm.errors import (
    ConnectionLost,
    ConnectionRefused,
    DriverError,
    MotionStoppedShort,
    SafetyError,
)
from tabletop.arm.franky_sim import FrankySimServer, free_loopback
from tabletop.arm.model import HOME_Q, PandaModel
from tabletop.arm.trajectory import PANDA_LIMITS, TrajectoryConfig, time_parametrize
from tabletop.errors import ConfigError

_MISSING = [m for m in ("franky", "franky_sim") if importlib.util.find_spec(m) is None]
pytestmark = pytest.mark.skipif(
    bool(_MISSING),
    reason=f"{' and '.join(_MISSING)} not installed (pip install franky-control franky-sim; "
    "scripts/bootstrap installs them with TABLETOP_BACKENDS=1)",
)

REFLEX_SERVER = "franky_sim_reflex_server.py"


class SimServer(FrankySimServer):
    """A franky-sim server on its own loopback address; the test skips, saying why, when it
    does not start."""

    def __init__(self, timeout: float = 60.0, reflexes: bool = False) -> None:
        # with reflexes: franky-sim plus the real robot's joint position limit reflex
        cmd = [sys.executable, "-u", str(Path(__file__).with_name(REFLEX_SERVER))]
        try:
            super().__init__(timeout, cmd if reflexes else None)
        except DriverError as exc:
            pytest.skip(str(exc))

    def kill(self) -> None:
        self.close()


@pytest.fixture(scope="module")
def server():
    srv = SimServer()
    yield srv
    srv.kill()


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def driver(server, model):
    from tabletop.arm.franky_driver import FrankyDriver

    drv = FrankyDriver(
        server.host,
        robot_model="fr3",
        model=model,
        realtime=False,
        velocity_scale=0.5,
        acceleration_scale=0.5,
        jerk_scale=0.2,
    )
    yield drv
    drv.close()


def _fast_config() -> TrajectoryConfig:
    return TrajectoryConfig(velocity_scale=0.5, acceleration_scale=0.5, jerk_scale=0.2)


def test_state_reading_and_the_clock(driver):
    a, b = driver.read_state(), driver.read_state()
    assert a.q.shape == (7,) and a.dq.shape == (7,)
    assert np.all(np.isfinite(a.q))
    # franky-sim starts at its own home; the FR3's joint 6 range starts at 0.5445 rad
    assert driver.limits.q_lower[5] <= a.q[5] <= driver.limits.q_upper[5]
    assert b.time_s >= a.time_s


def test_a_trajectory_is_executed_and_its_tracking_reported(driver, model):
    from tabletop.arm.franky_driver import FR3_LIMITS

    q0 = driver.read_state().q
    driver.command_positions(HOME_Q, 1.5)  # to the project's home, within the velocity limit
    assert np.abs(driver.read_state().q - HOME_Q).max() < driver.goal_tolerance
    q1 = HOME_Q + np.array([0.25, 0.1, -0.2, 0.15, 0.2, -0.1, 0.3])
    q2 = HOME_Q + np.array([-0.15, 0.05, 0.1, 0.1, -0.1, 0.05, -0.2])
    traj = time_parametrize([driver.read_state().q, q1, q2], FR3_LIMITS, _fast_config())
    driver.execute_trajectory(traj)
    rep = driver.last_tracking
    q_end = driver.read_state().q
    tcp_err = np.linalg.norm(model.fk(q_end)[:3, 3] - model.fk(q2)[:3, 3])
    print(
        f"\nfranky-sim tracking: {traj.duration:.3f} s planned, {rep.executed_duration:.3f} s "
        f"executed; measured against franky's command: max {rep.max_error:.4f} rad, rms "
        f"{rep.rms_error:.4f} rad; franky's command off the planned path by at most "
        f"{rep.path_deviation:.4f} rad; final joint error {rep.final_error:.4f} rad, TCP "
        f"{tcp_err * 1000:.1f} mm"
    )
    assert rep.final_error < driver.goal_tolerance
    assert tcp_err < 0.01
    assert len(rep.times) > 50  # sampled while it ran
    assert 0.5 * traj.duration < rep.executed_duration < 2.0 * traj.duration
    assert rep.path_deviation < 0.03  # franky regenerated the planned segments (0.014 seen)
    # franky-sim's MuJoCo position control lags franky's command (0.12 rad seen at half speed)
    assert rep.max_error < 0.25
    assert rep.max_error > 0  # measured, not the command echoed back
    del q0


def test_a_limit_violation_is_refused_on_our_side_before_sending(driver):
    from tabletop.arm.franky_driver import FR3_LIMITS

    # franky-sim leaves the wrist joint coasting between motions (about 0.07 rad/s), so "nothing
    # moved" means: the arm is where its measured velocity alone would have carried it
    before = driver.read_state()
    q_now = before.q
    # joint 6 at 0.45 rad is inside the Panda's range but below the FR3's (0.5445 rad)
    target = q_now.copy()
    target[5] = 0.45
    with pytest.raises(SafetyError, match=r"fr3 joint limits: joint 6 = 0.4500 rad"):
        driver.command_positions(target, 5.0)
    path = [q_now, target]
    traj = time_parametrize(path, PANDA_LIMITS, _fast_config())
    with pytest.raises(SafetyError, match=r"fr3 limits.*position of joint 6"):
        driver.execute_trajectory(traj)
    too_fast = time_parametrize(
        [q_now, q_now + np.array([0.3, 0, 0, 0, 0, 0, 0])],
        FR3_LIMITS,
        TrajectoryConfig(velocity_scale=1.0, acceleration_scale=1.0, jerk_scale=1.0),
    )
    with pytest.raises(SafetyError, match="above velocity_scale x limit"):
        driver.execute_trajectory(too_fast)
    after = driver.read_state()
    coasted = before.q + before.dq * (after.time_s - before.time_s)
    # nothing moved: the refused motions would have moved a joint by 0.3 rad or more; the
    # coasting wrist's own drift over a few seconds reaches about 1e-3 rad (1.1e-3 seen)
    assert np.abs(after.q - coasted).max() < 5e-3


def test_a_motion_blocked_by_the_joint_stop_stops_short(driver, model):
    """Our checks bypassed (the FR3 model's limit widened), a target beyond the simulated
    arm's joint range: franky-sim reports no error, the arm stops at the joint stop."""
    q_now = driver.read_state().q
    target = q_now.copy()
    target[0] = 2.85  # franky-sim's MuJoCo joint 1 range ends at 2.7437 rad
    saved = driver.limits, driver.workspace
    from tabletop.arm.trajectory import JointLimits
    from tabletop.arm.workspace import Workspace

    lim = driver.limits
    driver.limits = JointLimits(
        np.minimum(lim.q_lower, -3.0), np.maximum(lim.q_upper, 3.0), lim.v_max, lim.a_max, lim.j_max
    )
    driver.workspace = Workspace((-2.0, -2.0, -1.0), (2.0, 2.0, 2.0))
    try:
        with pytest.raises(MotionStoppedShort, match="rad from its goal") as info:
            driver.command_positions(target, 3.0)
    finally:
        driver.limits, driver.workspace = saved
    assert 0.05 < info.value.distance < 0.2
    driver.command_positions(HOME_Q, 3.0)  # the driver still works


def test_a_stop_from_another_thread_makes_the_motion_stop_short(driver):
    q_now = driver.read_state().q
    target = q_now + np.array([0.3, 0, 0, 0, 0, 0, 0])
    timer = threading.Timer(0.3, driver.stop)
    timer.start()
    with pytest.raises(MotionStoppedShort, match="stopped on request") as info:
        driver.command_positions(target, 2.0)
    timer.join()
    assert info.value.distance > driver.goal_tolerance
    driver.command_positions(q_now, 2.0)  # the robot accepts motions again


def test_the_gripper_moves_and_reports_its_width(driver):
    driver.move_gripper(0.02, 0.05)
    assert abs(driver.gripper_width() - 0.02) < 0.005
    driver.move_gripper(0.07, 0.05)
    assert abs(driver.gripper_width() - 0.07) < 0.005
    with pytest.raises(Exception, match=r"gripper width must be in \[0, 0.08\] m"):
        driver.move_gripper(0.2)


def test_nothing_listening_is_a_refused_connection():
    from tabletop.arm.franky_driver import FrankyDriver

    host = free_loopback()
    t = time.monotonic()
    with pytest.raises(ConnectionRefused, match=f"could not connect to a Franka robot at {host}"):
        FrankyDriver(host, realtime=False)
    assert time.monotonic() - t < 5.0


def test_killing_the_server_mid_motion_is_a_lost_connection(model):
    from tabletop.arm.franky_driver import FR3_LIMITS, FrankyDriver

    srv = SimServer()
    try:
        # (franky-sim serves one client at a time: the Panda model is checked on this server)
        with pytest.raises(ConfigError, match=r"robot_model must be one of \['fr3', 'panda'\]"):
            FrankyDriver(srv.host, robot_model="ur5", realtime=False)
        drv = FrankyDriver(srv.host, robot_model="panda", model=model, realtime=False)
        assert drv.limits is PANDA_LIMITS
        q0 = drv.read_state().q
        q = q0.copy()
        q[5] = 3.8  # inside the FR3's joint 6 range, beyond the Panda's (3.7525 rad)
        assert FR3_LIMITS.q_upper[5] > 3.8
        with pytest.raises(SafetyError, match="panda joint limits: joint 6"):
            drv.command_positions(q, 10.0)
        threading.Timer(0.5, srv.kill).start()
        t = time.monotonic()
        with pytest.raises(ConnectionLost, match="lost during a motion"):
            drv.command_positions(q0 + np.array([0.4, 0, 0, 0, 0, 0, 0]), 3.0)
        assert time.monotonic() - t < 15.0  # the client noticed, nothing hangs
        assert drv.closed
        with pytest.raises(ConnectionLost, match="is closed"):
            drv.read_state()
        assert isinstance(ConnectionLost("x"), DriverError)
    finally:
        srv.kill()
    assert srv.proc.returncode is not None


def test_a_limit_reflex_is_a_typed_error_and_the_driver_recovers(model):
    """On a franky-sim server that adds the real robot's joint position limit reflex
    (tests/franky_sim_reflex_server.py): a command past the FR3's joint 1 limit, our own check
    bypassed, is aborted by the robot; the driver says which reflex, recovers, and moves on."""
    from tabletop.arm.errors import ReflexError
    from tabletop.arm.franky_driver import FrankyDriver
    from tabletop.arm.trajectory import JointLimits
    from tabletop.arm.workspace import Workspace

    srv = SimServer(reflexes=True)
    try:
        drv = FrankyDriver(srv.host, robot_model="fr3", model=model, realtime=False)
        q0 = drv.read_state().q
        target = q0.copy()
        target[0] = 2.85  # the FR3's joint 1 ends at 2.7437 rad
        with pytest.raises(SafetyError, match="fr3 joint limits: joint 1"):
            drv.command_positions(target, 5.0)  # our side refuses first
        lim = drv.limits
        drv.limits = JointLimits(
            np.minimum(lim.q_lower, -3.0),
            np.maximum(lim.q_upper, 3.0),
            lim.v_max,
            lim.a_max,
            lim.j_max,
        )
        drv.workspace = Workspace((-2.0, -2.0, -1.0), (2.0, 2.0, 2.0))
        with pytest.raises(ReflexError, match="aborted the motion with a reflex") as info:
            drv.command_positions(target, 5.0)
        assert "joint_position_limits_violation" in info.value.errors
        assert info.value.recovered
        q_stop = drv.read_state().q
        assert 2.5 < q_stop[0] <= 2.7437 + 0.01  # stopped at the limit, not past it
        drv.limits = lim
        drv.command_positions(q0, 5.0)  # recovered: the robot moves again
        assert np.abs(drv.read_state().q - q0).max() < drv.goal_tolerance
        drv.close()
    finally:
        srv.kill()


@pytest.fixture(scope="module")
def scanned():
    from robot_helpers import scan_and_map

    return scan_and_map()


def test_the_goal_reaching_loop_runs_through_franky_as_in_the_simulator(driver, model, scanned):
    """A map from a PyBullet scan, ``ArmRobot(map, FrankyDriver)``: a goal is reached through
    libfranka's protocol (the local path sent as whole trajectories), the MuJoCo arm ends where
    the map's target says, and where the PyBullet arm ends. (One goal: each goal kind reaches
    the same controller, and a motion here runs in the simulator's real time.)"""
    from robot_helpers import box_distance

    from tabletop.robot import SimArm
    from tabletop.robot.arm import ArmRobot

    rec, m = scanned
    gt = {o["name"]: o for o in rec.ground_truth["objects"]}
    goals = [("obj", dict(obj="red mug"), gt["red_mug"])]
    robots = {"franky": ArmRobot(m, driver, model), "pybullet": SimArm(m, "default")}
    try:
        assert robots["franky"].controller.execution == "batch"
        assert robots["pybullet"].controller.execution == "stream"
        for kind, query, truth in goals:
            ends = {}
            for name, robot in robots.items():
                target = robot.get_max_pos_3d(robot.get_major_map(**query))
                res = robot.move_to(target)
                assert res.reached, (name, kind, res.reason)
                tcp = model.fk(robot.driver.read_state().q)[:3, 3]  # Pinocchio on the arm's q
                assert np.linalg.norm(tcp - res.goal) <= 0.01, (name, kind)
                if truth is not None:
                    assert box_distance(tcp, truth) <= 0.10, (name, kind)
                ends[name] = tcp
            assert np.linalg.norm(ends["franky"] - ends["pybullet"]) <= 0.01, kind
        assert driver.last_tracking is not None and driver.last_tracking.final_error < 0.01
    finally:
        robots["pybullet"].close()


def test_the_demo_arm_runs_its_own_franky_sim_and_counts_contacts_in_a_mirror(scanned):
    """``FrankySimArm`` (``tabletop demo --driver franky-sim``): it starts its own server, moves
    home through franky, reaches a goal, replays the measured joints in a PyBullet copy of the
    scene to count contacts, and kills the server when closed."""
    from robot_helpers import box_distance

    from tabletop.robot.franky_arm import FrankySimArm

    rec, m = scanned
    gt = {o["name"]: o for o in rec.ground_truth["objects"]}
    arm = FrankySimArm(m, "default")
    try:
        assert arm.server.running and arm.driver.robot_model == "fr3"
        assert np.abs(arm.driver.read_state().q - HOME_Q).max() < arm.driver.goal_tolerance
        res = arm.move_to(arm.get_max_pos_3d(arm.get_major_map(obj="red mug")))
        assert res.reached, res.reason
        assert box_distance(res.final_tcp, gt["red_mug"]) <= 0.10
        assert arm.contacts == [0] and arm.reflexes == 0
        reps = arm.tracking_reports
        assert reps and reps[-1].final_error < 0.01 and reps[-1].max_error > 0
        # the mirror counts what it should: the arm pitched down into the table touches it
        into_table = HOME_Q.copy()
        into_table[1] = 1.6
        assert arm._count_contacts([np.array([into_table])]) > 0
        assert arm._count_contacts([np.array([HOME_Q])]) == 0
    finally:
        arm.close()
    assert not arm.server.running and arm.driver.closed

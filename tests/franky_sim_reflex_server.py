"""franky-sim with the real robot's joint position limit reflex, for tests/test_franky_driver.py.

franky-sim 1.0.4 simulates no reflexes: its error flags are always clear and its error recovery
always succeeds. A real Franka arm aborts a motion whose commanded joint positions leave the
joint limits ("joint_position_limits_violation"), answers the motion's Move command with
"aborted by reflex", reports the error in its state and refuses motions until the automatic
error recovery. This server adds exactly that to franky-sim's robot server, over the unchanged
libfranka protocol, so the client side (libfranka's exception, franky, FrankyDriver's recovery)
is exercised as it would be on the robot. Everything else is franky-sim's.

Run: ``python tests/franky_sim_reflex_server.py --hostname 127.x.y.z``.
"""

from __future__ import annotations

import argparse

import numpy as np
from franky_sim import SimulationServer
from franky_sim.franka_robot_protocol import (
    AutomaticErrorRecoveryCommand,
    BaseCommand,
    MoveStatus,
    RobotCommand,
    RobotMode,
    UDPCommand,
)
from franky_sim.franka_robot_server import ControlMode, FrankaRobotServer
from franky_sim.mujoco_simulator import MujocoSimulator

#: the FR3's joint position limits [rad] (franky-sim's MuJoCo model has the same ranges)
Q_LOWER = np.array([-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159])
Q_UPPER = np.array([2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159])
#: index of joint_position_limits_violation in libfranka's error array
JOINT_POSITION_LIMITS_VIOLATION = 0


class _Recovery(AutomaticErrorRecoveryCommand):
    def handle(self, server):
        server.clear_reflex()
        super().handle(server)


class ReflexRobotServer(FrankaRobotServer):
    """franky-sim's robot server plus the joint position limit reflex."""

    def __init__(self, robot, hostname_candidates):
        super().__init__(robot, hostname_candidates)
        self._FrankaServer__command_class_map[RobotCommand.kAutomaticErrorRecovery] = _Recovery
        self.in_reflex = False
        self._aborted_motion = 0

    def send_state(self):
        super().send_state()
        if self._aborted_motion:
            BaseCommand.send_response(
                self._tcp_socket,
                RobotCommand.kMove,
                self._aborted_motion,
                MoveStatus.kReflexAborted,
            )
            self._aborted_motion = 0

    def clear_reflex(self) -> None:
        self.in_reflex = False

    def _handle_udp_command(self, command_data: bytes):
        if self.in_reflex:
            return  # the robot ignores commands until the error recovery
        cmd = UDPCommand.from_bytes(command_data)
        moving = self.current_motion_id and cmd.message_id > 0
        if (
            moving
            and not cmd.motion_generation_finished
            and self._FrankaRobotServer__control_mode == ControlMode.POSITION
        ):
            q = np.asarray(cmd.q_c)
            if np.any(q < Q_LOWER) or np.any(q > Q_UPPER):
                motion_id = self.current_motion_id
                self.in_reflex = True
                self.stop_motion(send_preemption_signal=False)
                self.reset_current_motion_id()
                # answered after the next state (which carries the error), as the robot does
                self._aborted_motion = motion_id
                return
        super()._handle_udp_command(command_data)

    @property
    def robot_state(self):
        state = super().robot_state
        if not self.in_reflex:
            return state
        errors = tuple(i == JOINT_POSITION_LIMITS_VIOLATION for i in range(41))
        return state.replace(robot_mode=RobotMode.kReflex, errors=errors, reflex_reason=errors)


class ReflexSimulationServer(SimulationServer):
    def init(self) -> None:
        for robot in self.sim.robots:
            rs = ReflexRobotServer(robot, self._remaining_hostname_candidates)
            rs.init()
            self.robot_servers.append(rs)
        self.sim.start()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hostname", required=True)
    args = parser.parse_args()
    with MujocoSimulator(enable_visualization=False) as sim:
        robot = sim.add_robot()
        with ReflexSimulationServer(sim, hostname_candidates=[args.hostname]) as server:
            print(
                f"Connect to the server using '{robot.hostname}' as the robot IP address",
                flush=True,
            )
            server.run_forever()


if __name__ == "__main__":
    main()

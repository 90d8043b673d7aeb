"""Drivers: what the reach controller talks to, simulated or real, behind one protocol.

A driver reads the arm's joint state, executes joint position or velocity commands for a
given duration, and executes a whole time-parametrised :class:`JointTrajectory` sample by
sample (``execute_trajectory``); ``stop`` brings the arm to rest. Implementations here:
:class:`PyBulletDriver` (physics stepping with position control, on a client and body someone
else built), :class:`KinematicDriver` (an ideal arm, for planning and tests), and in
:mod:`tabletop.arm.panda_py_driver` an adapter for a real Panda through panda-py.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from tabletop.arm.errors import DriverError
from tabletop.arm.model import ARM_JOINT_NAMES, FINGER_JOINT_NAMES, HOME_Q, as_arm_q
from tabletop.arm.trajectory import JointTrajectory
from tabletop.errors import ConfigError

__all__ = ["ArmDriver", "JointState", "KinematicDriver", "PyBulletDriver"]

#: Joint torque limits of the Panda [N m] (used as PyBullet motor forces).
TORQUE_LIMITS = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)


@dataclass(frozen=True)
class JointState:
    """The arm's measured state."""

    q: np.ndarray  # (7,) float64 [rad]
    dq: np.ndarray  # (7,) float64 [rad/s]
    time_s: float  # driver clock [s] (simulated time for simulators)


def touching_points(pb, body: int, other: int, client: int) -> int:
    """Contact points between two PyBullet bodies after the last physics step that touch or
    overlap (contact distance <= 0). PyBullet also reports pairs still apart by up to a few
    tenths of a millimetre (positive distance, within its contact threshold): those are close
    passes, not contacts (measured: a finger 0.3-0.8 mm beside a mug counted 11 "contacts")."""
    return sum(1 for c in pb.getContactPoints(body, other, physicsClientId=client) if c[8] <= 0.0)


def _check_duration(duration: float) -> float:
    if not (np.isfinite(duration) and duration > 0):
        raise ConfigError(f"command duration must be positive [s], got {duration}")
    return float(duration)


@runtime_checkable
class ArmDriver(Protocol):
    """What the reach controller needs from an arm, simulated or real."""

    def read_state(self) -> JointState:
        """The current joint positions and velocities."""
        ...

    def command_positions(self, q: np.ndarray, duration: float) -> None:
        """Track the (7,) joint positions ``q`` [rad] for ``duration`` [s], then return."""
        ...

    def command_velocities(self, dq: np.ndarray, duration: float) -> None:
        """Hold the (7,) joint velocities ``dq`` [rad/s] for ``duration`` [s], then return."""
        ...

    def execute_trajectory(self, trajectory: JointTrajectory) -> None:
        """Follow ``trajectory`` sample by sample (it starts where the arm is, at rest)."""
        ...

    def stop(self) -> None:
        """Bring the arm to rest where it is."""
        ...


def _check_trajectory_start(traj: JointTrajectory, q_now: np.ndarray, tol: float) -> None:
    if not isinstance(traj, JointTrajectory):
        raise ConfigError(f"trajectory must be a JointTrajectory, got {type(traj).__name__}")
    gap = float(np.abs(traj.q[0] - q_now).max())
    if gap > tol:
        raise DriverError(
            f"the trajectory starts {gap:.4f} rad from the arm's configuration "
            f"(allowed {tol} rad): plan it from the measured state"
        )


class KinematicDriver:
    """An ideal arm: commanded positions are reached exactly, instantly (no physics).

    Attributes:
        commands: commands executed (a trajectory counts one per sample after the first).
        trajectories: every trajectory executed, in order (the recording).
    """

    def __init__(self, q0: object = HOME_Q) -> None:
        self._q = as_arm_q(q0, "q0")
        self._dq = np.zeros(7)
        self._t = 0.0
        self.commands: int = 0
        self.trajectories: list[JointTrajectory] = []

    def read_state(self) -> JointState:
        return JointState(q=self._q.copy(), dq=self._dq.copy(), time_s=self._t)

    def command_positions(self, q: np.ndarray, duration: float) -> None:
        duration = _check_duration(duration)
        q = as_arm_q(q)
        self._dq = (q - self._q) / duration
        self._q = q
        self._t += duration
        self.commands += 1

    def command_velocities(self, dq: np.ndarray, duration: float) -> None:
        duration = _check_duration(duration)
        self._dq = as_arm_q(dq, "dq")
        self._q = self._q + self._dq * duration
        self._t += duration
        self.commands += 1

    def execute_trajectory(self, trajectory: JointTrajectory) -> None:
        _check_trajectory_start(trajectory, self._q, 0.01)
        self.trajectories.append(trajectory)
        self._q = trajectory.q[-1].copy()
        self._dq = trajectory.dq[-1].copy()
        self._t += trajectory.duration
        self.commands += len(trajectory) - 1

    def stop(self) -> None:
        self._dq = np.zeros(7)


class PyBulletDriver:
    """Drive a Panda body in an existing PyBullet client with physics and position control.

    The driver builds nothing: the caller owns the client (its gravity, time step and bodies).
    Each command sets the motors and steps the simulation for the command's duration. The
    fingers are held at their opening when the driver was created.

    Args:
        client_id: the PyBullet physics client id.
        body_id: the Panda's body id in that client.
        timestep: the client's physics time step [s] (PyBullet's default 1/240).
        position_gain: PyBullet's position gain of the motors.
        finger_opening: set both fingers to this opening [m] first; give the model's
            ``finger_opening`` so the collision checker's fingers are where the real ones are
            (default: hold the fingers where they are).
        on_step: called after every physics step (a benchmark counts contacts with it).
    """

    def __init__(
        self,
        client_id: int,
        body_id: int,
        *,
        timestep: float = 1.0 / 240.0,
        position_gain: float = 0.3,
        finger_opening: float | None = None,
        on_step: Callable[[], None] | None = None,
    ) -> None:
        import pybullet as pb

        self._pb = pb
        self.client_id = int(client_id)
        self.body_id = int(body_id)
        self.timestep = _check_duration(timestep)
        self.position_gain = float(position_gain)
        try:
            n = pb.getNumJoints(self.body_id, physicsClientId=self.client_id)
        except pb.error as exc:
            raise DriverError(f"PyBullet client {client_id} has no body {body_id}: {exc}") from None
        index = {}
        for j in range(n):
            info = pb.getJointInfo(self.body_id, j, physicsClientId=self.client_id)
            index[info[1].decode()] = j
        missing = [nm for nm in ARM_JOINT_NAMES if nm not in index]
        if missing:
            raise DriverError(
                f"body {body_id} is not a Panda: joints {missing} missing; has {sorted(index)}"
            )
        self._arm = [index[nm] for nm in ARM_JOINT_NAMES]
        self._fingers = [index[nm] for nm in FINGER_JOINT_NAMES if nm in index]
        if finger_opening is not None:
            if not 0.0 <= finger_opening <= 0.04:
                raise ConfigError(f"finger_opening must be in [0, 0.04] m, got {finger_opening}")
            for j in self._fingers:
                pb.resetJointState(
                    self.body_id, j, float(finger_opening), physicsClientId=self.client_id
                )
        self._finger_hold = [
            pb.getJointState(self.body_id, j, physicsClientId=self.client_id)[0]
            for j in self._fingers
        ]
        self._t = 0.0  # simulated time [s]
        self._t_cmd = 0.0  # commanded time [s]
        self.steps = 0  # physics steps taken [count]
        self.on_step = on_step
        #: tracking of the last executed trajectory: (time [s], |q - q_ref| max [rad]) per step
        self.tracking: list[tuple[float, float]] = []

    def read_state(self) -> JointState:
        states = self._pb.getJointStates(self.body_id, self._arm, physicsClientId=self.client_id)
        return JointState(
            q=np.array([s[0] for s in states]),
            dq=np.array([s[1] for s in states]),
            time_s=self._t,
        )

    def _hold_fingers(self) -> None:
        if self._fingers:
            self._pb.setJointMotorControlArray(
                self.body_id,
                self._fingers,
                self._pb.POSITION_CONTROL,
                targetPositions=self._finger_hold,
                forces=[20.0] * len(self._fingers),
                physicsClientId=self.client_id,
            )

    def _run(self, duration: float) -> None:
        # Whole physics steps; the rounding remainder carries over, so the simulated time
        # follows the commanded durations on average (0.01 s at 1/240 s: 2, 3, 2, 3, ... steps).
        self._t_cmd += duration
        n = max(1, round((self._t_cmd - self._t) / self.timestep))
        for _ in range(n):
            self._pb.stepSimulation(physicsClientId=self.client_id)
            if self.on_step is not None:
                self.on_step()
        self.steps += n
        self._t += n * self.timestep

    def _set_arm(self, q: np.ndarray, dq: np.ndarray) -> None:
        self._pb.setJointMotorControlArray(
            self.body_id,
            self._arm,
            self._pb.POSITION_CONTROL,
            targetPositions=q.tolist(),
            targetVelocities=dq.tolist(),
            forces=list(TORQUE_LIMITS),
            positionGains=[self.position_gain] * 7,
            physicsClientId=self.client_id,
        )
        self._hold_fingers()

    def command_positions(self, q: np.ndarray, duration: float) -> None:
        duration = _check_duration(duration)
        q = as_arm_q(q)
        q_now = self.read_state().q
        self._set_arm(q, (q - q_now) / duration)
        self._run(duration)

    def execute_trajectory(self, trajectory: JointTrajectory) -> None:
        """Follow the trajectory: at every physics step the motors get the sample (position and
        velocity) at that step's end time, so every sample period's motion is tracked even when
        the trajectory is sampled faster than the physics (1 kHz against 240 Hz); then the last
        sample is held. ``tracking`` records the error to the reference after every step."""
        _check_trajectory_start(trajectory, self.read_state().q, 0.05)
        self.tracking = []
        n_steps = max(1, int(np.ceil(trajectory.duration / self.timestep - 1e-9)))
        last = len(trajectory) - 1
        for k in range(1, n_steps + 1):
            i = min(last, round(k * self.timestep / trajectory.period))
            self._set_arm(trajectory.q[i], trajectory.dq[i])
            self._t_cmd = self._t  # exactly one physics step per sample time
            self._run(self.timestep)
            err = float(np.abs(self.read_state().q - trajectory.q[i]).max())
            self.tracking.append((self._t, err))

    def command_velocities(self, dq: np.ndarray, duration: float) -> None:
        duration = _check_duration(duration)
        dq = as_arm_q(dq, "dq")
        self._pb.setJointMotorControlArray(
            self.body_id,
            self._arm,
            self._pb.VELOCITY_CONTROL,
            targetVelocities=dq.tolist(),
            forces=list(TORQUE_LIMITS),
            physicsClientId=self.client_id,
        )
        self._hold_fingers()
        self._run(duration)

    def stop(self) -> None:
        """Hold the current joint positions (one physics step)."""
        q = self.read_state().q
        self._pb.setJointMotorControlArray(
            self.body_id,
            self._arm,
            self._pb.POSITION_CONTROL,
            targetPositions=q.tolist(),
            targetVelocities=[0.0] * 7,
            forces=list(TORQUE_LIMITS),
            physicsClientId=self.client_id,
        )
        self._hold_fingers()
        self._run(self.timestep)

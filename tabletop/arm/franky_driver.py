"""A Franka arm (Panda or FR3) behind the driver protocol, through franky (libfranka + ruckig).

franky (``pip install 'tabletop[real]'``, the ``franky-control`` package) is imported only when
a :class:`FrankyDriver` is created. The robot model is explicit (``"panda"`` or ``"fr3"``):
every check on our side uses that model's published joint limits (:data:`ROBOT_LIMITS`), and
franky's own motion limits are set to the same values before anything moves.

On our side, before anything is sent, a command or a whole
:class:`~tabletop.arm.trajectory.JointTrajectory` is refused with a :class:`SafetyError` when a
sample leaves the model's position, velocity, acceleration or jerk limits, its velocity exceeds
``velocity_scale`` times the limit, its hand or TCP leaves the workspace box, or it does not start
where the arm is. The checks are those of :class:`~tabletop.arm.panda_py_driver.PandaPyDriver`.

A trajectory is executed as one franky ``JointWaypointMotion`` through its rest points (the
planner's waypoints); franky's ruckig regenerates each rest-to-rest segment at 1 kHz within the
model's limits scaled by the driver's dynamics factors (the same limits the checked trajectory
keeps), with its own timing: ruckig in franky 2.0 failed to stretch segments to a given
minimum time (error -111, "synchronization calculation") often enough here that the planned
segment durations are not imposed. The executed samples are recorded (:class:`TrackingReport`):
the measured joints against franky's command, franky's command against the planned path.

Failures are typed: :class:`ConnectionRefused` (nothing accepts the connection),
:class:`ConnectionLost` (the link broke; the driver closes), :class:`ReflexError` (the robot
aborted with a reflex; the driver runs the automatic error recovery and says whether it
worked), :class:`MotionStoppedShort` (a motion ended without error away from its goal).

Tested against ``franky-sim`` (a libfranka-protocol server simulating an FR3 in MuJoCo) in
``tests/test_franky_driver.py``; see docs/real_robot.md for what that proves and what not.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from tabletop.arm.driver import JointState
from tabletop.arm.driver_checks import (
    check_start,
    check_trajectory_velocity,
    check_velocity,
    check_workspace,
)
from tabletop.arm.errors import (
    ConnectionLost,
    ConnectionRefused,
    DriverError,
    MotionStoppedShort,
    ReflexError,
    SafetyError,
)
from tabletop.arm.model import PandaModel, as_arm_q
from tabletop.arm.trajectory import PANDA_LIMITS, JointLimits, JointTrajectory, check_trajectory
from tabletop.arm.workspace import Workspace
from tabletop.errors import ConfigError

__all__ = ["FR3_LIMITS", "ROBOT_LIMITS", "FrankyDriver", "TrackingReport"]

log = logging.getLogger(__name__)

#: The FR3's joint limits as published by Franka Robotics ("Robot and interface
#: specifications", FR3; the position range is also the one of franky-sim's MuJoCo model). The
#: FR3 adds position-dependent velocity limits near the position limits, not modelled here.
FR3_LIMITS = JointLimits(
    q_lower=[-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159],
    q_upper=[2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159],
    v_max=[2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26],
    a_max=[10.0] * 7,
    j_max=[5000.0] * 7,
)
#: Robot model name -> its joint limits.
ROBOT_LIMITS: dict[str, JointLimits] = {"panda": PANDA_LIMITS, "fr3": FR3_LIMITS}


def _import_franky():
    try:
        import franky
    except ImportError as exc:
        raise DriverError(
            "FrankyDriver needs franky: pip install 'tabletop[real]' (the franky-control "
            f"package; its libfranka must match the robot's system version); import failed: {exc}"
        ) from None
    return franky


def _error_names(state) -> list[str]:
    """The names of libfranka's error flags (the boolean attributes of a state's Errors)."""
    errors = state.last_motion_errors
    return [
        n
        for n in dir(errors)
        if not n.startswith("_") and isinstance(getattr(errors, n), bool | np.bool_)
    ]


def _ms(seconds: float) -> int:
    return max(1, round(seconds * 1000.0))


@dataclass(frozen=True, eq=False)
class TrackingReport:
    """What the arm did during one executed trajectory, sampled on the robot's clock."""

    times: np.ndarray  # (K,) [s] robot clock, 0 when the motion was sent
    q: np.ndarray  # (K, 7) [rad] measured joints
    q_commanded: np.ndarray  # (K, 7) [rad] joints franky commanded (libfranka's q_d)
    max_error: float  # [rad] max over samples and joints of |q - q_commanded|
    rms_error: float  # [rad] root mean square of |q - q_commanded|
    path_deviation: float  # [rad] max distance of a commanded sample from the planned path
    final_error: float  # [rad] max |q - goal| once the arm settled
    planned_duration: float  # [s] the trajectory's duration
    executed_duration: float  # [s] robot clock from sending to the motion's end


def _path_deviation(q: np.ndarray, traj: JointTrajectory) -> float:
    """[rad] max over the rows of ``q`` (K, 7) of the max-norm distance to the nearest sample
    of ``traj`` (a time-free comparison of the paths)."""
    ref = traj.q[:: max(1, len(traj) // 2000)]
    worst = 0.0
    for chunk in np.array_split(q, max(1, len(q) // 256)):
        d = np.abs(chunk[:, None, :] - ref[None, :, :]).max(axis=2).min(axis=1)
        worst = max(worst, float(d.max(initial=0.0)))
    return worst


class FrankyDriver:
    """Drive a Franka arm through franky, with every limit checked on our side first.

    Args:
        hostname: the robot's address (franky-sim: the loopback address it bound).
        robot_model: ``"panda"`` or ``"fr3"``: whose joint limits our checks and franky use.
        velocity_scale, acceleration_scale, jerk_scale: fractions of the model's limits that
            commands may use, each in (0, 1] (franky's relative dynamics factor).
        model: the kinematic model for the workspace check (the Panda URDF; the FR3 shares its
            kinematic parameters).
        workspace: the box the hand and TCP must stay in.
        realtime: require a realtime kernel (libfranka's default on a real robot); ``False``
            for franky-sim.
        start_tolerance: largest gap [rad] between a trajectory's first sample and the arm.
        goal_tolerance: largest joint distance [rad] from a motion's goal once the arm has
            settled; beyond it the motion stopped short.
        settle_time: robot time [s] allowed after a motion for the arm to come within
            ``goal_tolerance``.
        stall_timeout: wall time [s] without a new robot state during a motion after which
            the connection counts as lost.
        connect_attempts: tries to connect (a server just started may not answer at once).
    """

    #: Each command is one franky motion, at rest at both ends: the reach controller sends its
    #: local path as one trajectory (:attr:`tabletop.arm.reach.ReachConfig.execution`).
    runs_whole_motions = True

    def __init__(
        self,
        hostname: str,
        *,
        robot_model: str = "panda",
        velocity_scale: float = 0.3,
        acceleration_scale: float = 0.2,
        jerk_scale: float = 0.05,
        model: PandaModel | None = None,
        workspace: Workspace | None = None,
        realtime: bool = True,
        start_tolerance: float = 0.01,
        goal_tolerance: float = 0.01,
        settle_time: float = 1.0,
        stall_timeout: float = 3.0,
        connect_attempts: int = 3,
    ) -> None:
        if robot_model not in ROBOT_LIMITS:
            raise ConfigError(
                f"robot_model must be one of {sorted(ROBOT_LIMITS)}, got {robot_model!r}"
            )
        for name, f in (
            ("velocity_scale", velocity_scale),
            ("acceleration_scale", acceleration_scale),
            ("jerk_scale", jerk_scale),
        ):
            if not 0 < f <= 1:
                raise ConfigError(f"{name} must be in (0, 1], got {f}")
        if not hostname:
            raise ConfigError("give the robot's hostname or address")
        self._franky = _import_franky()
        self.hostname = str(hostname)
        self.robot_model = robot_model
        self.limits = ROBOT_LIMITS[robot_model]
        self.dynamics = (float(velocity_scale), float(acceleration_scale), float(jerk_scale))
        self.v_limit = self.limits.v_max * velocity_scale  # (7,) [rad/s]
        self.model = model or PandaModel()
        self.workspace = workspace or Workspace()
        self.start_tolerance = float(start_tolerance)
        self.goal_tolerance = float(goal_tolerance)
        self.settle_time = float(settle_time)
        self.stall_timeout = float(stall_timeout)
        #: the last executed trajectory's tracking (None before the first)
        self.last_tracking: TrackingReport | None = None
        self._stop_requested = False
        self._gripper = None
        self._robot = self._connect(realtime, int(connect_attempts))

    # ------------------------------------------------------------------ connection
    def _connect(self, realtime: bool, attempts: int):
        fr = self._franky
        cfg = fr.RealtimeConfig.Enforce if realtime else fr.RealtimeConfig.Ignore
        last, robot = None, None
        for i in range(max(1, attempts)):
            try:
                robot = fr.Robot(self.hostname, realtime_config=cfg)
                break
            except fr.NetworkException as exc:
                last = exc
                if "refused" in str(exc).lower():
                    break  # nothing listens: retrying will not help
                time.sleep(0.5 * (i + 1))
        if robot is None:
            raise ConnectionRefused(
                f"could not connect to a Franka robot at {self.hostname}: {last} (is the robot "
                "on, FCI enabled, the address right; for franky-sim, is the server running?)"
            )
        # franky's own motion limits: the model's, scaled by our factors.
        robot.joint_velocity_limit.set(
            np.minimum(self.limits.v_max, robot.joint_velocity_limit.max)
        )
        robot.joint_acceleration_limit.set(
            np.minimum(self.limits.a_max, robot.joint_acceleration_limit.max)
        )
        robot.joint_jerk_limit.set(np.minimum(self.limits.j_max, robot.joint_jerk_limit.max))
        robot.relative_dynamics_factor = fr.RelativeDynamicsFactor(*self.dynamics)
        return robot

    @property
    def closed(self) -> bool:
        """True once the driver was closed or lost its connection."""
        return self._robot is None

    def close(self) -> None:
        """Release the robot and gripper connections (idempotent)."""
        self._robot, self._gripper = None, None

    def __enter__(self) -> FrankyDriver:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _lost(self, exc: BaseException, what: str) -> ConnectionLost:
        self.close()
        return ConnectionLost(
            f"the connection to the robot at {self.hostname} was lost {what}: {exc}; "
            "the driver is closed (connect a new one once the robot answers)"
        )

    def _robot_or_raise(self):
        if self._robot is None:
            raise ConnectionLost(f"the driver for {self.hostname} is closed")
        return self._robot

    def _state(self):
        robot = self._robot_or_raise()
        try:
            return robot.state
        except (self._franky.NetworkException, RuntimeError) as exc:
            raise self._lost(exc, "while reading the state") from None

    # ------------------------------------------------------------------ state
    def read_state(self) -> JointState:
        st = self._state()
        return JointState(
            q=np.array(st.q, dtype=np.float64),
            dq=np.array(st.dq, dtype=np.float64),
            time_s=float(st.time.to_sec()),
        )

    # ------------------------------------------------------------------ checks
    def _check_target(self, q: np.ndarray, what: str) -> None:
        lo, hi = self.limits.q_lower, self.limits.q_upper
        bad = (q < lo) | (q > hi)
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise SafetyError(
                f"{what} leaves the {self.robot_model} joint limits: joint {j + 1} = "
                f"{q[j]:.4f} rad, allowed [{lo[j]:.4f}, {hi[j]:.4f}]"
            )
        check_workspace(self.model, self.workspace, q, what)

    def _check_velocity(self, dq: np.ndarray) -> None:
        check_velocity(dq, self.v_limit)

    def check_trajectory(self, trajectory: JointTrajectory) -> None:
        """Raise :class:`SafetyError` unless every sample of ``trajectory`` is safe to send."""
        if not isinstance(trajectory, JointTrajectory):
            raise ConfigError(
                f"trajectory must be a JointTrajectory, got {type(trajectory).__name__}"
            )
        check = check_trajectory(trajectory, self.limits)
        if not check.ok:
            raise SafetyError(
                f"trajectory refused ({self.robot_model} limits): " + "; ".join(check.violations)
            )
        check_trajectory_velocity(trajectory, self.v_limit)
        for k in range(0, len(trajectory), max(1, len(trajectory) // 200)):
            self._check_target(trajectory.q[k], f"trajectory sample {k}")
        self._check_target(trajectory.q[-1], f"trajectory sample {len(trajectory) - 1}")
        check_start(trajectory, self.read_state().q, self.start_tolerance)

    # ------------------------------------------------------------------ motions
    def _waypoints(self, trajectory: JointTrajectory) -> list:
        """franky waypoints at the trajectory's rest samples after the first (its segment ends)."""
        fr = self._franky
        rest = np.flatnonzero(
            np.all(trajectory.dq == 0, axis=1) & np.all(trajectory.ddq == 0, axis=1)
        )
        ends = [int(k) for k in rest if k > 0]
        if not ends or ends[-1] != len(trajectory) - 1:
            ends.append(len(trajectory) - 1)
        return [fr.JointWaypoint(fr.JointState(trajectory.q[k])) for k in ends]

    def _run(self, motion, goal: np.ndarray, record: bool) -> tuple[np.ndarray, ...]:
        """Send ``motion``, follow it to its end, wait for the arm to settle at ``goal``.

        Returns (times [s] from sending, measured q, commanded q) sampled while it ran.
        """
        out = self._follow(motion, goal, record)
        end = self._settle(goal)
        if end > self.goal_tolerance:
            raise MotionStoppedShort(
                f"the motion ended {end:.4f} rad from its goal (allowed {self.goal_tolerance} "
                f"rad) without a robot error: blocked or stopped",
                end,
            )
        return out

    def _follow(self, motion, goal: np.ndarray, record: bool) -> tuple[np.ndarray, ...]:
        fr = self._franky
        robot = self._robot_or_raise()
        self._stop_requested = False
        t0 = self._state().time.to_sec()
        ts, qs, qds = [], [], []
        try:
            robot.move(motion, asynchronous=True)
            last_t, last_wall = t0, time.monotonic()
            while not robot.join_motion(0.002):
                st = robot.state
                t = st.time.to_sec()
                if t != last_t:
                    last_t, last_wall = t, time.monotonic()
                    if record:
                        ts.append(t - t0)
                        qs.append(np.array(st.q, dtype=np.float64))
                        qds.append(np.array(st.q_d, dtype=np.float64))
                elif time.monotonic() - last_wall > self.stall_timeout:
                    raise fr.NetworkException(
                        f"no new robot state for {self.stall_timeout} s during the motion"
                    )
        except fr.ControlException as exc:
            self._on_control_exception(exc, goal)
        except (fr.NetworkException, RuntimeError) as exc:
            if "planner" in str(exc).lower():
                raise MotionStoppedShort(
                    f"franky's motion planner failed: {exc}",
                    float(np.abs(self.read_state().q - goal).max()),
                ) from None
            raise self._lost(exc, "during a motion") from None
        return np.array(ts), np.array(qs).reshape(-1, 7), np.array(qds).reshape(-1, 7)

    def _settle(self, goal: np.ndarray) -> float:
        """Wait up to ``settle_time`` (robot clock) for the arm to reach ``goal``; the distance."""
        t_end = self._state().time.to_sec() + self.settle_time
        last_wall = time.monotonic()
        last_t = None
        while True:
            st = self._state()
            dist = float(np.abs(np.asarray(st.q) - goal).max())
            t = st.time.to_sec()
            if dist <= self.goal_tolerance or t >= t_end:
                return dist
            if t != last_t:
                last_t, last_wall = t, time.monotonic()
            elif time.monotonic() - last_wall > self.stall_timeout:
                raise self._lost(TimeoutError("no new robot state"), "after a motion")
            time.sleep(0.005)

    def _on_control_exception(self, exc: Exception, goal: np.ndarray) -> None:
        robot = self._robot
        try:
            st = robot.state
            names = tuple(n for n in _error_names(st) if getattr(st.last_motion_errors, n))
        except (self._franky.NetworkException, RuntimeError) as lost:
            raise self._lost(lost, "while a motion was aborted") from None
        reflex = "reflex" in str(exc).lower()
        if not names and not reflex:
            if "network" in str(exc).lower() or "udp" in str(exc).lower():
                raise self._lost(exc, "during a motion") from None
            dist = float(np.abs(np.asarray(robot.state.q) - goal).max())
            why = "stopped on request" if self._stop_requested else "preempted"
            raise MotionStoppedShort(
                f"the motion was {why} {dist:.4f} rad from its goal: {exc}", dist
            ) from None
        try:
            recovered = self.recover()
        except self._franky.Exception as rec:
            log.warning("automatic error recovery failed: %s", rec)
            recovered = False
        raise ReflexError(
            f"the robot aborted the motion with a reflex {list(names)}: {exc}; automatic "
            f"error recovery {'succeeded' if recovered else 'failed'}",
            names,
            recovered,
        ) from None

    def recover(self) -> bool:
        """Run the robot's automatic error recovery; True once the robot's state shows no
        error and no reflex (franky's own answer is judged on the state it held when the
        recovery's reply came, which may still show the error)."""
        robot = self._robot_or_raise()
        fr = self._franky
        try:
            robot.recover_from_errors()
            t_end = time.monotonic() + max(1.0, self.stall_timeout)
            while time.monotonic() < t_end:
                st = robot.state
                clear = not any(getattr(st.current_errors, n) for n in _error_names(st))
                if clear and st.robot_mode != fr.RobotMode.Reflex:
                    return True
                time.sleep(0.01)
            return False
        except (fr.NetworkException, RuntimeError) as exc:
            raise self._lost(exc, "during error recovery") from None

    def execute_trajectory(self, trajectory: JointTrajectory) -> None:
        """Check the whole trajectory, then execute it as one franky joint waypoint motion.

        The motion stops at each of the trajectory's rest points (its planned waypoints) and
        joins them with franky's own time-optimal rest-to-rest profiles within the model's
        limits scaled by the driver's factors, which the checked trajectory also keeps; the
        timing is franky's (``last_tracking`` gives both durations and how far franky's command
        left the planned path). Raises :class:`SafetyError` before anything is sent when a
        sample breaks a limit; :class:`ReflexError`, :class:`ConnectionLost` or
        :class:`MotionStoppedShort` when the motion fails.
        """
        self.check_trajectory(trajectory)
        goal = trajectory.q[-1]
        motion = self._franky.JointWaypointMotion(self._waypoints(trajectory))
        t, q, q_cmd = self._run(motion, goal, record=True)
        final = float(np.abs(self.read_state().q - goal).max())
        if len(t) == 0:
            t, q, q_cmd = np.zeros(1), self.read_state().q[None], goal[None]
        err = np.abs(q - q_cmd)
        self.last_tracking = TrackingReport(
            times=t,
            q=q,
            q_commanded=q_cmd,
            max_error=float(err.max()),
            rms_error=float(np.sqrt(np.mean(err**2))),
            path_deviation=_path_deviation(q_cmd, trajectory),
            final_error=final,
            planned_duration=trajectory.duration,
            executed_duration=float(t[-1]),
        )

    def command_positions(self, q: np.ndarray, duration: float) -> None:
        """Move to the (7,) joints ``q`` [rad] (one franky motion, at rest at both ends).

        Refused unless ``(q - q_now) / duration`` keeps the scaled velocity limit; franky
        times the motion itself within the scaled limits (it may take more or less than
        ``duration``: ruckig fails to stretch some profiles to a given minimum time).
        """
        if not (np.isfinite(duration) and duration > 0):
            raise ConfigError(f"command duration must be positive [s], got {duration}")
        q = as_arm_q(q)
        q_now = self.read_state().q
        self._check_velocity((q - q_now) / duration)
        self._check_target(q, "joint position command")
        fr = self._franky
        self._run(fr.JointWaypointMotion([fr.JointWaypoint(fr.JointState(q))]), q, record=False)

    def command_velocities(self, dq: np.ndarray, duration: float) -> None:
        """Hold the (7,) joint velocities ``dq`` [rad/s] for ``duration`` [s], then come to rest
        (franky ramps in and out within the scaled limits, so the distance travelled differs
        from ``dq * duration`` by the ramps)."""
        if not (np.isfinite(duration) and duration > 0):
            raise ConfigError(f"command duration must be positive [s], got {duration}")
        dq = as_arm_q(dq, "dq")
        self._check_velocity(dq)
        q_now = self.read_state().q
        self._check_target(q_now + dq * duration, "joint velocity command")
        fr = self._franky
        robot = self._robot_or_raise()
        motion = fr.JointVelocityWaypointMotion(
            [
                fr.JointVelocityWaypoint(dq, hold_target_duration=fr.Duration(_ms(duration))),
                fr.JointVelocityWaypoint(np.zeros(7)),
            ]
        )
        try:
            robot.move(motion)
        except fr.ControlException as exc:
            self._on_control_exception(exc, q_now + dq * duration)
        except (fr.NetworkException, RuntimeError) as exc:
            raise self._lost(exc, "during a velocity command") from None

    def stop(self) -> None:
        """Stop the running motion (from another thread: it then raises
        :class:`MotionStoppedShort`); the arm holds where it is."""
        robot = self._robot_or_raise()
        self._stop_requested = True
        try:
            robot.stop()
        except (self._franky.NetworkException, RuntimeError) as exc:
            raise self._lost(exc, "while stopping") from None

    # ------------------------------------------------------------------ gripper
    def _gripper_or_connect(self):
        if self._gripper is None:
            self._robot_or_raise()
            try:
                self._gripper = self._franky.Gripper(self.hostname)
            except self._franky.NetworkException as exc:
                raise ConnectionRefused(f"no gripper answers at {self.hostname}: {exc}") from None
        return self._gripper

    def _gripper_call(self, what: str, fn, *args):
        try:
            return fn(*args)
        except self._franky.NetworkException as exc:
            self._gripper = None
            raise ConnectionLost(f"the gripper connection was lost during {what}: {exc}") from None
        except self._franky.Exception as exc:
            raise DriverError(f"the gripper refused {what}: {exc}") from None

    @staticmethod
    def _check_width(width: float, speed: float) -> None:
        if not (np.isfinite(width) and 0.0 <= width <= 0.08):
            raise ConfigError(f"gripper width must be in [0, 0.08] m, got {width}")
        if not (np.isfinite(speed) and 0.0 < speed <= 0.1):
            raise ConfigError(f"gripper speed must be in (0, 0.1] m/s, got {speed}")

    def gripper_width(self) -> float:
        """The measured opening between the fingers [m]."""
        g = self._gripper_or_connect()
        return float(self._gripper_call("reading its width", lambda: g.width))

    def move_gripper(self, width: float, speed: float = 0.05) -> None:
        """Move the fingers to the opening ``width`` [m] at ``speed`` [m/s]."""
        self._check_width(width, speed)
        g = self._gripper_or_connect()
        if not self._gripper_call("a move", g.move, float(width), float(speed)):
            raise DriverError(f"the gripper did not reach the width {width} m")

    def grasp(
        self, width: float, force: float, speed: float = 0.05, tolerance: float = 0.005
    ) -> bool:
        """Close on an object ``width`` [m] wide with ``force`` [N]; True when it is held."""
        self._check_width(width, speed)
        if not (np.isfinite(force) and 0.0 < force <= 70.0):
            raise ConfigError(f"grasp force must be in (0, 70] N, got {force}")
        g = self._gripper_or_connect()
        return bool(
            self._gripper_call(
                "a grasp", g.grasp, float(width), float(speed), float(force), tolerance, tolerance
            )
        )

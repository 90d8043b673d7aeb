"""A real Panda behind the driver protocol, through panda-py (``pip install panda-python``).

panda-py is imported only when a :class:`PandaPyDriver` connects to a robot. Limits are
enforced here, on our side, before anything reaches the robot: every command is refused with a
:class:`SafetyError` if it leaves the joint limits, exceeds the velocity limit (a fraction of
the Panda's), or would put the TCP outside the workspace box. libfranka's own limits still
apply on top.

A time-parametrised :class:`~tabletop.arm.trajectory.JointTrajectory` is checked whole (every
sample within the Panda's published position, velocity, acceleration and jerk limits, the
velocity also within ``velocity_scale``, every sample's hand and TCP inside the workspace,
starting where the arm is) before its first sample is sent; then its samples are streamed to
panda-py's ``JointPosition`` controller (position and velocity), one per tick of a
``create_context`` loop at the trajectory's rate (1 kHz for the default 1 ms period).

Exercised here against a recording test double only (``tests/test_arm_panda_py_driver.py``);
nothing in this module has run on hardware.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from tabletop.arm.driver import JointState
from tabletop.arm.driver_checks import (
    check_start,
    check_trajectory_velocity,
    check_velocity,
    check_workspace,
)
from tabletop.arm.errors import DriverError, SafetyError
from tabletop.arm.model import PandaModel, as_arm_q
from tabletop.arm.trajectory import PANDA_LIMITS, JointLimits, JointTrajectory, check_trajectory
from tabletop.arm.workspace import Workspace
from tabletop.errors import ConfigError

__all__ = ["PandaPyDriver"]


class PandaPyDriver:
    """Drive a real Panda with panda-py's joint position and joint velocity controllers.

    Args:
        hostname: the robot's address (ignored when ``panda`` is given).
        model: the kinematic model used for the workspace check.
        velocity_scale: fraction of the URDF velocity limits allowed, in (0, 1].
        workspace: the box the TCP must stay in.
        panda: an already connected ``panda_py.Panda`` (or a test double).
        controllers: the ``panda_py.controllers`` module (or a test double).
        sleep: the function that waits out a command's duration (``time.sleep``).
        limits: the limits every trajectory sample must keep (the Panda's published ones).
        start_tolerance: largest gap [rad] between a trajectory's first sample and the measured
            configuration (a larger jump would trip libfranka's discontinuity reflex).
    """

    def __init__(
        self,
        hostname: str | None = None,
        *,
        model: PandaModel | None = None,
        velocity_scale: float = 0.3,
        workspace: Workspace | None = None,
        panda: object | None = None,
        controllers: object | None = None,
        sleep: Callable[[float], None] = time.sleep,
        limits: JointLimits = PANDA_LIMITS,
        start_tolerance: float = 0.01,
    ) -> None:
        if not 0 < velocity_scale <= 1:
            raise ConfigError(f"velocity_scale must be in (0, 1], got {velocity_scale}")
        if panda is None or controllers is None:
            try:
                import panda_py
                import panda_py.controllers
            except ImportError as exc:
                raise DriverError(
                    "the real-robot driver needs panda-py: pip install panda-python "
                    f"(matching your robot's libfranka version); import failed: {exc}"
                ) from None
            if panda is None:
                if not hostname:
                    raise ConfigError("give the robot's hostname (or a connected panda object)")
                panda = panda_py.Panda(hostname)
            controllers = controllers or panda_py.controllers
        self.panda = panda
        self.controllers = controllers
        self.model = model or PandaModel()
        self.v_limit = self.model.v_max * velocity_scale  # (7,) [rad/s]
        self.workspace = workspace or Workspace()
        self._sleep = sleep
        self.limits = limits
        self.start_tolerance = float(start_tolerance)
        self._active: str | None = None  # "position" / "velocity" / None
        self._ctrl = None
        self._t0 = time.monotonic()

    # ------------------------------------------------------------------ state
    def read_state(self) -> JointState:
        st = self.panda.get_state()
        q = np.asarray(st.q, dtype=np.float64).reshape(7)
        dq = np.asarray(st.dq, dtype=np.float64).reshape(7)
        return JointState(q=q, dq=dq, time_s=time.monotonic() - self._t0)

    # ------------------------------------------------------------------ checks
    def _check_target(self, q: np.ndarray, what: str) -> None:
        if not self.model.within_limits(q):
            raise SafetyError(
                f"{what} leaves the joint limits: q={np.round(q, 4).tolist()}, "
                f"lower={np.round(self.model.q_lower, 4).tolist()}, "
                f"upper={np.round(self.model.q_upper, 4).tolist()}"
            )
        check_workspace(self.model, self.workspace, q, what)

    def _check_velocity(self, dq: np.ndarray) -> None:
        check_velocity(dq, self.v_limit)

    def _use(self, kind: str):
        if self._active != kind:
            if self._active is not None:
                self.panda.stop_controller()
            ctrl = (
                self.controllers.JointPosition()
                if kind == "position"
                else self.controllers.JointVelocity()
            )
            self.panda.start_controller(ctrl)
            self._ctrl, self._active = ctrl, kind
        return self._ctrl

    # ------------------------------------------------------------------ commands
    def command_positions(self, q: np.ndarray, duration: float) -> None:
        if not (np.isfinite(duration) and duration > 0):
            raise ConfigError(f"command duration must be positive [s], got {duration}")
        q = as_arm_q(q)
        q_now = self.read_state().q
        dq = (q - q_now) / duration
        self._check_velocity(dq)
        self._check_target(q, "joint position command")
        self._use("position").set_control(q, dq)
        self._sleep(duration)

    def command_velocities(self, dq: np.ndarray, duration: float) -> None:
        if not (np.isfinite(duration) and duration > 0):
            raise ConfigError(f"command duration must be positive [s], got {duration}")
        dq = as_arm_q(dq, "dq")
        self._check_velocity(dq)
        q_end = self.read_state().q + dq * duration
        self._check_target(q_end, "joint velocity command")
        self._use("velocity").set_control(dq)
        self._sleep(duration)

    def check_trajectory(self, trajectory: JointTrajectory) -> None:
        """Raise :class:`SafetyError` unless every sample of ``trajectory`` is safe to send."""
        if not isinstance(trajectory, JointTrajectory):
            raise ConfigError(
                f"trajectory must be a JointTrajectory, got {type(trajectory).__name__}"
            )
        check = check_trajectory(trajectory, self.limits)
        if not check.ok:
            raise SafetyError("trajectory refused: " + "; ".join(check.violations))
        check_trajectory_velocity(trajectory, self.v_limit)
        for k, q in enumerate(trajectory.q):
            self._check_target(q, f"trajectory sample {k}")
        check_start(trajectory, self.read_state().q, self.start_tolerance)

    def execute_trajectory(self, trajectory: JointTrajectory) -> None:
        """Check the whole trajectory, then stream its samples at its own rate.

        Sample ``k`` (position and velocity) goes to the ``JointPosition`` controller on tick
        ``k`` of ``panda.create_context(frequency=1 / period)``; the context's ``ok()`` paces the
        loop. Raises :class:`SafetyError` before anything is sent when a sample breaks a limit,
        and :class:`DriverError` when the robot's loop ends before the last sample.
        """
        self.check_trajectory(trajectory)
        ctrl = self._use("position")
        ctx = self.panda.create_context(
            frequency=1.0 / trajectory.period, max_runtime=trajectory.duration + 1.0
        )
        sent = 0
        with ctx:
            while sent < len(trajectory) and ctx.ok():
                ctrl.set_control(trajectory.q[sent], trajectory.dq[sent])
                sent += 1
        if sent < len(trajectory):
            raise DriverError(
                f"the robot's control loop ended after {sent} of {len(trajectory)} samples"
            )

    def stop(self) -> None:
        """Command zero velocity (if a velocity controller runs) and stop the controller."""
        if self._active == "velocity":
            self._ctrl.set_control(np.zeros(7))
        if self._active is not None:
            self.panda.stop_controller()
        self._active, self._ctrl = None, None

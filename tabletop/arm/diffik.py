"""Differential IK on mink: one QP per control step with joint, velocity and collision limits.

The QP (mink on the MuJoCo model from :mod:`tabletop.arm.mjcf`) minimises a TCP frame task
(position, and orientation with a cheap yaw so the gripper may turn about its own axis) plus a
posture task, subject to joint position limits, joint velocity limits (a fraction of the URDF's)
and collision-avoidance limits between the hand/forearm geoms and the environment geoms (mink
needs the velocity limit for the collision limit to bound the motion). The default orientation
is top-down: the TCP's z axis points along world -z.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tabletop.arm.mjcf import build_mujoco_model, obstacle_geom_names, robot_geom_name
from tabletop.arm.model import HOME_Q, TCP_FRAME, PandaModel, as_arm_q
from tabletop.arm.obstacles import Obstacle
from tabletop.errors import ConfigError
from tabletop.transforms import as_transform, rotation_about

__all__ = ["DiffIKConfig", "DiffIKStep", "MinkDiffIK", "top_down_rotation"]

#: Robot links guarded by the collision-avoidance limit against the environment.
GUARDED_LINKS = (
    "panda_link3",
    "panda_link4",
    "panda_link5",
    "panda_link6",
    "panda_link7",
    "panda_hand",
    "panda_leftfinger",
    "panda_rightfinger",
)
#: Self-collision pairs guarded by the QP: the hand end against the base links.
GUARDED_SELF = (
    ("panda_link7", "panda_hand", "panda_leftfinger", "panda_rightfinger"),
    ("panda_link0", "panda_link1", "panda_link2"),
)


def top_down_rotation(yaw: float = 0.0) -> np.ndarray:
    """(3, 3) R_world_tcp with the TCP z axis along world -z, turned by ``yaw`` [rad] about z.

    ``yaw = 0`` is the orientation of :data:`HOME_Q` (TCP x along world +x).
    """
    return rotation_about("z", yaw) @ np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class DiffIKConfig:
    """Parameters of :class:`MinkDiffIK`."""

    dt: float = 0.01
    """Control period [s]: the QP's velocity is integrated over it."""
    velocity_scale: float = 0.5
    """Fraction of the URDF joint velocity limits the QP may use, in (0, 1]."""
    position_cost: float = 1.0
    """Weight of the TCP position error [1/m]."""
    orientation_cost: float = 0.5
    """Weight of the TCP tilt error (about its x and y axes) [1/rad]."""
    yaw_cost: float = 0.05
    """Weight of the TCP yaw error (about its own z axis) [1/rad]."""
    posture_cost: float = 1e-2
    """Weight of the posture task pulling towards ``q_posture`` [1/rad]."""
    lm_damping: float = 1e-3
    """Levenberg-Marquardt damping of the frame task."""
    damping: float = 1e-3
    """Tikhonov damping of the QP (on joint velocities)."""
    collision_min_distance: float = 0.02
    """Distance [m] the collision-avoidance limit keeps between guarded geoms."""
    collision_detection_distance: float = 0.10
    """Distance [m] from which the collision-avoidance limit becomes active."""
    solver: str = "daqp"
    """QP solver name for qpsolvers."""

    def __post_init__(self) -> None:
        if not self.dt > 0:
            raise ConfigError(f"dt must be positive [s], got {self.dt}")
        if not 0 < self.velocity_scale <= 1:
            raise ConfigError(f"velocity_scale must be in (0, 1], got {self.velocity_scale}")
        if not 0 <= self.collision_min_distance < self.collision_detection_distance:
            raise ConfigError(
                "need 0 <= collision_min_distance < collision_detection_distance, got "
                f"{self.collision_min_distance}, {self.collision_detection_distance}"
            )


@dataclass(frozen=True)
class DiffIKStep:
    """One control step of :meth:`MinkDiffIK.step`."""

    q: np.ndarray  # (7,) float64 [rad], the configuration to command (q_in when not solved)
    solved: bool  # False when the QP had no solution (e.g. already inside the margin)
    solve_time_s: float  # wall time of the step [s]


class MinkDiffIK:
    """A mink differential-IK controller for the Panda among obstacles.

    Args:
        model: the Pinocchio model (for the joint limits and the velocity limits).
        obstacles: the environment; it becomes geoms of the generated MuJoCo model.
        config: parameters.
        q_posture: (7,) configuration [rad] the posture task pulls towards (default HOME_Q).
    """

    def __init__(
        self,
        model: PandaModel,
        obstacles: Sequence[Obstacle] = (),
        config: DiffIKConfig | None = None,
        q_posture: object | None = None,
    ) -> None:
        self.panda = model
        self.config = config or DiffIKConfig()
        self.q_posture = as_arm_q(HOME_Q if q_posture is None else q_posture, "q_posture")
        self.timings_s: list[float] = []
        self.set_obstacles(obstacles)

    def set_obstacles(self, obstacles: Sequence[Obstacle]) -> None:
        """Rebuild the MuJoCo model, tasks and limits for a new environment (~50 ms)."""
        import mink

        c = self.config
        self.obstacles = tuple(obstacles)
        self.mj_model = build_mujoco_model(
            self.obstacles,
            urdf_path=self.panda.urdf_path,
            finger_opening=self.panda.finger_opening,
        )
        self.configuration = mink.Configuration(self.mj_model)
        self.frame_task = mink.FrameTask(
            TCP_FRAME,
            "body",
            position_cost=c.position_cost,
            orientation_cost=np.array([c.orientation_cost, c.orientation_cost, c.yaw_cost]),
            lm_damping=c.lm_damping,
        )
        self.posture_task = mink.PostureTask(self.mj_model, cost=c.posture_cost)
        self.posture_task.set_target(self.q_posture)
        v_max = {
            n: float(v) * c.velocity_scale
            for n, v in zip(self.panda.joint_names, self.panda.v_max, strict=True)
        }
        self.limits = [
            mink.ConfigurationLimit(self.mj_model),
            mink.VelocityLimit(self.mj_model, v_max),
        ]
        robot = [robot_geom_name(n) for n in GUARDED_LINKS]
        pairs = [
            (list(map(robot_geom_name, a)), list(map(robot_geom_name, b)))
            for a, b in [GUARDED_SELF]
        ]
        env = obstacle_geom_names(self.obstacles)
        if env:
            pairs.append((robot, env))
        self.limits.append(
            mink.CollisionAvoidanceLimit(
                self.mj_model,
                pairs,
                minimum_distance_from_collisions=c.collision_min_distance,
                collision_detection_distance=c.collision_detection_distance,
            )
        )
        self._mink = mink

    def set_posture(self, q_posture: object) -> None:
        """Make the posture task pull towards ``q_posture`` (7,) [rad]."""
        self.q_posture = as_arm_q(q_posture, "q_posture")
        self.posture_task.set_target(self.q_posture)

    def step(self, q: object, T_world_target: object) -> DiffIKStep:
        """One QP step from ``q`` towards the TCP pose ``T_world_target`` (4, 4)."""
        t0 = time.perf_counter()
        q = as_arm_q(q)
        T = as_transform(T_world_target, "T_world_target")
        mink = self._mink
        self.configuration.update(q)
        self.frame_task.set_target(mink.SE3.from_matrix(T))
        try:
            v = mink.solve_ik(
                self.configuration,
                [self.frame_task, self.posture_task],
                self.config.dt,
                self.config.solver,
                damping=self.config.damping,
                limits=self.limits,
            )
        except mink.exceptions.NoSolutionFound:
            dt = time.perf_counter() - t0
            self.timings_s.append(dt)
            return DiffIKStep(q=q, solved=False, solve_time_s=dt)
        q_next = self.configuration.integrate(v, self.config.dt)
        q_next = np.clip(q_next, self.panda.q_lower, self.panda.q_upper)
        dt = time.perf_counter() - t0
        self.timings_s.append(dt)
        return DiffIKStep(q=q_next, solved=True, solve_time_s=dt)

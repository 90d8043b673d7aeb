"""Differential IK on mink: one QP per control step with joint, velocity and collision limits.

The QP (mink on the MuJoCo model from :mod:`tabletop.arm.mjcf`) minimises a TCP frame task
(position, and orientation with a cheap yaw so the gripper may turn about its own axis) plus a
posture task, subject to joint position limits, joint velocity limits (a fraction of the URDF's)
and collision-avoidance limits between the hand/forearm geoms and the environment geoms (mink
needs the velocity limit for the collision limit to bound the motion). The default orientation
is top-down: the TCP's z axis points along world -z.

:meth:`MinkDiffIK.step` assembles and solves that QP itself (the same cost, bounds and
collision rows as ``mink.solve_ik`` with daqp, which :meth:`MinkDiffIK.step_reference` still
calls): the joint position and velocity limits become one box on the step, collision pairs
whose bounding spheres are farther apart than the detection distance are skipped before
MuJoCo's narrow distance query, and only the pairs inside it become rows. The QP is strictly
convex, so its solution is unique; it is found in the cheapest way that proves optimality:

1. the unconstrained minimiser, when it satisfies every bound and row (the usual case: the
   arm is away from its limits and from obstacles);
2. else the previous step's active set (a warm start): the equality-constrained solution with
   those constraints tight, kept when it satisfies the rest and its multipliers are >= 0
   (the KKT conditions);
3. else daqp, directly on the box and the rows.
"""

from __future__ import annotations

import math
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
#: Slack [rad] with which the solution of a guessed active set must satisfy the other bounds
#: and rows (rounding only: the solution of the tight constraints meets them to ~1e-16).
_KKT_TOL = 1e-12
#: ``as_transform``'s tolerances (``np.allclose``: atol + 1e-5 |expected|) on the last row
#: [0, 0, 0, 1] and on R^T R = I, a hair tighter: a pose this near a limit takes the slow check.
_ZERO_TOL = 0.999 * 1e-9
_ONE_TOL = 0.999 * (1e-9 + 1e-5)
_ORTHO_OFF_TOL = 0.999 * 1e-5
_ORTHO_DIAG_TOL = 0.999 * 2e-5


_F64 = np.dtype(np.float64)
_LAST_ROW = [0.0, 0.0, 0.0, 1.0]


def _arm_q(q: object) -> np.ndarray:
    """``as_arm_q(q)`` with a fast path for a finite float64 (7,) array (a copy, as there)."""
    if type(q) is np.ndarray and q.dtype == _F64 and q.shape == (7,):
        # a sum of finite values is finite or overflows to inf: both fall back
        if math.isfinite(sum(q.tolist())):
            return q.copy()
    return as_arm_q(q)


def _checked_pose(T: object) -> np.ndarray:
    """``as_transform(T)``'s checks, done on Python floats for a (4, 4) float64 array (which is
    returned as is: the step only reads it); any other input, or one near or past a limit,
    goes through ``as_transform`` (a copy, or its error)."""
    if type(T) is np.ndarray and T.shape == (4, 4) and T.dtype == np.float64:
        (a, b, c, _), (d, e, f, _), (g, h, i, _), last = rows = T.tolist()
        if (
            all(math.isfinite(v) for r in rows for v in r)
            and abs(last[0]) <= _ZERO_TOL
            and abs(last[1]) <= _ZERO_TOL
            and abs(last[2]) <= _ZERO_TOL
            and abs(last[3] - 1.0) <= _ONE_TOL
            and abs(a * a + d * d + g * g - 1.0) <= _ORTHO_DIAG_TOL
            and abs(b * b + e * e + h * h - 1.0) <= _ORTHO_DIAG_TOL
            and abs(c * c + f * f + i * i - 1.0) <= _ORTHO_DIAG_TOL
            and abs(a * b + d * e + g * h) <= _ORTHO_OFF_TOL
            and abs(a * c + d * f + g * i) <= _ORTHO_OFF_TOL
            and abs(b * c + e * f + h * i) <= _ORTHO_OFF_TOL
            and a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) >= 0
        ):
            return T
    return as_transform(T, "T_world_target")


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
        #: How many steps each way of solving the QP answered (see the module docstring):
        #: ``unconstrained``, ``warm`` (the previous active set), ``daqp``, ``mink`` (the
        #: reference path, for a solver other than daqp).
        self.qp_paths: dict[str, int] = {"unconstrained": 0, "warm": 0, "daqp": 0, "mink": 0}
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
        self._prepare_qp()

    def _prepare_qp(self) -> None:
        """Constant parts of the QP that :meth:`step` assembles (once per environment)."""
        import mujoco

        m = self.mj_model
        config_limit, velocity_limit, collision_limit = self.limits
        nv = m.nv
        every_dof = np.arange(nv)
        self._q_lower, self._q_upper = self.panda.q_lower, self.panda.q_upper
        self._direct = (
            self.config.solver == "daqp"
            and m.nq == nv
            and np.array_equal(config_limit.indices, every_dof)
            and np.array_equal(velocity_limit.indices, every_dof)
            and len(config_limit._ball_qposadr) == 0
        )
        self._q_lo = np.array(config_limit.lower)
        self._q_hi = np.array(config_limit.upper)
        self._limit_gain = float(config_limit.gain)
        self._gain_hi = self._limit_gain * self._q_hi
        self._gain_lo = self._limit_gain * self._q_lo
        self._dq_max = self.config.dt * np.asarray(velocity_limit.limit, dtype=np.float64)
        self._dq_min = -self._dq_max
        cost = np.asarray(self.posture_task.cost, dtype=np.float64)
        self._posture_w2 = cost * cost
        self._posture_neg_gain = -float(self.posture_task.gain)
        self._posture_lm = float(self.posture_task.lm_damping)
        self._H_const = np.diag(self._posture_w2 + self.config.damping)
        # Collision pairs: mink's own list. A pair farther apart than the detection distance
        # gives no row, so it is skipped before the narrow query when a bound says so: for a
        # robot geom against a world geom (static), the distance from the robot geom's
        # bounding sphere (MuJoCo's rbound) to the world geom's box; for two moving geoms,
        # between their bounding spheres. Pairs with an unbounded geom (a plane) are always
        # queried.
        self._col = collision_limit
        distmax = collision_limit.collision_detection_distance
        pairs = np.array(collision_limit.geom_id_pairs, dtype=np.int64).reshape(-1, 2)
        self._pairs = [(int(a), int(b)) for a, b in pairs]
        rb = m.geom_rbound
        g1, g2 = pairs[:, 0], pairs[:, 1]
        bounded = (rb[g1] > 0) & (rb[g2] > 0)
        static = m.body_weldid[m.geom_bodyid] == 0  # geoms welded to the world
        world1, world2 = static[g1] & ~static[g2], static[g2] & ~static[g1]
        fixed = bounded & (world1 | world2)
        moving = bounded & ~fixed
        # One test for both kinds: |x_a - centre| - half, clamped at 0, is the gap from the
        # point x_a to the box (centre, half); a sphere is a box of half 0 whose centre is
        # the other geom's position, written in at each step.
        a = np.where(world1, g2, g1)  # the robot geom (the first of a moving pair)
        self._bp_idx = np.concatenate([np.nonzero(fixed)[0], np.nonzero(moving)[0]])
        self._bp_a = a[self._bp_idx]
        wg = np.where(world1, g1, g2)[fixed]  # the world geom of each fixed pair
        data = self.configuration.data
        R = data.geom_xmat[wg].reshape(-1, 3, 3)
        n_fixed = len(wg)
        self._bp_centre = np.zeros((len(self._bp_idx), 3))
        self._bp_half = np.zeros((len(self._bp_idx), 3))
        self._bp_centre[:n_fixed] = data.geom_xpos[wg] + np.einsum(
            "kij,kj->ki", R, m.geom_aabb[wg, :3]
        )
        self._bp_half[:n_fixed] = np.einsum("kij,kj->ki", np.abs(R), m.geom_aabb[wg, 3:])
        self._bp_centre_moving = self._bp_centre[n_fixed:]
        self._bp_b = g2[moving]  # the other geom of each moving pair
        reach = rb[self._bp_a] + distmax
        reach[n_fixed:] += rb[self._bp_b]
        self._bp_reach2 = reach * reach
        self._always = np.nonzero(~bounded)[0].tolist()
        self._geom_body = [int(b) for b in m.geom_bodyid]
        self._fromto = np.empty(6)
        self._normal = np.empty(3)
        self._jac1 = np.empty((3, nv))
        self._jac2 = np.empty((3, nv))
        self._target = None  # the frame task's target, written in place by step()
        self._target_quat = self._target_pos = None  # views of its wxyz and xyz
        self._rot: tuple | None = None  # the rotation block of the pose last checked
        # The frame task's residual, as mink's FrameTask computes it with its native Lie ops
        # (the same calls on the same arrays, so the same numbers), without its Python layers.
        try:
            from mink.lie import _lie_ops_c as native
        except ImportError:  # mink without its native ops: its own residual
            native = None
        ft, data = self.frame_task, self.configuration.data
        self._native = native
        self._tcp_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, ft.frame_name)
        self._direct = self._direct and ft.frame_type == "body" and self._tcp_body >= 0
        self._tcp_xpos = data.xpos[self._tcp_body]
        self._tcp_xmat = data.xmat[self._tcp_body]
        self._jac6 = np.empty((6, nv))
        self._jac_p, self._jac_r = self._jac6[:3], self._jac6[3:]
        self._ft_cost = np.asarray(ft.cost, dtype=np.float64)
        self._ft_neg_cost_col = -self._ft_cost[:, None]
        self._ft_gain = float(ft.gain)
        self._ft_lm = float(ft.lm_damping)
        self._qpos = data.qpos
        self._geom_xpos = data.geom_xpos
        self._neq = m.neq
        self._dt = float(self.config.dt)
        self._H = np.empty((nv, nv))  # the QP's Hessian, written in place by _objective
        self._H_diag = self._H.reshape(-1)[:: nv + 1]
        self._ones3 = np.ones(3)
        # geoms on a body that moves (else welded to the world: a zero Jacobian)
        self._geom_moves = (m.body_weldid[m.geom_bodyid] != 0).tolist()
        self._active: tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]] | None = None
        self._mj = mujoco
        from scipy.linalg import lapack

        self._posv = lapack.dposv

    def set_posture(self, q_posture: object) -> None:
        """Make the posture task pull towards ``q_posture`` (7,) [rad]."""
        self.q_posture = as_arm_q(q_posture, "q_posture")
        self.posture_task.set_target(self.q_posture)

    def step(self, q: object, T_world_target: object) -> DiffIKStep:
        """One QP step from ``q`` towards the TCP pose ``T_world_target`` (4, 4)."""
        t0 = time.perf_counter()
        q = _arm_q(q)
        T, rot = self._pose(T_world_target)
        if not self._direct:
            return self._step_mink(q, T, t0)
        mujoco = self._mj
        m, data = self.mj_model, self.configuration.data
        # Configuration.update(q): forward kinematics, and the com positions for Jacobians
        self._qpos[:] = q
        mujoco.mj_kinematics(m, data)
        mujoco.mj_comPos(m, data)
        if self._neq > 0:
            mujoco.mj_makeConstraint(m, data)
        target = self.frame_task.transform_target_to_world
        if target is None or target is not self._target:  # set elsewhere: own it again
            self.frame_task.set_target(self._mink.SE3.identity())
            self._target = target = self.frame_task.transform_target_to_world
            self._target_quat, self._target_pos = target.wxyz_xyz[:4], target.wxyz_xyz[4:]
            self._rot = None
        if rot is None or rot != self._rot:  # as SE3.from_matrix (else already there)
            self._rot = None
            mujoco.mju_mat2Quat(self._target_quat, T[:3, :3].ravel())
            self._rot = rot
        self._target_pos[:] = T[:3, 3]
        H, g = self._objective(q)
        lb, ub, G, h, rows = self._constraints(q)
        x = self._solve(H, g, lb, ub, G, h, rows)
        if x is None:
            dt = time.perf_counter() - t0
            self.timings_s.append(dt)
            return DiffIKStep(q=q, solved=False, solve_time_s=dt)
        # mink's velocity x / dt, integrated as mj_integratePos does: q + v dt, then clipped
        q_next = x / self._dt
        q_next *= self._dt
        q_next += q
        np.maximum(q_next, self._q_lower, out=q_next)
        np.minimum(q_next, self._q_upper, out=q_next)
        dt = time.perf_counter() - t0
        self.timings_s.append(dt)
        return DiffIKStep(q=q_next, solved=True, solve_time_s=dt)

    def _pose(self, T: object) -> tuple[np.ndarray, tuple | None]:
        """(``_checked_pose(T)``, its rotation block as a tuple, or None). The rotation of the
        target written last (``_rot``) has passed the checks: a pose with that rotation needs
        only its translation and last row checked."""
        if type(T) is np.ndarray and T.shape == (4, 4) and T.dtype == _F64:
            r0, r1, r2, last = T.tolist()
            rot = (r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2])
            if rot == self._rot and last == _LAST_ROW and math.isfinite(r0[3] + r1[3] + r2[3]):
                return T, rot
            return _checked_pose(T), rot  # raises for a bad pose; a copy of T near a limit
        return _checked_pose(T), None

    def _objective(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H, g) of the QP, g = -c: the frame task's weighted residual plus the posture
        task's (its Jacobian is the identity, so its part is diagonal), as ``mink.solve_ik``
        sums them. With mink's native Lie ops, the operations of
        ``FrameTask.compute_qp_residual`` on the same arrays, signs moved where that is exact
        (-(a) @ b = -(a @ b), and the residual's sign cancels in H and in e @ e)."""
        native = self._native
        H = self._H
        if native is None:
            W, e, mu = self.frame_task.compute_qp_residual(self.configuration)
            ep = -e
        else:
            frame = native.xmat_xpos_to_wxyz_xyz(self._tcp_xmat, self._tcp_xpos)
            self._mj.mj_jacBody(
                self.mj_model, self.configuration.data, self._jac_p, self._jac_r, self._tcp_body
            )
            jac = native.se3_rotation_adjoint_from_xmat(self._tcp_xmat).dot(self._jac6)
            target = self._target.wxyz_xyz
            error = native.se3_rminus(target, frame)
            jac = native.se3_jlog(native.se3_inverse_multiply(target, frame)).dot(jac)
            # W = cost * -(jlog @ jac); ep = -e = cost * (gain * error)
            W = self._ft_neg_cost_col * jac
            ep = self._ft_cost * (error if self._ft_gain == 1.0 else self._ft_gain * error)
            mu = self._ft_lm * float(ep.dot(ep))
        # the posture task's weighted error is cost * -gain * (q ⊖ target); q ⊖ target = q - target
        if self._posture_neg_gain == -1.0:
            e_post = self.posture_task.target_q - q
        else:
            e_post = (q - self.posture_task.target_q) * self._posture_neg_gain
        np.dot(W.T, W, out=H)
        H += self._H_const  # diag(posture cost², damping)
        if self._posture_lm:
            mu += self._posture_lm * float((e_post * e_post).dot(self._posture_w2))
        if mu:
            self._H_diag += mu
        # c = -(e @ W) - posture_w2 * e_post, so g = -c = posture_w2 * e_post - ep @ W
        g = self._posture_w2 * e_post
        g -= ep.dot(W)
        return H, g

    def _constraints(self, q: np.ndarray):
        """(lb, ub, G, h, pairs): the joint position and velocity limits as one box
        ``lb <= x <= ub`` on the step x, and the collision rows ``G x <= h`` of the pairs
        within the detection distance (``pairs``: their indices in mink's pair list)."""
        gq = self._limit_gain * q
        ub = np.minimum(self._gain_hi - gq, self._dq_max)  # gain (q_hi - q), as mink has it
        lb = np.maximum(self._gain_lo - gq, self._dq_min)
        mujoco = self._mj
        m, data = self.mj_model, self.configuration.data
        col = self._col
        xpos = self._geom_xpos
        xpos.take(self._bp_b, axis=0, out=self._bp_centre_moving)
        gap = xpos[self._bp_a]
        gap -= self._bp_centre
        np.abs(gap, out=gap)
        gap -= self._bp_half
        np.maximum(gap, 0.0, out=gap)
        gap *= gap
        near = self._bp_idx[gap.dot(self._ones3) <= self._bp_reach2].tolist()
        if self._always:
            near = self._always + near
        if not near:
            return lb, ub, None, None, near
        distmax = col.collision_detection_distance
        min_dist = col.minimum_distance_from_collisions
        fromto, normal, jac1, jac2 = self._fromto, self._normal, self._jac1, self._jac2
        body, moved = self._geom_body, self._geom_moves
        rows, hs, ids = [], [], []
        for idx in near:
            g1, g2 = self._pairs[idx]
            dist = mujoco.mj_geomDistance(m, data, g1, g2, distmax, fromto)
            if abs(dist - distmax) < 1e-12:
                continue
            normal[:] = fromto[3:] - fromto[:3]
            mujoco.mju_normalize3(normal)
            # normal @ (jac2 - jac1), either Jacobian zero for a geom welded to the world
            if not moved[g2]:
                mujoco.mj_jac(m, data, jac1, None, fromto[:3], body[g1])
                row = -normal.dot(jac1)
            elif not moved[g1]:
                mujoco.mj_jac(m, data, jac2, None, fromto[3:], body[g2])
                row = normal.dot(jac2)
            else:
                mujoco.mj_jac(m, data, jac2, None, fromto[3:], body[g2])
                mujoco.mj_jac(m, data, jac1, None, fromto[:3], body[g1])
                row = normal.dot(jac2 - jac1)
            bound = col.gain * (dist - min_dist) / self.config.dt if dist > min_dist else 0.0
            rows.append(-row if dist >= 0 else row)
            hs.append(bound + col.bound_relaxation)
            ids.append(idx)
        if not rows:
            return lb, ub, None, None, ids
        return lb, ub, np.array(rows), np.array(hs), ids

    def _solve(self, H, g, lb, ub, G, h, rows) -> np.ndarray | None:
        """The QP's minimiser (None when it has none): unconstrained, warm, else daqp.
        ``g`` is the negated linear term (-c)."""
        _, x, info = self._posv(H, g)  # Cholesky: H is positive definite with damping > 0
        if info != 0:  # not positive definite (no damping, no posture cost): daqp decides
            return self._solve_daqp(H, -g, lb, ub, G, h, rows)
        nv = len(x)
        if (
            np.count_nonzero(x <= ub) == nv
            and np.count_nonzero(x >= lb) == nv
            and (G is None or np.count_nonzero(G.dot(x) <= h) == len(h))
        ):
            self._active = None
            self.qp_paths["unconstrained"] += 1
            return x
        c = -g
        if self._active is not None:
            x = self._solve_active(H, c, lb, ub, G, h, rows, *self._active)
            if x is not None:
                self.qp_paths["warm"] += 1
                return x
        return self._solve_daqp(H, c, lb, ub, G, h, rows)

    def _solve_active(self, H, c, lb, ub, G, h, rows, upper, lower, pairs):
        """The minimiser with the given joints at their upper / lower bound and the given
        collision pairs' rows tight, when that is the QP's minimiser (feasible, multipliers
        >= 0), else None."""
        at = {p: k for k, p in enumerate(rows)}
        if any(p not in at for p in pairs):
            return None
        nv = len(c)
        n = len(upper) + len(lower) + len(pairs)
        A = np.zeros((n, nv))
        b = np.empty(n)
        k = 0
        for j in upper:
            A[k, j], b[k] = 1.0, ub[j]
            k += 1
        for j in lower:
            A[k, j], b[k] = -1.0, -lb[j]
            k += 1
        for p in pairs:
            A[k], b[k] = G[at[p]], h[at[p]]
            k += 1
        K = np.zeros((nv + n, nv + n))
        K[:nv, :nv] = H
        K[:nv, nv:] = A.T
        K[nv:, :nv] = A
        try:
            sol = np.linalg.solve(K, np.concatenate([-c, b]))
        except np.linalg.LinAlgError:
            return None
        x, lam = sol[:nv], sol[nv:]
        if not (lam >= 0).all():
            return None
        # stationarity H x + c + A^T lam = 0, to rounding (guards a near-singular K)
        if np.abs(H @ x + c + lam @ A).max() > 1e-9 * (1.0 + np.abs(c).max()):
            return None
        if not ((x <= ub + _KKT_TOL).all() and (x >= lb - _KKT_TOL).all()):
            return None
        if G is not None and not (G @ x <= h + _KKT_TOL).all():
            return None
        return x

    def _solve_daqp(self, H, c, lb, ub, G, h, rows) -> np.ndarray | None:
        import daqp

        nv = len(c)
        if G is None:
            A, bu, bl = np.zeros((0, nv)), ub, lb
        else:
            A = G
            bu = np.concatenate([ub, h])
            bl = np.concatenate([lb, np.full(len(h), -1e30)])
        x, _, flag, info = daqp.solve(H, c, A, bu, bl, np.zeros(len(bu), dtype=np.intc))
        self.qp_paths["daqp"] += 1
        if flag <= 0:
            self._active = None
            return None
        lam = info["lam"]
        self._active = (
            tuple(int(j) for j in np.nonzero(lam[:nv] > 0)[0]),
            tuple(int(j) for j in np.nonzero(lam[:nv] < 0)[0]),
            tuple(rows[k] for k in np.nonzero(lam[nv:] != 0)[0]),
        )
        return np.asarray(x, dtype=np.float64)

    def step_reference(self, q: object, T_world_target: object) -> DiffIKStep:
        """The same step through ``mink.solve_ik`` and qpsolvers (the QP as mink builds it,
        every limit as rows): what :meth:`step` must agree with."""
        t0 = time.perf_counter()
        return self._step_mink(as_arm_q(q), as_transform(T_world_target, "T_world_target"), t0)

    def _step_mink(self, q: np.ndarray, T: np.ndarray, t0: float) -> DiffIKStep:
        mink = self._mink
        self.configuration.update(q)
        self.frame_task.set_target(mink.SE3.from_matrix(T))
        self.qp_paths["mink"] += 1
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

"""Inverse kinematics by damped least squares on the Pinocchio model.

This is the plain reference loop (fast per iteration, no constraints beyond joint limits);
:mod:`tabletop.arm.diffik` holds the constrained mink controller. Each iteration solves

    dq = J^T (J J^T + W)^-1 e + N k (q_posture - q),      W = (lambda_e ||e||^2 + lambda_0) I

where ``e`` stacks the position error [m] and the rotation error [rad] (world-aligned axes at
the frame), ``W`` is the error-scaled Levenberg-Marquardt damping (quadratic convergence near a
solution, bounded steps near singularities), ``N = I - J^+ J`` projects the posture term into
the task's null space, and joints that would cross a limit are stopped there (an active set).
A step that would increase the task error is retried without the posture term, then halved, so
the error decreases monotonically; the loop stops early at a local minimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from tabletop.arm.model import HOME_Q, TCP_FRAME, PandaModel, as_arm_q
from tabletop.errors import ConfigError
from tabletop.transforms import as_transform

__all__ = ["IKResult", "pose_error", "solve_ik"]


@dataclass(frozen=True)
class IKResult:
    """Outcome of :func:`solve_ik`."""

    q: np.ndarray  # (7,) float64 [rad], the last iterate (inside the joint limits)
    success: bool  # True when the errors are within the tolerances
    pos_error_m: float  # |p_target - p| [m] at ``q``
    rot_error_rad: float  # angle of R_target R^T [rad] at ``q`` (reported even if position_only)
    iterations: int  # iterations run (0 when q0 already met the tolerances)
    error_history: tuple[float, ...] = ()  # task error norm before each iteration, then final


def pose_error(T_world_frame: np.ndarray, T_world_target: np.ndarray) -> np.ndarray:
    """(6,) error (position [m], rotation vector [rad]) from a frame to a target, world axes."""
    e = np.empty(6)
    e[:3] = T_world_target[:3, 3] - T_world_frame[:3, 3]
    e[3:] = pin.log3(T_world_target[:3, :3] @ T_world_frame[:3, :3].T)
    return e


def _dls_step(
    J: np.ndarray,
    e: np.ndarray,
    q: np.ndarray,
    q_post: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    damping: float,
    min_damping: float,
    posture_gain: float,
) -> np.ndarray:
    """One damped-least-squares step with an active set on the joint limits.

    A joint whose step would cross a limit is stopped at the limit, its column removed, and the
    remaining joints re-solve the residual task (at most 7 passes, usually 1).
    """
    n = J.shape[0]
    free = np.ones(7, dtype=bool)
    dq = np.zeros(7)
    lam = damping * float(e @ e) + min_damping
    for _ in range(7):
        Jf = J[:, free]
        r = e - J[:, ~free] @ dq[~free]
        A = Jf @ Jf.T + lam * np.eye(n)
        A_inv = np.linalg.inv(A)
        dqf = Jf.T @ (A_inv @ r)
        if posture_gain > 0.0:
            N = np.eye(Jf.shape[1]) - Jf.T @ A_inv @ Jf
            dqf += N @ (posture_gain * (q_post[free] - q[free]))
        dq[free] = dqf
        over = free & ((q + dq > hi) | (q + dq < lo))
        if not over.any():
            break
        dq[over] = np.clip(q[over] + dq[over], lo[over], hi[over]) - q[over]
        free &= ~over
        if not free.any():
            break
    return dq


def solve_ik(
    model: PandaModel,
    T_target: object,
    q0: object,
    *,
    position_only: bool = False,
    max_iters: int = 100,
    tol_pos: float = 1e-4,
    tol_rot: float = 1e-3,
    frame: str = TCP_FRAME,
    q_posture: object | None = None,
    posture_gain: float = 0.1,
    damping: float = 1e-3,
    min_damping: float = 1e-6,
    max_step: float = 0.5,
    limit_margin: float = 1e-4,
) -> IKResult:
    """Find ``q`` with ``fk(q, frame)`` at ``T_target`` by damped least squares from ``q0``.

    Args:
        model: the Panda model (its ``data`` is used as scratch).
        T_target: (4, 4) target pose ``T_world_frame``; only its translation counts when
            ``position_only``.
        q0: (7,) start configuration [rad]; clipped into the joint limits first.
        position_only: track the 3 position rows only; orientation is left to the posture term.
        max_iters: iteration budget.
        tol_pos: position tolerance [m].
        tol_rot: rotation tolerance [rad] (ignored when ``position_only``).
        frame: the frame to place (default the TCP).
        q_posture: (7,) preferred configuration [rad] for the null-space term (default HOME_Q).
        posture_gain: null-space gain per iteration (0 disables the posture term).
        damping: lambda_e, damping per squared error norm.
        min_damping: lambda_0, the damping floor.
        max_step: largest joint change per iteration [rad] (infinity norm).
        limit_margin: distance kept from the joint limits [rad].

    Returns:
        an :class:`IKResult`; ``success`` is False when the budget ran out (the target may be
        out of reach or blocked by a joint limit). Never raises for an unreachable target.
    """
    T_target = as_transform(T_target, "T_target")
    q = model.clip(as_arm_q(q0, "q0"), limit_margin)
    q_post = HOME_Q if q_posture is None else as_arm_q(q_posture, "q_posture")
    if max_iters < 0:
        raise ConfigError(f"max_iters must be >= 0, got {max_iters}")
    if tol_pos <= 0 or tol_rot <= 0:
        raise ConfigError(f"tolerances must be positive, got tol_pos={tol_pos}, tol_rot={tol_rot}")
    fid = model.frame_id(frame)
    m, d = model.model, model.data
    rows = slice(0, 3) if position_only else slice(0, 6)
    lo, hi = model.q_lower + limit_margin, model.q_upper - limit_margin
    history: list[float] = []

    def evaluate(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
        J = pin.computeFrameJacobian(m, d, q, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        pin.updateFramePlacement(m, d, fid)
        e = pose_error(d.oMf[fid].homogeneous, T_target)
        return J, e, float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))

    J, e, pos_err, rot_err = evaluate(q)
    it = 0
    while True:
        e_task = e[rows]
        history.append(float(np.linalg.norm(e_task)))
        done = pos_err <= tol_pos and (position_only or rot_err <= tol_rot)
        if done or it >= max_iters:
            break
        err0 = history[-1]
        # Backtracking: the full step with the posture term first; if the task error grew,
        # the step without posture, then halved steps. The error never increases.
        for attempt in range(5):
            gain = posture_gain if attempt == 0 else 0.0
            dq = _dls_step(J[rows], e_task, q, q_post, lo, hi, damping, min_damping, gain)
            step = float(np.max(np.abs(dq)))
            scale = min(1.0, max_step / step) if step > 0 else 1.0
            scale *= 0.5 ** max(0, attempt - 1)
            q_new = np.clip(q + scale * dq, lo, hi)
            cand = evaluate(q_new)
            if float(np.linalg.norm(cand[1][rows])) < err0:
                break
        else:
            break  # no descent direction inside the limits: a local minimum
        q = q_new
        J, e, pos_err, rot_err = cand
        it += 1

    success = pos_err <= tol_pos and (position_only or rot_err <= tol_rot)
    return IKResult(
        q=q,
        success=bool(success),
        pos_error_m=pos_err,
        rot_error_rad=rot_err,
        iterations=it,
        error_history=tuple(history),
    )

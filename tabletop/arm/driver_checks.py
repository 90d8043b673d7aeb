"""The checks every hardware driver makes before it sends a motion (one copy for the panda-py
adapter and the franky driver): the hand inside the workspace box, joint speeds within the
driver's velocity limit, a trajectory's speeds within it, and a trajectory that starts where
the arm is."""

from __future__ import annotations

import numpy as np

from tabletop.arm.errors import SafetyError
from tabletop.arm.model import PandaModel
from tabletop.arm.trajectory import JointTrajectory
from tabletop.arm.workspace import Workspace

__all__ = ["check_start", "check_trajectory_velocity", "check_velocity", "check_workspace"]


def check_workspace(model: PandaModel, workspace: Workspace, q: np.ndarray, what: str) -> None:
    """:class:`SafetyError` unless the hand and the grasp point at ``q`` lie in ``workspace``."""
    for frame in ("panda_hand", "panda_grasptarget"):
        p = model.fk(q, frame)[:3, 3]
        if not workspace.contains(p):
            raise SafetyError(
                f"{what} puts {frame} at {np.round(p, 3).tolist()} m, outside the workspace "
                f"box {list(workspace.lower)}..{list(workspace.upper)}"
            )


def check_velocity(dq: np.ndarray, v_limit: np.ndarray) -> None:
    """:class:`SafetyError` unless every joint speed of ``dq`` [rad/s] is within ``v_limit``."""
    over = np.abs(dq) > v_limit + 1e-9
    if over.any():
        raise SafetyError(
            f"joint velocity {np.round(dq, 3).tolist()} rad/s exceeds the limit "
            f"{np.round(v_limit, 3).tolist()} rad/s at joints "
            f"{[int(i) + 1 for i in np.nonzero(over)[0]]}"
        )


def check_trajectory_velocity(trajectory: JointTrajectory, v_limit: np.ndarray) -> None:
    """:class:`SafetyError` naming the first sample and joint of ``trajectory`` faster than
    ``v_limit`` (the driver's velocity scale times the model's limits)."""
    over = np.abs(trajectory.dq) > v_limit + 1e-9
    if over.any():
        k, j = np.argwhere(over)[0]
        raise SafetyError(
            f"trajectory refused: velocity of joint {j + 1} at sample {k} is "
            f"{trajectory.dq[k, j]:.3f} rad/s, above velocity_scale x limit "
            f"{v_limit[j]:.3f} rad/s"
        )


def check_start(trajectory: JointTrajectory, q_now: np.ndarray, tolerance: float) -> None:
    """:class:`SafetyError` unless ``trajectory`` starts within ``tolerance`` [rad] of the
    measured configuration ``q_now``."""
    gap = float(np.abs(trajectory.q[0] - q_now).max())
    if gap > tolerance:
        raise SafetyError(
            f"trajectory refused: it starts {gap:.4f} rad from the measured configuration "
            f"(allowed {tolerance} rad)"
        )

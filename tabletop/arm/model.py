"""The Panda's kinematic model: Pinocchio, built from the one URDF in ``urdf/``.

The model keeps the 7 arm joints; both finger joints are locked at a fixed opening (the
fingers are not actuated by anything in this package). Frames are the URDF's link and joint
frames; the tool centre point (TCP) is ``panda_grasptarget``, 0.105 m beyond ``panda_hand``
along its z axis. The world frame is the robot base frame (``panda_link0``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from tabletop.arm.errors import FrameError
from tabletop.errors import ConfigError
from tabletop.paths import panda_urdf_path

__all__ = [
    "ARM_JOINT_NAMES",
    "FINGER_JOINT_NAMES",
    "HOME_Q",
    "TCP_FRAME",
    "PandaModel",
    "as_arm_q",
]

ARM_JOINT_NAMES = tuple(f"panda_joint{i}" for i in range(1, 8))
FINGER_JOINT_NAMES = ("panda_finger_joint1", "panda_finger_joint2")
TCP_FRAME = "panda_grasptarget"
#: A comfortable configuration above the table, gripper pointing down [rad] (as in tabletop.sim).
HOME_Q = np.array([0.0, -0.6, 0.0, -2.3, 0.0, 1.75, 0.785])
HOME_Q.setflags(write=False)


def as_arm_q(q: object, name: str = "q") -> np.ndarray:
    """Validate an arm configuration; return a float64 (7,) copy [rad]."""
    arr = np.array(q, dtype=np.float64)
    if arr.shape != (7,):
        raise ConfigError(f"{name} must have shape (7,) (one angle per arm joint), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ConfigError(f"{name} contains non-finite values: {arr.tolist()}")
    return arr


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


class PandaModel:
    """Pinocchio model and scratch data of the Panda arm (7 joints, fingers locked).

    Attributes:
        model: the reduced ``pin.Model`` (``nq == nv == 7``).
        data: its scratch ``pin.Data``; every method here overwrites it.
        urdf_path: the URDF that was loaded.
        package_dir: the directory that ``package://`` mesh paths resolve against.
        finger_opening: the locked opening of each finger [m].
        joint_names: the 7 arm joint names, in configuration order.
        q_lower, q_upper: (7,) float64 [rad] joint position limits (read-only).
        v_max: (7,) float64 [rad/s] joint velocity limits (read-only).
        frame_names: every frame in the model (links, joints, the TCP).
    """

    def __init__(self, urdf_path: str | Path | None = None, finger_opening: float = 0.04) -> None:
        path = Path(urdf_path) if urdf_path is not None else panda_urdf_path()
        if not path.is_file():
            raise ConfigError(f"URDF not found: {path}")
        if not 0.0 <= finger_opening <= 0.04:
            raise ConfigError(f"finger_opening must be in [0, 0.04] m, got {finger_opening}")
        self.urdf_path = path
        self.package_dir = path.parent
        self.finger_opening = float(finger_opening)
        full = pin.buildModelFromUrdf(str(path))
        self._full_model = full
        q_ref = pin.neutral(full)
        lock = []
        for name in FINGER_JOINT_NAMES:
            jid = full.getJointId(name)
            q_ref[full.joints[jid].idx_q] = self.finger_opening
            lock.append(jid)
        self._q_ref_full = q_ref
        self.model: pin.Model = pin.buildReducedModel(full, lock, q_ref)
        self.data: pin.Data = self.model.createData()
        names = tuple(self.model.names[i] for i in range(1, self.model.njoints))
        if names != ARM_JOINT_NAMES:
            raise ConfigError(f"URDF arm joints {names} differ from the expected {ARM_JOINT_NAMES}")
        self.joint_names = ARM_JOINT_NAMES
        self.q_lower = _frozen(self.model.lowerPositionLimit)
        self.q_upper = _frozen(self.model.upperPositionLimit)
        self.v_max = _frozen(self.model.velocityLimit)
        self.frame_names = tuple(f.name for f in self.model.frames)
        self._frame_ids = {n: i for i, n in enumerate(self.frame_names)}

    # ------------------------------------------------------------------ frames
    def frame_id(self, frame: str) -> int:
        """Index of a frame in ``model.frames``; raises :class:`FrameError` naming the options."""
        try:
            return self._frame_ids[frame]
        except KeyError:
            raise FrameError(
                f"frame {frame!r} not in the Panda model; available: {list(self.frame_names)}"
            ) from None

    def fk(self, q: object, frame: str = TCP_FRAME) -> np.ndarray:
        """(4, 4) float64 pose ``T_world_frame`` of ``frame`` at arm configuration ``q`` [rad]."""
        fid = self.frame_id(frame)
        q = as_arm_q(q)
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[fid].homogeneous.copy()

    def fk_frames(self, q: object, frames: list[str] | tuple[str, ...]) -> dict[str, np.ndarray]:
        """Poses ``T_world_frame`` of several frames from a single kinematics pass."""
        ids = [self.frame_id(f) for f in frames]
        pin.framesForwardKinematics(self.model, self.data, as_arm_q(q))
        return {f: self.data.oMf[i].homogeneous.copy() for f, i in zip(frames, ids, strict=True)}

    def jacobian(self, q: object, frame: str = TCP_FRAME) -> np.ndarray:
        """(6, 7) frame Jacobian, rows (linear, angular), expressed in world-aligned axes at the
        frame's origin (``pin.LOCAL_WORLD_ALIGNED``)."""
        fid = self.frame_id(frame)
        q = as_arm_q(q)
        return pin.computeFrameJacobian(
            self.model, self.data, q, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        ).copy()

    # ------------------------------------------------------------------ limits
    def within_limits(self, q: object, tol: float = 1e-9) -> bool:
        """True when every joint of ``q`` lies inside its position limits (plus ``tol`` rad)."""
        q = as_arm_q(q)
        return bool(np.all(q >= self.q_lower - tol) and np.all(q <= self.q_upper + tol))

    def clip(self, q: object, margin: float = 0.0) -> np.ndarray:
        """``q`` clipped into ``[q_lower + margin, q_upper - margin]`` (a new array)."""
        q = as_arm_q(q)
        return np.clip(q, self.q_lower + margin, self.q_upper - margin)

    def random_q(self, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
        """A uniformly random configuration inside the limits shrunk by ``margin`` [rad]."""
        return rng.uniform(self.q_lower + margin, self.q_upper - margin)

    def full_q(self, q: object) -> np.ndarray:
        """The (9,) configuration of the unreduced URDF model: ``q`` plus the locked fingers."""
        out = self._q_ref_full.copy()
        out[:7] = as_arm_q(q)
        return out

    def __repr__(self) -> str:
        return f"PandaModel(urdf={str(self.urdf_path)!r}, finger_opening={self.finger_opening})"

"""What the readers share: matching streams by time, interpolating poses and joints at the
frame stamps, the audio track on the frame clock, and the :class:`Recording` they all make."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tabletop.ingest.checks import check_clock, check_order
from tabletop.ingest.errors import ImportFormatError
from tabletop.recording import Recording

__all__ = ["ImportOptions", "Kinematics", "assemble", "interpolate_joints", "interpolate_poses"]


@dataclass(frozen=True)
class ImportOptions:
    """Options every reader takes (the CLI's flags)."""

    depth_scale: float | None = None
    """Depth units per metre for 16-bit depth (TUM: 5000; ROS 16UC1: 1000). None: the format's
    default."""
    pose_time_offset: float = 0.0
    """[s] added to the pose (or joint-state) stamps: a constant offset between two clocks."""
    max_pair_dt: float = 0.02
    """[s] the largest gap between a colour frame and the depth frame matched to it."""
    T_hand_cam: np.ndarray | None = None
    """The hand-camera extrinsic (4, 4), where the source does not hold it."""
    K: np.ndarray | None = None
    """Intrinsics (3, 3), where the source does not hold them."""


class Kinematics:
    """What the readers need of the arm where only joint states are given (the Panda's is
    ``tabletop.arm.recording_kinematics.PandaRecordingKinematics``)."""

    joint_names: tuple[str, ...]
    hand_frame: str

    def hand_poses(self, q: np.ndarray) -> np.ndarray:  # pragma: no cover - a protocol
        raise NotImplementedError


def _key_index(t: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each query time: the key index below it and the weight of the next key (0 where a
    stamp matches a key exactly, so matched stamps reproduce the keys bit for bit)."""
    k = np.clip(np.searchsorted(keys, t, side="right") - 1, 0, max(len(keys) - 2, 0))
    if len(keys) < 2:
        return k, np.zeros(len(t))
    span = keys[k + 1] - keys[k]
    a = np.clip((t - keys[k]) / span, 0.0, 1.0)
    a[t == keys[k]] = 0.0
    exact_next = t == keys[k + 1]
    k = np.where(exact_next, k + 1, k)
    a = np.where(exact_next, 0.0, a)
    k = np.minimum(k, len(keys) - 1)
    return k, a


def interpolate_joints(t: np.ndarray, keys: np.ndarray, q: np.ndarray) -> np.ndarray:
    k, a = _key_index(t, keys)
    nxt = np.minimum(k + 1, len(keys) - 1)
    return q[k] + a[:, None] * (q[nxt] - q[k])


def _quat(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_quat()


def interpolate_poses(t: np.ndarray, keys: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(N, 4, 4) poses at ``t``: translation linear, rotation by slerp between the keys."""
    from scipy.spatial.transform import Rotation

    k, a = _key_index(t, keys)
    nxt = np.minimum(k + 1, len(keys) - 1)
    out = T[k].copy()
    move = a > 0
    if move.any():
        i, j, w = k[move], nxt[move], a[move]
        out[move, :3, 3] = T[i, :3, 3] + w[:, None] * (T[j, :3, 3] - T[i, :3, 3])
        r0 = Rotation.from_matrix(T[i, :3, :3])
        rel = r0.inv() * Rotation.from_matrix(T[j, :3, :3])
        out[move, :3, :3] = (r0 * Rotation.from_rotvec(rel.as_rotvec() * w[:, None])).as_matrix()
    return out


def quat_to_matrix(xyz, quat_xyzw) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(np.asarray(quat_xyzw, np.float64)).as_matrix()
    T[:3, 3] = xyz
    return T


def matrix_to_quat(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(xyz, quaternion x y z w) of a rigid transform."""
    return np.asarray(T, np.float64)[:3, 3].copy(), _quat(np.asarray(T, np.float64)[:3, :3])


def match_depth(rgb_t: np.ndarray, depth_t: np.ndarray, max_dt: float) -> np.ndarray:
    """Index of the depth frame nearest each colour frame; :class:`ImportFormatError` where
    the nearest is more than ``max_dt`` away."""
    if not len(depth_t):
        raise ImportFormatError("no depth frames")
    k = np.clip(np.searchsorted(depth_t, rgb_t), 1, max(len(depth_t) - 1, 1))
    k0 = np.maximum(k - 1, 0)
    k1 = np.minimum(k, len(depth_t) - 1)
    best = np.where(np.abs(depth_t[k0] - rgb_t) <= np.abs(depth_t[k1] - rgb_t), k0, k1)
    gap = np.abs(depth_t[best] - rgb_t)
    if (gap > max_dt).any():
        i = int(np.argmax(gap > max_dt))
        raise ImportFormatError(
            f"colour frame {i} ({rgb_t[i]:.6f} s) has no depth frame within {max_dt} s (nearest "
            f"{gap[i]:.4f} s away): are colour and depth on the same clock? (--max-pair-dt "
            "widens the match)"
        )
    return best


def assemble(
    *,
    stamps: np.ndarray,
    rgb: np.ndarray,
    depth: np.ndarray,
    K: np.ndarray,
    T_hand_cam: np.ndarray,
    pose_stamps: np.ndarray,
    pose_name: str,
    hand_poses: np.ndarray | None = None,
    camera_poses: np.ndarray | None = None,
    joint_stamps: np.ndarray | None = None,
    joints: np.ndarray | None = None,
    joint_names: tuple[str, ...] = (),
    kinematics: Kinematics | None = None,
    audio: tuple[np.ndarray, int, float] | None = None,
    depth_resolution: float = 1e-4,
    ee_frame: str = "panda_hand",
    meta: dict | None = None,
) -> Recording:
    """The recording of frames at ``stamps`` (source clock [s]): poses from ``hand_poses`` or
    ``camera_poses`` at ``pose_stamps`` (interpolated), or from ``joints`` through
    ``kinematics``; ``audio`` = (samples, rate, stamp of sample 0). Time 0 of the recording is
    the earliest of the first frame and the first audio sample."""
    stamps = np.asarray(stamps, np.float64)
    check_order("colour frame", stamps)
    pose_stamps = np.asarray(pose_stamps, np.float64)
    check_order(pose_name, pose_stamps)
    check_clock("colour frame", stamps, pose_name, pose_stamps)
    T_hand_cam = np.asarray(T_hand_cam, np.float64)
    q = None
    if joints is not None:
        joint_stamps = np.asarray(joint_stamps, np.float64)
        if joint_stamps is not pose_stamps:
            check_order("joint state", joint_stamps)
            check_clock("colour frame", stamps, "joint state", joint_stamps)
        q = interpolate_joints(stamps, joint_stamps, np.asarray(joints, np.float64))
    if hand_poses is not None:
        T_world_hand = interpolate_poses(stamps, pose_stamps, np.asarray(hand_poses, np.float64))
    elif camera_poses is not None:
        T_wc = interpolate_poses(stamps, pose_stamps, np.asarray(camera_poses, np.float64))
        T_world_hand = T_wc @ np.linalg.inv(T_hand_cam)
    else:
        if q is None or kinematics is None:
            raise ImportFormatError(
                "no poses: give a pose stream (TF, groundtruth) or joint states"
            )
        T_world_hand = kinematics.hand_poses(q[:, :7])
    if q is None:
        q = np.zeros((len(stamps), 1))
        joint_names = ("none",)
    t0 = float(stamps[0]) if len(stamps) else 0.0
    samples, rate = None, 16000
    if audio is not None:
        samples, rate, a0 = audio
        check_clock("audio", np.array([a0]), "colour frame", stamps, slack_s=5.0)
        t0 = min(t0, float(a0))
        pad = round((a0 - t0) * rate)
        samples = np.concatenate([np.zeros(pad, np.float32), np.asarray(samples, np.float32)])
    return Recording(
        timestamps=stamps - t0,
        rgb=rgb,
        depth=depth,
        joint_positions=q,
        T_world_hand=T_world_hand,
        K=K,
        T_hand_cam=T_hand_cam,
        depth_resolution=depth_resolution,
        audio=samples,
        audio_rate=int(rate),
        meta={**(meta or {}), "clock_origin_s": t0},
        ee_frame=ee_frame,
        joint_names=tuple(joint_names),
    )

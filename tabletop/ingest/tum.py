"""A TUM-style RGB-D folder (the TUM RGB-D benchmark's layout) as a recording.

``rgb.txt`` and ``depth.txt`` list ``timestamp filename`` per frame (``#`` lines are comments);
``rgb/`` holds colour PNGs or JPEGs, ``depth/`` 16-bit PNGs of ``depth_scale`` units per metre
(5000 in TUM); ``groundtruth.txt`` holds ``timestamp tx ty tz qx qy qz qw``: the pose of the
camera's optical frame in the world, ``T_world_cam``. Each colour frame is matched with the
nearest depth frame (within ``max_pair_dt``) and the pose interpolated at its stamp.

This project adds two optional files a robot recording can carry:
``camera.json`` ({"K": 3x3, "T_hand_cam": 4x4}, both also given by the CLI) and ``joints.txt``
(``timestamp q1 .. q7``: the arm's joint positions, which the robot self-filter needs). Without
``T_hand_cam`` the hand frame is the camera itself (``ee_frame`` "camera").
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from tabletop.ingest.common import ImportOptions, assemble, match_depth, quat_to_matrix
from tabletop.ingest.errors import ImportFormatError
from tabletop.recording import Recording

__all__ = ["TUM_DEPTH_SCALE", "read_tum"]

#: TUM RGB-D's 16-bit depth: 5000 units per metre.
TUM_DEPTH_SCALE = 5000.0


def _table(path: Path, min_cols: int, what: str) -> list[list[str]]:
    if not path.is_file():
        raise ImportFormatError(f"{path} is missing: a TUM folder holds {what}")
    rows = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        cols = line.replace(",", " ").split()
        if len(cols) < min_cols:
            raise ImportFormatError(
                f"{path}:{n}: {line!r} has {len(cols)} fields, need {min_cols} ({what})"
            )
        rows.append(cols)
    if not rows:
        raise ImportFormatError(f"{path} lists nothing ({what})")
    return rows


def _floats(path: Path, rows: list[list[str]], cols: slice) -> np.ndarray:
    try:
        return np.array([[float(x) for x in r[cols]] for r in rows], np.float64)
    except ValueError as e:
        raise ImportFormatError(f"{path}: a number is not a number ({e})") from None


def _image(path: Path, flags: int) -> np.ndarray:
    img = cv2.imread(str(path), flags)
    if img is None:
        raise ImportFormatError(f"{path} is missing or not a readable image")
    return img


def read_tum(src: str | Path, options: ImportOptions | None = None) -> tuple[Recording, str]:
    """(recording, pose_of) of a TUM-style folder; ``pose_of`` is "camera" (the groundtruth's
    camera poses) for :func:`tabletop.ingest.checks.check_recording`."""
    src = Path(src)
    options = options or ImportOptions()
    if not src.is_dir():
        raise ImportFormatError(
            f"{src} is not a folder (a TUM RGB-D folder: rgb.txt, depth.txt, groundtruth.txt)"
        )
    scale = TUM_DEPTH_SCALE if options.depth_scale is None else float(options.depth_scale)
    if not scale > 0:
        raise ImportFormatError(f"depth scale must be > 0 units per metre, got {scale}")
    rgb_rows = _table(src / "rgb.txt", 2, "'timestamp filename' of the colour frames")
    depth_rows = _table(src / "depth.txt", 2, "'timestamp filename' of the depth frames")
    gt_path = src / "groundtruth.txt"
    gt_rows = _table(gt_path, 8, "'timestamp tx ty tz qx qy qz qw' camera poses")
    rgb_t = _floats(src / "rgb.txt", rgb_rows, slice(0, 1))[:, 0]
    depth_t = _floats(src / "depth.txt", depth_rows, slice(0, 1))[:, 0]
    gt = _floats(gt_path, gt_rows, slice(0, 8))
    pose_t = gt[:, 0] + options.pose_time_offset
    from tabletop.ingest.checks import check_order

    check_order("rgb.txt", rgb_t)
    check_order("depth.txt", depth_t)
    check_order("groundtruth.txt", pose_t)
    T_wc = np.stack([quat_to_matrix(r[1:4], r[4:8]) for r in gt])

    cam = {}
    if (src / "camera.json").is_file():
        try:
            cam = json.loads((src / "camera.json").read_text())
        except ValueError as e:
            raise ImportFormatError(f"{src / 'camera.json'} is not JSON: {e}") from None
    K = options.K if options.K is not None else cam.get("K")
    if K is None:
        raise ImportFormatError(
            "no intrinsics: pass --intrinsics FX FY CX CY or put {'K': 3x3} in "
            f"{src / 'camera.json'}"
        )
    T_hand_cam = options.T_hand_cam if options.T_hand_cam is not None else cam.get("T_hand_cam")
    ee_frame = "panda_hand" if T_hand_cam is not None else "camera"
    T_hand_cam = np.eye(4) if T_hand_cam is None else np.asarray(T_hand_cam, np.float64)

    pair = match_depth(rgb_t, depth_t, options.max_pair_dt)
    rgb = np.stack([_image(src / r[1], cv2.IMREAD_COLOR)[..., ::-1] for r in rgb_rows])
    depth = []
    for k in pair:
        units = _image(src / depth_rows[k][1], cv2.IMREAD_UNCHANGED)
        if units.dtype != np.uint16 or units.ndim != 2:
            raise ImportFormatError(
                f"{src / depth_rows[k][1]}: depth must be a 16-bit one-channel PNG"
            )
        depth.append((units.astype(np.float64) * (1.0 / scale)).astype(np.float32))
    depth = np.stack(depth)
    if depth.shape[1:] != rgb.shape[1:3]:
        raise ImportFormatError(
            f"depth images are {depth.shape[2]}x{depth.shape[1]}, colour "
            f"{rgb.shape[2]}x{rgb.shape[1]}: "
            "depth must be registered to the colour image"
        )
    joints = joint_t = None
    names: tuple[str, ...] = ()
    if (src / "joints.txt").is_file():
        jr = _table(src / "joints.txt", 8, "'timestamp q1 .. q7' joint positions [rad]")
        jj = _floats(src / "joints.txt", jr, slice(0, 8))
        joint_t, joints = jj[:, 0] + options.pose_time_offset, jj[:, 1:]
        names = tuple(f"panda_joint{i}" for i in range(1, 8))
    rec = assemble(
        stamps=rgb_t,
        rgb=rgb,
        depth=depth,
        K=np.asarray(K, np.float64),
        T_hand_cam=T_hand_cam,
        pose_stamps=pose_t,
        pose_name="groundtruth",
        camera_poses=T_wc,
        joint_stamps=joint_t,
        joints=joints,
        joint_names=names,
        depth_resolution=min(max(1.0 / scale, 1e-6), 0.01),
        ee_frame=ee_frame,
        meta={"source": "tum", "path": str(src), "depth_scale": scale},
    )
    return rec, "camera"

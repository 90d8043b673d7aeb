"""``tabletop import``: a user's own recording (a ROS 2 bag, a TUM-style RGB-D folder) into the
project's recording format, checked for the classic frame mistakes (docs/real_robot.md)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

__all__ = ["add_commands", "cmd_import"]


def _matrix(path: str, shape: tuple[int, int], what: str) -> np.ndarray:
    from tabletop.errors import ConfigError

    form = (
        f'{shape[0]}x{shape[1]} numbers, as JSON ([[...], ...] or {{"T_hand_cam": [[...]]}}) '
        f"or whitespace text, one row a line"
    )
    try:
        text = Path(path).read_text()
    except UnicodeDecodeError:
        raise ConfigError(f"{what}: {path} is not text; it must hold {form}") from None
    except OSError as e:
        raise ConfigError(f"{what}: cannot read {path}: {e.strerror or e}") from None
    try:
        v = json.loads(text)
        if isinstance(v, dict):
            v = next(iter(v.values())) if len(v) == 1 else v.get("T_hand_cam", v)
        a = np.array(v, np.float64)
    except (ValueError, TypeError):
        try:
            a = np.array(
                [[float(x) for x in ln.split()] for ln in text.splitlines() if ln.strip()],
                np.float64,
            )
        except ValueError as e:
            raise ConfigError(f"{what}: {path} must hold {form}; {e}") from None
    if a.shape != shape:
        raise ConfigError(f"{what}: {path} must hold a {shape[0]}x{shape[1]} matrix, got {a.shape}")
    if not np.isfinite(a).all():
        raise ConfigError(
            f"{what}: {path} holds non-finite numbers (NaN or inf); it must hold {form}"
        )
    return a


def _check_rigid(T: np.ndarray, path: str, what: str) -> np.ndarray:
    """A 4x4 rigid transform: a rotation (orthonormal, det +1) and a last row [0, 0, 0, 1]."""
    from tabletop.errors import ConfigError

    R = T[:3, :3]
    if not (
        np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6)
        and np.allclose(R @ R.T, np.eye(3), atol=1e-4)
        and np.linalg.det(R) > 0
    ):
        raise ConfigError(
            f"{what}: {path} is not a rigid transform: it must be [[R, t], [0, 0, 0, 1]] with R "
            f"a rotation (orthonormal, determinant +1), got last row {T[3].tolist()} and "
            f"det(R) = {np.linalg.det(R):.4g}"
        )
    return T


def _check_import_flags(args: argparse.Namespace) -> None:
    """The numeric flags and ``--out`` checked before anything is read."""
    from tabletop.cli.output import check_output_flag
    from tabletop.errors import ConfigError

    if args.intrinsics is not None:
        fx, fy = args.intrinsics[:2]
        if not (np.isfinite(args.intrinsics).all() and fx > 0 and fy > 0):
            raise ConfigError(
                f"--intrinsics FX FY CX CY: finite pixels with FX, FY > 0, got {args.intrinsics}"
            )
    if not (np.isfinite(args.max_pair_dt) and args.max_pair_dt > 0):
        raise ConfigError(
            f"--max-pair-dt must be a finite number of seconds > 0, got {args.max_pair_dt}"
        )
    if not np.isfinite(args.pose_time_offset):
        raise ConfigError(
            f"--pose-time-offset must be a finite number of seconds, got {args.pose_time_offset}"
        )
    check_output_flag("--out", args.out, directory=True)


def cmd_import(args: argparse.Namespace) -> int:
    from tabletop.arm.recording_kinematics import PandaRecordingKinematics
    from tabletop.errors import ConfigError
    from tabletop.ingest import BagTopics, ImportOptions, import_recording

    _check_import_flags(args)
    T_hand_cam = None
    if args.hand_cam is not None:
        T_hand_cam = _check_rigid(
            _matrix(args.hand_cam, (4, 4), "--hand-cam"), args.hand_cam, "--hand-cam"
        )
    K = None
    if args.intrinsics is not None:
        fx, fy, cx, cy = args.intrinsics
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    if args.depth_scale is not None and not args.depth_scale > 0:
        raise ConfigError(
            f"--depth-scale must be > 0 depth units per metre, got {args.depth_scale}"
        )
    options = ImportOptions(
        depth_scale=args.depth_scale,
        pose_time_offset=args.pose_time_offset,
        max_pair_dt=args.max_pair_dt,
        T_hand_cam=T_hand_cam,
        K=K,
    )
    topics = BagTopics(
        rgb=args.rgb_topic,
        depth=args.depth_topic,
        camera_info=args.info_topic,
        joint_states=args.joints_topic,
        audio=args.audio_topic,
        world_frame=args.world_frame,
        hand_frame=args.hand_frame,
    )
    kin = PandaRecordingKinematics()
    rec, report = import_recording(
        args.src,
        args.out,
        args.format,
        options=options,
        topics=topics,
        kinematics=kin,
        arm=kin,
        overwrite=args.overwrite,
    )
    print(
        f"imported {len(rec)} frames ({rec.image_size[0]}x{rec.image_size[1]}, "
        f"{rec.duration:.1f} s, poses from {rec.meta['poses_from']}"
        f"{', audio' if rec.audio is not None else ''}) -> {args.out}"
    )
    print(
        f"checks passed: {report.agreement:.0%} of points agree between neighbouring views, "
        f"{report.level:.0%} on the level table at z = {report.table_z:+.3f} m, median depth "
        f"{report.median_depth:.3f} m"
    )
    return 0


def add_commands(sub) -> None:
    """Register ``import`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser(
        "import",
        help="import a ROS 2 bag or a TUM RGB-D folder as a recording, checking its frames",
        description=(
            "Read a ROS 2 bag (the 'import' extra: rosbags) or a TUM-style RGB-D folder into "
            "the recording format (docs/recording_format.md), after checks that name an "
            "inverted pose, a camera body frame for the optical frame, a wrong depth unit, "
            "timestamps out of order or on another clock, and a camera inside the arm "
            "(docs/real_robot.md)."
        ),
    )
    p.add_argument("src", help="bag directory (metadata.yaml) or TUM folder (rgb.txt, ...)")
    p.add_argument("--out", required=True, help="recording directory to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing recording")
    p.add_argument("--format", choices=["rosbag2", "tum"], help="default: from the folder")
    p.add_argument(
        "--depth-scale",
        type=float,
        metavar="UNITS",
        help="16-bit depth units per metre (default: 5000 for TUM, 1000 for a 16UC1 topic; "
        "float depth is in metres)",
    )
    p.add_argument(
        "--intrinsics",
        type=float,
        nargs=4,
        metavar=("FX", "FY", "CX", "CY"),
        help="camera intrinsics [px] (TUM without camera.json; overrides CameraInfo)",
    )
    p.add_argument(
        "--hand-cam",
        metavar="FILE",
        help="4x4 T_hand_cam (JSON or whitespace text): the camera optical frame in "
        "the hand frame (default: /tf_static, or the TUM folder's camera.json)",
    )
    p.add_argument(
        "--pose-time-offset",
        type=float,
        default=0.0,
        metavar="S",
        help="seconds added to the pose/joint stamps (a constant clock offset)",
    )
    p.add_argument(
        "--max-pair-dt",
        type=float,
        default=0.02,
        metavar="S",
        help="largest gap between a colour frame and its depth frame [s]",
    )
    p.add_argument("--rgb-topic")
    p.add_argument("--depth-topic")
    p.add_argument("--info-topic")
    p.add_argument("--joints-topic")
    p.add_argument("--audio-topic")
    p.add_argument("--world-frame", default="panda_link0", help="TF frame of the world")
    p.add_argument("--hand-frame", default="panda_hand", help="TF frame of the hand")
    p.set_defaults(func=cmd_import)

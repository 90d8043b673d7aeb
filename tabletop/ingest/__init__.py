"""Import a user's own recordings (a ROS 2 bag, a TUM-style RGB-D folder) into the project's
recording format, with frame checks that name the classic mistakes (docs/real_robot.md).

Core-level: it imports no arm, mapping or simulator code. Where joint states stand in for hand
poses, the caller passes the arm's kinematics and geometry
(``tabletop.arm.recording_kinematics.PandaRecordingKinematics``); the CLI does.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from tabletop.ingest.checks import ArmGeometry, CheckReport, check_recording
from tabletop.ingest.common import ImportOptions, Kinematics
from tabletop.ingest.errors import (
    CameraFrameError,
    CameraInsideArmError,
    DepthScaleError,
    FrameCheckError,
    ImportFormatError,
    InvertedPoseError,
    MissingExtraError,
    TimestampError,
)
from tabletop.ingest.rosbag2 import BagTopics
from tabletop.recording import Recording, check_output, save_recording

__all__ = [
    "FORMATS",
    "BagTopics",
    "CameraFrameError",
    "CameraInsideArmError",
    "CheckReport",
    "DepthScaleError",
    "FrameCheckError",
    "ImportFormatError",
    "ImportOptions",
    "InvertedPoseError",
    "MissingExtraError",
    "TimestampError",
    "guess_format",
    "import_recording",
    "read_source",
]

FORMATS = ("rosbag2", "tum")


def guess_format(src: str | Path) -> str:
    """``rosbag2`` for a folder with a ``metadata.yaml`` (or an .mcap/.db3 file), ``tum`` for one
    with an ``rgb.txt``."""
    src = Path(src)
    if not src.exists():
        raise ImportFormatError(f"{src} does not exist: give a ROS 2 bag or a TUM RGB-D folder")
    if (src.is_dir() and (src / "metadata.yaml").is_file()) or src.suffix in (".mcap", ".db3"):
        return "rosbag2"
    if src.is_dir() and (src / "rgb.txt").is_file():
        return "tum"
    raise ImportFormatError(
        f"cannot tell the format of {src} (no metadata.yaml of a ROS 2 bag, no rgb.txt of a TUM "
        f"folder); pass --format, one of {list(FORMATS)}"
    )


def read_source(
    src: str | Path,
    fmt: str | None = None,
    options: ImportOptions | None = None,
    topics: BagTopics | None = None,
    kinematics: Kinematics | None = None,
) -> tuple[Recording, str]:
    """(recording, pose_of) read from ``src``, unchecked."""
    fmt = fmt or guess_format(src)
    if fmt == "rosbag2":
        from tabletop.ingest.rosbag2 import read_rosbag2

        return read_rosbag2(src, options, topics, kinematics)
    if fmt == "tum":
        from tabletop.ingest.tum import read_tum

        return read_tum(src, options)
    raise ImportFormatError(f"unknown format {fmt!r}; valid: {list(FORMATS)}")


def import_recording(
    src: str | Path,
    out: str | Path | None = None,
    fmt: str | None = None,
    *,
    options: ImportOptions | None = None,
    topics: BagTopics | None = None,
    kinematics: Kinematics | None = None,
    arm: ArmGeometry | None = None,
    overwrite: bool = False,
) -> tuple[Recording, CheckReport]:
    """Read ``src``, run the frame checks (raising the typed error of a mistake they find) and,
    when ``out`` is given, write the recording there (atomically, with the recording module's
    own writer). The checks' measurements go into the recording's ``meta["import_checks"]``."""
    if out is not None:
        check_output(out, overwrite)
    rec, pose_of = read_source(src, fmt, options, topics, kinematics)
    report = check_recording(
        rec, pose_of=pose_of, arm=arm if rec.joint_names != ("none",) else None
    )
    rec = replace(rec, meta={**rec.meta, "import_checks": report.to_dict(), "poses_from": pose_of})
    if out is not None:
        save_recording(rec, out, overwrite=overwrite)
    return rec, report

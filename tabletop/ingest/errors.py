"""Errors of importing a user's own recording: one class per classic frame mistake.

Each is a :class:`tabletop.errors.RecordingError`: the message says what the data showed and the
likely fix. :class:`FrameCheckError` is their base (and is raised itself when the views disagree
in a way none of the known mistakes explains).
"""

from __future__ import annotations

from tabletop.errors import ConfigError, RecordingError

__all__ = [
    "CameraFrameError",
    "CameraInsideArmError",
    "DepthScaleError",
    "FrameCheckError",
    "ImportFormatError",
    "InvertedPoseError",
    "MissingExtraError",
    "TimestampError",
]


class ImportFormatError(RecordingError):
    """The source is not what its format says: a missing file or topic, an unknown encoding."""


class MissingExtraError(ConfigError):
    """An optional library the import needs is not installed; the message names the extra."""


class FrameCheckError(RecordingError):
    """The imported frames are not consistent with one another (points of one surface seen from
    several views do not agree, or the table is not level)."""


class InvertedPoseError(FrameCheckError):
    """The poses are inverted: ``T_cam_world`` (or ``T_hand_world``) was given where
    ``T_world_cam`` (``T_world_hand``) is meant."""


class CameraFrameError(FrameCheckError):
    """A camera body frame (x forward, z up) was given where the optical frame (z forward,
    x right, y down) is meant."""


class DepthScaleError(FrameCheckError):
    """Depth is in the wrong unit: millimetres read as metres, or a wrong depth scale."""


class TimestampError(FrameCheckError):
    """Timestamps out of order, or streams stamped on different clocks."""


class CameraInsideArmError(FrameCheckError):
    """The hand-camera extrinsic puts the camera inside the arm's own links."""

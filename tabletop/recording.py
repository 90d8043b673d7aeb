"""Recordings: what the wrist camera, the arm and the microphone produced, on disk and in memory.

The format (``tabletop-recording`` version 2; version 1 still loads) is documented in
``docs/recording_format.md``. A real Panda with a wrist camera produces the same thing: RGB,
metric depth, end-effector poses in the base frame, the calibrated hand-camera extrinsic, the
microphone's pose in the hand frame, and a mono audio track on the frame clock. The simulator
adds its segmentation (for the oracle encoders) and the ground truth.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import RecordingError

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "Frame",
    "Recording",
    "Segment",
    "check_output",
    "load_recording",
    "read_header",
    "save_recording",
]

log = logging.getLogger(__name__)

FORMAT_NAME = "tabletop-recording"
FORMAT_VERSION = 2
#: Versions this code reads: 1 (no microphone pose: the scans of version 1 carried the
#: microphone at the Panda's tool centre point) and 2.
READABLE_VERSIONS = (1, 2)
#: The microphone of version-1 recordings: at the Panda's tool centre point, 0.105 m along the
#: hand frame's z axis (``panda_grasptarget`` in the URDF).
V1_T_HAND_MIC = (
    (1.0, 0.0, 0.0, 0.0),
    (0.0, 1.0, 0.0, 0.0),
    (0.0, 0.0, 1.0, 0.105),
    (0.0, 0.0, 0.0, 1.0),
)
_HEADER = "recording.json"
_POSES = "poses.npz"
_AUDIO = "audio.npy"


@dataclass(frozen=True)
class Segment:
    """A named span of frames ``[start, stop)``: the mapping sweep, a transit, an episode."""

    name: str
    kind: str  # "mapping" | "transit" | "episode" | free text for real data
    start: int
    stop: int


@dataclass(frozen=True)
class Frame:
    """One time step of a recording (views into the recording's arrays)."""

    index: int
    timestamp: float  # [s] on the frame clock
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 [m], 0 = invalid
    joint_positions: np.ndarray  # (J,) float64 [rad]: the arm's 7 joints, a base's 2 wheels
    T_world_hand: np.ndarray  # (4, 4) pose of the camera's mount frame (``ee_frame``)
    T_world_cam: np.ndarray  # (4, 4) camera optical frame (OpenCV) in the base frame
    segmentation: np.ndarray | None  # (H, W) uint16 instance ids; simulator only


@dataclass(frozen=True, eq=False)
class Recording:
    """A whole recording in memory. Arrays are validated and made read-only on creation."""

    timestamps: np.ndarray  # (N,) float64 [s], strictly increasing
    rgb: np.ndarray  # (N, H, W, 3) uint8
    depth: np.ndarray  # (N, H, W) float32 [m], 0 = invalid
    joint_positions: np.ndarray
    """(N, J) float64 [rad]: the robot's joints per frame, J >= 1 (the Panda's 7 arm joints;
    a wheeled base's 2 wheel angles); ``joint_names`` names them when given."""
    T_world_hand: np.ndarray
    """(N, 4, 4) float64 [m]: the pose of the frame the camera and microphone are mounted on
    (``ee_frame``: the Panda's hand, a base's footprint) in the world frame."""
    K: np.ndarray  # (3, 3) float64 [px]
    T_hand_cam: np.ndarray  # (4, 4) float64, calibrated camera extrinsic [m]
    T_hand_mic: np.ndarray = V1_T_HAND_MIC  # type: ignore[assignment]
    """(4, 4) float64 [m]: the microphone's pose in the hand frame (where a sound was heard
    from). The simulated scans carry it at the tool centre point."""
    depth_resolution: float = 1e-4
    """Depth quantum [m]; depth values are integer multiples of it (stored as uint16)."""
    audio: np.ndarray | None = None  # (S,) float32 mono in [-1, 1], sample 0 at t = 0 s
    audio_rate: int = 16000  # [Hz]
    segments: tuple[Segment, ...] = ()
    segmentation: np.ndarray | None = None  # (N, H, W) uint16, simulator oracle only
    T_world_hand_true: np.ndarray | None = None  # (N, 4, 4) noise-free poses (simulator)
    ground_truth: dict | None = None  # scene and sound-event ground truth (simulator)
    meta: dict = field(default_factory=dict)  # free-form provenance (source, seed, renderer, …)
    ee_frame: str = "panda_hand"
    """The frame ``T_world_hand`` refers to (``panda_hand``; ``base_footprint`` for the wheeled
    base, whose camera rides on its mast)."""
    joint_names: tuple[str, ...] = ()
    """Names of the J joints of ``joint_positions`` (empty: the Panda's ``panda_joint1..7``)."""

    def __post_init__(self) -> None:
        def arr(name, dtype, shape_tail, ndim):
            value = getattr(self, name)
            a = np.array(value, dtype=dtype, copy=True)
            if a.ndim != ndim or (shape_tail and a.shape[1:] != shape_tail):
                raise RecordingError(
                    f"{name} must have shape (N, {', '.join(map(str, shape_tail))}) "
                    f"and dtype {np.dtype(dtype).name}, got {getattr(value, 'shape', None)}"
                )
            a.setflags(write=False)
            object.__setattr__(self, name, a)
            return a

        t = arr("timestamps", np.float64, (), 1)
        n = len(t)
        rgb = arr("rgb", np.uint8, (), 4)
        if rgb.shape[-1] != 3:
            raise RecordingError(f"rgb must be (N, H, W, 3) uint8, got {rgb.shape}")
        h, w = rgb.shape[1:3]
        arr("depth", np.float32, (h, w), 3)
        jp = arr("joint_positions", np.float64, (), 2)
        if jp.shape[1] < 1:
            raise RecordingError(f"joint_positions must be (N, J) with J >= 1, got {jp.shape}")
        if not isinstance(self.ee_frame, str) or not self.ee_frame:
            raise RecordingError(f"ee_frame must be a frame name, got {self.ee_frame!r}")
        names = self.joint_names
        if not isinstance(names, (tuple, list)) or not all(isinstance(x, str) for x in names):
            raise RecordingError(f"joint_names must be a tuple of strings, got {names!r}")
        object.__setattr__(self, "joint_names", tuple(names))
        if names and len(names) != jp.shape[1]:
            raise RecordingError(
                f"joint_names has {len(names)} names for {jp.shape[1]} joints in joint_positions"
            )
        arr("T_world_hand", np.float64, (4, 4), 3)
        for name in ("rgb", "depth", "joint_positions", "T_world_hand"):
            if len(getattr(self, name)) != n:
                raise RecordingError(
                    f"{name} has {len(getattr(self, name))} frames, timestamps has {n}"
                )
        if not np.all(np.isfinite(t)):
            bad = np.flatnonzero(~np.isfinite(t))
            raise RecordingError(f"timestamps must be finite [s]; frame {bad[0]} is {t[bad[0]]}")
        if n and np.any(np.diff(t) <= 0):
            i = int(np.flatnonzero(np.diff(t) <= 0)[0])
            raise RecordingError(
                f"timestamps must be strictly increasing; frame {i + 1} ({t[i + 1]} s) does "
                f"not follow frame {i} ({t[i]} s)"
            )
        K = np.array(self.K, dtype=np.float64)
        if K.shape != (3, 3):
            raise RecordingError(f"K must be (3, 3), got {K.shape}")
        if (
            not np.all(np.isfinite(K))
            or K[0, 0] <= 0
            or K[1, 1] <= 0
            or not np.allclose(K[2], (0.0, 0.0, 1.0))
            or K[1, 0] != 0
        ):
            raise RecordingError(
                f"K must be a pinhole matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with finite "
                f"fx, fy > 0 [px], got {K.tolist()}"
            )
        K.setflags(write=False)
        object.__setattr__(self, "K", K)
        for name in ("T_hand_cam", "T_hand_mic"):
            T = np.array(getattr(self, name), dtype=np.float64)
            if T.shape != (4, 4):
                raise RecordingError(f"{name} must be a (4, 4) transform, got {T.shape}")
            _check_rigid(T[None], name)
            T.setflags(write=False)
            object.__setattr__(self, name, T)
        _check_rigid(self.T_world_hand, "T_world_hand")
        if not np.all(np.isfinite(self.joint_positions)):
            raise RecordingError("joint_positions must be finite [rad]")
        if (
            isinstance(self.depth_resolution, bool)
            or not isinstance(self.depth_resolution, (int, float, np.floating))
            or not 1e-6 <= self.depth_resolution <= 0.01
        ):
            raise RecordingError(
                f"depth_resolution must be in [1e-6, 0.01] m per depth unit, got "
                f"{self.depth_resolution!r}"
            )
        if np.any(self.depth < 0) or not np.all(np.isfinite(self.depth)):
            raise RecordingError("depth must be finite and >= 0 (0 = invalid)")
        if self.segmentation is not None:
            arr("segmentation", np.uint16, (h, w), 3)
            if len(self.segmentation) != n:
                raise RecordingError(f"segmentation has {len(self.segmentation)} frames, not {n}")
        if self.T_world_hand_true is not None:
            arr("T_world_hand_true", np.float64, (4, 4), 3)
            if len(self.T_world_hand_true) != n:
                raise RecordingError("T_world_hand_true must have one pose per frame")
            _check_rigid(self.T_world_hand_true, "T_world_hand_true")
        if self.audio is not None:
            arr("audio", np.float32, (), 1)
            if (
                isinstance(self.audio_rate, bool)
                or not isinstance(self.audio_rate, (int, np.integer))
                or not 1000 <= self.audio_rate <= 384000
            ):
                raise RecordingError(
                    f"audio_rate must be an integer in [1000, 384000] Hz, got {self.audio_rate!r}"
                )
            if not np.all(np.isfinite(self.audio)):
                raise RecordingError("audio must be finite samples in [-1, 1]")
            peak = float(np.max(np.abs(self.audio))) if len(self.audio) else 0.0
            if peak > 1.0:
                raise RecordingError(
                    f"audio must be float samples in [-1, 1], its peak is {peak:g}"
                )
        for s in self.segments:
            if not isinstance(s, Segment) or not all(
                isinstance(v, int) and not isinstance(v, bool) for v in (s.start, s.stop)
            ):
                raise RecordingError(
                    f"segments must be Segment(name, kind, start, stop), got {s!r}"
                )
            if s.start >= s.stop:
                raise RecordingError(
                    f"segment {s.name!r} [{s.start}, {s.stop}) is empty or reversed: its start "
                    "must come before its stop (frame indices, the stop excluded)"
                )
            if not 0 <= s.start < s.stop <= n:
                raise RecordingError(f"segment {s.name!r} [{s.start}, {s.stop}) outside 0..{n}")

    # ------------------------------------------------------------------ access
    def __len__(self) -> int:
        return len(self.timestamps)

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) [px]."""
        return self.rgb.shape[2], self.rgb.shape[1]

    @property
    def T_world_cam(self) -> np.ndarray:
        """(N, 4, 4) camera poses, ``T_world_hand @ T_hand_cam``."""
        return self.T_world_hand @ self.T_hand_cam

    @property
    def T_world_mic(self) -> np.ndarray:
        """(N, 4, 4) microphone poses, ``T_world_hand @ T_hand_mic``."""
        return self.T_world_hand @ self.T_hand_mic

    def frame(self, i: int) -> Frame:
        if not -len(self) <= i < len(self):
            raise IndexError(f"frame {i} out of range for a recording of {len(self)} frames")
        i = i % len(self)
        return Frame(
            index=i,
            timestamp=float(self.timestamps[i]),
            rgb=self.rgb[i],
            depth=self.depth[i],
            joint_positions=self.joint_positions[i],
            T_world_hand=self.T_world_hand[i],
            T_world_cam=self.T_world_hand[i] @ self.T_hand_cam,
            segmentation=None if self.segmentation is None else self.segmentation[i],
        )

    def __iter__(self) -> Iterator[Frame]:
        return (self.frame(i) for i in range(len(self)))

    def segment(self, name: str) -> Segment:
        for s in self.segments:
            if s.name == name:
                return s
        raise RecordingError(f"no segment {name!r}; segments: {[s.name for s in self.segments]}")

    @property
    def duration(self) -> float:
        """[s] from the first to the last frame."""
        return float(self.timestamps[-1] - self.timestamps[0]) if len(self) else 0.0


MAX_POSE_DISTANCE_M = 100.0
"""The farthest [m] a recorded pose may lie from the base frame's origin: an arm reaches about
1 m and a mobile base crosses a building; farther is a unit or frame error."""


def _check_rigid(T: np.ndarray, name: str, tol: float = 1e-4) -> None:
    """(N, 4, 4) finite rigid transforms near the origin, else :class:`RecordingError` naming
    the first bad frame."""
    if not T.size:
        return
    finite = np.isfinite(T).all(axis=(1, 2))
    R = np.where(finite[:, None, None], T[:, :3, :3], np.eye(3))
    ortho = np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max(axis=(1, 2)) < tol
    proper = np.linalg.det(R) > 0
    bottom = np.abs(np.nan_to_num(T[:, 3]) - (0.0, 0.0, 0.0, 1.0)).max(axis=1) < tol
    t = np.where(finite[:, None], T[:, :3, 3], 0.0)
    near = np.linalg.norm(t, axis=1) <= MAX_POSE_DISTANCE_M
    for ok, what in (
        (finite, "finite"),
        (ortho & proper & bottom, "a rigid transform (orthonormal rotation, last row 0 0 0 1)"),
        (near, f"within {MAX_POSE_DISTANCE_M:.0f} m of the base frame (a unit error?)"),
    ):
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            where = f"frame {i}" if len(T) > 1 else "it"
            raise RecordingError(f"{name} must be {what}; {where} is {np.round(T[i], 4).tolist()}")


# ---------------------------------------------------------------------- writing
def _image_name(kind: str, i: int) -> str:
    return f"{kind}/{i:06d}.png"


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image):
        raise RecordingError(f"could not write {path}")


def check_output(path: str | Path, overwrite: bool = False) -> Path:
    """Check before any work that a recording may be written to ``path``: it must not exist, or
    (with ``overwrite``) be a recording this package wrote, whose header names its format. Any
    other existing file or directory is never replaced: the user's data is not ours to delete.
    """
    path = Path(path)
    if not path.exists():
        return path
    if not overwrite:
        raise RecordingError(f"{path} exists; pass overwrite=True (--overwrite) to replace it")
    header = path / _HEADER
    try:
        ok = path.is_dir() and json.loads(header.read_text()).get("format") == FORMAT_NAME
    except (OSError, ValueError, AttributeError):
        ok = False
    if not ok:
        raise RecordingError(
            f"{path} exists and is not a recording (no {_HEADER} of format {FORMAT_NAME!r}); "
            "--overwrite only replaces a previous recording: choose another path"
        )
    return path


def _recording_path(path) -> Path:
    """``path`` as a :class:`Path`, or :class:`RecordingError` where it is no path."""
    if not isinstance(path, (str, Path)):
        raise RecordingError(f"a recording is a directory path, got {type(path).__name__}")
    return Path(path)


def save_recording(
    rec: Recording, path: str | Path, *, overwrite: bool = False, workers: int = 2
) -> Path:
    """Write ``rec`` to directory ``path`` atomically (a temporary sibling, then a rename).

    An existing ``path`` is an error unless ``overwrite``; then it is replaced only once the
    new recording is complete, so a failure never leaves half a recording behind.
    """
    if not isinstance(rec, Recording):
        raise RecordingError(f"save_recording writes a Recording, got {type(rec).__name__}")
    path = _recording_path(path)
    check_output(path, overwrite)
    if not path.exists():
        with atomic_path(path, directory=True) as tmp:
            _write_into(rec, tmp, workers)
        return path
    staged = path.with_name(f".{path.name}.new-{os.getpid()}")
    old = path.with_name(f".{path.name}.old-{os.getpid()}")
    with atomic_path(staged, directory=True) as tmp:
        _write_into(rec, tmp, workers)
    try:  # the previous recording is replaced only once the new one is whole
        path.rename(old)
        staged.rename(path)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise
    shutil.rmtree(old)
    return path


def _write_into(rec: Recording, out: Path, workers: int) -> None:
    n = len(rec)
    kinds = ["rgb", "depth"] + (["segmentation"] if rec.segmentation is not None else [])
    for k in kinds:
        (out / k).mkdir()
    scale = 1.0 / rec.depth_resolution
    max_units = float(rec.depth.max(initial=0.0)) * scale
    if max_units > 65535:
        raise RecordingError(
            f"depth up to {rec.depth.max():.3f} m does not fit 16 bits at "
            f"depth_resolution={rec.depth_resolution} m"
        )

    def write_frame(i: int) -> None:
        _write_png(out / _image_name("rgb", i), np.ascontiguousarray(rec.rgb[i][..., ::-1]))
        units = np.round(rec.depth[i].astype(np.float64) * scale).astype(np.uint16)
        _write_png(out / _image_name("depth", i), units)
        if rec.segmentation is not None:
            _write_png(out / _image_name("segmentation", i), rec.segmentation[i])

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        list(pool.map(write_frame, range(n)))

    poses = {
        "timestamps": rec.timestamps,
        "joint_positions": rec.joint_positions,
        "T_world_hand": rec.T_world_hand,
    }
    if rec.T_world_hand_true is not None:
        poses["T_world_hand_true"] = rec.T_world_hand_true
    np.savez(out / _POSES, **poses)
    if rec.audio is not None:
        np.save(out / _AUDIO, rec.audio)

    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    header = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "n_frames": n,
        "width": rec.image_size[0],
        "height": rec.image_size[1],
        "K": rec.K.tolist(),
        "T_hand_cam": rec.T_hand_cam.tolist(),
        "T_hand_mic": rec.T_hand_mic.tolist(),
        "ee_frame": rec.ee_frame,
        "joint_names": list(rec.joint_names),
        "depth_resolution": rec.depth_resolution,
        "has_segmentation": rec.segmentation is not None,
        "audio": None
        if rec.audio is None
        else {"file": _AUDIO, "sample_rate": rec.audio_rate, "n_samples": len(rec.audio)},
        "segments": [vars(s) for s in rec.segments],
        "meta": rec.meta,
        "ground_truth": rec.ground_truth,
        "files": {f: (out / f).stat().st_size for f in files},
    }
    (out / _HEADER).write_text(json.dumps(header, indent=1))


# ---------------------------------------------------------------------- reading
def _header_error(header_path: Path, field: str, value: object, valid: str) -> RecordingError:
    shown = repr(value)
    if len(shown) > 80:
        shown = shown[:77] + "..."
    return RecordingError(f"{header_path}: {field} is {shown}; valid: {valid}")


def _json_kind(v: object) -> str:
    """The JSON name of a decoded value's type (array, string, number, ...)."""
    kinds = ((list, "array"), (str, "string"), (bool, "boolean"), ((int, float), "number"))
    return next((name for t, name in kinds if isinstance(v, t)), "null")


def _is_int(v: object) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _check_header(h: dict, header_path: Path) -> None:
    """Types, ranges and consistency of a recording header's fields, before any file is read:
    a :class:`RecordingError` names the field, its value and what is valid."""
    if not isinstance(h, dict):
        raise RecordingError(f"{header_path}: must hold a JSON object, got {type(h).__name__}")
    required = ["n_frames", "width", "height", "K", "T_hand_cam", "depth_resolution", "files"]
    missing = [k for k in required if k not in h]
    if missing:
        raise RecordingError(f"{header_path}: missing fields {missing}")
    if not _is_int(h["n_frames"]) or not 0 <= h["n_frames"] <= 10**6:
        raise _header_error(header_path, "n_frames", h["n_frames"], "an integer in [0, 1e6]")
    for k in ("width", "height"):
        if not _is_int(h[k]) or not 1 <= h[k] <= 8192:
            raise _header_error(header_path, k, h[k], "an integer in [1, 8192] px")
    for k, shape in (("K", (3, 3)), ("T_hand_cam", (4, 4)), ("T_hand_mic", (4, 4))):
        if k not in h:
            continue
        v = h[k]
        ok = (
            isinstance(v, list)
            and len(v) == shape[0]
            and all(
                isinstance(r, list)
                and len(r) == shape[1]
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in r)
                for r in v
            )
        )
        if not ok:
            raise _header_error(header_path, k, v, f"a {shape[0]}x{shape[1]} list of numbers")
    r = h["depth_resolution"]
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not 1e-6 <= r <= 0.01:
        raise _header_error(header_path, "depth_resolution", r, "a number in [1e-6, 0.01] m")
    files = h["files"]
    if not isinstance(files, dict) or not all(
        isinstance(k, str) and _is_int(v) and v >= 0 for k, v in files.items()
    ):
        raise _header_error(header_path, "files", files, "an object of file name -> byte size")
    for rel in files:
        parts = Path(rel).parts
        if not parts or Path(rel).is_absolute() or ".." in parts:
            raise _header_error(header_path, "files", rel, "paths inside the recording directory")
    segs = h.setdefault("segments", [])
    keys = {"name", "kind", "start", "stop"}
    if not isinstance(segs, list) or not all(
        isinstance(x, dict)
        and set(x) == keys
        and isinstance(x["name"], str)
        and isinstance(x["kind"], str)
        and _is_int(x["start"])
        and _is_int(x["stop"])
        for x in segs
    ):
        raise _header_error(
            header_path, "segments", segs, "a list of {name, kind, start, stop} objects"
        )
    audio = h.get("audio")
    if audio is not None:
        if not (
            isinstance(audio, dict)
            and set(audio) == {"file", "sample_rate", "n_samples"}
            and isinstance(audio["file"], str)
            and audio["file"] in files
            and _is_int(audio["sample_rate"])
            and _is_int(audio["n_samples"])
            and audio["n_samples"] >= 0
        ):
            raise _header_error(
                header_path,
                "audio",
                audio,
                "null, or {file (one of the listed files), sample_rate, n_samples (integers)}",
            )
    for k in ("meta", "ground_truth"):
        if h.get(k) is not None and not isinstance(h[k], dict):
            raise _header_error(header_path, k, h[k], "an object or null")
    if not isinstance(h.get("ee_frame", "panda_hand"), str):
        raise _header_error(header_path, "ee_frame", h["ee_frame"], "a frame name")
    names = h.get("joint_names", [])
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        raise _header_error(header_path, "joint_names", names, "a list of joint names")
    if not isinstance(h.get("has_segmentation", False), bool):
        raise _header_error(header_path, "has_segmentation", h["has_segmentation"], "true or false")


def _read_png(path: Path, flags: int) -> np.ndarray:
    img = cv2.imread(str(path), flags)
    if img is None:
        raise RecordingError(f"{path} is missing or not a readable PNG")
    return img


_NPY_MAGIC = {".npy": b"\x93NUMPY", ".npz": b"PK"}

# A scan's audio track runs one frame period past its last frame (sim/sound_insertion.py:
# ceil((t_last + dt) * rate) samples); an import pads the audio to start with the frames and
# lets its first sample lie up to 5 s from the frames' span (ingest/common.py, check_clock's
# slack_s=5.0), and the track may end a few seconds before or after the last frame. A larger
# gap between the audio's duration (samples / sample_rate) and the frames' time span means the
# header's sample rate is not the audio's (16 kHz audio declared as 8 kHz lasts twice as long).
AUDIO_SPAN_TOLERANCE_S = 5.0


def _load_array_file(path: Path, what: str):
    """``np.load`` of a .npy or .npz file without pickles; a file that is not one (text,
    garbage, a pickle) is named as not a NumPy array file, never numpy's allow_pickle advice."""
    magic = _NPY_MAGIC[path.suffix]
    kind = f"a NumPy {path.suffix} file"
    try:
        with open(path, "rb") as f:
            head = f.read(len(magic))
    except OSError as e:
        raise RecordingError(f"{path} cannot be read: {e.strerror or e}") from None
    if head != magic:
        raise RecordingError(f"{path} is not {kind} ({what} is stored as {kind})")
    try:
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        return np.load(path, allow_pickle=False)
    except Exception as e:
        reason = "it holds pickled Python objects" if "pickle" in str(e) else str(e)
        raise RecordingError(f"{path} is not a valid {kind} ({what}): {reason}") from None


def read_header(path: str | Path) -> dict:
    """The checked header of the recording directory ``path`` (its frames are not read: what a
    command checks its flags against before loading them); :class:`RecordingError` names what
    is wrong."""
    path = _recording_path(path)
    header_path = path / _HEADER
    if not path.exists():
        raise RecordingError(f"{path} does not exist: a recording is a directory (tabletop scan)")
    if not path.is_dir():
        raise RecordingError(f"{path} is a file, not a recording: a recording is a directory")
    if not header_path.is_file():
        raise RecordingError(f"{path} is not a recording: {header_path} is missing")
    try:
        text = header_path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise RecordingError(
            f"{header_path} is not text (byte {e.start} is not UTF-8): a recording's header is "
            f"a JSON object of format {FORMAT_NAME!r}"
        ) from None
    except OSError as e:
        raise RecordingError(f"{header_path} cannot be read: {e.strerror or e}") from None
    try:
        h = json.loads(text)
    except json.JSONDecodeError as e:
        raise RecordingError(f"{header_path} is not valid JSON (truncated?): {e}") from None
    except RecursionError:
        raise RecordingError(f"{header_path} nests JSON too deeply to be a header") from None
    if not isinstance(h, dict):
        raise RecordingError(
            f"{header_path} holds a JSON {_json_kind(h)}, not an object: a recording's header "
            f"is a JSON object of format {FORMAT_NAME!r}"
        )
    if h.get("format") != FORMAT_NAME:
        raise RecordingError(f"{header_path}: format is {h.get('format')!r}, not {FORMAT_NAME!r}")
    if h.get("version") not in READABLE_VERSIONS:
        raise RecordingError(
            f"{header_path}: version {h.get('version')!r} is not supported; "
            f"this tabletop reads versions {list(READABLE_VERSIONS)}"
        )
    _check_header(h, header_path)
    return h


def load_recording(path: str | Path, *, workers: int = 2) -> Recording:
    """Load and validate a recording directory written by :func:`save_recording`.

    Every file the header lists must exist with its recorded size: a missing or truncated
    file raises :class:`RecordingError` naming it.
    """
    path = _recording_path(path)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise RecordingError(f"workers must be a whole number >= 1, got {workers!r}")
    h = read_header(path)
    for rel, size in h["files"].items():
        f = path / rel
        if not f.is_file():
            raise RecordingError(f"{f} is missing (listed in {_HEADER})")
        actual = f.stat().st_size
        if actual != size:
            raise RecordingError(f"{f} has {actual} bytes, expected {size}: truncated or changed")

    n = int(h["n_frames"])
    poses = _load_array_file(path / _POSES, "poses and timestamps")
    for k in ("timestamps", "joint_positions", "T_world_hand"):
        if k not in poses:
            raise RecordingError(f"{path / _POSES} lacks array {k!r}")
        if np.ndim(poses[k]) == 0 or len(poses[k]) != n:
            raise RecordingError(
                f"{path / _POSES}: {k} has shape {np.shape(poses[k])}, the header {n} frames"
            )

    scale = float(h["depth_resolution"])

    def read_frame(i: int):
        bgr = _read_png(path / _image_name("rgb", i), cv2.IMREAD_COLOR)
        units = _read_png(path / _image_name("depth", i), cv2.IMREAD_UNCHANGED)
        if units.dtype != np.uint16:
            raise RecordingError(f"{path / _image_name('depth', i)} must be a 16-bit PNG")
        seg = None
        if h.get("has_segmentation"):
            seg = _read_png(path / _image_name("segmentation", i), cv2.IMREAD_UNCHANGED)
        return bgr[..., ::-1], (units.astype(np.float64) * scale).astype(np.float32), seg

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        frames = list(pool.map(read_frame, range(n)))
    H, W = int(h["height"]), int(h["width"])
    for i, images in enumerate(frames):
        for kind, img in zip(("rgb", "depth", "segmentation"), images, strict=True):
            if img is not None and img.shape[:2] != (H, W):
                raise RecordingError(
                    f"{path / _image_name(kind, i)}: image is {img.shape[1]}x{img.shape[0]}, "
                    f"header says {W}x{H}"
                )
    rgb = np.stack([f[0] for f in frames]) if n else np.zeros((0, H, W, 3), np.uint8)
    depth = np.stack([f[1] for f in frames]) if n else np.zeros((0, H, W), np.float32)
    seg = np.stack([f[2] for f in frames]) if h.get("has_segmentation") and n else None

    audio = None
    audio_rate = 16000
    if h.get("audio"):
        audio_path = path / h["audio"]["file"]
        if audio_path.suffix != ".npy":
            raise RecordingError(f"{audio_path}: audio is stored as a NumPy .npy file")
        audio = _load_array_file(audio_path, "the audio track")
        audio_rate = h["audio"]["sample_rate"]
        if getattr(audio, "ndim", 0) != 1 or len(audio) != h["audio"]["n_samples"]:
            raise RecordingError(
                f"{audio_path}: must hold the header's {h['audio']['n_samples']} "
                f"mono samples, holds an array of shape {getattr(audio, 'shape', None)}"
            )
        if not np.issubdtype(audio.dtype, np.floating):
            raise RecordingError(
                f"{audio_path} holds {audio.dtype} samples; valid: float samples in [-1, 1] "
                "(integer PCM is not scaled on load)"
            )
    try:
        rec = Recording(
            timestamps=poses["timestamps"],
            rgb=rgb,
            depth=depth,
            joint_positions=poses["joint_positions"],
            T_world_hand=poses["T_world_hand"],
            K=np.array(h["K"]),
            T_hand_cam=np.array(h["T_hand_cam"]),
            T_hand_mic=np.array(h.get("T_hand_mic", V1_T_HAND_MIC)),
            depth_resolution=scale,
            audio=audio,
            audio_rate=audio_rate,
            segments=tuple(Segment(**s) for s in h["segments"]),
            segmentation=seg,
            T_world_hand_true=poses.get("T_world_hand_true"),
            ground_truth=h.get("ground_truth"),
            meta=h.get("meta", {}),
            ee_frame=h.get("ee_frame", "panda_hand"),
            joint_names=tuple(h.get("joint_names", ())),
        )
    except RecordingError as e:
        raise RecordingError(f"{path}: {e}") from None
    except (TypeError, ValueError) as e:  # arrays of the wrong kind (text where numbers are)
        raise RecordingError(f"{path}: a pose or header array is malformed ({e})") from None
    if rec.audio is not None:
        span, audio_s = rec.duration, len(rec.audio) / rec.audio_rate
        if abs(audio_s - span) > AUDIO_SPAN_TOLERANCE_S:
            raise RecordingError(
                f"{path / h['audio']['file']}: {len(rec.audio)} samples at the header's "
                f"sample_rate {rec.audio_rate} Hz last {audio_s:.3f} s, but the frames' "
                f"timestamps span {span:.3f} s (more than {AUDIO_SPAN_TOLERANCE_S:g} s apart): "
                "the sample rate is not the audio's"
            )
    return rec

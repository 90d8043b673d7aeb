"""Sensor imperfections for robustness tests: noisy poses, noisy and missing depth, lost frames,
a wrong camera extrinsic, an audio clock that is off.

:func:`apply_noise` works on any :class:`Recording` — a simulated scan or a real one — and
keeps the clean poses beside the noisy ones, so a test can measure what the noise cost.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from tabletop.errors import ConfigError
from tabletop.recording import Recording, Segment
from tabletop.sim.ground_truth import GroundTruth
from tabletop.transforms import make_transform

__all__ = ["NoiseConfig", "apply_noise"]

_NONNEGATIVE = (
    "pose_translation_m",
    "pose_rotation_rad",
    "depth_relative",
    "extrinsic_translation_m",
    "extrinsic_rotation_rad",
)
_LIMITS = {  # far beyond any sensor's noise: a typo in units, refused
    "pose_translation_m": 0.5,
    "pose_rotation_rad": np.pi,
    "depth_relative": 1.0,
    "extrinsic_translation_m": 0.5,
    "extrinsic_rotation_rad": np.pi,
    "clock_offset_s": 10.0,
}


@dataclass(frozen=True)
class NoiseConfig:
    """Sensor imperfections for robustness tests; all off by default. Seeded."""

    seed: int = 0
    pose_translation_m: float = 0.0
    """Std [m] of per-frame Gaussian noise on the recorded end-effector position."""
    pose_rotation_rad: float = 0.0
    """Std [rad] of per-frame Gaussian noise on the recorded end-effector orientation."""
    depth_relative: float = 0.0
    """Std of depth noise relative to depth² [1/m] (stereo-like: 0.002 gives 2 mm at 1 m)."""
    depth_dropout: float = 0.0
    """Fraction of valid depth pixels set to 0 (invalid)."""
    drop_frames: float = 0.0
    """Probability that a frame is lost (it is left out; the timestamps show the gap)."""
    extrinsic_translation_m: float = 0.0
    """Size [m] of a fixed error of the recorded wrist-camera extrinsic ``T_hand_cam`` (one
    seeded direction for the whole recording: a calibration that is off)."""
    extrinsic_rotation_rad: float = 0.0
    """Angle [rad] of a fixed rotation error of the recorded ``T_hand_cam`` (seeded axis)."""
    clock_offset_s: float = 0.0
    """Offset [s] of the audio clock against the frame clock: the track is shifted so a sound
    is recorded this much later (negative: earlier) than it was heard."""

    def __post_init__(self) -> None:
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise ConfigError(f"noise seed must be an integer >= 0, got {self.seed!r}")
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "seed":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise ConfigError(f"noise {f.name} must be a finite number, got {v!r}")
        for name in _NONNEGATIVE:
            if getattr(self, name) < 0:
                raise ConfigError(f"noise {name} must be >= 0, got {getattr(self, name)}")
        for name in ("depth_dropout", "drop_frames"):
            if not 0 <= getattr(self, name) < 1:
                raise ConfigError(f"noise {name} must be in [0, 1), got {getattr(self, name)}")
        for name, top in _LIMITS.items():
            if abs(getattr(self, name)) > top:
                raise ConfigError(
                    f"noise {name} = {getattr(self, name)} is beyond {top}: not sensor noise"
                )

    @classmethod
    def from_dict(cls, d: object, where: str = "noise") -> NoiseConfig:
        """From a task file's ``[noise]`` table or a CLI's ``key=value`` pairs; unknown keys
        and bad values raise :class:`ConfigError` naming the key and the valid ones."""
        if not isinstance(d, dict):
            raise ConfigError(f"{where} must be a table of noise settings, got {d!r}")
        valid = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(valid))
        if unknown:
            raise ConfigError(f"{where}: unknown settings {unknown}; valid: {valid}")
        try:
            return cls(**d)
        except ConfigError as e:
            raise ConfigError(f"{where}: {e}") from None

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def any(self) -> bool:
        return any(getattr(self, f.name) != 0 for f in fields(self) if f.name != "seed")


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def apply_noise(rec: Recording, noise: NoiseConfig) -> Recording:
    """A copy of ``rec`` with seeded noise; ``T_world_hand_true`` keeps the clean poses.

    Pose noise perturbs each recorded end-effector pose independently (in the hand frame);
    depth noise is Gaussian with std ``depth_relative * z**2`` and is re-quantised to the
    recording's depth resolution; dropped frames are removed and their segments, sound-event
    frame ranges and ``meta["dropped_frames"]`` updated; the extrinsic error replaces the
    recorded ``T_hand_cam`` by ``T_hand_cam @ dT`` (the images stay those of the true camera);
    the clock offset delays the audio track (zero-filled), so the map ties each sound to the
    poses of a later (or earlier) moment.
    """
    rng = np.random.default_rng(noise.seed)
    n = len(rec)
    kw = {f.name: getattr(rec, f.name) for f in fields(Recording)}
    truth = None if rec.ground_truth is None else GroundTruth.of(rec)
    kw["meta"] = {**rec.meta, "noise": noise.to_dict()}
    true = rec.T_world_hand if rec.T_world_hand_true is None else rec.T_world_hand_true
    noisy = np.array(rec.T_world_hand)
    if noise.pose_translation_m > 0 or noise.pose_rotation_rad > 0:
        for i in range(n):
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
            angle = rng.normal(0.0, noise.pose_rotation_rad) if noise.pose_rotation_rad else 0.0
            dT = make_transform(
                _axis_angle(axis, angle), rng.normal(0.0, noise.pose_translation_m, 3)
            )
            noisy[i] = noisy[i] @ dT
    kw["T_world_hand"], kw["T_world_hand_true"] = noisy, true
    if noise.extrinsic_translation_m > 0 or noise.extrinsic_rotation_rad > 0:
        # Its own generator: the extrinsic error does not change with the other settings.
        ext = np.random.default_rng([noise.seed, 1])
        axis, direction = ext.normal(size=3), ext.normal(size=3)
        dT = make_transform(
            _axis_angle(axis / np.linalg.norm(axis), noise.extrinsic_rotation_rad),
            direction / np.linalg.norm(direction) * noise.extrinsic_translation_m,
        )
        kw["T_hand_cam"] = np.asarray(rec.T_hand_cam) @ dT
    if noise.clock_offset_s != 0 and rec.audio is not None:
        shift = round(noise.clock_offset_s * rec.audio_rate)
        audio = np.zeros_like(rec.audio)
        if shift >= 0:
            audio[shift:] = rec.audio[: len(audio) - shift]
        else:
            audio[:shift] = rec.audio[-shift:]
        kw["audio"] = audio

    depth = rec.depth.astype(np.float64)
    valid = depth > 0
    if noise.depth_relative > 0:
        depth += valid * rng.normal(size=depth.shape) * noise.depth_relative * depth**2
    if noise.depth_dropout > 0:
        depth[valid & (rng.random(depth.shape) < noise.depth_dropout)] = 0.0
    res = rec.depth_resolution
    kw["depth"] = (np.round(np.maximum(depth, 0.0) / res) * res).astype(np.float32)

    if noise.drop_frames > 0:
        keep = rng.random(n) >= noise.drop_frames
        keep[0] = True
        index = np.cumsum(keep) - 1  # new index of each kept frame
        for k in (
            "timestamps",
            "rgb",
            "depth",
            "joint_positions",
            "T_world_hand",
            "T_world_hand_true",
            "segmentation",
        ):
            if kw[k] is not None:
                kw[k] = kw[k][keep]
        segments = []
        for s in rec.segments:
            a, b = index[s.start] + (not keep[s.start]), index[s.stop - 1] + 1
            if b > a:
                segments.append(Segment(s.name, s.kind, int(a), int(b)))
        kw["segments"] = tuple(segments)
        kw["meta"]["dropped_frames"] = int((~keep).sum())
        if truth is not None:
            events = []
            for ev in truth.sound_events:
                frames = ev.frames
                if frames:
                    f0, f1 = frames
                    kept = np.nonzero(keep[f0 : f1 + 1])[0] + f0
                    frames = (int(index[kept[0]]), int(index[kept[-1]])) if len(kept) else ()
                events.append(replace(ev, frames=frames))
            truth = replace(truth, sound_events=tuple(events))
    # A new dict: the input recording's ground truth is not modified.
    kw["ground_truth"] = None if truth is None else truth.to_dict()
    return Recording(**kw)

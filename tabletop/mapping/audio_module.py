"""The audio module: sound segments of a recording, each with an embedding and the place the
robot's microphone was while it played.

The noise gate and silence segmentation (:mod:`tabletop.mapping.audio_segments`) split the
track; each segment is encoded and tied to the mean microphone position over the frames heard
during it. A query's text embedding is scored against every segment; heat decays top-down from
each segment's place with its min-max normalised score. The evidence is the best score's margin
over the typical score: the median over the segments with three segments or more; with one
or two segments, whose median says nothing about what is typical, the median over the segments
and :data:`REFERENCE_SOUNDS` (generic sound descriptions, encoded like the query), so a query
for a sound that never played is refused instead of being found by fiat.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.area_module import normalize_scores
from tabletop.mapping.audio_segments import AudioSegment, NoiseGateConfig, segment_audio
from tabletop.mapping.heatmaps import Heatmap, Judge, scored_points_heatmap_xy

__all__ = ["REFERENCE_SOUNDS", "AudioConfig", "AudioModule"]

#: Generic sound descriptions that stand in for the typical score of a map with one or two
#: sound segments.
REFERENCE_SOUNDS = (
    "a sound",
    "noise",
    "people talking",
    "music playing",
    "an animal making a sound",
    "a machine running",
    "footsteps",
    "a door closing",
    "water running",
    "a bell ringing",
    "a car passing by",
    "wind blowing",
)


@dataclass(frozen=True)
class AudioConfig:
    """How the audio module cuts a track and judges a query."""

    gate: NoiseGateConfig = field(default_factory=NoiseGateConfig)
    """The noise gate and silence segmentation."""
    reference_sounds: tuple[str, ...] = REFERENCE_SOUNDS
    """Descriptions that stand in for the typical score of a map with one or two segments."""

    def __post_init__(self) -> None:
        if not isinstance(self.gate, NoiseGateConfig):
            raise ConfigError(f"gate must be a NoiseGateConfig, got {type(self.gate).__name__}")
        if len(self.reference_sounds) < 3:
            raise ConfigError("give at least 3 reference sounds")
        object.__setattr__(self, "reference_sounds", tuple(self.reference_sounds))


class AudioModule:
    """Segments (``segments``), their embeddings (``embeddings``: (dim,) float32 each) and
    places (``positions``: (3,) [m] world frame, the mean microphone position while heard)."""

    def __init__(self, grid: VoxelGrid, config: AudioConfig | None = None) -> None:
        self.grid = grid
        self.config = config or AudioConfig()
        self.segments: list[AudioSegment] = []
        self.embeddings: list[np.ndarray] = []
        self.positions: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.segments)

    def add(
        self,
        audio: np.ndarray,
        sample_rate: int,
        timestamps: np.ndarray,
        T_world_mic: np.ndarray,
        encoder,
    ) -> int:
        """Segment a track (mono float32 at ``sample_rate`` [Hz], sample 0 at t = 0 s) and tie
        each segment to the microphone poses (N, 4, 4) of the frames at ``timestamps`` (N,) [s]
        heard during it (the nearest frame when none was). Returns the number of segments."""
        timestamps = np.asarray(timestamps, np.float64)
        T_world_mic = np.asarray(T_world_mic, np.float64)
        if T_world_mic.shape != (len(timestamps), 4, 4):
            raise ConfigError(
                f"T_world_mic must be ({len(timestamps)}, 4, 4), one pose per timestamp, "
                f"got {T_world_mic.shape}"
            )
        if not len(timestamps):
            raise ConfigError("a track needs the poses of at least one frame")
        mic = T_world_mic[:, :3, 3]
        segs = segment_audio(audio, sample_rate, self.config.gate)
        for seg in segs:
            heard = (timestamps >= seg.start_s) & (timestamps <= seg.end_s)
            if not heard.any():
                mid = np.abs(timestamps - (seg.start_s + seg.end_s) / 2)
                heard = mid == mid.min()
            a, b = int(seg.start_s * sample_rate), int(seg.end_s * sample_rate)
            emb = encoder.encode_audio(
                audio[a:b], sample_rate, {"span_s": (seg.start_s, seg.end_s)}
            )
            self.segments.append(seg)
            self.embeddings.append(np.asarray(emb, np.float32))
            self.positions.append(mic[heard].mean(axis=0))
        return len(segs)

    def heatmap(self, query: str, decay: float, text, judge: Judge) -> Heatmap:
        """Heat around where the sound best matching ``query`` was heard."""
        if not self.embeddings:
            return Heatmap.not_found(
                self.grid, query, "sound", decay, "the map has no audio segments"
            )
        q = text.encode_text([query])[0]
        s = np.stack(self.embeddings) @ q
        pos = np.stack(self.positions)[:, :2]
        values = scored_points_heatmap_xy(self.grid, pos, normalize_scores(s), decay)
        typical = s
        if len(s) <= 2:
            refs = text.encode_text(list(self.config.reference_sounds))
            typical = np.concatenate([s, refs @ q])
        floor = float(np.median(typical))
        margin = float(s.max()) - floor
        conf, found = judge("sound", margin)
        reason = "" if found else f"no sound segment matches {query!r} well (confidence {conf:.2f})"
        return Heatmap(self.grid, values, query, "sound", decay, conf, found, reason, margin)

"""The audio module: sound segments of a recording, each with an embedding and the place the
robot's microphone was while it played.

The noise gate and silence segmentation (:mod:`tabletop.mapping.audio_segments`) split the
track; each segment is encoded and tied to the mean microphone position over the frames heard
during it.

**With a vocabulary** (a learned encoder that records the sound categories it knows, the
embedded default): the query is read against the vocabulary and every segment scored by its
posterior mass on the asked categories (:mod:`tabletop.mapping.sound_vocabulary`). A query that
names no known sound, or that no segment carries, is not found; the evidence is the best
segment's score. Heat decays top-down from every segment within ``keep_ratio`` of the best
(a sound heard twice is hot in both places).

**Without one** (an open-vocabulary encoder such as CLAP): the query's text embedding is scored
against every segment; heat decays from each segment's place with its min-max normalised score.
The evidence is the best score's margin over the typical score: the median over the segments
with three segments or more; with one or two segments, the median over the segments and
:data:`REFERENCE_SOUNDS` (generic sound descriptions, encoded like the query), so a query for a
sound that never played is refused instead of being found by fiat.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tabletop.errors import ConfigError
from tabletop.grid import VoxelGrid
from tabletop.mapping.area_module import normalize_scores
from tabletop.mapping.audio_segments import AudioSegment, NoiseGateConfig, segment_audio
from tabletop.mapping.heatmaps import Heatmap, Judge, scored_points_heatmap_xy
from tabletop.mapping.sound_vocabulary import GENERAL, SoundMatcher, SoundVocabulary

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
    """Descriptions that stand in for the typical score of a map with one or two segments
    (encoders without a vocabulary)."""
    text_min: float = 0.42
    """A query whose best cosine with every known sound's phrasings is below this names no
    sound the encoder knows: not found. (The tune pool's sound phrasings scored 0.50 and up;
    a sound outside the vocabulary that passes is still refused by the segments' posteriors.)"""
    text_margin: float = 0.05
    """Categories within this cosine of the query's best one are asked for too."""
    other_margin: float = 0.12
    """A query nearer by more than this cosine to a phrasing of a sound the encoder's vocabulary
    lacks (``tabletop/data/sound_phrasings.toml`` names 14 sounds outside the bank) than to every
    known sound reads as that sound: not found. Chosen on the tune pools' phrasings: the present
    sounds' gaps reach 0.10 ("finger clicks": mouse click over finger snapping), the absent
    sounds' start at 0.14 ("a submarine": sea waves over a toilet flush); only "a dripping tap"
    (water drops in the phrasings file) is refused among 410 present phrasings, and 7 of 24
    absent sounds are."""
    keep_ratio: float = 0.5
    """Segments scoring at least this share of the best stay hot."""
    tie_break: float = 0.05
    """Hot segments whose posteriors all round to 1 are told apart by their log-odds: each
    is cooled by up to this share, ``tie_break * (1 - exp(log-odds - the best's))``, so the
    heat's peak is the surest segment and the others stay hot (vocabulary path)."""
    join_gap_s: float = 1.0
    """Neighbouring segments closer than this [s] that sound alike are joined into one."""
    join_cosine: float = 0.85
    """How alike (embedding cosine) neighbouring segments must be to be joined."""

    def __post_init__(self) -> None:
        if not isinstance(self.gate, NoiseGateConfig):
            raise ConfigError(f"gate must be a NoiseGateConfig, got {type(self.gate).__name__}")
        if len(self.reference_sounds) < 3:
            raise ConfigError("give at least 3 reference sounds")
        object.__setattr__(self, "reference_sounds", tuple(self.reference_sounds))
        if not 0 <= self.other_margin <= 2:
            raise ConfigError(f"other_margin must be in [0, 2], got {self.other_margin}")
        if not -1 <= self.text_min <= 1 or not 0 <= self.text_margin <= 2:
            raise ConfigError(
                f"need text_min in [-1, 1] and text_margin in [0, 2], got {self.text_min}, "
                f"{self.text_margin}"
            )
        if self.join_gap_s < 0 or not -1 <= self.join_cosine <= 1:
            raise ConfigError(
                f"need join_gap_s >= 0 and join_cosine in [-1, 1], got {self.join_gap_s}, "
                f"{self.join_cosine}"
            )
        if not 0 < self.keep_ratio <= 1:
            raise ConfigError(f"keep_ratio must be in (0, 1], got {self.keep_ratio}")
        if not 0 <= self.tie_break < 1:
            raise ConfigError(f"tie_break must be in [0, 1), got {self.tie_break}")


class AudioModule:
    """Segments (``segments``), their embeddings (``embeddings``: (dim,) float32 each) and
    places (``positions``: (3,) [m] world frame, the mean microphone position while heard)."""

    def __init__(
        self,
        grid: VoxelGrid,
        config: AudioConfig | None = None,
        vocabulary: SoundVocabulary | None = None,
    ) -> None:
        self.grid = grid
        self.config = config or AudioConfig()
        self.vocabulary = vocabulary
        """The sounds the audio encoder knows (None: score queries by raw cosine)."""
        self._matcher: SoundMatcher | None = None
        self.segments: list[AudioSegment] = []
        self.embeddings: list[np.ndarray] = []
        self.positions: list[np.ndarray] = []
        self.class_logits: list[np.ndarray] = []
        """Per segment, the encoder's AudioSet class logits (K,) when it gives them (the YAMNet
        backbone: :mod:`tabletop.mapping.open_sounds`); empty otherwise."""
        self.class_names: tuple[str, ...] = ()
        """The names of those classes, in logit order."""

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

        with_logits = hasattr(encoder, "encode_audio_with_logits") and (
            not self.segments or len(self.class_logits) == len(self.segments)
        )
        logits: dict[tuple[float, float], np.ndarray] = {}

        def encode(seg: AudioSegment) -> np.ndarray:
            a, b = int(seg.start_s * sample_rate), int(seg.end_s * sample_rate)
            if with_logits:
                e, logits[(seg.start_s, seg.end_s)] = encoder.encode_audio_with_logits(
                    audio[a:b], sample_rate
                )
            else:
                span = {"span_s": (seg.start_s, seg.end_s)}
                e = encoder.encode_audio(audio[a:b], sample_rate, span)
            return np.asarray(e, np.float32)

        segs = segment_audio(audio, sample_rate, self.config.gate)
        embs = [encode(seg) for seg in segs]
        segs, embs = self._join(segs, embs, encode)
        if with_logits:
            self.class_names = tuple(encoder.class_names)
            self._matcher = None  # rebuilt with the open vocabulary
            self.class_logits += [logits[(s.start_s, s.end_s)] for s in segs]
        for seg, emb in zip(segs, embs, strict=True):
            heard = (timestamps >= seg.start_s) & (timestamps <= seg.end_s)
            if not heard.any():
                mid = np.abs(timestamps - (seg.start_s + seg.end_s) / 2)
                heard = mid == mid.min()
            self.segments.append(seg)
            self.embeddings.append(emb)
            self.positions.append(mic[heard].mean(axis=0))
        return len(segs)

    def _join(self, segs: list[AudioSegment], embs: list[np.ndarray], encode):
        """Join neighbouring segments that sound alike (a sound with pauses: a ticking clock, a
        dog barking twice): closer than ``join_gap_s`` and embeddings at cosine
        ``join_cosine`` or more; the joined span is encoded again. Different sounds a moment
        apart keep a segment each."""
        cfg = self.config
        i = 0
        while i + 1 < len(segs):
            a, b = segs[i], segs[i + 1]
            near = b.start_s - a.end_s < cfg.join_gap_s
            if near and float(embs[i] @ embs[i + 1]) >= cfg.join_cosine:
                joined = AudioSegment(a.start_s, b.end_s)
                segs[i : i + 2] = [joined]
                embs[i : i + 2] = [encode(joined)]
            else:
                i += 1
        return segs, embs

    def heatmap(self, query: str, decay: float, text, judge: Judge, match=None) -> Heatmap:
        """Heat around where the sound best matching ``query`` was heard; ``match``: the
        query's :meth:`match` where the caller has it already."""
        if not self.embeddings:
            return Heatmap.not_found(
                self.grid, query, "sound", decay, "the map has no audio segments"
            )
        if self.vocabulary is not None:
            return self._vocabulary_heatmap(query, decay, text, judge, match)
        q = text.encode_text([query])[0]
        s = np.stack(self.embeddings) @ q
        pos = np.stack(self.positions)[:, :2]
        values = scored_points_heatmap_xy(self.grid, pos, normalize_scores(s), decay)
        # What a query typically scores: the segments' scores, with the reference sounds'
        # when few distinct sounds were heard (two of three segments the same sound, as in a
        # room scan with a sound heard at two tables, would make the median the match itself).
        typical = s
        if len(np.unique(np.round(s, 4))) <= 3:
            refs = text.encode_text(list(self.config.reference_sounds))
            typical = np.concatenate([s, refs @ q])
        floor = float(np.median(typical))
        margin = float(s.max()) - floor
        conf, found = judge("sound", margin)
        reason = "" if found else f"no sound segment matches {query!r} well (confidence {conf:.2f})"
        return Heatmap(self.grid, values, query, "sound", decay, conf, found, reason, margin)

    def matcher(self, text) -> SoundMatcher:
        """The vocabulary's matcher with ``text`` (built once), with the class names of
        :attr:`class_names` as an open vocabulary when the segments have class logits."""
        if self._matcher is None or self._matcher.text is not text:
            from tabletop.mapping.open_sounds import OpenSoundVocabulary

            cfg = self.config
            names = self.class_names
            self._matcher = SoundMatcher(
                self.vocabulary,
                text,
                cfg.text_min,
                cfg.text_margin,
                other_margin=cfg.other_margin,
                open_vocabulary=OpenSoundVocabulary(names, text) if names else None,
            )
        return self._matcher

    def match(self, query: str, text):
        """``query`` read against the vocabulary (and the open vocabulary, when the segments
        have class logits) and scored on every segment
        (:class:`~tabletop.mapping.sound_vocabulary.SoundQuery`)."""
        n = len(self.embeddings)
        logits = np.stack(self.class_logits) if len(self.class_logits) == n else None
        return self.matcher(text).match(query, np.stack(self.embeddings), logits)

    def _vocabulary_heatmap(
        self, query: str, decay: float, text, judge: Judge, match=None
    ) -> Heatmap:
        m = match if match is not None else self.match(query, text)
        if not m.known:
            nearest = self.vocabulary.caption(m.nearest)
            if m.other == GENERAL:
                why = (
                    f"{query!r} names no particular sound: it reads as sound in general "
                    f"(similarity {m.other_score:.2f}) more than as any sound the audio encoder "
                    f"knows (nearest: {nearest!r}, {m.text_score:.2f}); say what made it or how "
                    "it sounds"
                )
            elif m.other:
                why = (
                    f"{query!r} reads as {m.other.replace('_', ' ')!r} (similarity "
                    f"{m.other_score:.2f}), a sound the audio encoder was not trained to hear "
                    f"(nearest it knows: {nearest!r}, {m.text_score:.2f})"
                )
            else:
                why = (
                    f"{query!r} names no sound the audio encoder knows (nearest: {nearest!r}, "
                    f"similarity {m.text_score:.2f} < {self.config.text_min})"
                )
            return Heatmap.not_found(self.grid, query, "sound", decay, why)
        s = m.scores
        best = float(s.max())
        lo = np.nan_to_num(m.log_odds, nan=-np.inf, posinf=np.finfo(float).max)
        tie = 1.0 - self.config.tie_break * (1.0 - np.exp(np.minimum(lo - lo.max(), 0.0)))
        keep = np.where(s >= self.config.keep_ratio * best, s / max(best, 1e-12) * tie, 0.0)
        pos = np.stack(self.positions)[:, :2]
        values = scored_points_heatmap_xy(self.grid, pos, keep, decay)
        conf, found = judge("sound", best)
        reason = (
            ""
            if found
            else f"no sound heard here is {query!r} (best segment {best:.2f} on "
            f"{', '.join(m.categories)}; confidence {conf:.2f})"
        )
        return Heatmap(self.grid, values, query, "sound", decay, conf, found, reason, best)

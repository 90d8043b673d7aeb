"""The simulator oracle: encoders that read the simulator's answers instead of the pixels.

An UPPER BOUND, like the paper's "GT map" row, never the default: the dense encoder gives each
pixel the text embedding of its object's label (from the segmentation), the global encoder the
pixel-weighted mean of those, the audio encoder the embedding of the inserted clip's caption (from
the recording's sound-event ground truth). Every report names the encoders that produced it.
"""

from __future__ import annotations

import numpy as np

from tabletop.errors import ConfigError
from tabletop.mapping.encoders.base import TextEncoder, l2_normalize

__all__ = [
    "ORACLE_BACKGROUND_LABELS",
    "OracleAudioEncoder",
    "OracleDenseEncoder",
    "OracleGlobalImageEncoder",
    "oracle_labels",
]

#: What the oracle calls the non-object instances (0 = nothing seen: no feature).
ORACLE_BACKGROUND_LABELS = {1: "floor", 2: "table", 3: "robot arm"}


#: What the oracle calls a room's own instances (by their ground-truth names).
ORACLE_ROOM_LABELS = {"floor": "floor", "robot": "robot"}


def oracle_labels(ground_truth: dict) -> dict[int, str]:
    """Instance id -> label ("red mug", "table", "wall", ...) from a recording's ground truth:
    a room's furniture and walls by their category, objects by their label."""
    if ground_truth.get("furniture"):  # a room numbers its own instances
        names = {int(k): v for k, v in ground_truth.get("instances", {}).items()}
        labels = {i: ORACLE_ROOM_LABELS[n] for i, n in names.items() if n in ORACLE_ROOM_LABELS}
        for f in ground_truth["furniture"]:
            labels[int(f["instance_id"])] = f["category"]
    else:
        labels = dict(ORACLE_BACKGROUND_LABELS)
    for o in ground_truth.get("objects", []):
        labels[int(o["instance_id"])] = o["label"]
    return labels


def _need_context(context: dict | None, key: str, who: str):
    if not context or key not in context or context[key] is None:
        raise ConfigError(
            f"{who} is the simulator oracle: it needs context[{key!r}] (recordings from "
            "tabletop.sim carry it); use the 'default' encoders for real data"
        )
    return context[key]


class OracleDenseEncoder:
    """Text embedding of the segmented instance's label at every ``stride``-th pixel (the
    pixel at the top-left of each cell); 0 where nothing is seen."""

    def __init__(self, text: TextEncoder, labels: dict[int, str], stride: int = 2) -> None:
        self.stride = int(stride)
        self.text = text
        self.space, self.dim = text.space, text.dim
        self.labels = dict(labels)
        top = max(self.labels, default=0)
        self._table = np.zeros((top + 1, self.dim), np.float32)
        ids = sorted(self.labels)
        self._table[ids] = text.encode_text([self.labels[i] for i in ids])

    def encode_dense(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        seg = np.asarray(_need_context(context, "segmentation", type(self).__name__))
        if seg.shape != np.asarray(rgb).shape[:2]:
            raise ConfigError(f"segmentation {seg.shape} does not match the image {rgb.shape[:2]}")
        seg = seg[:: self.stride, :: self.stride]
        seg = np.where(seg < len(self._table), seg, 0)
        return self._table[seg]

    def encode_dense_at(
        self, rgb: np.ndarray, context: dict | None, px: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """What :meth:`encode_dense` gives at the cells of the pixels ``px`` (n, 2: row,
        column), as a table (L, D) of the labels' embeddings and each pixel's row (n,) in it:
        without the rest of the image (a map fuses a few thousand pixels of a frame; the whole
        image's features are 30 MB a frame) and without a row per pixel."""
        seg = np.asarray(_need_context(context, "segmentation", type(self).__name__))
        if seg.shape != np.asarray(rgb).shape[:2]:
            raise ConfigError(f"segmentation {seg.shape} does not match the image {rgb.shape[:2]}")
        s = self.stride
        ids = seg[(px[:, 0] // s) * s, (px[:, 1] // s) * s]
        return self._table, np.where(ids < len(self._table), ids, 0)


class OracleGlobalImageEncoder:
    """Pixel-weighted mean of the oracle's label embeddings over the image."""

    def __init__(self, text: TextEncoder, labels: dict[int, str]) -> None:
        self._dense = OracleDenseEncoder(text, labels)
        self.space, self.dim = text.space, text.dim

    def encode_image(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        seg = np.asarray(_need_context(context, "segmentation", type(self).__name__))
        counts = np.bincount(seg.ravel(), minlength=len(self._dense._table))
        counts = counts[: len(self._dense._table)].astype(np.float32)
        return l2_normalize(counts @ self._dense._table)


def _default_sound_texts() -> dict[str, tuple[str, ...]] | None:
    """The embedded default audio encoder's vocabulary texts (its head file's), or None."""
    try:
        from tabletop.mapping.encoders.yamnet_audio import DEFAULT_HEAD_WEIGHTS, load_head
        from tabletop.mapping.sound_vocabulary import SoundVocabulary

        meta = load_head(DEFAULT_HEAD_WEIGHTS).meta
        vocabulary = SoundVocabulary.from_meta(meta.get("vocabulary"))
    except Exception:  # no weights or foreign weights: the phrasings file instead
        return None
    return None if vocabulary is None else dict(vocabulary.texts)


class OracleAudioEncoder:
    """The label of the inserted clip that overlaps the segment most, as the prototype of its
    category: an audio encoder that is never wrong, behind the same words -> categories step
    as the embedded default (:mod:`tabletop.mapping.sound_vocabulary`; its vocabulary is the
    default audio checkpoint's, or, where that cannot be read, every sound of the phrasings
    file), so that the oracle row differs from the default's by what the audio network hears,
    not by how words are read. A clip of a category outside the vocabulary, and events without
    a category (older recordings), fall back to the caption's embedding."""

    BACKGROUND = "background noise"
    #: Inverse temperature of the vocabulary: a segment's posterior is all on its own category.
    LOGIT_SCALE = 100.0

    def __init__(self, text: TextEncoder, sound_events: list[dict]) -> None:
        from tabletop.mapping.sound_vocabulary import (
            SoundVocabulary,
            load_phrasings,
            phrases_for,
        )

        self.text = text
        self.space, self.dim = text.space, text.dim
        self.events = [dict(e) for e in sound_events]
        texts = _default_sound_texts()
        if texts is None:
            texts = {c: tuple(v) for c, v in load_phrasings().items()}
            for e in self.events:
                c = e.get("category")
                if isinstance(c, str) and c:
                    texts[c] = tuple(phrases_for(c, e["caption"]))
        self.vocabulary = SoundVocabulary(texts, logit_scale=self.LOGIT_SCALE)
        self._prototypes: dict[str, np.ndarray] = {}

    def _prototype(self, category: str) -> np.ndarray:
        """The normalised mean embedding of the category's texts (what the matcher uses)."""
        if category not in self._prototypes:
            emb = np.asarray(self.text.encode_text(list(self.vocabulary.texts[category])))
            self._prototypes[category] = l2_normalize(emb.mean(axis=0))
        return self._prototypes[category]

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        t0, t1 = _need_context(context, "span_s", type(self).__name__)
        best, overlap = None, 0.0
        for e in self.events:
            o = min(t1, e["offset_s"]) - max(t0, e["onset_s"])
            if o > overlap:
                best, overlap = e, o
        if best is not None and best.get("category") in self.vocabulary.texts:
            return self._prototype(best["category"])
        caption = best["caption"] if best is not None else self.BACKGROUND
        return self.text.encode_text([caption])[0]

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


class OracleAudioEncoder:
    """The caption embedding of the inserted clip that overlaps the segment most."""

    BACKGROUND = "background noise"

    def __init__(self, text: TextEncoder, sound_events: list[dict]) -> None:
        self.text = text
        self.space, self.dim = text.space, text.dim
        self.events = [dict(e) for e in sound_events]

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        t0, t1 = _need_context(context, "span_s", type(self).__name__)
        best, overlap = None, 0.0
        for e in self.events:
            o = min(t1, e["offset_s"]) - max(t0, e["onset_s"])
            if o > overlap:
                best, overlap = e, o
        caption = best["caption"] if best is not None else self.BACKGROUND
        return self.text.encode_text([caption])[0]

"""An audio encoder of frozen aiSFX and a trained head into MiniLM's text space (an ablation).

The same head as the embedded default's (:class:`~tabletop.mapping.encoders.yamnet_audio.
HeadWeights`, trained by :func:`~tabletop.train.audio_head.train_audio_head` with
``HeadTrainConfig(backbone="aisfx")``), on the mean and the max of aiSFX's 512-d window
embeddings (:mod:`tabletop.mapping.encoders.aisfx_backbone`) instead of YAMNet's. It costs
about 50 ms per second of audio on one thread, ten times the default's aim, so no encoder set
uses it: ``tools/audio_bank_ablation.py --aisfx-head`` measures it. aiSFX has no class logits,
so this encoder has no open vocabulary (no ``encode_audio_with_logits``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tabletop.errors import AssetError
from tabletop.mapping.encoders.aisfx_backbone import AISFX_DIM, AisfxBackbone, AisfxOutput
from tabletop.mapping.encoders.minilm import MINILM_SPACE
from tabletop.mapping.encoders.yamnet_audio import _cached_head, pool_patches
from tabletop.mapping.sound_vocabulary import SoundVocabulary

__all__ = ["AISFX_POOLED_DIM", "AisfxAudioEncoder"]

#: Size of the pooled segment feature: the mean and the max of the window embeddings.
AISFX_POOLED_DIM = 2 * AISFX_DIM


class AisfxAudioEncoder:
    """An :class:`~tabletop.mapping.encoders.base.AudioEncoder` into MiniLM's 384-d space:
    frozen aiSFX, pooled over the segment, and a trained head.

    ``weights``: a head file trained on aiSFX (there is no default: none ships);
    ``backbone``: an :class:`~tabletop.mapping.encoders.aisfx_backbone.AisfxBackbone` to share
    (default: one on ``num_threads`` torch threads). ``vocabulary`` is the sound categories the
    head was trained against. Learned encoders ignore ``context``.
    """

    space = MINILM_SPACE
    dim = 384
    backbone_name = "aisfx"

    def __init__(
        self,
        weights: str | Path,
        *,
        backbone: AisfxBackbone | None = None,
        num_threads: int = 1,
    ) -> None:
        self.weights = Path(weights)
        path = self.weights.resolve()
        mtime = path.stat().st_mtime_ns if path.is_file() else -1
        self.head = _cached_head(str(path), mtime)
        if self.head.input_dim != AISFX_POOLED_DIM:
            raise AssetError(
                f"{self.weights} reads {self.head.input_dim} pooled features, not aiSFX's "
                f"{AISFX_POOLED_DIM}: a head of another backbone "
                f"({self.head.meta.get('backbone')!r})"
            )
        self.meta = self.head.meta
        self.backbone = backbone if backbone is not None else AisfxBackbone(num_threads=num_threads)
        self.vocabulary = SoundVocabulary.from_meta(self.meta.get("vocabulary"))
        """The sound categories the head was trained on."""

    def __repr__(self) -> str:
        return f"AisfxAudioEncoder(weights={str(self.weights)!r})"

    def backbone_output(self, audio: np.ndarray, sample_rate: int) -> AisfxOutput:
        """aiSFX's per-window embeddings of one segment."""
        return self.backbone(audio, sample_rate)

    def encode_pooled(self, pooled: np.ndarray) -> np.ndarray:
        """(N, 384) embeddings of (N, 1024) pooled aiSFX features."""
        return self.head(np.asarray(pooled, np.float32).reshape(-1, AISFX_POOLED_DIM))

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        """(384,) float32 unit embedding of one mono segment (S,) float at ``sample_rate``
        [Hz] (any rate, any length; under one 2.3 s window it is padded with silence)."""
        out = self.backbone_output(audio, sample_rate)
        return self.encode_pooled(pool_patches(out.embeddings, AISFX_DIM))[0]

    def encode_audio_batch(self, segments: list[np.ndarray], sample_rate: int) -> np.ndarray:
        """(N, 384): N calls of :meth:`encode_audio`."""
        if not len(segments):
            return np.zeros((0, self.dim), np.float32)
        return np.stack([self.encode_audio(s, sample_rate) for s in segments])

"""The embedded default audio encoder: frozen YAMNet and a light head into MiniLM's text space.

A segment is cut into 0.96 s patches (:mod:`tabletop.mapping.encoders.yamnet`); the patches'
1024-d YAMNet embeddings are pooled over the segment (mean and max, 2048 values), standardised,
and mapped by a two-layer head (:class:`HeadWeights`) to a 384-d unit vector in the space of
all-MiniLM-L6-v2, where the sound vocabulary's prototypes live
(:mod:`tabletop.mapping.sound_vocabulary`). The head is trained by ``tabletop train audio``
(:mod:`tabletop.train.audio_head`) on cached embeddings of augmented training clips and
stored as ``tabletop/data/weights/audio_yamnet_head.npz`` (fp16, about 2.5 MB; no pickle).

Beside the embedding, :meth:`YamnetAudioEncoder.class_scores` gives YAMNet's own AudioSet
class scores of a segment (521 values): the audio side of sounds the bank never had.
"""

from __future__ import annotations

import functools
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.atomic import atomic_path
from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import l2_normalize
from tabletop.mapping.encoders.minilm import MINILM_SPACE
from tabletop.mapping.encoders.yamnet import YAMNET_DIM, YamnetBackbone, YamnetOutput
from tabletop.mapping.sound_vocabulary import SoundVocabulary
from tabletop.paths import DATA_DIR

__all__ = [
    "DEFAULT_HEAD_WEIGHTS",
    "HEAD_FORMAT",
    "HeadWeights",
    "YamnetAudioEncoder",
    "load_head",
    "pool_patches",
    "save_head",
]

#: The committed head of the embedded default.
DEFAULT_HEAD_WEIGHTS = DATA_DIR / "weights" / "audio_yamnet_head.npz"
#: ``format`` of a head file written by :func:`save_head`.
HEAD_FORMAT = "tabletop-yamnet-head"
HEAD_VERSION = 1
#: Size of the pooled segment feature: the mean and the max of the patch embeddings.
POOLED_DIM = 2 * YAMNET_DIM


def pool_patches(embeddings: np.ndarray, dim: int = YAMNET_DIM) -> np.ndarray:
    """(2048,) float32: the mean and the max over patches of (P, 1024) patch embeddings
    (``dim``: the size of another backbone's patch embeddings; the result is twice that)."""
    e = np.asarray(embeddings, np.float32)
    if e.ndim != 2 or e.shape[1] != dim or not len(e):
        raise ConfigError(f"patch embeddings must be (P >= 1, {dim}), got {e.shape}")
    return np.concatenate([e.mean(axis=0), e.max(axis=0)])


@dataclass(frozen=True)
class HeadWeights:
    """The head: ``normalize(relu(((x - mean) / std) @ w1 + b1) @ w2 + b2)``.

    ``mean``, ``std`` (2048,); ``w1`` (2048, H); ``b1`` (H,); ``w2`` (H, 384); ``b2`` (384,);
    all float32 (2048: YAMNet's pooled features; a head on another backbone, such as aiSFX's
    1024, has that input size instead). ``meta`` is JSON-like (the vocabulary, the training
    config and figures).
    """

    mean: np.ndarray
    std: np.ndarray
    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: np.ndarray
    meta: dict

    def __post_init__(self) -> None:
        arrays = {k: np.asarray(getattr(self, k), np.float32) for k in _ARRAYS}
        h = arrays["w1"].shape[1] if arrays["w1"].ndim == 2 else -1
        d = arrays["mean"].shape[0] if arrays["mean"].ndim == 1 else -1
        want = {
            "mean": (d,),
            "std": (d,),
            "w1": (d, h),
            "b1": (h,),
            "w2": (h, 384),
            "b2": (384,),
        }
        for k, a in arrays.items():
            if a.shape != want[k] or h < 1 or d < 1:
                raise AssetError(f"audio head: {k} has shape {a.shape}, expected {want[k]}")
            if not np.all(np.isfinite(a)):
                raise AssetError(f"audio head: {k} holds NaN or inf")
            a.setflags(write=False)
            object.__setattr__(self, k, a)
        if np.any(arrays["std"] <= 0):
            raise AssetError("audio head: std must be > 0")

    @property
    def input_dim(self) -> int:
        """Size of the pooled features the head reads (2048 for YAMNet's)."""
        return int(self.mean.shape[0])

    def __call__(self, pooled: np.ndarray) -> np.ndarray:
        """(N, 384) unit vectors of (N, 2048) pooled features."""
        x = (np.asarray(pooled, np.float32) - self.mean) / self.std
        h = np.maximum(x @ self.w1 + self.b1, 0.0)
        return l2_normalize(h @ self.w2 + self.b2, axis=1)


_ARRAYS = ("mean", "std", "w1", "b1", "w2", "b2")


def save_head(path: str | Path, head: HeadWeights) -> Path:
    """Write ``head`` (fp16 arrays, JSON meta) to ``path`` as an ``.npz`` without pickles."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"format": HEAD_FORMAT, "version": HEAD_VERSION, "space": MINILM_SPACE, **head.meta}
    blob = {k: np.asarray(getattr(head, k), np.float16) for k in _ARRAYS}
    blob["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **blob)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(buf.getvalue())
    return path


def load_head(path: str | Path) -> HeadWeights:
    """The head stored at ``path`` (:class:`~tabletop.errors.AssetError` when it is missing,
    unreadable, of another format or version, or its arrays do not fit)."""
    path = Path(path)
    if not path.is_file():
        raise AssetError(
            f"audio head weights not found at {path}; they ship with the repository "
            f"({DEFAULT_HEAD_WEIGHTS.name}) or are rebuilt by `tabletop train audio`"
        )
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k].astype(np.float32) for k in _ARRAYS}
            meta = json.loads(z["meta"].tobytes().decode())
    except (OSError, ValueError, KeyError, UnicodeDecodeError) as e:
        raise AssetError(f"cannot read audio head {path}: {e}") from None
    if not isinstance(meta, dict) or meta.get("format") != HEAD_FORMAT:
        raise AssetError(f"{path} is not a tabletop YAMNet head (format {HEAD_FORMAT!r})")
    if meta.get("version") != HEAD_VERSION:
        raise AssetError(
            f"{path}: head version {meta.get('version')!r}, this code reads {HEAD_VERSION}; "
            "retrain with `tabletop train audio`"
        )
    return HeadWeights(**arrays, meta=meta)


@functools.lru_cache(maxsize=8)
def _cached_head(path: str, mtime_ns: int) -> HeadWeights:
    return load_head(path)


class YamnetAudioEncoder:
    """An :class:`~tabletop.mapping.encoders.base.AudioEncoder` into MiniLM's 384-d space
    (``space = "minilm-l6-v2"``): frozen YAMNet, pooled over the segment, and a trained head.

    ``weights``: a head file (default: the committed ``audio_yamnet_head.npz``); ``backbone``:
    a :class:`~tabletop.mapping.encoders.yamnet.YamnetBackbone` to share (default: one on
    ``num_threads`` onnxruntime threads). ``vocabulary`` is the sound categories the head was
    trained against. Learned encoders ignore ``context``.
    """

    space = MINILM_SPACE
    dim = 384
    backbone_name = "yamnet"

    def __init__(
        self,
        weights: str | Path | None = None,
        *,
        backbone: YamnetBackbone | None = None,
        num_threads: int = 1,
    ) -> None:
        self.weights = Path(weights) if weights is not None else DEFAULT_HEAD_WEIGHTS
        path = self.weights.resolve()
        mtime = path.stat().st_mtime_ns if path.is_file() else -1
        self.head = _cached_head(str(path), mtime)
        if self.head.input_dim != POOLED_DIM:
            raise AssetError(
                f"{self.weights} reads {self.head.input_dim} pooled features, not YAMNet's "
                f"{POOLED_DIM}: a head of another backbone ({self.head.meta.get('backbone')!r})"
            )
        self.meta = self.head.meta
        tail = self.meta.get("tail")  # a head trained on a tuned tail reads its embeddings
        self.backbone = (
            backbone
            if backbone is not None
            else YamnetBackbone(
                num_threads=num_threads,
                tail=None if tail is None else self.weights.resolve().parent / str(tail),
            )
        )
        self.vocabulary = SoundVocabulary.from_meta(self.meta.get("vocabulary"))
        """The sound categories the head was trained on."""

    def __repr__(self) -> str:
        return f"YamnetAudioEncoder(weights={str(self.weights)!r})"

    def backbone_output(self, audio: np.ndarray, sample_rate: int) -> YamnetOutput:
        """YAMNet's per-patch embeddings and logits of one segment."""
        return self.backbone(audio, sample_rate)

    def encode_pooled(self, pooled: np.ndarray) -> np.ndarray:
        """(N, 384) embeddings of (N, 2048) pooled YAMNet features (:func:`pool_patches`)."""
        return self.head(np.asarray(pooled, np.float32).reshape(-1, POOLED_DIM))

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        """(384,) float32 unit embedding of one mono segment (S,) float in [-1, 1] at
        ``sample_rate`` [Hz] (any rate, any length; under 0.975 s it is tiled)."""
        out = self.backbone_output(audio, sample_rate)
        return self.encode_pooled(pool_patches(out.embeddings))[0]

    def encode_audio_batch(self, segments: list[np.ndarray], sample_rate: int) -> np.ndarray:
        """(N, 384): N calls of :meth:`encode_audio`."""
        if not len(segments):
            return np.zeros((0, self.dim), np.float32)
        return np.stack([self.encode_audio(s, sample_rate) for s in segments])

    @property
    def class_names(self) -> tuple[str, ...]:
        """The 521 AudioSet class names of :meth:`encode_audio_with_logits`' logits."""
        from tabletop.mapping.encoders.yamnet import yamnet_class_names

        return yamnet_class_names()

    def encode_audio_with_logits(
        self, audio: np.ndarray, sample_rate: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """One backbone pass for both: the (384,) embedding of :meth:`encode_audio` and the
        (521,) float32 AudioSet logits of the segment (each class's max over its patches)."""
        out = self.backbone_output(audio, sample_rate)
        emb = self.encode_pooled(pool_patches(out.embeddings))[0]
        return emb, out.logits.max(axis=0)

    def class_scores(self, audio: np.ndarray, sample_rate: int) -> np.ndarray:
        """(521,) float32 in [0, 1]: YAMNet's AudioSet class scores of one segment (the
        sigmoid of each class's logit, the max over the segment's patches)."""
        logits = self.backbone_output(audio, sample_rate).logits.max(axis=0)
        return (1.0 / (1.0 + np.exp(-logits.astype(np.float64)))).astype(np.float32)

"""Encoder protocols: text, dense (pixel-aligned) image, global image and audio encoders.

Every encoder declares the embedding ``space`` it maps into (for example
``"minilm-l6-v2"``) and its dimension. Embeddings are float32 and L2-normalised, so cosine
similarity is a dot product. Two encoders can be compared only when they share a space:
:func:`check_same_space` refuses mismatched pairs with a clear error.
"""

from __future__ import annotations

import contextlib
import math
from typing import Protocol, runtime_checkable

import numpy as np

from tabletop.errors import ConfigError

__all__ = [
    "AudioEncoder",
    "DenseImageEncoder",
    "EncoderMismatchError",
    "GlobalImageEncoder",
    "TextEncoder",
    "check_same_space",
    "l2_normalize",
    "torch_threads",
]


class EncoderMismatchError(ConfigError):
    """Two encoders that must share an embedding space do not."""


@contextlib.contextmanager
def torch_threads(n: int | None):
    """Run a forward pass with ``n`` torch intra-op threads (None: leave torch's setting),
    restoring the previous count after. The embedded networks are small: one thread is as fast
    as two on an idle machine and does not collapse (measured 60 ms vs 1 s per image) when
    other processes keep the cores busy."""
    import torch

    before = torch.get_num_threads()
    if n is not None:
        torch.set_num_threads(int(n))
    try:
        with torch.inference_mode():
            yield
    finally:
        torch.set_num_threads(before)


def mono_at(audio: np.ndarray, sample_rate: int, rate: int) -> np.ndarray:
    """One mono segment (S,) validated and resampled to ``rate`` [Hz] (polyphase FIR): what
    every audio encoder's front end starts from. :class:`ConfigError` for a bad rate, audio
    that is not mono, empty audio, or NaN / inf."""
    if isinstance(sample_rate, bool) or int(sample_rate) != sample_rate or sample_rate <= 0:
        raise ConfigError(f"sample_rate must be a positive integer [Hz], got {sample_rate!r}")
    x = np.asarray(audio, dtype=np.float32)
    if x.ndim != 1:
        raise ConfigError(f"audio must be mono (S,), got shape {x.shape}")
    if len(x) == 0:
        raise ConfigError("audio is empty")
    if not np.all(np.isfinite(x)):
        raise ConfigError("audio contains NaN or inf")
    if sample_rate != rate:
        from scipy.signal import resample_poly

        g = math.gcd(int(sample_rate), rate)
        x = resample_poly(x, rate // g, int(sample_rate) // g).astype(np.float32)
    return x


#: ImageNet statistics: the dense image encoders' input normalisation.
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def preprocess(rgb: np.ndarray, mean: tuple = IMAGENET_MEAN, std: tuple = IMAGENET_STD):
    """(H, W, 3) uint8 RGB (or (B, H, W, 3)) -> (B, 3, H, W) float32 normalised tensor
    (per-channel ``(x / 255 - mean) / std``; ImageNet statistics by default)."""
    import torch

    x = torch.from_numpy(np.require(rgb, requirements=["C", "W"])).float().div_(255.0)
    if x.ndim == 3:
        x = x[None]
    x = x.permute(0, 3, 1, 2)
    m = torch.tensor(mean).view(1, 3, 1, 1)
    s = torch.tensor(std).view(1, 3, 1, 1)
    return (x - m) / s


def l2_normalize(x: np.ndarray, axis: int = -1, eps: float = 1e-12) -> np.ndarray:
    """``x`` scaled to unit L2 norm along ``axis`` (zero vectors stay zero), as float32."""
    x = np.asarray(x, dtype=np.float32)
    n = np.linalg.norm(x, axis=axis, keepdims=True)
    return x / np.maximum(n, eps)


def check_same_space(a: object, b: object) -> None:
    """Raise :class:`EncoderMismatchError` unless ``a`` and ``b`` embed into one space."""
    sa, sb = getattr(a, "space", None), getattr(b, "space", None)
    da, db = getattr(a, "dim", None), getattr(b, "dim", None)
    if sa != sb or da != db:
        raise EncoderMismatchError(
            f"{type(a).__name__} embeds into {sa!r} ({da}-d) but {type(b).__name__} into "
            f"{sb!r} ({db}-d); pick encoders of one space (see tabletop.mapping.encoders)"
        )


@runtime_checkable
class TextEncoder(Protocol):
    """Text to embeddings."""

    space: str
    dim: int

    def encode_text(self, texts: list[str]) -> np.ndarray:
        """(N, dim) float32, L2-normalised."""
        ...


@runtime_checkable
class DenseImageEncoder(Protocol):
    """An image to pixel-aligned embeddings (LSeg / OpenSeg / MaskCLIP style).

    ``encode_dense`` returns (h, w, dim) float32 L2-normalised features on a grid of
    ``h x w`` cells covering the image (``h = H // stride``, ``w = W // stride``); cell (i, j)
    describes pixels ``[i*stride, (i+1)*stride) x [j*stride, (j+1)*stride)``. ``context`` carries
    what some backends need beside the pixels — the simulator oracle reads
    ``context["segmentation"]`` (H, W) uint16 — and is ignored by the others.
    """

    space: str
    dim: int
    stride: int

    def encode_dense(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray: ...


@runtime_checkable
class GlobalImageEncoder(Protocol):
    """An image to one embedding (the area module, image goals, retrieval)."""

    space: str
    dim: int

    def encode_image(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(dim,) float32, L2-normalised, for an (H, W, 3) uint8 RGB image."""
        ...


@runtime_checkable
class AudioEncoder(Protocol):
    """A mono audio segment to one embedding.

    ``context`` may carry ``{"span_s": (t0, t1)}``, the segment's place on the recording's
    clock; the simulator oracle uses it to look up the inserted clip, learned encoders ignore it.
    """

    space: str
    dim: int

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        """(dim,) float32, L2-normalised."""
        ...

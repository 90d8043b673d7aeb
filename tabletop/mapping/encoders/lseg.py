"""The embedded default image encoder: a small LSeg-style network trained into MiniLM's space.

:class:`LSegEncoder` maps an RGB image to pixel-aligned 384-d embeddings (output stride 4)
that live in all-MiniLM-L6-v2's text space, so a pixel is compared to a query by a dot product
with the query's MiniLM embedding, exactly as LSeg compares pixels to CLIP text embeddings.
It also gives one global embedding per image (see :meth:`LSegEncoder.encode_image`).

The network (:class:`LSegNet`, about 0.3 M parameters, stored in fp16) is trained by
:func:`tabletop.train.vision.train_vision` on images rendered by :mod:`tabletop.sim`; its
weights ship in ``tabletop/data/weights/vision_dense.pt``. It knows the simulator's object
kinds, colours, the table and the robot — nothing else: it is a stand-in for LSeg/OpenSeg on a
machine that cannot download them, not a general-purpose segmenter.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import torch_threads
from tabletop.mapping.encoders.minilm import MINILM_SPACE
from tabletop.paths import DATA_DIR

__all__ = ["VISION_WEIGHTS_PATH", "LSegEncoder", "LSegNet", "build_lseg_net"]

log = logging.getLogger(__name__)

VISION_WEIGHTS_PATH = DATA_DIR / "weights" / "vision_dense.pt"
"""Where the committed weights of the embedded default image encoder live."""

_MEAN = (0.485, 0.456, 0.406)
_STD = (0.229, 0.224, 0.225)


def build_lseg_net(width: int = 32, dim: int = 384):
    """A fresh (randomly initialised) :class:`LSegNet`; ``width`` scales every layer."""
    return LSegNet(width=width, dim=dim)


def _torch():
    import torch

    return torch


def _make_net_class():
    torch = _torch()
    nn = torch.nn
    F = torch.nn.functional

    def cbr(i, o, s=1, d=1):
        return nn.Sequential(
            nn.Conv2d(i, o, 3, s, padding=d, dilation=d, bias=False),
            nn.BatchNorm2d(o),
            nn.ReLU(inplace=True),
        )

    def sep(i, o):
        return nn.Sequential(
            nn.Conv2d(i, i, 3, 1, 1, groups=i, bias=False),
            nn.BatchNorm2d(i),
            nn.Conv2d(i, o, 1, bias=False),
            nn.BatchNorm2d(o),
            nn.ReLU(inplace=True),
        )

    class _LSegNet(nn.Module):
        """A small encoder-decoder: stride-16 context (dilated convs + image pooling) fused
        back to stride 4, then a linear projection to ``dim`` and L2 normalisation."""

        def __init__(self, width: int = 32, dim: int = 384) -> None:
            super().__init__()
            w = width
            self.width, self.dim, self.stride = w, dim, 4
            self.s4 = nn.Sequential(cbr(3, 24, 2), cbr(24, w, 2), cbr(w, w))
            self.s8 = nn.Sequential(cbr(w, 2 * w, 2), cbr(2 * w, 2 * w))
            self.s16 = nn.Sequential(
                cbr(2 * w, 4 * w, 2), cbr(4 * w, 4 * w), cbr(4 * w, 4 * w, d=2),
                cbr(4 * w, 4 * w, d=4),
            )  # fmt: skip
            self.ctx = nn.Sequential(nn.Conv2d(4 * w, 4 * w, 1), nn.ReLU(inplace=True))
            self.fuse8 = nn.Sequential(
                nn.Conv2d(6 * w, 3 * w, 1, bias=False), nn.BatchNorm2d(3 * w),
                nn.ReLU(inplace=True), cbr(3 * w, 3 * w),
            )  # fmt: skip
            self.fuse4 = sep(4 * w, 2 * w)
            self.proj = nn.Conv2d(2 * w, dim, 1)
            self.logit_scale = nn.Parameter(torch.tensor(np.log(1 / 0.07), dtype=torch.float32))

        def features(self, x):
            """(B, 2*width, H/4, W/4) pre-projection features of a normalised image batch."""
            f4 = self.s4(x)
            f8 = self.s8(f4)
            f16 = self.s16(f8)
            f16 = f16 + self.ctx(f16.mean(dim=(2, 3), keepdim=True))
            up = F.interpolate(f16, size=f8.shape[-2:], mode="bilinear", align_corners=False)
            f8 = self.fuse8(torch.cat([f8, up], 1))
            up = F.interpolate(f8, size=f4.shape[-2:], mode="bilinear", align_corners=False)
            return self.fuse4(torch.cat([f4, up], 1))

        def forward(self, x):
            """(B, dim, H/4, W/4) L2-normalised pixel embeddings."""
            return F.normalize(self.proj(self.features(x)), dim=1)

    return _LSegNet


@functools.cache
def _net_class():
    return _make_net_class()


def LSegNet(width: int = 32, dim: int = 384):
    """The network (a ``torch.nn.Module``); see :func:`build_lseg_net`."""
    return _net_class()(width=width, dim=dim)


def preprocess(rgb: np.ndarray):
    """(H, W, 3) uint8 RGB (or (B, H, W, 3)) -> (B, 3, H, W) float32 normalised tensor."""
    torch = _torch()
    x = torch.from_numpy(np.require(rgb, requirements=["C", "W"])).float().div_(255.0)
    if x.ndim == 3:
        x = x[None]
    x = x.permute(0, 3, 1, 2)
    mean = torch.tensor(_MEAN).view(1, 3, 1, 1)
    std = torch.tensor(_STD).view(1, 3, 1, 1)
    return (x - mean) / std


@functools.cache
def _load(path: str):
    torch = _torch()
    p = Path(path)
    if not p.is_file():
        raise AssetError(
            f"vision encoder weights not found at {p}; they ship with the repository "
            f"(tabletop/data/weights/vision_dense.pt) — restore them with git, or retrain with "
            f"`tabletop train vision`"
        )
    try:
        ckpt = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:  # a truncated file or a Git LFS pointer
        raise AssetError(f"vision encoder weights at {p} are unreadable: {e}") from None
    if ckpt.get("space") != MINILM_SPACE:
        raise AssetError(f"{p} embeds into {ckpt.get('space')!r}, expected {MINILM_SPACE!r}")
    net = LSegNet(width=int(ckpt["width"]), dim=int(ckpt["dim"]))
    net.load_state_dict({k: v.float() for k, v in ckpt["state_dict"].items()})
    net.eval()
    return net, ckpt


class LSegEncoder:
    """Dense and global image embeddings in MiniLM space from the committed small network.

    Implements both :class:`~tabletop.mapping.encoders.base.DenseImageEncoder` (stride 4) and
    :class:`~tabletop.mapping.encoders.base.GlobalImageEncoder`. Weights load once per path.
    Images of any size divisible by 4 work; the network was trained at 320x240.
    """

    space = MINILM_SPACE
    dim = 384
    stride = 4

    def __init__(self, weights: str | Path | None = None, *, num_threads: int | None = 1) -> None:
        if num_threads is not None and (int(num_threads) != num_threads or num_threads < 1):
            raise ConfigError(f"num_threads must be a positive integer or None: {num_threads!r}")
        self.num_threads = num_threads
        """torch threads during a forward pass (see :func:`~.base.torch_threads`)."""
        self.weights = Path(weights) if weights is not None else VISION_WEIGHTS_PATH
        self._net, ckpt = _load(str(self.weights))
        self.metrics: dict = dict(ckpt.get("metrics", {}))
        """Held-out figures recorded when the weights were trained."""

    def _check(self, rgb: np.ndarray) -> np.ndarray:
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ConfigError(f"rgb must be an (H, W, 3) uint8 image, got {rgb.shape} {rgb.dtype}")
        H, W = rgb.shape[:2]
        if H % self.stride or W % self.stride or H < 32 or W < 32:
            raise ConfigError(
                f"image size {W}x{H} must be at least 32x32 and divisible by {self.stride}"
            )
        return rgb

    def _embed(self, rgb: np.ndarray):
        with torch_threads(self.num_threads):
            return self._net(preprocess(rgb))[0]  # (dim, h, w)

    def encode_dense(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(H/4, W/4, 384) float32 L2-normalised cell embeddings of an (H, W, 3) uint8 image."""
        emb = self._embed(self._check(rgb))
        return np.ascontiguousarray(emb.permute(1, 2, 0).numpy(), dtype=np.float32)

    def encode_image(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(384,) float32 L2-normalised global embedding of an (H, W, 3) uint8 image.

        The mean of the image's cell embeddings, re-normalised: a "bag of what the image
        shows" in MiniLM space. Its dot product with a label's text embedding grows with how
        much of the image that label covers; two views of the same part of a table are close.
        It carries no geometry beyond what is visible (use local features for poses).
        """
        emb = self._embed(self._check(rgb))
        g = emb.mean(dim=(1, 2)).numpy().astype(np.float32)
        return g / max(float(np.linalg.norm(g)), 1e-12)

    def encode_dense_and_global(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Both embeddings from one forward pass: ((H/4, W/4, 384), (384,)), float32."""
        emb = self._embed(self._check(rgb))
        g = emb.mean(dim=(1, 2)).numpy().astype(np.float32)
        dense = np.ascontiguousarray(emb.permute(1, 2, 0).numpy(), dtype=np.float32)
        return dense, g / max(float(np.linalg.norm(g)), 1e-12)

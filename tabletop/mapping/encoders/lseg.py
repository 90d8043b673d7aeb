"""The embedded default image encoder: a small LSeg-style network trained into MiniLM's space.

:class:`LSegEncoder` maps an RGB image to pixel-aligned 384-d embeddings (output stride 4)
that live in all-MiniLM-L6-v2's text space, so a pixel is compared to a query by a dot product
with the query's MiniLM embedding, exactly as LSeg compares pixels to CLIP text embeddings.
It also gives one global embedding per image (see :meth:`LSegEncoder.encode_image`).

A weights file records the architecture it was trained with (``arch``; see :data:`ARCHS`):

- ``"lseg-small"`` (:class:`LSegNet`, 0.74 M parameters trained from scratch; files without an
  ``arch`` record are this one): ``tabletop/data/weights/vision_dense.pt``.
- ``"effnet-lite0-fpn"`` (:func:`~tabletop.mapping.encoders.effnet.build_effnet_lseg_net`: an
  ImageNet-pretrained EfficientNet-Lite0 with a light FPN head, 3.2 M parameters):
  ``tabletop/data/weights/vision_dense_effnet.pt``.

Both are trained by :func:`tabletop.train.vision.train_vision` on images rendered by
:mod:`tabletop.sim` and stored in fp16, with the input normalisation they expect. They know the
simulator's object kinds, colours, the table and the robot — nothing else: a stand-in for
LSeg/OpenSeg on a machine that cannot download them, not a general-purpose segmenter.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import IMAGENET_MEAN, IMAGENET_STD, preprocess, torch_threads
from tabletop.mapping.encoders.minilm import MINILM_SPACE
from tabletop.paths import DATA_DIR

__all__ = [
    "ARCHS",
    "BACKENDS",
    "EFFNET_WEIGHTS_PATH",
    "ROOM_WEIGHTS_PATH",
    "VISION_NETWORKS",
    "VISION_WEIGHTS_PATH",
    "LSegEncoder",
    "LSegNet",
    "build_lseg_net",
    "build_vision_net",
]

log = logging.getLogger(__name__)

VISION_WEIGHTS_PATH = DATA_DIR / "weights" / "vision_dense.pt"
"""The committed weights of the first (small) image encoder: what ``LSegEncoder()`` loads
without a path."""

EFFNET_WEIGHTS_PATH = DATA_DIR / "weights" / "vision_dense_effnet.pt"
"""Where the committed weights of the EfficientNet-Lite0 image encoder live."""

ROOM_WEIGHTS_PATH = DATA_DIR / "weights" / "vision_dense_room.pt"
"""The room-aware EfficientNet-Lite0 encoder: the table encoder fine-tuned on table renders
and on rooms seen from the mobile base's mast, enlarged twice (``tabletop train vision
--rooms``)."""

VISION_NETWORKS = {"table": EFFNET_WEIGHTS_PATH, "room": ROOM_WEIGHTS_PATH}
"""The default set's committed image networks by name (``MapConfig.image_network``)."""

_MEAN, _STD = IMAGENET_MEAN, IMAGENET_STD

ARCHS = ("lseg-small", "effnet-lite0-fpn")
"""Architectures a vision weights file may record (``ckpt["arch"]``)."""

BACKENDS = ("auto", "torch", "int8")
"""How :class:`LSegEncoder` runs its network: ``"auto"`` (onnxruntime when it can, else
torch), ``"torch"``, or ``"int8"`` (onnxruntime on the statically quantised graph: faster,
embeddings not equal to the others; falls back to ``"auto"``)."""
UPSCALES = (1, 2)
"""``LSegEncoder(upscale=...)``: how many times an image is enlarged before the network."""


def build_vision_net(arch: str, arch_config: dict):
    """A fresh network of a named architecture (see :data:`ARCHS`) from its recorded config:
    ``lseg-small``: ``width``, ``dim``; ``effnet-lite0-fpn``: see
    :func:`~tabletop.mapping.encoders.effnet.build_effnet_lseg_net`."""
    cfg = dict(arch_config)
    try:
        if arch == "lseg-small":
            return LSegNet(**cfg)
        if arch == "effnet-lite0-fpn":
            from tabletop.mapping.encoders.effnet import build_effnet_lseg_net

            return build_effnet_lseg_net(**cfg)
    except TypeError as e:
        raise ConfigError(f"vision architecture {arch!r}: bad config {cfg}: {e}") from None
    raise ConfigError(f"unknown vision architecture {arch!r}; valid: {list(ARCHS)}")


def _arch_of(ckpt: dict) -> tuple[str, dict, tuple, tuple]:
    """(arch, arch_config, input mean, input std) recorded by a checkpoint; files written
    before the record existed are ``lseg-small`` with ImageNet normalisation."""
    arch = ckpt.get("arch", "lseg-small")
    if arch == "lseg-small" and "arch_config" not in ckpt:
        cfg = {"width": int(ckpt["width"]), "dim": int(ckpt["dim"])}
    else:
        cfg = dict(ckpt.get("arch_config", {}))
    mean = tuple(float(v) for v in ckpt.get("input_mean", _MEAN))
    std = tuple(float(v) for v in ckpt.get("input_std", _STD))
    return arch, cfg, mean, std


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

    from tabletop.mapping.encoders.effnet import separable_conv as sep

    class _LSegNet(nn.Module):
        """A small encoder-decoder: stride-16 context (dilated convs + image pooling) fused
        back to stride 4, then a linear projection to ``dim`` and L2 normalisation."""

        def __init__(self, width: int = 32, dim: int = 384) -> None:
            super().__init__()
            w = width
            self.width, self.dim, self.stride = w, dim, 4
            self.arch, self.arch_config = "lseg-small", {"width": int(w), "dim": int(dim)}
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
    if not isinstance(ckpt, dict) or ckpt.get("space") != MINILM_SPACE:
        space = ckpt.get("space") if isinstance(ckpt, dict) else None
        raise AssetError(f"{p} embeds into {space!r}, expected {MINILM_SPACE!r}")
    arch, cfg, mean, std = _arch_of(ckpt)
    if arch not in ARCHS:
        raise AssetError(
            f"{p} records the vision architecture {arch!r}, which this version does not know; "
            f"valid: {list(ARCHS)}"
        )
    net = build_vision_net(arch, cfg)
    try:
        net.load_state_dict({k: v.float() for k, v in ckpt["state_dict"].items()})
    except RuntimeError as e:
        raise AssetError(f"{p}: weights do not fit the recorded {arch!r} {cfg}: {e}") from None
    net.eval()
    return net, ckpt, arch, mean, std


class LSegEncoder:
    """Dense and global image embeddings in MiniLM space from a committed network.

    Implements both :class:`~tabletop.mapping.encoders.base.DenseImageEncoder` (``stride``:
    the network's output stride, 4 for both shipped files) and
    :class:`~tabletop.mapping.encoders.base.GlobalImageEncoder`. The weights file says which
    architecture to build (``arch``) and how to normalise the input. Weights load once per
    path. Images of any size divisible by ``stride`` work; the networks were trained at 320x240.
    The network runs on onnxruntime, from a graph exported once per weights file and image size
    (:mod:`~tabletop.mapping.encoders.lseg_onnx`; the same embeddings to 1e-4, 0.5-0.7 of the
    time), and on torch where that cannot be done or ``backend="torch"``.
    """

    space = MINILM_SPACE
    dim = 384

    def __init__(
        self,
        weights: str | Path | None = None,
        *,
        num_threads: int | None = 1,
        backend: str = "auto",
        upscale: int = 1,
    ) -> None:
        if num_threads is not None and (int(num_threads) != num_threads or num_threads < 1):
            raise ConfigError(f"num_threads must be a positive integer or None: {num_threads!r}")
        if backend not in BACKENDS:
            raise ConfigError(f"unknown backend {backend!r}; valid: {list(BACKENDS)}")
        self.backend = backend
        """``"auto"``: onnxruntime where it runs the network (see
        :mod:`~tabletop.mapping.encoders.lseg_onnx`), else torch; ``"torch"``: torch only;
        ``"int8"``: the quantised graph on onnxruntime where it can be built, else ``"auto"``."""
        self.num_threads = num_threads
        """Threads of a forward pass: onnxruntime's intra-op threads, or torch's (see
        :func:`~.base.torch_threads`)."""
        self.weights = Path(weights) if weights is not None else VISION_WEIGHTS_PATH
        self._net, ckpt, self.arch, self._mean, self._std = _load(str(self.weights))
        net_stride = int(self._net.stride)
        if isinstance(upscale, bool) or upscale not in UPSCALES or net_stride % upscale:
            raise ConfigError(f"upscale must be one of {list(UPSCALES)}, got {upscale!r}")
        self.upscale = int(upscale)
        """The image is enlarged this many times before the network sees it (finer cells for
        small, far objects; about ``upscale``² the time)."""
        self.stride: int = net_stride // self.upscale
        """Output stride [px]: one embedding per ``stride`` x ``stride`` pixel cell."""
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
            return self._net(preprocess(rgb, self._mean, self._std))[0]  # (dim, h, w)

    def _session(self, rgb: np.ndarray):
        """The onnxruntime session for images of ``rgb``'s size, or None (torch runs)."""
        if self.backend == "torch":
            return None
        from tabletop.mapping.encoders.lseg_onnx import session

        H, W = rgb.shape[:2]
        args = (self._net, self.weights, self._mean, self._std, H, W, self.num_threads)
        if self.backend == "int8":
            sess = session(*args, int8=True)
            if sess is not None:
                return sess
        return session(*args)

    def _dense(self, rgb: np.ndarray) -> np.ndarray:
        """(H/s, W/s, dim) float32 C-contiguous L2-normalised cell embeddings of a checked
        image."""
        rgb = self._check(rgb)
        if self.upscale > 1:
            import cv2

            H, W = rgb.shape[:2]
            rgb = cv2.resize(rgb, (W * self.upscale, H * self.upscale), cv2.INTER_LINEAR)
        sess = self._session(rgb)
        if sess is not None:
            return sess.run(None, {"rgb": np.ascontiguousarray(rgb)})[0][0]
        emb = self._embed(rgb)
        return np.ascontiguousarray(emb.permute(1, 2, 0).numpy(), dtype=np.float32)

    @staticmethod
    def _global(dense: np.ndarray) -> np.ndarray:
        g = dense.reshape(-1, dense.shape[-1]).mean(axis=0, dtype=np.float32)
        return g / max(float(np.linalg.norm(g)), 1e-12)

    def encode_dense(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(H/s, W/s, 384) float32 L2-normalised cell embeddings of an (H, W, 3) uint8 image,
        ``s`` = :attr:`stride`."""
        return self._dense(rgb)

    def encode_image(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(384,) float32 L2-normalised global embedding of an (H, W, 3) uint8 image.

        The mean of the image's cell embeddings, re-normalised: a "bag of what the image
        shows" in MiniLM space. Its dot product with a label's text embedding grows with how
        much of the image that label covers; two views of the same part of a table are close.
        It carries no geometry beyond what is visible (use local features for poses).
        """
        return self._global(self._dense(rgb))

    def encode_dense_and_global(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Both embeddings from one forward pass: ((H/s, W/s, 384), (384,)), float32."""
        dense = self._dense(rgb)
        return dense, self._global(dense)

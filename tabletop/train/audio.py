"""Train and evaluate the embedded default audio encoder (``tabletop train audio``).

CLAP/wav2clip-style training into MiniLM's text space: every training clip of the sound bank is
turned, on the fly, into a segment like the ones a scan's noise gate cuts (a random crop of the
clip, speed-perturbed, at a random gain, inserted into :func:`~tabletop.audio.background_noise`
at a random SNR around the scans' 15 dB, with noise before and after it). The network's 384-d
embedding is contrasted (softmax cross-entropy with a learned temperature) against MiniLM
embeddings of one phrasing per category, drawn each step from the category's caption and its
paraphrases (:data:`PARAPHRASES`), so queries worded differently from the caption still match.
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

from tabletop.errors import ConfigError

__all__ = [
    "HELDOUT_QUERIES",
    "PARAPHRASES",
    "AudioTrainConfig",
    "evaluate_audio",
    "make_segment",
    "phrases_for",
    "train_audio",
]

log = logging.getLogger(__name__)

#: Phrasings of each category used in training beside its caption.
PARAPHRASES: dict[str, tuple[str, ...]] = {
    "dog": ("a dog barking", "a barking dog", "dog bark", "woof woof", "a puppy yapping"),
    "rooster": ("a rooster crowing", "cock-a-doodle-doo", "a cockerel", "rooster call"),
    "pig": ("a pig oinking", "oink oink", "a grunting pig", "pig sounds"),
    "cow": ("a cow mooing", "moo", "cattle lowing", "a mooing cow"),
    "frog": ("a frog croaking", "ribbit", "a croaking toad", "frogs at night"),
    "cat": ("a cat meowing", "meow", "a meowing kitten", "a cat purring and mewing"),
    "hen": ("a hen clucking", "a chicken clucking", "chickens", "clucking hens"),
    "insects": ("buzzing insects", "a bee buzzing", "a fly buzzing", "buzzing bugs"),
    "sheep": ("a sheep bleating", "baa", "a bleating lamb", "sheep sounds"),
    "crow": ("a crow cawing", "caw caw", "a raven croaking", "a cawing crow"),
    "rain": ("rain falling", "rainfall", "raindrops", "a rain shower"),
    "sea_waves": ("ocean waves", "waves crashing on a beach", "the sea", "surf"),
    "crackling_fire": ("a crackling fire", "a campfire", "fire burning", "flames crackling"),
    "crickets": ("crickets chirping", "a cricket", "grasshoppers chirping", "chirping crickets"),
    "chirping_birds": ("birds chirping", "birdsong", "a bird singing", "tweeting birds"),
    "water_drops": ("water dripping", "drops of water", "a dripping tap", "drip drip"),
    "wind": ("wind blowing", "a gust of wind", "howling wind", "a breeze"),
    "pouring_water": ("water pouring", "pouring a glass of water", "liquid being poured"),
    "toilet_flush": ("a toilet flushing", "flushing toilet", "a flush", "toilet flush"),
    "thunderstorm": ("thunder", "a thunderstorm", "thunder rumbling", "a storm"),
    "crying_baby": ("a baby crying", "a crying infant", "a wailing baby", "a baby"),
    "sneezing": ("someone sneezing", "a sneeze", "achoo", "a person sneezes"),
    "clapping": ("hands clapping", "applause", "a round of applause", "clapping hands"),
    "breathing": ("someone breathing", "breaths", "heavy breathing", "inhale and exhale"),
    "coughing": ("someone coughing", "a cough", "a person coughs", "coughing"),
    "footsteps": ("footsteps", "someone walking", "steps on the floor", "walking feet"),
    "laughing": ("someone laughing", "laughter", "a person laughs", "giggling"),
    "brushing_teeth": ("teeth being brushed", "a toothbrush", "brushing teeth"),
    "snoring": ("someone snoring", "a snore", "a sleeping person snoring"),
    "drinking_sipping": ("someone slurping a drink", "sipping", "drinking", "a gulp"),
    "door_wood_knock": ("knocking on a door", "a knock at the door", "knock knock", "knocking"),
    "mouse_click": ("a mouse click", "clicking a computer mouse", "a click"),
    "keyboard_typing": ("typing on a keyboard", "keystrokes", "a typewriter", "typing"),
    "door_wood_creaks": ("a door creaking", "a creaky door", "a squeaking hinge", "creak"),
    "can_opening": ("a can being opened", "opening a soda can", "a can pop"),
    "washing_machine": ("a washing machine", "a washer running", "laundry machine"),
    "vacuum_cleaner": ("a vacuum cleaner", "vacuuming", "a hoover"),
    "clock_alarm": ("an alarm clock ringing", "an alarm", "a ringing alarm clock", "beeping alarm"),
    "clock_tick": ("a clock ticking", "tick tock", "a ticking watch", "ticking"),
    "glass_breaking": ("glass breaking", "shattering glass", "a window smashing"),
    "helicopter": ("a helicopter", "helicopter rotors", "a chopper flying"),
    "chainsaw": ("a chainsaw", "a chainsaw cutting", "a power saw"),
    "siren": ("a siren", "a police siren", "an ambulance siren", "an emergency siren"),
    "car_horn": ("a car horn honking", "honk honk", "a car honking", "a horn beeping"),
    "engine": ("an engine running", "a motor", "an idling engine", "a car engine"),
    "train": ("a train", "a train passing", "a locomotive", "a steam train whistle"),
    "church_bells": ("church bells ringing", "a bell tolling", "a big bell", "bells"),
    "airplane": ("an airplane flying", "a jet plane", "an aircraft overhead", "a plane"),
    "fireworks": ("fireworks exploding", "firecrackers", "fireworks", "bangs and pops"),
    "hand_saw": ("a hand saw cutting wood", "sawing", "a saw", "sawing wood"),
    "duck": ("a duck quacking", "quack quack", "a quacking duck", "ducks"),
    "horse": ("a horse neighing", "a neighing horse", "a whinny", "a horse"),
    "owl": ("an owl hooting", "hoot hoot", "a hooting owl", "an owl at night"),
    "goose": ("a goose honking", "geese", "a honking goose", "a goose"),
    "monkey": ("a monkey chattering", "a chimpanzee", "monkeys screeching", "an ape"),
    "wolf": ("a wolf howling", "a howling wolf", "wolves howl", "a wolf"),
    "elephant": ("an elephant trumpeting", "an elephant", "a trumpeting elephant"),
    "lion": ("a lion roaring", "a roaring lion", "a big cat roar", "a lion"),
    "water": ("splashing water", "water dripping", "water splashing", "running water"),
    "telephone": ("a telephone ringing", "a phone ringing", "a ringing phone", "a ringtone"),
    "camera_shutter": ("a camera shutter clicking", "taking a photo", "a camera click"),
    "zipper": ("a zipper", "zipping up a jacket", "a zip being pulled", "unzipping"),
    "glass_clinking": ("glasses clinking", "a toast with glasses", "clinking glass", "cheers"),
    "hammering": ("hammering", "a hammer hitting a nail", "banging a hammer", "a hammer"),
    "scissors": ("scissors snipping", "cutting with scissors", "scissors", "snip snip"),
    "dice": ("dice rolling", "rolling dice", "throwing dice", "dice"),
    "writing": ("writing with a pen", "chalk on a blackboard", "a pencil scratching", "writing"),
    "trumpet": ("a trumpet playing", "a trumpet", "a brass horn", "a bugle"),
    "guitar": ("a guitar playing", "a guitar", "strumming a guitar", "guitar chords"),
    "piano": ("a piano playing", "a piano", "piano keys", "piano music"),
    "violin": ("a violin playing", "a violin", "a fiddle", "string music"),
    "drums": ("drums playing", "a drum", "a drum beat", "drumming"),
    "cymbals": ("a cymbal crashing", "a cymbal", "crash cymbals", "cymbals"),
    "xylophone": ("a xylophone playing", "a xylophone", "a glockenspiel", "mallet bells"),
    "flute": ("a flute playing", "a flute", "a recorder", "a whistle-like flute"),
}

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
    "trumpet": "a brass instrument",
    "guitar": "an acoustic guitar",
    "piano": "a keyboard instrument",
    "violin": "a cello",
    "drums": "a drummer",
    "cymbals": "a crash",
    "xylophone": "a marimba",
    "flute": "a woodwind instrument",
}


def phrases_for(category: str, caption: str) -> list[str]:
    """The caption of ``category`` and its training paraphrases (generic ones for a category
    without entries in :data:`PARAPHRASES`)."""
    words = category.replace("_", " ")
    extra = PARAPHRASES.get(category) or (words, f"a {words}", f"{words} sound", f"{words} noise")
    return list(dict.fromkeys([caption, *extra]))


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
    steps: int = 1000
    """Optimiser steps (about 1 s each on one core)."""
    batch_size: int = 64
    """Segments per step."""
    lr: float = 3e-3
    """Peak AdamW learning rate (linear warm-up, then cosine decay to 1 %)."""
    weight_decay: float = 5e-2
    """AdamW weight decay."""
    warmup_steps: int = 100
    """Linear warm-up steps."""
    min_segment_s: float = 0.3
    """Shortest segment [s] (the noise gate's)."""
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
    mixup_fraction: float = 0.3
    """Share of segments that get a second clip of another category at -10..-20 dB."""
    text_smoothing: float = 0.0
    """Share of each target spread over the other categories in proportion to
    ``softmax(caption similarity / 0.05)`` (semantic label smoothing; 0 = one-hot)."""
    channels: tuple[int, ...] = (16, 32, 64, 128)
    """Conv block widths of :class:`~tabletop.mapping.encoders.audio.AudioCNN`."""
    band_norm: bool = False
    """Per-band mean normalisation of the log-mel input (see ``AudioNetConfig.band_norm``)."""
    dropout: float = 0.2
    """Dropout before the projection head."""
    n_threads: int = 1
    """torch intra-op threads (other jobs share the machine)."""
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
        for name in ("snr_db", "gain_db", "speed"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ConfigError(f"{name} must be a (low, high) range, got {(lo, hi)}")
            object.__setattr__(self, name, (float(lo), float(hi)))
        if not self.speed[0] > 0:
            raise ConfigError(f"speed factors must be > 0, got {self.speed}")
        for name in ("clean_fraction", "mixup_fraction", "text_smoothing"):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
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


def evaluate_audio(
    encoder=None,
    bank=None,
    *,
    text_encoder=None,
    snr_db: float = 15.0,
    seed: int = 0,
    max_clips: int | None = None,
) -> dict:
    """Held-out retrieval figures of an audio ``encoder`` (default: the committed
    :class:`~tabletop.mapping.encoders.audio.MelCNNAudioEncoder`) on ``bank``'s clips of split
    "heldout" (default bank: ``SoundBank.default()``).

    Each held-out clip (first 3 s) is inserted into seeded background noise at ``snr_db``
    (default the scans' 15 dB) with 0.1 s of noise before and after it, and embedded. The
    queries are the captions of **all** the bank's categories ("the sound of a dog barking"),
    embedded by ``text_encoder`` (default MiniLM). With N held-out clips, C categories and Q
    the categories that have held-out clips:

    - ``audio_recall{1,3}_heldout`` (text-to-audio): for each of the Q captions, rank the N
      segments by cosine similarity; a hit when a segment of that category is among the top k.
      Mean over the Q queries.
    - ``audio_to_text_recall{1,3}_heldout``: for each of the N segments, rank the C captions;
      a hit when its own caption is among the top k. Mean over the N segments.
    - ``audio_paraphrase_recall{1,3}_heldout``: text-to-audio as above with
      :data:`HELDOUT_QUERIES` (phrasings training never used) instead of the captions, over
      the Q' categories that have one.

    Returns those figures (fractions in [0, 1]) with ``n_clips``, ``n_queries``,
    ``n_categories``, ``snr_db`` and ``seed``. ``max_clips`` keeps the first clips in bank
    order (a quick check). Deterministic for a given bank, encoder and seed.
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
    audio_emb = np.stack([encoder.encode_audio(s, rate) for s in segs])  # (N, D)
    cats = bank.categories
    text_emb = text_encoder.encode_text([bank.caption(c) for c in cats])  # (C, D)
    clip_cat = np.array([cats.index(c.category) for c in clips])
    sim = audio_emb @ text_emb.T  # (N, C)
    relevant_a2t = clip_cat[:, None] == np.arange(len(cats))[None, :]  # (N, C)

    q = sorted(set(clip_cat.tolist()))
    t2a_scores = sim[:, q].T  # (Q, N)
    t2a_rel = relevant_a2t[:, q].T
    out = {
        "audio_recall1_heldout": _recall_at(t2a_scores, t2a_rel, 1),
        "audio_recall3_heldout": _recall_at(t2a_scores, t2a_rel, 3),
        "audio_to_text_recall1_heldout": _recall_at(sim, relevant_a2t, 1),
        "audio_to_text_recall3_heldout": _recall_at(sim, relevant_a2t, 3),
    }
    para = [i for i in q if cats[i] in HELDOUT_QUERIES]
    if para:
        pe = text_encoder.encode_text([HELDOUT_QUERIES[cats[i]] for i in para])  # (Q', D)
        ps = pe @ audio_emb.T
        prel = relevant_a2t[:, para].T
        out["audio_paraphrase_recall1_heldout"] = _recall_at(ps, prel, 1)
        out["audio_paraphrase_recall3_heldout"] = _recall_at(ps, prel, 3)
    out.update(
        n_clips=len(clips),
        n_queries=len(q),
        n_categories=len(cats),
        snr_db=float(snr_db),
        seed=int(seed),
    )
    return out


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
    return logmel + torch.from_numpy(curve.astype(np.float32))[:, :, None]


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


def train_audio(config: AudioTrainConfig | None = None) -> Path:
    """Train the audio encoder as ``config`` says and write its checkpoint; returns its path.

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
        bank = _load_bank(cfg.bank_manifest)
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
            channels=cfg.channels, band_norm=cfg.band_norm, dropout=cfg.dropout
        )
        net = _Net(net_cfg)
        logit_scale = torch.nn.Parameter(torch.tensor(math.log(1 / 0.07)))
        params = [*net.parameters(), logit_scale]
        opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)

        def lr_at(step: int) -> float:
            if step < cfg.warmup_steps:
                return cfg.lr * (step + 1) / cfg.warmup_steps
            p = (step - cfg.warmup_steps) / max(1, cfg.steps - cfg.warmup_steps)
            return cfg.lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * p)))

        net.train()
        for step in range(cfg.steps):
            length = float(rng.uniform(cfg.min_segment_s, cfg.max_segment_s))
            ks = rng.choice(train_cats, size=cfg.batch_size)  # balanced over categories
            waves = []
            for k in ks:
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
                    other = [c for c in train_cats if c != k]
                    j = int(rng.choice(by_cat[int(rng.choice(other))]))
                    o = make_segment(audio[j], rate, length, rng, snr_db=None)
                    po, ps = float(np.mean(o**2)), float(np.mean(seg**2))
                    if po > 0:
                        g = math.sqrt(ps / po * 10 ** (-rng.uniform(10, 20) / 10))
                        seg = np.clip(seg + g * o, -1, 1).astype(np.float32)
                waves.append(seg)
            x = torch.from_numpy(np.stack(waves))
            with torch.no_grad():
                logmel = net.frontend(x)
                if cfg.eq_db > 0:
                    logmel = _random_eq(logmel, rng, cfg.eq_db)
                if cfg.spec_mask:
                    logmel = _spec_mask(logmel, rng)
            emb = net.cnn(logmel)  # (B, D)
            # one phrasing per category this step
            t = torch.stack([pe[int(rng.integers(len(pe)))] for pe in phrase_emb])  # (C, D)
            logits = logit_scale.clamp(max=math.log(100.0)).exp() * emb @ t.T
            target = soft[torch.from_numpy(ks).long()]  # (B, C)
            loss = torch.nn.functional.cross_entropy(logits, target)
            for g in opt.param_groups:
                g["lr"] = lr_at(step)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            if step % 50 == 0 or step == cfg.steps - 1:
                acc = float((logits.argmax(1).numpy() == ks).mean())
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
                enc = _InMemoryEncoder(net)
                log.info("step %d held-out: %s", step + 1, evaluate_audio(enc, bank))
                net.train()

        net.eval()
        train_s = time.perf_counter() - t_start
        meta = {
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

    def __init__(self, net) -> None:
        self._net = net

    def encode_audio(self, audio, sample_rate, context=None):
        import torch

        from tabletop.mapping.encoders.audio import _prepare
        from tabletop.mapping.encoders.base import l2_normalize

        with torch.inference_mode():
            x = torch.from_numpy(_prepare(audio, sample_rate))[None]
            return l2_normalize(self._net(x).numpy()[0])

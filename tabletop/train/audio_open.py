"""Sounds the bank never had: found where they played, refused where they did not.

The out-of-bank set (``SoundBank.out_of_bank()``: recordings of categories the bank lacks,
never trained on) is heard through the default audio encoder's open vocabulary
(:mod:`tabletop.mapping.open_sounds`). Each clip (its first 3 s) is inserted into seeded
background noise at the scans' SNR with 0.1 s around it, as ``evaluate_audio`` does. Then
``n_maps`` seeded maps of 3 out-of-bank segments of distinct categories beside 3 held-out bank
segments of distinct categories are asked, by caption, for

- each out-of-bank category they played: found when the best segment's score reaches the
  operating point and it is the segment of that sound (``audio_open_found``);
- two out-of-bank categories they did not play: refused when no segment reaches it
  (``audio_open_refused``).

The score is what a map computes (:meth:`~tabletop.mapping.sound_vocabulary.SoundMatcher.match`
with the segments' AudioSet logits), the operating point the shipped calibration's.
"""

from __future__ import annotations

import numpy as np
from scipy.special import expit

from tabletop.errors import ConfigError

__all__ = ["evaluate_open_sounds"]


def _segments(bank, encoder, snr_db: float, seed: int, salt: int):
    from tabletop.train.audio import _eval_segment

    clips = bank.clips(split="heldout")
    rate = bank.sample_rate
    pairs = [
        encoder.encode_audio_with_logits(
            _eval_segment(c.load(), rate, np.random.default_rng([seed, salt, i]), snr_db), rate
        )
        for i, c in enumerate(clips)
    ]
    cats = np.array([c.category for c in clips])
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs]), cats


def evaluate_open_sounds(
    out_of_bank,
    encoder=None,
    bank=None,
    *,
    text_encoder=None,
    snr_db: float = 15.0,
    seed: int = 0,
    n_maps: int = 40,
    threshold: float | None = None,
) -> dict:
    """``audio_open_found`` and ``audio_open_refused`` (module docstring) of ``encoder``
    (default: the YAMNet head) on the ``out_of_bank`` set's clips beside ``bank``'s held-out
    clips (default: the shipped bank), with ``n_open_categories`` and ``n_open_clips``."""
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
    from tabletop.mapping.open_sounds import OpenSoundVocabulary
    from tabletop.mapping.sound_vocabulary import SoundMatcher
    from tabletop.train.audio import _found_threshold, _load_bank

    if encoder is None:
        from tabletop.mapping.encoders.yamnet_audio import YamnetAudioEncoder

        encoder = YamnetAudioEncoder()
    if not hasattr(encoder, "encode_audio_with_logits") or encoder.vocabulary is None:
        raise ConfigError(
            f"{type(encoder).__name__} has no open vocabulary (class logits and a sound "
            "vocabulary); the YAMNet encoder has one"
        )
    bank = bank if bank is not None else _load_bank(None)
    text = text_encoder if text_encoder is not None else MiniLMTextEncoder()
    threshold = _found_threshold() if threshold is None else float(threshold)
    o_emb, o_log, o_cat = _segments(out_of_bank, encoder, snr_db, seed, 11)
    b_emb, b_log, b_cat = _segments(bank, encoder, snr_db, seed, 12)
    kinds = sorted(set(o_cat.tolist()))
    if len(kinds) < 5:
        raise ConfigError(f"need 5 or more out-of-bank categories, got {len(kinds)}")
    matcher = SoundMatcher(
        encoder.vocabulary,
        text,
        words={},
        open_vocabulary=OpenSoundVocabulary(encoder.class_names, text),
    )
    rng = np.random.default_rng([seed, 99])
    found = asked = refused = absent = 0
    for _ in range(n_maps):
        mine = [str(k) for k in rng.choice(kinds, size=3, replace=False)]
        rows = [int(rng.choice(np.flatnonzero(o_cat == k))) for k in mine]
        theirs = rng.choice(sorted(set(b_cat.tolist())), size=3, replace=False)
        brows = [int(rng.choice(np.flatnonzero(b_cat == k))) for k in theirs]
        emb = np.concatenate([o_emb[rows], b_emb[brows]])
        logits = np.concatenate([o_log[rows], b_log[brows]])
        for j, k in enumerate(mine):
            m = matcher.match(out_of_bank.caption(k), emb, logits)
            if m.known:
                found += int(expit(m.log_odds).max() >= threshold and m.log_odds.argmax() == j)
            asked += 1
        for k in rng.choice([k for k in kinds if k not in mine], size=2, replace=False):
            m = matcher.match(out_of_bank.caption(str(k)), emb, logits)
            refused += int(not m.known or expit(m.log_odds).max() < threshold)
            absent += 1
    return {
        "audio_open_found": found / asked,
        "audio_open_refused": refused / absent,
        "n_open_categories": len(kinds),
        "n_open_clips": len(o_cat),
    }

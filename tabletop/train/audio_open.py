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

__all__ = ["evaluate_open_sounds", "fit_open_scorer"]


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


def _logistic(x: np.ndarray, y: np.ndarray, l2: float = 1e-3, iters: int = 50) -> np.ndarray:
    """Weights (D + 1,) of a logistic regression of ``y`` (N,) bool on ``x`` (N, D) (the
    last is the bias), by Newton's method with a small ridge."""
    a = np.concatenate([x, np.ones((len(x), 1))], axis=1)
    w = np.zeros(a.shape[1])
    t = y.astype(np.float64)
    for _ in range(iters):
        p = expit(a @ w)
        g = a.T @ (p - t) + l2 * w
        h = (a * (p * (1 - p))[:, None]).T @ a + l2 * np.eye(len(w))
        step = np.linalg.solve(h, g)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return w


def _map_figures(score, cat, kinds, threshold_logit, n_maps, seed):
    """found / refused in seeded maps of 6 segments of distinct categories (3 asked for by
    caption, 2 categories not played asked too), as :func:`evaluate_open_sounds` counts them;
    ``score(rows, k)`` gives the segments' log-odds for category ``k``'s caption."""
    rng = np.random.default_rng([seed, 99])
    found = refused = 0
    for _ in range(n_maps):
        mine = [str(k) for k in rng.choice(kinds, size=6, replace=False)]
        rows = [int(rng.choice(np.flatnonzero(cat == k))) for k in mine]
        for j, k in enumerate(mine[:3]):
            lo = score(rows, k)
            found += int(lo.max() >= threshold_logit and lo.argmax() == j)
        for k in rng.choice([k for k in kinds if k not in mine], size=2, replace=False):
            refused += int(score(rows, str(k)).max() < threshold_logit)
    return found / (3 * n_maps), refused / (2 * n_maps)


def fit_open_scorer(
    bank=None,
    backbone=None,
    *,
    text_encoder=None,
    seed: int = 0,
    null_quantile: float = 0.95,
    rank: int = 3,
    refused_aim: float = 0.97,
    n_maps: int = 300,
    threshold: float | None = None,
):
    """Fit the open vocabulary's segment scorer (:class:`~tabletop.mapping.open_sounds.
    OpenScorer`) on ``bank``'s training clips (default: the shipped bank; held-out clips are
    never loaded) and YAMNet's logits.

    Every training category stands in for a sound the bank lacks: its clips (cut as a scan's
    noise gate cuts them, at 15 dB) are asked for by its caption through the class names.
    The scorer's reference logits (``null``) are, while fitting, taken without the asked
    category's clips, as a sound the bank never had is absent from the shipped reference. A
    logistic regression on the two features (segment of that category or not) gives the
    weights; the bias is then lowered until, in ``n_maps`` seeded maps of six segments, at
    least ``refused_aim`` of the categories not played are refused at the shipped operating
    point (``threshold``), the margin that keeps unseen sounds refused. The shipped
    ``null`` is over every training clip and the scans' background noise."""
    from tabletop.audio import background_noise
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
    from tabletop.mapping.encoders.yamnet import YamnetBackbone, yamnet_class_names
    from tabletop.mapping.open_sounds import OpenScorer, OpenSoundVocabulary, _names_digest
    from tabletop.train.audio import _eval_segment, _found_threshold, _load_bank

    bank = bank if bank is not None else _load_bank(None)
    backbone = backbone if backbone is not None else YamnetBackbone(num_threads=1)
    text = text_encoder if text_encoder is not None else MiniLMTextEncoder()
    threshold = _found_threshold() if threshold is None else float(threshold)
    t_logit = float(np.log(threshold / (1 - threshold)))
    names = yamnet_class_names()
    clips = bank.clips(split="train")
    if not clips:
        raise ConfigError(f"sound bank {bank.name!r} has no training clips")
    rate = bank.sample_rate
    logits = np.stack(
        [
            backbone(
                _eval_segment(c.load(), rate, np.random.default_rng([seed, 13, i]), 15.0), rate
            ).logits.max(axis=0)
            for i, c in enumerate(clips)
        ]
    ).astype(np.float64)
    noise = []
    for i in range(40):
        rng = np.random.default_rng([seed, 14, i])
        x = background_noise(int(rate * rng.uniform(0.5, 3.0)), rate, rng)
        noise.append(backbone(np.asarray(x, np.float32), rate).logits.max(axis=0))
    noise = np.asarray(noise, np.float64)
    cat = np.array([c.category for c in clips])
    ov = OpenSoundVocabulary(names, text, scorer=None)
    kinds, want = [], {}
    for k in sorted(set(cat.tolist())):
        w = ov.asked(text.encode_text([bank.caption(k)])[0])
        if w.any():
            kinds.append(k)
            want[k] = w
    if len(kinds) < 8:
        raise ConfigError(f"need 8 or more categories the class names read, got {len(kinds)}")
    digest = _names_digest(names)
    usable = ov._usable
    feats = {}
    for k in kinds:
        null = np.quantile(np.concatenate([logits[cat != k], noise]), null_quantile, axis=0)
        sc = OpenScorer(null, 1.0, 1.0, 0.0, rank, digest)
        feats[k] = sc.features(logits, want[k], usable)
    x = np.concatenate([feats[k] for k in kinds])
    y = np.concatenate([cat == k for k in kinds])
    w_rel, w_abs, bias = (float(v) for v in _logistic(x, y))

    def figures(b):
        return _map_figures(
            lambda rows, k: w_rel * feats[k][rows, 0] + w_abs * feats[k][rows, 1] + b,
            cat,
            kinds,
            t_logit,
            n_maps,
            seed,
        )

    shift = 0.0
    found, refused = figures(bias)
    while refused < refused_aim and shift < 10:
        shift += 0.25
        found, refused = figures(bias - shift)
    rule = _map_figures(
        lambda rows, k: ov.segment_log_odds(logits[rows], want[k]),
        cat,
        kinds,
        t_logit,
        n_maps,
        seed,
    )
    null = np.quantile(np.concatenate([logits, noise]), null_quantile, axis=0)
    meta = {
        "fitted_on": f"{bank.name}: {len(clips)} training clips, {len(kinds)} categories",
        "null_quantile": null_quantile,
        "threshold": threshold,
        "bias_lowered_by": shift,
        "train_found": round(found, 4),
        "train_refused": round(refused, 4),
        "rank_rule_train_found": round(rule[0], 4),
        "rank_rule_train_refused": round(rule[1], 4),
        "seed": seed,
    }
    return OpenScorer(null, w_rel, w_abs, bias - shift, rank, digest, meta)

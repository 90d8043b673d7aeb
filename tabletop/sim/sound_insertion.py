"""Insert sound-bank clips into a scan's audio track, one per audio episode, and record where
they were heard.

The whole recording gets a background-noise track on the frame clock. Each episode (a short
hover over one table region) receives one clip at a random time wholly inside it. Some
categories are inserted in two regions (``ScanConfig.repeat_sounds``), so that "the sound of a
dog" is ambiguous without another cue, as in the paper's cross-modal experiments.
"""

from __future__ import annotations

import numpy as np

from tabletop.errors import ConfigError
from tabletop.recording import Segment

__all__ = ["MIN_EVENT_S", "insert_sounds"]

#: Clips shorter than this [s] are repeated (with 0.15 s gaps) up to it: a hammer is heard
#: hammering, a knock knocking. A lone 0.2 s sound is below what a noise gate with a 250 ms
#: attack can pass.
MIN_EVENT_S = 1.0


def _repeat_to(audio: np.ndarray, rate: int, min_s: float) -> np.ndarray:
    if len(audio) >= min_s * rate:
        return audio
    gap = np.zeros(int(0.15 * rate), audio.dtype)
    parts = [audio]
    while sum(len(p) for p in parts) < min_s * rate:
        parts += [gap, audio]
    return np.concatenate(parts)


def _choose_categories(
    bank, rng: np.random.Generator, n: int, repeats: int, split: str, min_recordings: int = 1
):
    """``n`` categories, the first ``repeats`` twice, of those with ``split`` clips and at
    least ``min_recordings`` clips in all (the most-recorded ones if too few reach it), among
    the bank's :attr:`~tabletop.sim.sound_bank.SoundBank.scan_categories` where it pins them."""
    wanted = None if split == "any" else split
    pinned = getattr(bank, "scan_categories", None)
    usable = [
        c
        for c in bank.categories
        if bank.clips(category=c, split=wanted) and (pinned is None or c in pinned)
    ]
    unique = n - repeats
    count = {c: len(bank.clips(category=c)) for c in usable}
    rich = [c for c in usable if count[c] >= min_recordings]
    if len(rich) < unique:  # a small bank: the most-recorded categories
        rich = sorted(usable, key=lambda c: (-count[c], c))[:unique]
        rich = [c for c in usable if c in rich]
    usable = rich
    if unique > len(usable):
        raise ConfigError(
            f"{n} episodes with {repeats} repeated sounds need {unique} categories with "
            f"{split} clips; the bank has {len(usable)}"
        )
    cats = [str(c) for c in rng.choice(usable, size=unique, replace=False)]
    cats += cats[:repeats]  # the first `repeats` categories sound in two regions
    order = rng.permutation(len(cats))
    return [cats[i] for i in order], wanted


def insert_sounds(
    timestamps: np.ndarray,
    tcp_world: np.ndarray,
    segments: list[Segment],
    episode_centers,
    config,
    bank=None,
) -> tuple[np.ndarray, int, list[dict]]:
    """Audio track (S,) float32, its sample rate [Hz], and one ground-truth dict per sound.

    ``timestamps`` (N,) [s] and ``tcp_world`` (N, 3) [m] are the scan's true TCP path; the
    ``episode`` segments say where sounds may go; ``config`` is the scan's ``ScanConfig``.
    """
    from tabletop.audio import background_noise, insert_clip
    from tabletop.sim.sound_bank import SoundBank

    bank = bank or SoundBank.default()
    rate = bank.sample_rate
    rng = np.random.default_rng([config.seed, 1])
    episodes = [s for s in segments if s.kind == "episode"]
    cats, split = _choose_categories(
        bank,
        rng,
        len(episodes),
        config.repeat_sounds,
        config.clip_split,
        config.min_recordings,
    )
    dt = 1.0 / config.rate_hz
    n_samples = int(np.ceil((timestamps[-1] + dt) * rate))
    track = background_noise(n_samples, rate, rng)
    events = []
    used: dict[str, list[str]] = {}
    for seg, center, cat in zip(episodes, episode_centers, cats, strict=True):
        clips = bank.clips(category=cat, split=split)
        # A repeated category uses another clip if there is one.
        fresh = [c for c in clips if c.id not in used.get(cat, [])] or clips
        clip = fresh[int(rng.integers(len(fresh)))]
        used.setdefault(cat, []).append(clip.id)
        audio = _repeat_to(clip.load(), rate, MIN_EVENT_S)
        t0, t1 = timestamps[seg.start], timestamps[seg.stop - 1] + dt
        length = len(audio) / rate
        if length > (t1 - t0) - 0.4:
            audio = audio[: int(((t1 - t0) - 0.4) * rate)]
            length = len(audio) / rate
        start, stop = insert_clip(
            track, audio, float(rng.uniform(t0 + 0.2, t1 - 0.2 - length)), rate, config.snr_db
        )
        onset, offset = start / rate, stop / rate
        heard = np.nonzero((timestamps >= onset) & (timestamps <= offset))[0]
        p = tcp_world[heard].mean(axis=0)
        events.append(
            {
                "episode": seg.name,
                "category": cat,
                "caption": bank.caption(cat),
                "clip_id": clip.id,
                "onset_s": round(onset, 6),
                "offset_s": round(offset, 6),
                "frames": [int(heard[0]), int(heard[-1])],
                "tcp_mean": p.tolist(),
                "table_point": [float(p[0]), float(p[1]), 0.0],
                "region_center": [float(center[0]), float(center[1]), 0.0],
            }
        )
    return track.astype(np.float32), rate, events

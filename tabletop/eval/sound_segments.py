"""How well the audio front end cuts sounds out of a scan-like track.

:func:`segmentation_figures` builds seeded tracks like a scan's (the scans' background noise,
five bank clips a track, 30 % of them cut to 0.08-0.25 s, 0.2-3 s apart, at a given SNR),
segments them with :func:`~tabletop.mapping.audio_segments.segment_audio` and counts the
sounds that got a segment **of their own**: one that covers at least half of the sound (or
0.25 s of a longer one) and less than 50 ms of any other sound. ``tabletop check-encoders``
prints it for the scans' 15 dB and for 5 dB, on held-out clips.
"""

from __future__ import annotations

import numpy as np

from tabletop.errors import ConfigError

__all__ = ["GAPS_S", "has_own_segment", "segmentation_figures"]

#: Silence [s] between one sound and the next in the measure's tracks.
GAPS_S = (0.2, 0.4, 0.7, 1.5, 3.0)


def _track(clips, rng: np.random.Generator, snr_db: float, rate: int, n: int = 5):
    from tabletop.audio import background_noise, insert_clip

    x = background_noise(40 * rate, rate, rng).astype(np.float64)
    t, truth = 1.0, []
    for _ in range(n):
        a = clips[int(rng.integers(len(clips)))].load()
        if rng.random() < 0.3:
            a = a[: int(rng.uniform(0.08, 0.25) * rate)]
        s, e = insert_clip(x, a, t, rate, snr_db)
        truth.append((s / rate, e / rate))
        t = e / rate + float(rng.choice(GAPS_S))
    return x[: int((t + 1) * rate)].astype(np.float32), truth


def has_own_segment(segs, span, others) -> bool:
    """Whether one of ``segs`` covers at least half of the sound ``span`` = (start, end) [s]
    (or 0.25 s of a longer one) and less than 50 ms of the ``others`` spans."""
    a, b = span
    for s in segs:
        cover = min(b, s.end_s) - max(a, s.start_s)
        spill = sum(max(0.0, min(d, s.end_s) - max(c, s.start_s)) for c, d in others)
        if cover >= 0.5 * min(b - a, 0.5) and spill < 0.05:
            return True
    return False


def segmentation_figures(
    bank=None,
    snr_db: float = 15.0,
    *,
    tracks: int = 40,
    seed: int = 100,
    split: str = "heldout",
    config=None,
) -> dict:
    """``{"own_segment": share of sounds with a segment of their own, "segments_per_sound":
    segments cut / sounds inserted, "sounds": how many}`` over ``tracks`` seeded tracks of
    ``bank``'s ``split`` clips (default: the shipped bank's held-out clips) at ``snr_db``,
    segmented with ``config`` (a ``NoiseGateConfig``; default the map's)."""
    from tabletop.mapping.audio_segments import segment_audio
    from tabletop.sim.sound_bank import SoundBank

    bank = bank if bank is not None else SoundBank.default()
    clips = bank.clips(split=split)
    if not clips:
        raise ConfigError(f"sound bank {bank.name!r} has no {split!r} clips")
    rng = np.random.default_rng(seed)
    own = cut = total = 0
    for _ in range(int(tracks)):
        x, truth = _track(clips, rng, snr_db, bank.sample_rate)
        segs = segment_audio(x, bank.sample_rate, config)
        own += sum(
            has_own_segment(segs, span, truth[:i] + truth[i + 1 :]) for i, span in enumerate(truth)
        )
        cut += len(segs)
        total += len(truth)
    return {"own_segment": own / total, "segments_per_sound": cut / total, "sounds": total}

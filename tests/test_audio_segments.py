"""Noise gate and silence segmentation find inserted sounds over background noise."""

import numpy as np
import pytest

from tabletop.audio import background_noise, insert_clip
from tabletop.errors import ConfigError
from tabletop.mapping.audio_segments import NoiseGateConfig, noise_gate, segment_audio

RATE = 16000


def track_with_tones(spans, seconds=20.0, snr_db=15.0, seed=0, loud=None):
    rng = np.random.default_rng(seed)
    x = background_noise(int(seconds * RATE), RATE, rng).astype(np.float64)
    for k, (a, b) in enumerate(spans):
        t = np.arange(int((b - a) * RATE)) / RATE
        clip = np.sin(2 * np.pi * (300 + 100 * k) * t)
        if loud == k:  # one clip whose power sits in a 20 ms burst (a bang)
            clip = np.where(t < 0.02, np.sin(2 * np.pi * 900 * t), 0.001)
        insert_clip(x, clip, a, RATE, snr_db)
    return x.astype(np.float32)


def test_segments_match_inserted_sounds():
    spans = [(2.0, 3.5), (8.0, 9.0), (14.0, 17.0)]
    segs = segment_audio(track_with_tones(spans), RATE)
    assert len(segs) == 3
    for s, (a, b) in zip(segs, spans, strict=True):
        assert abs(s.start_s - a) < 0.3
        assert a < s.end_s <= b + 1.2  # the hold keeps the gate open up to 1 s after


def test_noise_floor_reference_keeps_quiet_sounds_that_the_peak_reference_loses():
    spans = [(2.0, 3.5), (8.0, 9.5), (14.0, 15.5)]
    x = track_with_tones(spans, loud=1)
    floor = segment_audio(x, RATE, NoiseGateConfig(reference="noise_floor"))
    peak = segment_audio(x, RATE, NoiseGateConfig(reference="peak"))

    def found(segs, span):
        return any(s.start_s < span[1] and s.end_s > span[0] for s in segs)

    # the two steady tones, as loud (in power) as the bang, are found against the floor...
    assert found(floor, spans[0]) and found(floor, spans[2])
    # ...but fall below -10 dB of the bang's loudest window with the peak reference
    assert not found(peak, spans[0]) and not found(peak, spans[2])


def test_gate_phases_and_errors():
    cfg = NoiseGateConfig()
    assert (cfg.threshold_db, cfg.attack_s, cfg.hold_s, cfg.release_s) == (-10.0, 0.25, 1.0, 0.17)
    x = track_with_tones([(2.0, 3.0)], seconds=6.0)
    g = noise_gate(x, RATE, cfg)
    assert g.shape == x.shape
    assert np.abs(g[:RATE]).max() == 0.0  # closed before the sound
    assert np.abs(g[int(2.5 * RATE) : int(2.9 * RATE)]).max() > 0  # open during it
    assert np.abs(g[int(4.5 * RATE) :]).max() == 0.0  # closed after hold and release
    assert segment_audio(np.zeros(RATE, np.float32), RATE) == []
    with pytest.raises(ConfigError, match="reference must be 'noise_floor' or 'peak'"):
        NoiseGateConfig(reference="loudest")

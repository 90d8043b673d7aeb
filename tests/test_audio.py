"""Tests of tabletop.audio: WAV I/O, resampling, noise, clip insertion and episodes."""

from __future__ import annotations

import wave

import numpy as np
import pytest

from tabletop.audio import (
    EpisodeAudio,
    background_noise,
    compose_episode_audio,
    insert_clip,
    loudest_window,
    read_wav,
    resample,
    rms,
    write_wav,
)
from tabletop.errors import AssetError, ConfigError
from tabletop.sim.sound_bank import SoundBank

RATE = 16000


@pytest.fixture(scope="module")
def bank() -> SoundBank:
    return SoundBank.default()


@pytest.fixture(scope="module")
def rooster(bank) -> np.ndarray:
    """A real shipped clip, (S,) float32 at 16 kHz."""
    return bank.clips(category="rooster")[0].load()


def xcorr_lag(signal: np.ndarray, template: np.ndarray) -> int:
    """Sample offset at which ``template`` best matches inside ``signal`` (FFT correlation)."""
    n = 1 << int(np.ceil(np.log2(len(signal) + len(template))))
    c = np.fft.irfft(np.fft.rfft(signal, n) * np.conj(np.fft.rfft(template, n)), n)
    return int(np.argmax(c[: len(signal) - len(template) + 1]))


def snr_db(clip_part: np.ndarray, background: np.ndarray) -> float:
    return 10 * np.log10(np.mean(clip_part.astype(np.float64) ** 2) / np.mean(background**2))


# --------------------------------------------------------------------------- WAV I/O
def test_wav_round_trip_16bit(tmp_path):
    x = (0.5 * np.sin(2 * np.pi * 440 * np.arange(RATE) / RATE)).astype(np.float32)
    write_wav(tmp_path / "a.wav", x, RATE)
    y, rate = read_wav(tmp_path / "a.wav")
    assert rate == RATE and y.dtype == np.float32 and y.shape == x.shape
    assert np.max(np.abs(y - x)) < 1.0 / 32767


@pytest.mark.parametrize("width", [1, 2, 3, 4])
def test_read_wav_widths_and_stereo_downmix(tmp_path, width):
    n = 800
    left = np.linspace(-0.5, 0.5, n)
    right = -0.25 * np.ones(n)
    full = {1: 127, 2: 32767, 3: 2**23 - 1, 4: 2**31 - 1}[width]
    ints = np.round(np.stack([left, right], axis=1) * full).astype(np.int64)
    if width == 1:
        raw = (ints + 128).astype(np.uint8).tobytes()
    elif width == 3:
        u = (ints.reshape(-1) & 0xFFFFFF).astype(np.uint32)
        raw = np.stack([u & 0xFF, (u >> 8) & 0xFF, (u >> 16) & 0xFF], axis=1).astype(np.uint8)
        raw = raw.tobytes()
    else:
        raw = ints.astype({2: "<i2", 4: "<i4"}[width]).tobytes()
    with wave.open(str(tmp_path / "s.wav"), "wb") as w:
        w.setnchannels(2)
        w.setsampwidth(width)
        w.setframerate(22050)
        w.writeframes(raw)
    y, rate = read_wav(tmp_path / "s.wav")
    assert rate == 22050 and y.shape == (n,)
    np.testing.assert_allclose(y, (left + right) / 2, atol=2.0 / 127 if width == 1 else 1e-4)


def test_read_wav_errors_name_the_file(tmp_path):
    with pytest.raises(AssetError, match="not found: .*missing.wav"):
        read_wav(tmp_path / "missing.wav")
    bad = tmp_path / "float.wav"
    # A 32-bit float WAV (format tag 3): the standard library cannot read it.
    header = b"RIFF" + (36 + 8).to_bytes(4, "little") + b"WAVEfmt " + (16).to_bytes(4, "little")
    header += (3).to_bytes(2, "little") + (1).to_bytes(2, "little") + RATE.to_bytes(4, "little")
    header += (
        (RATE * 4).to_bytes(4, "little") + (4).to_bytes(2, "little") + (32).to_bytes(2, "little")
    )
    bad.write_bytes(header + b"data" + (8).to_bytes(4, "little") + bytes(8))
    with pytest.raises(AssetError, match=r"float\.wav is not a readable PCM WAV.*integer PCM"):
        read_wav(bad)


# --------------------------------------------------------------------------- resampling
@pytest.mark.parametrize(
    ("orig", "new", "freq"),
    [(44100, 16000, 440.0), (44100, 16000, 5000.0), (16000, 44100, 1000.0), (8000, 16000, 3000.0)],
)
def test_resample_matches_the_analytic_sine(orig, new, freq):
    t = np.arange(orig) / orig  # 1 s
    y = resample(np.sin(2 * np.pi * freq * t + 0.3), orig, new)
    assert y.dtype == np.float32 and y.shape == (new,)
    ref = np.sin(2 * np.pi * freq * np.arange(new) / new + 0.3)
    edge = new // 50  # the kernel sees zeros beyond the ends
    assert np.max(np.abs(y[edge:-edge] - ref[edge:-edge])) < 2e-3


def test_resample_removes_content_above_the_new_nyquist():
    t = np.arange(44100) / 44100
    y = resample(np.sin(2 * np.pi * 10000.0 * t), 44100, 16000)  # 10 kHz > 8 kHz Nyquist
    assert rms(y[400:-400]) < 1e-3  # a naive decimation would alias it to 6 kHz at rms 0.7


def test_resample_identity_length_and_errors():
    x = np.random.default_rng(0).standard_normal(1001)
    np.testing.assert_array_equal(resample(x, RATE, RATE), x.astype(np.float32))
    assert len(resample(x, 48000, 16000)) == 334  # round(1001 / 3)
    with pytest.raises(ConfigError, match="orig_rate must be in"):
        resample(x, 0, RATE)
    with pytest.raises(ConfigError, match="new_rate must be an integer"):
        resample(x, RATE, 16000.5)
    with pytest.raises(ConfigError, match=r"mono 1-D array \(S,\), got shape \(2, 3\)"):
        resample(np.zeros((2, 3)), RATE, 8000)


# --------------------------------------------------------------------------- trimming
def test_loudest_window_finds_the_burst():
    rng = np.random.default_rng(1)
    x = 0.001 * rng.standard_normal(10 * RATE)
    x[6 * RATE : 7 * RATE] += np.sin(2 * np.pi * 300 * np.arange(RATE) / RATE)
    w = loudest_window(x, RATE, 2.0)
    assert len(w) == 2 * RATE
    start = xcorr_lag(x, w)
    assert 5 * RATE <= start <= 6 * RATE  # the window contains the whole 1 s burst
    assert len(loudest_window(x[:100], RATE, 2.0)) == 100  # short clips stay whole


# --------------------------------------------------------------------------- background noise
def test_background_noise_is_seeded_and_at_its_level():
    a = background_noise(RATE * 2, RATE, np.random.default_rng(7))
    b = background_noise(RATE * 2, RATE, np.random.default_rng(7))
    c = background_noise(RATE * 2, RATE, np.random.default_rng(8))
    assert a.dtype == np.float32 and a.shape == (2 * RATE,)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert rms(a) == pytest.approx(0.01, rel=1e-4)
    assert rms(background_noise(RATE, RATE, np.random.default_rng(0), rms_level=0.05)) == (
        pytest.approx(0.05, rel=1e-4)
    )


def test_background_noise_is_pink_with_a_hum():
    x = background_noise(8 * RATE, RATE, np.random.default_rng(3), hum_hz=60.0)
    p = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(len(x), 1 / RATE)

    def density(lo, hi):
        return p[(f >= lo) & (f < hi)].mean()

    # 1/f: a band 16x higher in frequency has ~16x less power per Hz (12 dB); allow 8-20 dB.
    ratio_db = 10 * np.log10(density(200, 400) / density(3200, 6400))
    assert 8 < ratio_db < 20
    hum_bin = np.argmin(np.abs(f - 60.0))
    assert p[hum_bin] > 100 * density(40, 80)  # a line, far above the noise around it


def test_background_noise_errors():
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="numpy.random.Generator"):
        background_noise(100, RATE, 0)
    with pytest.raises(ConfigError, match="n_samples must be a positive integer"):
        background_noise(0, RATE, rng)
    with pytest.raises(ConfigError, match=r"rms_level must be in \(0, 1\)"):
        background_noise(100, RATE, rng, rms_level=2.0)
    with pytest.raises(ConfigError, match="sample_rate must be in"):
        background_noise(100, 10, rng)


# --------------------------------------------------------------------------- insert_clip
def test_insert_clip_lands_where_it_says_at_the_asked_snr(rooster):
    rng = np.random.default_rng(11)
    track = background_noise(6 * RATE, RATE, rng).astype(np.float64)
    before = track.copy()
    start, stop = insert_clip(track, rooster, 2.5, RATE, snr_db=10.0)
    assert (start, stop) == (int(2.5 * RATE), int(2.5 * RATE) + len(rooster))
    added = track - before
    assert np.all(added[:start] == 0) and np.all(added[stop:] == 0)
    assert xcorr_lag(track, rooster) == start  # found by correlation in the mix
    # SNR against the noise power measured away from the clip (stationary noise): within 1 dB.
    outside = np.concatenate([before[:start], before[stop:]])
    assert snr_db(added[start:stop], outside) == pytest.approx(10.0, abs=1.0)
    assert snr_db(added[start:stop], before[start:stop]) == pytest.approx(10.0, abs=1e-6)


@pytest.mark.parametrize("snr", [-5.0, 0.0, 20.0])
def test_insert_clip_snr_on_a_float32_track(rooster, snr):
    track = background_noise(4 * RATE, RATE, np.random.default_rng(2))
    before = track.astype(np.float64)
    start, stop = insert_clip(track, rooster, 0.5, RATE, snr)
    assert track.dtype == np.float32
    added = track.astype(np.float64) - before
    assert snr_db(added[start:stop], before[start:stop]) == pytest.approx(snr, abs=0.05)


def test_insert_clip_keeps_the_track_in_range_and_every_snr(bank, rooster):
    """An impulsive clip at 15 dB would peak far above 1: the whole track is scaled instead."""
    chalk = bank.get("writing-qabcs-chalkboard").load()
    track = background_noise(8 * RATE, RATE, np.random.default_rng(4))
    before = track.astype(np.float64)
    r0, r1 = insert_clip(track, rooster, 0.5, RATE, 15.0)
    after_first = track.astype(np.float64)
    c0, c1 = insert_clip(track, chalk, 4.0, RATE, 15.0)
    assert np.max(np.abs(track)) <= 1.0
    scale = track[-1] / after_first[-1]  # the last sample holds noise only
    assert 0.05 < scale < 0.9
    added = track.astype(np.float64) / scale - before
    assert snr_db(added[c0:c1], before[c0:c1]) == pytest.approx(15.0, abs=0.05)
    assert snr_db(added[r0:r1], before[r0:r1]) == pytest.approx(15.0, abs=0.05)


def test_insert_clip_errors(rooster):
    rate = RATE
    track = background_noise(2 * rate, rate, np.random.default_rng(0))
    long_clip = np.ones(3 * rate, dtype=np.float32) * 0.1
    with pytest.raises(ConfigError, match=r"ends at .* past the track's end at 2\.000 s"):
        insert_clip(track, long_clip, 0.0, rate, 10.0)
    with pytest.raises(ConfigError, match="past the track's end"):
        insert_clip(track, rooster, 2.0 - len(rooster) / rate + 0.01, rate, 10.0)
    with pytest.raises(ConfigError, match="start_s must be >= 0"):
        insert_clip(track, rooster, -0.1, rate, 10.0)
    with pytest.raises(ConfigError, match="sample_rate must be in"):
        insert_clip(track, rooster, 0.0, 0, 10.0)
    with pytest.raises(ConfigError, match="sample_rate must be an integer"):
        insert_clip(track, rooster, 0.0, "16k", 10.0)
    with pytest.raises(ConfigError, match="silent"):
        insert_clip(track, np.zeros(100), 0.0, rate, 10.0)
    with pytest.raises(ConfigError, match="NaN"):
        insert_clip(track, np.array([0.1, np.nan]), 0.0, rate, 10.0)
    with pytest.raises(ConfigError, match="snr_db must be finite"):
        insert_clip(track, rooster, 0.0, rate, float("inf"))
    with pytest.raises(ConfigError, match="float32 or float64"):
        insert_clip(np.zeros(rate * 2, dtype=np.int16), rooster, 0.0, rate, 10.0)
    frozen = track.copy()
    frozen.setflags(write=False)
    with pytest.raises(ConfigError, match="read-only"):
        insert_clip(frozen, rooster, 0.0, rate, 10.0)
    with pytest.raises(ConfigError, match="silent over"):
        insert_clip(np.zeros(2 * rate), rooster, 0.0, rate, 10.0)


# --------------------------------------------------------------------------- episodes
def test_compose_episode_places_the_clip_inside(rooster):
    ep = compose_episode_audio(4.0, RATE, rooster, np.random.default_rng(5), snr_db=12.0)
    assert isinstance(ep, EpisodeAudio)
    assert ep.audio.dtype == np.float32 and ep.audio.shape == (4 * RATE,)
    assert not ep.audio.flags.writeable
    assert ep.duration_s == pytest.approx(4.0)
    assert 0.0 <= ep.onset_s and ep.offset_s <= 4.0
    assert ep.offset_s - ep.onset_s == pytest.approx(len(rooster) / RATE)
    assert xcorr_lag(ep.audio, rooster) == round(ep.onset_s * RATE)
    i0, i1 = round(ep.onset_s * RATE), round(ep.offset_s * RATE)
    outside = np.concatenate([ep.audio[:i0], ep.audio[i1:]]).astype(np.float64)
    inside = ep.audio[i0:i1].astype(np.float64)
    # inside = clip + noise (uncorrelated): clip power = P_inside - P_noise.
    p_clip = np.mean(inside**2) - np.mean(outside**2)
    assert 10 * np.log10(p_clip / np.mean(outside**2)) == pytest.approx(12.0, abs=1.0)


def test_compose_episode_is_deterministic_and_varies_with_the_seed(rooster):
    a = compose_episode_audio(5.0, RATE, rooster, np.random.default_rng(21))
    b = compose_episode_audio(5.0, RATE, rooster, np.random.default_rng(21))
    np.testing.assert_array_equal(a.audio, b.audio)
    assert a.onset_s == b.onset_s
    onsets = {
        compose_episode_audio(5.0, RATE, rooster, np.random.default_rng(s)).onset_s
        for s in range(8)
    }
    assert len(onsets) >= 6


def test_compose_episode_margins_and_headroom(rooster):
    for seed in range(10):
        ep = compose_episode_audio(
            3.0, RATE, rooster, np.random.default_rng(seed), margin_s=0.4, snr_db=45.0
        )
        assert ep.onset_s >= 0.4 - 1e-9 and ep.offset_s <= 3.0 - 0.4 + 1e-9
        assert np.max(np.abs(ep.audio)) <= 1.0  # scaled down, not clipped


def test_compose_episode_errors(rooster):
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match=r"clip does not fit in a 1\.000 s episode"):
        compose_episode_audio(1.0, RATE, np.full(2 * RATE, 0.1), rng)
    with pytest.raises(ConfigError, match="does not fit"):
        compose_episode_audio(len(rooster) / RATE + 0.1, RATE, rooster, rng, margin_s=0.2)
    with pytest.raises(ConfigError, match="duration_s must be > 0"):
        compose_episode_audio(0.0, RATE, rooster, rng)
    with pytest.raises(ConfigError, match="sample_rate must be in"):
        compose_episode_audio(3.0, 100, rooster, rng)

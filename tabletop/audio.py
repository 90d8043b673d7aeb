"""Audio primitives: WAV input/output, a numpy-only resampler, background noise and clip mixing.

Every signal here is mono float32 in [-1, 1] with an explicit sample rate in Hz; times are in
seconds. Nothing in this module needs more than numpy and the standard library's ``wave``.

Levels are root-mean-square (RMS) amplitudes of full-scale-1 signals: an RMS of 0.01 is
-40 dBFS. A signal-to-noise ratio (SNR) is ``10 * log10(P_clip / P_background)``, both mean
powers taken over the samples the clip occupies.
"""

from __future__ import annotations

import logging
import math
import wave
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError

__all__ = [
    "EpisodeAudio",
    "background_noise",
    "compose_episode_audio",
    "insert_clip",
    "loudest_window",
    "read_wav",
    "resample",
    "rms",
    "write_wav",
]

log = logging.getLogger(__name__)

#: Sample rates [Hz] accepted anywhere in this module.
MIN_SAMPLE_RATE = 1000
MAX_SAMPLE_RATE = 384_000


def _check_rate(sample_rate, name: str = "sample_rate") -> int:
    """A sample rate as a positive int in [MIN_SAMPLE_RATE, MAX_SAMPLE_RATE], or ConfigError."""
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, np.integer)):
        if isinstance(sample_rate, (float, np.floating)) and float(sample_rate).is_integer():
            sample_rate = int(sample_rate)
        else:
            raise ConfigError(f"{name} must be an integer number of Hz, got {sample_rate!r}")
    rate = int(sample_rate)
    if not MIN_SAMPLE_RATE <= rate <= MAX_SAMPLE_RATE:
        raise ConfigError(
            f"{name} must be in [{MIN_SAMPLE_RATE}, {MAX_SAMPLE_RATE}] Hz, got {rate}"
        )
    return rate


def _as_mono(x, name: str) -> np.ndarray:
    """``x`` as a finite 1-D float64 array (a copy), or ConfigError."""
    arr = np.asarray(x)
    if arr.ndim != 1:
        raise ConfigError(f"{name} must be a mono 1-D array (S,), got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.floating) and not np.issubdtype(arr.dtype, np.integer):
        raise ConfigError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} contains NaN or infinite samples")
    return arr


def rms(x: np.ndarray) -> float:
    """Root-mean-square amplitude of ``x`` (any shape); 0.0 for an empty array."""
    arr = np.asarray(x, dtype=np.float64)
    return float(np.sqrt(np.mean(arr**2))) if arr.size else 0.0


# --------------------------------------------------------------------------- WAV files
def read_wav(path: str | Path) -> tuple[np.ndarray, int]:
    """Read a PCM WAV file (8/16/24/32-bit integer, any channel count).

    Returns ``(audio, sample_rate)``: ``audio`` (S,) float32 in [-1, 1], the channels averaged
    to mono; ``sample_rate`` in Hz. Raises AssetError if the file is missing or is not integer
    PCM (floating-point and compressed WAVs are not read by the standard library).
    """
    path = Path(path)
    if not path.is_file():
        raise AssetError(f"sound file not found: {path}")
    try:
        with wave.open(str(path), "rb") as w:
            n_channels = w.getnchannels()
            width = w.getsampwidth()
            rate = w.getframerate()
            raw = w.readframes(w.getnframes())
    except (wave.Error, EOFError) as e:
        raise AssetError(
            f"{path} is not a readable PCM WAV file ({e}); convert it to 8/16/24/32-bit "
            "integer PCM, e.g. `sox in.wav -b 16 out.wav`"
        ) from None
    if width == 1:
        data = (np.frombuffer(raw, np.uint8).astype(np.float32) - 128.0) / 128.0
    elif width == 2:
        data = np.frombuffer(raw, "<i2").astype(np.float32) / 32768.0
    elif width == 3:
        b = np.frombuffer(raw, np.uint8)
        b = b[: len(b) - len(b) % 3].reshape(-1, 3).astype(np.int32)
        v = b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)
        v = np.where(v >= 1 << 23, v - (1 << 24), v)
        data = v.astype(np.float32) / float(1 << 23)
    elif width == 4:
        data = (np.frombuffer(raw, "<i4").astype(np.float64) / 2147483648.0).astype(np.float32)
    else:  # pragma: no cover - wave refuses other widths already
        raise AssetError(f"{path}: unsupported sample width {width} bytes; use 1, 2, 3 or 4")
    usable = len(data) - len(data) % n_channels
    audio = data[:usable].reshape(-1, n_channels).mean(axis=1, dtype=np.float32)
    return np.ascontiguousarray(audio, dtype=np.float32), int(rate)


def write_wav(path: str | Path, audio: np.ndarray, sample_rate: int) -> Path:
    """Write ``audio`` (S,) float in [-1, 1] as a mono 16-bit PCM WAV; values are clipped."""
    rate = _check_rate(sample_rate)
    x = _as_mono(audio, "audio")
    pcm = np.clip(np.round(x * 32767.0), -32768, 32767).astype("<i2")
    path = Path(path)
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(pcm.tobytes())
    return path


# --------------------------------------------------------------------------- resampling
def resample(
    audio: np.ndarray,
    orig_rate: int,
    new_rate: int,
    *,
    zero_crossings: int = 24,
    rolloff: float = 0.945,
    kaiser_beta: float = 8.6,
) -> np.ndarray:
    """Band-limited resampling by a Kaiser-windowed sinc kernel (numpy only).

    ``audio`` (S,) float at ``orig_rate`` Hz becomes (round(S * new_rate / orig_rate),) float32
    at ``new_rate`` Hz; output sample n sits at time n / new_rate, like input sample n at
    n / orig_rate. When downsampling, the kernel's cutoff is ``rolloff`` times the new Nyquist
    frequency, so content above it is removed rather than aliased. ``zero_crossings`` is the
    kernel's half-width in zero crossings of the sinc (longer = sharper, slower).
    """
    orig = _check_rate(orig_rate, "orig_rate")
    new = _check_rate(new_rate, "new_rate")
    if zero_crossings < 2:
        raise ConfigError(f"zero_crossings must be >= 2, got {zero_crossings}")
    if not 0.5 <= rolloff <= 1.0:
        raise ConfigError(f"rolloff must be in [0.5, 1], got {rolloff}")
    x = _as_mono(audio, "audio")
    if orig == new or len(x) == 0:
        return x.astype(np.float32)
    g = math.gcd(orig, new)
    up, down = new // g, orig // g  # output n sits at input position n * down / up
    n_out = round(len(x) * new / orig)
    cutoff = rolloff * min(1.0, new / orig)  # in cycles per input sample * 2 (1 = Nyquist)
    half_width = zero_crossings / cutoff  # kernel half-width [input samples]
    w = math.ceil(half_width)
    taps = np.arange(-w + 1, w + 1)  # offsets from floor(position)

    # The fractional position repeats with period `up`: build one filter row per phase.
    phases = np.arange(up)
    frac = (phases * down % up) / up  # (up,)
    d = frac[:, None] - taps[None, :]  # distance from each tap [input samples]
    kernel = cutoff * np.sinc(cutoff * d)
    inside = np.abs(d) < half_width
    window = np.zeros_like(d)
    window[inside] = np.i0(kaiser_beta * np.sqrt(1.0 - (d[inside] / half_width) ** 2))
    kernel *= window / np.i0(kaiser_beta)

    padded = np.concatenate([np.zeros(w), x, np.zeros(w + 1)])
    out = np.empty(n_out, dtype=np.float64)
    chunk = max(1, 2**20 // len(taps))
    for start in range(0, n_out, chunk):
        n = np.arange(start, min(n_out, start + chunk))
        base = n * down // up  # floor of the input position
        idx = base[:, None] + taps[None, :] + w
        out[start : start + len(n)] = np.einsum("ij,ij->i", padded[idx], kernel[n % up])
    return out.astype(np.float32)


# --------------------------------------------------------------------------- trimming
def loudest_window(audio: np.ndarray, sample_rate: int, max_duration_s: float) -> np.ndarray:
    """The contiguous span of at most ``max_duration_s`` seconds with the most energy.

    ``audio`` (S,) float; returns a float32 copy. A clip no longer than the window is returned
    whole. Ties go to the earliest window.
    """
    rate = _check_rate(sample_rate)
    if not max_duration_s > 0:
        raise ConfigError(f"max_duration_s must be > 0, got {max_duration_s}")
    x = _as_mono(audio, "audio")
    n = max(1, round(max_duration_s * rate))
    if len(x) <= n:
        return x.astype(np.float32)
    energy = np.concatenate([[0.0], np.cumsum(x**2)])
    window_energy = energy[n:] - energy[:-n]
    start = int(np.argmax(window_energy))
    return x[start : start + n].astype(np.float32)


# --------------------------------------------------------------------------- background noise
def background_noise(
    n_samples: int,
    sample_rate: int,
    rng: np.random.Generator,
    *,
    rms_level: float = 0.01,
    hum_hz: float = 50.0,
    hum_fraction: float = 0.1,
) -> np.ndarray:
    """Seeded room-like background: pink (1/f power) noise plus a faint mains hum.

    Returns (n_samples,) float32 whose RMS is exactly ``rms_level`` (0.01 = -40 dBFS).
    ``hum_fraction`` in [0, 1) is the share of the power in the hum (a sine at ``hum_hz`` [Hz]
    with its 2nd and 3rd harmonics, random phase); the rest is pink noise. The same ``rng``
    state gives the same samples.
    """
    rate = _check_rate(sample_rate)
    if isinstance(n_samples, bool) or int(n_samples) != n_samples or n_samples < 1:
        raise ConfigError(f"n_samples must be a positive integer, got {n_samples!r}")
    n = int(n_samples)
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got "
            f"{type(rng).__name__}"
        )
    if not (math.isfinite(rms_level) and 0 < rms_level < 1):
        raise ConfigError(f"rms_level must be in (0, 1), got {rms_level}")
    if not 0 <= hum_fraction < 1:
        raise ConfigError(f"hum_fraction must be in [0, 1), got {hum_fraction}")
    if hum_fraction > 0 and not 0 < hum_hz < rate / 6:
        raise ConfigError(
            f"hum_hz must be in (0, sample_rate / 6 = {rate / 6:g}) Hz so that its 3rd "
            f"harmonic is below Nyquist, got {hum_hz}"
        )
    white = rng.standard_normal(n)
    spectrum = np.fft.rfft(white)
    f = np.fft.rfftfreq(n, d=1.0 / rate)
    shape = np.zeros_like(f)
    shape[1:] = 1.0 / np.sqrt(np.maximum(f[1:], 20.0))  # pink above 20 Hz, flat below
    pink = np.fft.irfft(spectrum * shape, n=n)
    pink /= max(rms(pink), 1e-12)
    t = np.arange(n) / rate
    phase = rng.uniform(0.0, 2 * np.pi, size=3)
    hum = sum(
        a * np.sin(2 * np.pi * k * hum_hz * t + p)
        for k, a, p in zip((1, 2, 3), (1.0, 0.5, 0.25), phase, strict=True)
    )
    hum /= max(rms(hum), 1e-12)
    mix = np.sqrt(1.0 - hum_fraction) * pink + np.sqrt(hum_fraction) * hum
    mix *= rms_level / max(rms(mix), 1e-12)
    return mix.astype(np.float32)


# --------------------------------------------------------------------------- mixing
def insert_clip(
    track: np.ndarray,
    clip_audio: np.ndarray,
    start_s: float,
    sample_rate: int,
    snr_db: float,
) -> tuple[int, int]:
    """Add ``clip_audio`` into ``track`` **in place** at ``start_s`` seconds, at ``snr_db``.

    ``track`` (S,) writable float32/float64 array, sample 0 at t = 0 s; ``clip_audio`` (C,)
    float at the same ``sample_rate`` [Hz]. The clip is scaled so that its mean power over its
    C samples is ``snr_db`` dB above the track's mean power over the same samples (before
    insertion). The clip must lie wholly inside the track. Returns the sample span
    ``(start, stop)`` that now holds the clip.

    If the sum would leave [-1, 1], the **whole track** is scaled down in place so that its peak
    is 1: every SNR in the track (this clip's and earlier ones') is unchanged, the background
    level drops. Impulsive clips (ticks, dice, chalk) have a high peak-to-mean ratio and need
    this at moderate SNRs over a -40 dBFS background.
    """
    rate = _check_rate(sample_rate)
    if not isinstance(track, np.ndarray) or track.ndim != 1:
        raise ConfigError("track must be a 1-D numpy array (S,) that is modified in place")
    if not np.issubdtype(track.dtype, np.floating):
        raise ConfigError(f"track must be a float32 or float64 array, got dtype {track.dtype}")
    if not track.flags.writeable:
        raise ConfigError("track is read-only; pass a writable copy (track.copy())")
    clip = _as_mono(clip_audio, "clip_audio")
    if len(clip) == 0:
        raise ConfigError("clip_audio is empty")
    clip_power = float(np.mean(clip**2))
    if clip_power == 0.0:
        raise ConfigError("clip_audio is silent (all zeros); it cannot be set to an SNR")
    if not math.isfinite(snr_db):
        raise ConfigError(f"snr_db must be finite, got {snr_db}")
    if not math.isfinite(start_s) or start_s < 0:
        raise ConfigError(f"start_s must be >= 0 s, got {start_s}")
    start = round(start_s * rate)
    stop = start + len(clip)
    if stop > len(track):
        raise ConfigError(
            f"a {len(clip) / rate:.3f} s clip starting at {start_s:.3f} s ends at "
            f"{stop / rate:.3f} s, past the track's end at {len(track) / rate:.3f} s"
        )
    background_power = float(np.mean(np.asarray(track[start:stop], dtype=np.float64) ** 2))
    if background_power == 0.0:
        raise ConfigError(
            f"the track is silent over [{start / rate:.3f}, {stop / rate:.3f}] s; an SNR needs "
            "background noise there (see background_noise)"
        )
    gain = math.sqrt(background_power / clip_power * 10.0 ** (snr_db / 10.0))
    track[start:stop] += (gain * clip).astype(track.dtype)
    peak = float(np.max(np.abs(track[start:stop])))
    if peak > 1.0:
        log.info("clip at %.1f dB SNR peaks at %.2f: track scaled by 1/%.2f", snr_db, peak, peak)
        track *= track.dtype.type(1.0 / peak)
        # float32 rounding can leave a sample a hair above 1
        np.clip(track, -1.0, 1.0, out=track)
    return start, stop


@dataclass(frozen=True)
class EpisodeAudio:
    """One episode's audio: a clip over background noise, and where the clip lies."""

    audio: np.ndarray  # (S,) float32 in [-1, 1], sample 0 at t = 0 s, read-only
    sample_rate: int  # [Hz]
    onset_s: float  # clip start [s] from the episode start
    offset_s: float  # clip end [s] (exclusive), onset_s + clip length
    snr_db: float  # clip-to-background ratio [dB] over the clip's span

    @property
    def duration_s(self) -> float:
        """Episode length [s]."""
        return len(self.audio) / self.sample_rate


def compose_episode_audio(
    duration_s: float,
    sample_rate: int,
    clip_audio: np.ndarray,
    rng: np.random.Generator,
    *,
    snr_db: float = 15.0,
    noise_rms: float = 0.01,
    margin_s: float = 0.0,
) -> EpisodeAudio:
    """Background noise of ``duration_s`` seconds with the clip at a random time wholly inside.

    The onset is drawn uniformly so that the clip lies in [margin_s, duration_s - margin_s].
    ``clip_audio`` (C,) float at ``sample_rate`` [Hz]. Everything random comes from ``rng``;
    the same generator state gives the same episode. If the mix would leave [-1, 1], the whole
    episode is scaled down (the SNR is unchanged; see :func:`insert_clip`).
    """
    rate = _check_rate(sample_rate)
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"duration_s must be > 0, got {duration_s}")
    if not (math.isfinite(margin_s) and margin_s >= 0):
        raise ConfigError(f"margin_s must be >= 0, got {margin_s}")
    clip = _as_mono(clip_audio, "clip_audio")
    n = round(duration_s * rate)
    room = n - round(2 * margin_s * rate) - len(clip)
    if room < 0:
        raise ConfigError(
            f"a {len(clip) / rate:.3f} s clip does not fit in a {duration_s:.3f} s episode "
            f"with {margin_s:.3f} s margins; shorten the clip or lengthen the episode"
        )
    track = background_noise(n, rate, rng, rms_level=noise_rms).astype(np.float64)
    start = round(margin_s * rate) + int(rng.integers(0, room + 1))
    start, stop = insert_clip(track, clip, start / rate, rate, snr_db)
    audio = track.astype(np.float32)
    audio.setflags(write=False)
    return EpisodeAudio(
        audio=audio,
        sample_rate=rate,
        onset_s=start / rate,
        offset_s=stop / rate,
        snr_db=float(snr_db),
    )

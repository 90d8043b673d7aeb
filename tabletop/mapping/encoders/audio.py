"""The embedded default audio encoder: a small CNN on log-mel spectrograms, trained
CLAP/wav2clip-style into all-MiniLM-L6-v2's text space (``tabletop train audio``).

A mono segment (any length from ~0.1 s up; 0.3-3 s is what the noise gate cuts) at any sample
rate is resampled to 16 kHz, turned into a 64-band log-mel spectrogram (25 ms window, 10 ms hop;
:class:`LogMel`), run through :class:`AudioCNN` and projected to 384-d, L2-normalised. Its
cosine similarity to a :class:`~tabletop.mapping.encoders.minilm.MiniLMTextEncoder` embedding of
"a dog barking" is high for a bark. The weights live in ``tabletop/data/weights/audio.pt``
(fp16, ~1 MB); see ``docs/encoders_audio.md`` for training and held-out figures.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from tabletop.atomic import atomic_path
from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import l2_normalize, mono_at, torch_threads
from tabletop.mapping.encoders.minilm import MINILM_SPACE
from tabletop.mapping.sound_vocabulary import SoundVocabulary
from tabletop.paths import DATA_DIR

__all__ = [
    "AUDIO_SAMPLE_RATE",
    "AUDIO_WEIGHTS_FORMAT",
    "DEFAULT_AUDIO_WEIGHTS",
    "AudioCNN",
    "AudioNetConfig",
    "EffNetAudio",
    "LogMel",
    "MelCNNAudioEncoder",
    "load_audio_checkpoint",
    "save_audio_checkpoint",
]

log = logging.getLogger(__name__)

#: Rate [Hz] the network runs at; other rates are resampled on the way in.
AUDIO_SAMPLE_RATE = 16000
#: The committed weights of the embedded default.
DEFAULT_AUDIO_WEIGHTS = DATA_DIR / "weights" / "audio.pt"
#: ``format`` field of a checkpoint written by :func:`save_audio_checkpoint`.
AUDIO_WEIGHTS_FORMAT = "tabletop-audio-encoder"
AUDIO_WEIGHTS_VERSION = 1
#: Shorter segments are tiled (repeated) up to this length [s].
MIN_SEGMENT_S = 0.1
#: Network designs an :class:`AudioNetConfig` may name.
AUDIO_BACKBONES = ("cnn", "effnet-lite0")


@dataclass(frozen=True)
class AudioNetConfig:
    """Architecture of the log-mel CNN (stored in the checkpoint)."""

    n_fft: int = 512
    """STFT size [samples] at 16 kHz (32 ms)."""
    win_length: int = 400
    """Hann window length [samples] (25 ms)."""
    hop_length: int = 160
    """Frame hop [samples] (10 ms)."""
    n_mels: int = 64
    """Mel bands between ``f_min`` and ``f_max``."""
    f_min: float = 50.0
    """Lowest mel band edge [Hz]."""
    f_max: float = 8000.0
    """Highest mel band edge [Hz] (<= Nyquist)."""
    channels: tuple[int, ...] = (32, 64, 128, 192)
    """Output channels of the conv blocks; each block halves time and frequency."""
    dim: int = 384
    """Embedding size (MiniLM's)."""
    dropout: float = 0.2
    """Dropout before the projection (training only)."""
    band_norm: bool = False
    """Subtract each mel band's mean over time (removes a fixed channel colouring) instead of
    one mean over all bins."""
    backbone: str = "cnn"
    """``"cnn"``: :class:`AudioCNN` (``channels`` wide); ``"effnet-lite0"``: the
    EfficientNet-Lite0 image backbone (:mod:`tabletop.mapping.encoders.effnet`, ImageNet
    initialised when trained) on the log-mel spectrogram as a one-channel image."""
    last_stage: int = 6
    """Last EfficientNet-Lite0 stage kept (``"effnet-lite0"`` only; 6 = the whole backbone)."""

    def __post_init__(self) -> None:
        if self.backbone not in AUDIO_BACKBONES:
            raise ConfigError(
                f"unknown audio backbone {self.backbone!r}; valid: {', '.join(AUDIO_BACKBONES)}"
            )
        object.__setattr__(self, "channels", tuple(int(c) for c in self.channels))
        if not self.win_length <= self.n_fft:
            raise ConfigError(f"win_length {self.win_length} must be <= n_fft {self.n_fft}")
        if not 0 <= self.f_min < self.f_max <= AUDIO_SAMPLE_RATE / 2:
            raise ConfigError(
                f"need 0 <= f_min < f_max <= {AUDIO_SAMPLE_RATE / 2} Hz, got "
                f"{self.f_min}, {self.f_max}"
            )
        if not self.channels or min(self.channels) < 1:
            raise ConfigError(f"channels must be positive integers, got {self.channels}")
        if self.backbone == "cnn" and self.n_mels < 2 ** len(self.channels):
            raise ConfigError(
                f"n_mels {self.n_mels} too small for {len(self.channels)} halving blocks"
            )
        if not 0 <= self.dropout < 1:
            raise ConfigError(f"dropout must be in [0, 1), got {self.dropout}")


def _mel_filterbank(n_fft: int, n_mels: int, f_min: float, f_max: float, rate: int) -> np.ndarray:
    """(n_fft // 2 + 1, n_mels) float32 triangular filters on the HTK mel scale, area-normalised."""

    def hz_to_mel(f):
        return 2595.0 * np.log10(1.0 + np.asarray(f) / 700.0)

    def mel_to_hz(m):
        return 700.0 * (10.0 ** (np.asarray(m) / 2595.0) - 1.0)

    freqs = np.linspace(0.0, rate / 2, n_fft // 2 + 1)
    edges = mel_to_hz(np.linspace(hz_to_mel(f_min), hz_to_mel(f_max), n_mels + 2))
    lo, mid, hi = edges[:-2], edges[1:-1], edges[2:]
    up = (freqs[:, None] - lo) / (mid - lo)
    down = (hi - freqs[:, None]) / (hi - mid)
    fb = np.maximum(0.0, np.minimum(up, down))
    fb *= 2.0 / (hi - lo)  # Slaney-style: equal area per band
    return fb.astype(np.float32)


class LogMel(nn.Module):
    """Waveforms (B, S) float at 16 kHz -> log-mel spectrograms (B, n_mels, T) float32.

    ``T = 1 + S // hop_length`` (centred frames, reflect padding). Values are
    ``log(mel power + 1e-6)`` minus each example's mean over all bins, so a gain change does
    not change the output.
    """

    def __init__(self, cfg: AudioNetConfig) -> None:
        super().__init__()
        self.n_fft, self.hop, self.win = cfg.n_fft, cfg.hop_length, cfg.win_length
        self.register_buffer("window", torch.hann_window(cfg.win_length), persistent=False)
        fb = _mel_filterbank(cfg.n_fft, cfg.n_mels, cfg.f_min, cfg.f_max, AUDIO_SAMPLE_RATE)
        self.register_buffer("fb", torch.from_numpy(fb), persistent=False)
        self.band_norm = cfg.band_norm

    def forward(self, wave: torch.Tensor) -> torch.Tensor:
        spec = torch.stft(
            wave,
            self.n_fft,
            hop_length=self.hop,
            win_length=self.win,
            window=self.window,
            center=True,
            pad_mode="reflect",
            return_complex=True,
        )
        power = spec.real**2 + spec.imag**2  # (B, F, T)
        mel = torch.einsum("bft,fm->bmt", power, self.fb)
        logmel = torch.log(mel + 1e-6)
        dims = (2,) if self.band_norm else (1, 2)
        return logmel - logmel.mean(dim=dims, keepdim=True)


def _pool_and_project(x: torch.Tensor, dropout: nn.Module, proj: nn.Module) -> torch.Tensor:
    """A feature map (B, C, F', T') -> mean over frequency, mean and max over time, the
    projection, L2 normalisation: (B, dim) (the tail both audio networks share)."""
    x = x.mean(dim=2)  # (B, C, T')
    x = torch.cat([x.mean(dim=2), x.amax(dim=2)], dim=1)
    return nn.functional.normalize(proj(dropout(x)), dim=1)


class AudioCNN(nn.Module):
    """Log-mel CNN: conv blocks (3x3 conv, BN, ReLU, 2x2 average pool), mean over frequency,
    mean + max over time, linear projection to ``dim``, L2 normalisation.

    ``forward(logmel)`` takes (B, n_mels, T) and returns (B, dim) unit vectors.
    """

    def __init__(self, cfg: AudioNetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        layers: list[nn.Module] = [nn.BatchNorm2d(1)]
        c_in = 1
        for c in cfg.channels:
            layers += [
                nn.Conv2d(c_in, c, 3, padding=1, bias=False),
                nn.BatchNorm2d(c),
                nn.ReLU(inplace=True),
                nn.Conv2d(c, c, 3, padding=1, bias=False),
                nn.BatchNorm2d(c),
                nn.ReLU(inplace=True),
                nn.AvgPool2d(2, ceil_mode=True),
            ]
            c_in = c
        self.features = nn.Sequential(*layers)
        self.dropout = nn.Dropout(cfg.dropout)
        self.proj = nn.Sequential(
            nn.Linear(2 * c_in, 2 * c_in), nn.ReLU(inplace=True), nn.Linear(2 * c_in, cfg.dim)
        )

    def forward(self, logmel: torch.Tensor) -> torch.Tensor:
        return _pool_and_project(self.features(logmel[:, None]), self.dropout, self.proj)


class EffNetAudio(nn.Module):
    """EfficientNet-Lite0 on a log-mel spectrogram: a learned input scale (batch norm over the
    one channel), the spectrogram repeated to the three input channels the ImageNet weights
    expect, the backbone to ``last_stage``, mean over frequency, mean + max over time, a
    two-layer projection to ``dim``, L2 normalisation. Same contract as :class:`AudioCNN`."""

    def __init__(self, cfg: AudioNetConfig) -> None:
        super().__init__()
        from tabletop.mapping.encoders.effnet import EfficientNetLite0

        self.cfg = cfg
        self.norm = nn.BatchNorm2d(1)
        self.backbone = EfficientNetLite0(last_stage=cfg.last_stage)
        c = self.backbone.channels[max(self.backbone.channels)]
        self.dropout = nn.Dropout(cfg.dropout)
        self.proj = nn.Sequential(
            nn.Linear(2 * c, 512), nn.ReLU(inplace=True), nn.Linear(512, cfg.dim)
        )

    def forward(self, logmel: torch.Tensor) -> torch.Tensor:
        feats = self.backbone(self.norm(logmel[:, None]).expand(-1, 3, -1, -1))
        return _pool_and_project(feats[max(feats)], self.dropout, self.proj)


class _Net(nn.Module):
    """Frontend + network: (B, S) 16 kHz waveforms -> (B, dim) embeddings."""

    def __init__(self, cfg: AudioNetConfig) -> None:
        super().__init__()
        self.frontend = LogMel(cfg)
        self.cnn = AudioCNN(cfg) if cfg.backbone == "cnn" else EffNetAudio(cfg)

    def forward(self, wave: torch.Tensor) -> torch.Tensor:
        return self.cnn(self.frontend(wave))


def save_audio_checkpoint(
    path: str | Path, net: nn.Module, cfg: AudioNetConfig, meta: dict | None = None
) -> Path:
    """Write ``net``'s weights (fp16) with its architecture and ``meta`` (JSON-like) to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {
        k: (v.half() if v.is_floating_point() else v).cpu() for k, v in net.state_dict().items()
    }
    blob = {
        "format": AUDIO_WEIGHTS_FORMAT,
        "version": AUDIO_WEIGHTS_VERSION,
        "space": MINILM_SPACE,
        "net": asdict(cfg),
        "state_dict": state,
        "meta": dict(meta or {}),
    }
    with atomic_path(path) as tmp:
        torch.save(blob, tmp)
    return path


def load_audio_checkpoint(path: str | Path) -> tuple[_Net, dict]:
    """The network (eval mode, float32) and the checkpoint's ``meta`` from ``path``."""
    path = Path(path)
    if not path.is_file():
        raise AssetError(
            f"audio encoder weights not found at {path}; they ship with the repository "
            f"(tabletop/data/weights/audio.pt) or are rebuilt by `tabletop train audio`"
        )
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # a truncated or foreign file
        raise AssetError(f"cannot read audio encoder weights {path}: {e}") from None
    if not isinstance(blob, dict) or blob.get("format") != AUDIO_WEIGHTS_FORMAT:
        raise AssetError(
            f"{path} is not a tabletop audio encoder checkpoint (format "
            f"{AUDIO_WEIGHTS_FORMAT!r} expected)"
        )
    if blob.get("version") != AUDIO_WEIGHTS_VERSION:
        raise AssetError(
            f"{path}: checkpoint version {blob.get('version')!r}, this code reads "
            f"{AUDIO_WEIGHTS_VERSION}; retrain with `tabletop train audio`"
        )
    cfg = AudioNetConfig(**blob["net"])
    net = _Net(cfg)
    try:
        net.load_state_dict({k: v.float() for k, v in blob["state_dict"].items()})
    except RuntimeError as e:
        raise AssetError(f"{path}: weights do not fit the stored architecture: {e}") from None
    net.eval()
    return net, dict(blob.get("meta", {}))


@functools.lru_cache(maxsize=8)
def _cached_net(path: str, mtime_ns: int) -> tuple[_Net, dict]:
    return load_audio_checkpoint(path)


def _prepare(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """Validate one segment and bring it to 16 kHz, at least :data:`MIN_SEGMENT_S` long."""
    x = mono_at(audio, sample_rate, AUDIO_SAMPLE_RATE)
    n_min = round(MIN_SEGMENT_S * AUDIO_SAMPLE_RATE)
    if len(x) < n_min:
        reps = math.ceil(n_min / len(x))
        x = np.tile(x, reps)[:n_min]
    return x


class MelCNNAudioEncoder:
    """The embedded default :class:`~tabletop.mapping.encoders.base.AudioEncoder`: audio into
    MiniLM's 384-d text space (``space = "minilm-l6-v2"``).

    ``weights`` is a checkpoint path (default: the committed ``tabletop/data/weights/audio.pt``);
    a missing or foreign file raises :class:`~tabletop.errors.AssetError`. The network is loaded
    once per path and shared. ``num_threads`` is the torch intra-op thread count used during a
    forward pass and restored after it (the network is small: one thread is as fast as two and
    does not collapse when other processes keep the cores busy); None leaves torch's setting.
    Learned encoders ignore ``context``.
    """

    space = MINILM_SPACE
    dim = 384

    def __init__(self, weights: str | Path | None = None, *, num_threads: int | None = 1) -> None:
        if num_threads is not None and (int(num_threads) != num_threads or num_threads < 1):
            raise ConfigError(
                f"num_threads must be a positive integer or None, got {num_threads!r}"
            )
        self.num_threads = num_threads
        self.weights = Path(weights) if weights is not None else DEFAULT_AUDIO_WEIGHTS
        path = self.weights.resolve()
        mtime = path.stat().st_mtime_ns if path.is_file() else -1
        self._net, self.meta = _cached_net(str(path), mtime)
        if self._net.cnn.cfg.dim != self.dim:
            raise AssetError(f"{self.weights}: embeds into {self._net.cnn.cfg.dim}-d, not 384-d")
        self.vocabulary = SoundVocabulary.from_meta(self.meta.get("vocabulary"))
        """The sound categories the network was trained on (None for older checkpoints)."""

    @property
    def backbone(self) -> str:
        """The network design of the loaded weights (``AudioNetConfig.backbone``)."""
        return self._net.cnn.cfg.backbone

    def __repr__(self) -> str:
        return f"MelCNNAudioEncoder(weights={str(self.weights)!r})"

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        """(384,) float32 L2-normalised embedding of one mono segment ``audio`` (S,) float in
        [-1, 1] at ``sample_rate`` [Hz]."""
        x = _prepare(audio, sample_rate)
        with torch_threads(self.num_threads):
            e = self._net(torch.from_numpy(np.require(x, requirements=["C", "W"]))[None])
        return l2_normalize(e.numpy()[0])

    def encode_audio_batch(self, segments: list[np.ndarray], sample_rate: int) -> np.ndarray:
        """(N, 384) float32 embeddings of N segments (each (S_i,) at ``sample_rate`` [Hz]).

        Segments are run one at a time (no padding), so the result equals N calls of
        :meth:`encode_audio`.
        """
        if not len(segments):
            return np.zeros((0, self.dim), np.float32)
        return np.stack([self.encode_audio(s, sample_rate) for s in segments])

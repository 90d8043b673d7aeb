"""aiSFX, a sound-effects embedding CNN (512-d), frozen, on CPU: the backbone of an ablation head.

aiSFX (Ma and Lerch, "Representation Learning for the Automatic Indexing of Sound Effects
Libraries", ISMIR 2022) is a nine-layer CNN trained across sound-effects libraries labelled
with the Universal Category System. It ships as the ``aisfx==0.1.2`` wheel (PyPI): the network
class in ``aisfx.models.cnn2d`` and the best checkpoint ``aisfx/models/checkpoint.pth``. Only
the embedding network is used (the per-dataset classifiers of the checkpoint are dropped).
The front end is written here after the package's librosa path; its Essentia path is not
used.

Front end: mono 44.1 kHz (other rates resampled), peak-normalised (the package normalises each
file to a peak of 1), centred frames of 2048 samples (periodic Hann window, zero padding at
the ends) every 1024 samples, power spectrum, 96 HTK mel bands 0-22050 Hz (each filter of unit
sum), ``log10(1 + 10000 * mel)`` divided by 9.4578 (the package's ``"original"`` min-max
normalisation, minimum 0). Windows of 100 frames (2.3 s) every 50 frames (1.16 s), as the
package's inference blocks them: the last partial window is dropped, and a segment shorter
than one window is padded with zeros to it. Each window gives one 512-d embedding (the
network's mean over frequency, then max over time).

Cost: about 50 ms of one CPU thread per window, i.e. per second of audio for longer segments
(the embedded default's YAMNet: about 3 ms), so aiSFX is measured as an ablation and is not a
default. Licences (``tabletop/data/weights/AUDIO_LICENSES.md``): the weights CC BY 4.0 by A. B.
Ma and A. Lerch, the code MIT. Install with ``pip install --no-deps aisfx==0.1.2`` (its
declared requirements pin an old numpy and librosa); the front end needs librosa (the
``aisfx`` extra) for its mel filterbank.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import mono_at

__all__ = [
    "AISFX_DIM",
    "AISFX_RATE",
    "AisfxBackbone",
    "AisfxOutput",
    "aisfx_checkpoint",
    "aisfx_log_mel",
    "aisfx_windows",
]

#: Sample rate [Hz] of the network's front end.
AISFX_RATE = 44100
#: Size of one window's embedding.
AISFX_DIM = 512
#: Frames per window (2.3 s) and between window starts (1.16 s).
WINDOW_FRAMES, WINDOW_HOP = 100, 50
_NFFT, _HOP, _MELS, _FMIN, _FMAX = 2048, 1024, 96, 0.0, 22050.0
#: Maximum of the log-mel values the network was trained on (the package's normalisation).
_SPEC_MAX = 9.457798957824707
_INSTALL = "install it with `pip install --no-deps aisfx==0.1.2` (scripts/bootstrap does)"


def aisfx_checkpoint() -> Path:
    """Path of ``aisfx/models/checkpoint.pth`` in the installed ``aisfx`` distribution."""
    from importlib import metadata

    try:
        dist = metadata.distribution("aisfx")
    except metadata.PackageNotFoundError:
        raise AssetError(f"the aiSFX backbone needs the `aisfx` package: {_INSTALL}") from None
    path = Path(dist.locate_file("aisfx/models/checkpoint.pth"))
    if not path.is_file():
        raise AssetError(f"aiSFX checkpoint not found at {path}: {_INSTALL}")
    return path


@functools.lru_cache(maxsize=1)
def _mel_matrix() -> np.ndarray:
    """(96, 1025) float32 HTK mel filterbank, each filter of unit sum (librosa's ``norm=1``)."""
    try:
        import librosa
    except ImportError:
        raise AssetError("the aiSFX front end needs librosa: pip install -e '.[aisfx]'") from None
    fb = librosa.filters.mel(
        sr=AISFX_RATE, n_fft=_NFFT, n_mels=_MELS, fmin=_FMIN, fmax=_FMAX, htk=True, norm=1.0
    )
    return np.asarray(fb, np.float32)


def prepare_wave(audio: np.ndarray, sample_rate: int) -> np.ndarray:
    """Validate one mono segment, bring it to 44.1 kHz and a peak of 1 (silence stays 0)."""
    x = mono_at(audio, sample_rate, AISFX_RATE)
    peak = float(np.max(np.abs(x)))
    return x / peak if peak > 0 else x


def aisfx_log_mel(wave: np.ndarray) -> np.ndarray:
    """(T, 96) float32 normalised log-mel frames of a 44.1 kHz wave (time first)."""
    x = np.pad(np.asarray(wave, np.float32), _NFFT // 2)
    n = 1 + (len(x) - _NFFT) // _HOP
    frames = np.lib.stride_tricks.sliding_window_view(x, _NFFT)[::_HOP][:n]
    window = (0.5 - 0.5 * np.cos(2 * np.pi * np.arange(_NFFT) / _NFFT)).astype(np.float32)
    power = np.abs(np.fft.rfft(frames * window, axis=1)) ** 2
    mel = power.astype(np.float32) @ _mel_matrix().T
    return (np.log10(1.0 + 10000.0 * mel) / _SPEC_MAX).astype(np.float32)


def aisfx_windows(logmel: np.ndarray) -> np.ndarray:
    """(W, 100, 96) windows of (T, 96) frames: one every 50 frames, the partial last one
    dropped, a spectrogram shorter than one window padded with zeros."""
    t = len(logmel)
    count = 1 if t < WINDOW_FRAMES else (t - WINDOW_FRAMES) // WINDOW_HOP + 1
    padded = np.zeros((max(t, WINDOW_FRAMES), logmel.shape[1]), np.float32)
    padded[:t] = logmel
    return np.stack([padded[i * WINDOW_HOP : i * WINDOW_HOP + WINDOW_FRAMES] for i in range(count)])


@dataclass(frozen=True)
class AisfxOutput:
    """aiSFX on one segment: one embedding per 2.3 s window."""

    embeddings: np.ndarray
    """(W, 512) float32, non-negative (max over time of ReLU features)."""


def _embedding_net_class():
    try:
        from aisfx.models.cnn2d import EmbeddingNet
    except ModuleNotFoundError as e:
        if (e.name or "").split(".")[0] == "aisfx":
            raise AssetError(f"the aiSFX backbone needs the `aisfx` package: {_INSTALL}") from None
        # A requirement of the package's __init__ (tqdm) is missing: load the model module alone.
        import importlib.util

        path = aisfx_checkpoint().with_name("cnn2d.py")
        spec = importlib.util.spec_from_file_location("_tabletop_aisfx_cnn2d", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        EmbeddingNet = module.EmbeddingNet
    return EmbeddingNet


@functools.lru_cache(maxsize=2)
def _network(path: str):
    import torch

    # The checkpoint is (state dict, {dataset: (index, classes)}) with numpy integers in the
    # second part: allow exactly those to the safe (weights-only) unpickler.
    safe = [
        (np._core.multiarray.scalar, "numpy.core.multiarray.scalar"),
        np.dtype,
        type(np.dtype("int64")),
    ]
    try:
        with torch.serialization.safe_globals(safe):
            state, _datasets = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # a truncated or foreign file: torch raises several kinds
        raise AssetError(f"cannot read the aiSFX checkpoint {path}: {e}") from None
    prefix = "embedding_net."
    sub = {k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)}
    net = _embedding_net_class()("max", 3, 1, 64)  # the package's best model, X-Sequential-CE
    try:
        net.load_state_dict(sub)
    except RuntimeError as e:
        raise AssetError(f"{path}: not the aiSFX checkpoint this loader knows: {e}") from None
    net.eval()
    for p in net.parameters():
        p.requires_grad_(False)
    return net


class AisfxBackbone:
    """The frozen aiSFX embedding network on torch (``num_threads`` threads while it runs).

    ``checkpoint``: the package's ``checkpoint.pth`` (default: the installed ``aisfx``'s).
    Called like :class:`~tabletop.mapping.encoders.yamnet.YamnetBackbone`: one mono segment
    and its rate give per-window embeddings (``.embeddings``, (W, 512)).
    """

    dim = AISFX_DIM

    def __init__(self, checkpoint: str | Path | None = None, *, num_threads: int = 1) -> None:
        if isinstance(num_threads, bool) or int(num_threads) != num_threads or num_threads < 1:
            raise ConfigError(f"num_threads must be a positive integer, got {num_threads!r}")
        self.checkpoint = Path(checkpoint) if checkpoint is not None else aisfx_checkpoint()
        if not self.checkpoint.is_file():
            raise AssetError(f"aiSFX checkpoint not found at {self.checkpoint}: {_INSTALL}")
        self.num_threads = int(num_threads)
        self._net = _network(str(self.checkpoint.resolve()))
        _mel_matrix()  # fail now, not at the first segment, when librosa is missing

    def run(self, windows: np.ndarray) -> AisfxOutput:
        """aiSFX on (W, 100, 96) normalised log-mel windows."""
        import torch

        old = torch.get_num_threads()
        torch.set_num_threads(self.num_threads)
        try:
            with torch.inference_mode():
                emb = self._net(torch.from_numpy(np.ascontiguousarray(windows, np.float32)))
        finally:
            torch.set_num_threads(old)
        return AisfxOutput(emb.numpy().astype(np.float32))

    def __call__(self, wave: np.ndarray, sample_rate: int = AISFX_RATE) -> AisfxOutput:
        """aiSFX on one mono segment (S,) float at ``sample_rate`` [Hz]."""
        return self.run(aisfx_windows(aisfx_log_mel(prepare_wave(wave, sample_rate))))

"""A real CLAP backend: Microsoft's CLAP (the ``msclap`` package), loaded from local files.

CLAP embeds audio and text into one space of its own (1024-d), so a map whose audio features
come from CLAP must take its sound queries' text embeddings from CLAP too: this class is both
an :class:`~tabletop.mapping.encoders.base.AudioEncoder` and a
:class:`~tabletop.mapping.encoders.base.TextEncoder`, with ``space = "msclap-<version>"``, and
:func:`~tabletop.mapping.encoders.base.check_same_space` refuses pairing it with MiniLM.

Nothing is downloaded. The user provides

- ``checkpoint``: the CLAP weights file (``CLAP_weights_2023.pth`` or ``CLAP_weights_2022.pth``
  from the msclap release), a ``torch.save`` of ``{"model": state_dict, ...}`` or a bare state
  dict;
- ``text_model``: a local directory holding the Hugging Face text model the version was built
  on (``gpt2`` for 2023, ``bert-base-uncased`` for 2022): its ``config.json``, tokenizer files
  and weights, as ``save_pretrained`` writes them. The CLAP checkpoint overwrites the weights.

Only the ``msclap.models`` code is used (the network definitions and msclap's own YAML configs);
msclap's ``CLAPWrapper`` imports torchaudio, which does not install beside this project's CPU
torch, so its preprocessing (resample to 44.1 kHz, repeat-pad or crop to the version's
duration, GPT-2's ``<|endoftext|>`` suffix and ``!`` padding) is re-implemented here. See
``docs/encoders_audio.md``: the loading and feature code is tested with random weights of the
same architecture; the semantics with real weights were not verified here.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import os
import sys
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import l2_normalize

__all__ = ["MSCLAP_VERSIONS", "MSClapEncoder", "build_msclap_model", "msclap_config"]

log = logging.getLogger(__name__)

#: CLAP versions whose configs msclap ships (``msclap/configs/config_<version>.yml``).
MSCLAP_VERSIONS = ("2022", "2023")

_EXTRA_HINT = (
    "the CLAP backend needs the 'clap' extra: `pip install -e '.[clap]'` and "
    "`pip install --no-deps msclap` (msclap's own requirements would replace CPU torch)"
)


def _msclap_models():
    """``msclap.models.clap``, imported without msclap's ``__init__`` when torchaudio is missing.

    msclap's package ``__init__`` imports ``CLAPWrapper``, which imports torchaudio at the top.
    The network code (``msclap.models``) needs only torch, transformers and torchlibrosa. When
    torchaudio is absent, the ``msclap`` package is registered as a bare namespace (its
    ``__init__`` not run) so that ``msclap.models`` can be imported.
    """
    try:
        return importlib.import_module("msclap.models.clap")
    except ModuleNotFoundError as e:
        if e.name not in ("torchaudio", "msclap"):
            raise AssetError(f"{_EXTRA_HINT} ({e.name} is missing)") from None
        if e.name == "msclap":
            raise AssetError(f"{_EXTRA_HINT} (msclap is missing)") from None
    spec = importlib.util.find_spec("msclap")
    if spec is None or not spec.submodule_search_locations:  # pragma: no cover - checked above
        raise AssetError(f"{_EXTRA_HINT} (msclap is missing)")
    if "msclap" not in sys.modules:
        # the package object with its spec and __path__, its __init__ not executed
        sys.modules["msclap"] = importlib.util.module_from_spec(spec)
    try:
        return importlib.import_module("msclap.models.clap")
    except ModuleNotFoundError as e:
        raise AssetError(f"{_EXTRA_HINT} ({e.name} is missing)") from None


def msclap_config(version: str = "2023") -> dict:
    """msclap's shipped configuration of ``version`` (one of :data:`MSCLAP_VERSIONS`)."""
    if version not in MSCLAP_VERSIONS:
        raise ConfigError(f"CLAP version must be one of {MSCLAP_VERSIONS}, got {version!r}")
    spec = importlib.util.find_spec("msclap")
    if spec is None or not spec.submodule_search_locations:
        raise AssetError(f"{_EXTRA_HINT} (msclap is missing)")
    path = Path(next(iter(spec.submodule_search_locations))) / "configs" / f"config_{version}.yml"
    try:
        import yaml
    except ImportError:
        raise AssetError(f"{_EXTRA_HINT} (pyyaml is missing)") from None
    if not path.is_file():
        raise AssetError(f"msclap's config {path} is missing; reinstall msclap")
    return dict(yaml.safe_load(path.read_text()))


def build_msclap_model(version: str, text_model: str | Path):
    """An msclap ``CLAP`` network of ``version``'s architecture (weights: random audio side,
    the text model's own weights from ``text_model``), in eval mode, with its config dict."""
    cfg = msclap_config(version)
    text_dir = Path(text_model)
    if not (text_dir.is_dir() and (text_dir / "config.json").is_file()):
        raise ConfigError(
            f"text_model must be a local directory with the Hugging Face {cfg['text_model']!r} "
            f"model (config.json, tokenizer files, weights) saved by save_pretrained; got "
            f"{str(text_model)!r}. Nothing is downloaded here."
        )
    clap_mod = _msclap_models()
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    model = clap_mod.CLAP(
        audioenc_name=cfg["audioenc_name"],
        sample_rate=cfg["sampling_rate"],
        window_size=cfg["window_size"],
        hop_size=cfg["hop_size"],
        mel_bins=cfg["mel_bins"],
        fmin=cfg["fmin"],
        fmax=cfg["fmax"],
        classes_num=cfg["num_classes"],
        out_emb=cfg["out_emb"],
        text_model=str(text_dir),
        transformer_embed_dim=cfg["transformer_embed_dim"],
        d_proj=cfg["d_proj"],
    )
    # msclap picks the text pooling (GPT last token / BERT CLS) by substring of this name
    model.caption_encoder.text_model = cfg["text_model"]
    model.eval()
    return model, cfg


def _load_state_dict(path: Path, trust_checkpoint: bool) -> dict:
    import pickle

    import torch

    try:
        blob = torch.load(path, map_location="cpu", weights_only=not trust_checkpoint)
    except pickle.UnpicklingError as e:
        raise AssetError(
            f"{path} holds more than tensors ({str(e).splitlines()[0]}); if you trust the "
            "file, pass trust_checkpoint=True to unpickle it in full"
        ) from None
    except (OSError, RuntimeError, EOFError) as e:
        raise AssetError(f"cannot read CLAP checkpoint {path}: {e}") from None
    state = blob.get("model", blob) if isinstance(blob, dict) else None
    if not isinstance(state, dict) or not state:
        raise AssetError(f"{path} is not a CLAP checkpoint (no 'model' state dict)")
    # unwrap DistributedDataParallel names
    return {k.removeprefix("module."): v for k, v in state.items()}


class MSClapEncoder:
    """Microsoft CLAP audio and text embeddings (``space = "msclap-<version>"``, 1024-d).

    ``checkpoint``: local CLAP weights file; ``text_model``: local directory of the text model
    (``gpt2`` for version "2023", ``bert-base-uncased`` for "2022"); see the module docstring.
    ``trust_checkpoint`` allows a full (pickle) load for checkpoints that hold more than
    tensors. Raises :class:`~tabletop.errors.AssetError` for a missing file, package or
    mismatched weights, :class:`~tabletop.errors.ConfigError` for a bad argument.
    """

    dim: int

    def __init__(
        self,
        checkpoint: str | Path,
        text_model: str | Path,
        *,
        version: str = "2023",
        trust_checkpoint: bool = False,
    ) -> None:
        self.checkpoint = Path(checkpoint)
        if not self.checkpoint.is_file():
            raise AssetError(
                f"CLAP checkpoint not found at {self.checkpoint}; download "
                f"CLAP_weights_{version}.pth from the msclap release on a machine with access and "
                "pass its local path"
            )
        self.version = str(version)
        self._model, self._cfg = build_msclap_model(self.version, text_model)
        state = _load_state_dict(self.checkpoint, trust_checkpoint)
        missing, unexpected = self._model.load_state_dict(state, strict=False)
        # buffers some transformers versions keep outside the state dict
        missing = [k for k in missing if not k.endswith("position_ids")]
        unexpected = [k for k in unexpected if not k.endswith("position_ids")]
        if missing or unexpected:
            raise AssetError(
                f"{self.checkpoint} does not fit the CLAP {self.version} architecture: "
                f"{len(missing)} missing keys (e.g. {missing[:3]}), {len(unexpected)} unexpected "
                f"(e.g. {unexpected[:3]})"
            )
        self._model.eval()
        from transformers import AutoTokenizer

        self._tokenizer = AutoTokenizer.from_pretrained(str(text_model))
        self._gpt = "gpt" in self._cfg["text_model"]
        if self._gpt:
            self._tokenizer.add_special_tokens({"pad_token": "!"})
        self.sample_rate = int(self._cfg["sampling_rate"])
        self.duration_s = float(self._cfg["duration"])
        self.dim = int(self._cfg["d_proj"])
        self.space = f"msclap-{self.version}"

    def __repr__(self) -> str:
        return f"MSClapEncoder(checkpoint={str(self.checkpoint)!r}, version={self.version!r})"

    # ------------------------------------------------------------------ text
    def encode_text(self, texts: list[str]) -> np.ndarray:
        """(N, dim) float32 L2-normalised CLAP text embeddings."""
        import torch

        if isinstance(texts, str):
            texts = [texts]
        texts = [str(t) for t in texts]
        if not texts:
            return np.zeros((0, self.dim), np.float32)
        if self._gpt:
            texts = [t + " <|endoftext|>" for t in texts]
        tok = self._tokenizer(
            texts,
            add_special_tokens=True,
            max_length=int(self._cfg["text_len"]),
            padding="max_length",
            truncation=True,
            return_tensors="pt",
        )
        keys = ["input_ids", "attention_mask"]
        if "bert" in self._cfg["text_model"] and "token_type_ids" in tok:
            keys.append("token_type_ids")
        with torch.inference_mode():
            emb = self._model.caption_encoder({k: tok[k] for k in keys})
        return l2_normalize(emb.numpy())

    # ------------------------------------------------------------------ audio
    def _prepare(self, audio: np.ndarray, sample_rate: int) -> np.ndarray:
        from tabletop.audio import resample

        if isinstance(sample_rate, bool) or int(sample_rate) != sample_rate or sample_rate <= 0:
            raise ConfigError(f"sample_rate must be a positive integer [Hz], got {sample_rate!r}")
        x = np.asarray(audio, dtype=np.float32)
        if x.ndim != 1 or len(x) == 0:
            raise ConfigError(f"audio must be a non-empty mono array (S,), got shape {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ConfigError("audio contains NaN or inf")
        if sample_rate != self.sample_rate:
            x = resample(x, int(sample_rate), self.sample_rate)
        n = round(self.duration_s * self.sample_rate)
        if len(x) < n:  # msclap repeats short audio to fill its window
            x = np.tile(x, -(-n // len(x)))[:n]
        elif len(x) > n:  # msclap crops at random; take the centre (deterministic)
            s = (len(x) - n) // 2
            x = x[s : s + n]
        return x

    def encode_audio_batch(self, segments: list[np.ndarray], sample_rate: int) -> np.ndarray:
        """(N, dim) float32 L2-normalised embeddings of mono segments at ``sample_rate`` [Hz]."""
        import torch

        if not len(segments):
            return np.zeros((0, self.dim), np.float32)
        x = torch.from_numpy(np.stack([self._prepare(s, sample_rate) for s in segments]))
        with torch.inference_mode():
            emb, _ = self._model.audio_encoder(x)
        return l2_normalize(emb.numpy())

    def encode_audio(
        self, audio: np.ndarray, sample_rate: int, context: dict | None = None
    ) -> np.ndarray:
        """(dim,) float32 L2-normalised embedding of ``audio`` (S,) at ``sample_rate`` [Hz]."""
        return self.encode_audio_batch([audio], sample_rate)[0]

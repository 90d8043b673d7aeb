"""The msclap CLAP backend, end to end on randomly initialised weights of the real architecture
(HTSAT audio encoder, projection heads; a one-layer GPT-2 with a tiny vocabulary as the text
model), saved to a temporary checkpoint. Checks loading, preprocessing, shapes, normalisation,
batching and the space check; the semantics of real weights are not (cannot be) checked here."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torchlibrosa", reason="the CLAP backend needs the 'clap' extra")
pytest.importorskip("transformers", reason="the CLAP backend needs the 'clap' extra")
if __import__("importlib").util.find_spec("msclap") is None:
    pytest.skip("msclap is not installed (the 'clap' extra)", allow_module_level=True)

import torch

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import (
    AudioEncoder,
    EncoderMismatchError,
    TextEncoder,
    check_same_space,
)
from tabletop.mapping.encoders.clap import (
    MSClapEncoder,
    build_msclap_model,
    msclap_config,
)

WORDS = "the sound of a dog barking cat meowing alarm clock ringing bell".split()


def _tiny_gpt2_dir(path):
    """A local 'gpt2' directory: a word-level tokenizer with '!' as id 0 (GPT-2's pad trick)
    and a one-layer GPT-2 with the real hidden size (768)."""
    from tokenizers import Tokenizer, models, pre_tokenizers
    from transformers import GPT2Config, GPT2Model, PreTrainedTokenizerFast

    vocab = {"!": 0, "<|endoftext|>": 1, "[UNK]": 2}
    for w in WORDS:
        vocab.setdefault(w, len(vocab))
    tok = Tokenizer(models.WordLevel(vocab, unk_token="[UNK]"))
    tok.pre_tokenizer = pre_tokenizers.WhitespaceSplit()
    fast = PreTrainedTokenizerFast(
        tokenizer_object=tok, eos_token="<|endoftext|>", unk_token="[UNK]"
    )
    fast.save_pretrained(path)
    torch.manual_seed(0)
    cfg = GPT2Config(
        vocab_size=len(vocab),
        n_positions=128,
        n_embd=768,
        n_layer=1,
        n_head=2,
        bos_token_id=1,
        eos_token_id=1,
    )
    GPT2Model(cfg).save_pretrained(path)
    return path


@pytest.fixture(scope="module")
def clap_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("clap")
    text_dir = _tiny_gpt2_dir(root / "gpt2")
    torch.manual_seed(0)
    model, _ = build_msclap_model("2023", text_dir)
    ckpt = root / "CLAP_weights_2023.pth"
    torch.save({"model": {f"module.{k}": v for k, v in model.state_dict().items()}}, ckpt)
    return ckpt, text_dir


@pytest.fixture(scope="module")
def clap(clap_files):
    ckpt, text_dir = clap_files
    return MSClapEncoder(ckpt, text_dir, version="2023")


def test_config_is_msclaps_own():
    cfg = msclap_config("2023")
    assert cfg["audioenc_name"] == "HTSAT"
    assert cfg["d_proj"] == 1024
    with pytest.raises(ConfigError, match="one of"):
        msclap_config("2021")


def test_protocols_and_space(clap):
    assert isinstance(clap, AudioEncoder)
    assert isinstance(clap, TextEncoder)
    assert clap.space == "msclap-2023"
    assert clap.dim == 1024
    check_same_space(clap, clap)


def test_text_embeddings(clap):
    e = clap.encode_text(["the sound of a dog barking", "a cat meowing", "bell"])
    assert e.shape == (3, 1024)
    assert e.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-5)
    assert not np.allclose(e[0], e[1])
    np.testing.assert_allclose(clap.encode_text(["a cat meowing"])[0], e[1], atol=1e-5)
    assert clap.encode_text([]).shape == (0, 1024)


def test_audio_embeddings_and_batching(clap):
    rng = np.random.default_rng(0)
    a = (0.1 * rng.standard_normal(16000)).astype(np.float32)
    b = np.sin(2 * np.pi * 440 * np.arange(8000) / 16000).astype(np.float32) * 0.3
    ea = clap.encode_audio(a, 16000)
    assert ea.shape == (1024,)
    assert ea.dtype == np.float32
    assert abs(np.linalg.norm(ea) - 1.0) < 1e-5
    both = clap.encode_audio_batch([a, b], 16000)
    assert both.shape == (2, 1024)
    np.testing.assert_allclose(both[0], ea, atol=1e-4)
    assert not np.allclose(both[0], both[1], atol=1e-3)
    # a segment longer than the model's window (7 s) is cropped, at 44.1 kHz no resampling
    long = (0.05 * rng.standard_normal(8 * 44100)).astype(np.float32)
    assert clap.encode_audio(long, 44100).shape == (1024,)


def test_bad_audio_is_refused(clap):
    with pytest.raises(ConfigError, match="mono"):
        clap.encode_audio(np.zeros((2, 100), np.float32), 16000)
    with pytest.raises(ConfigError, match="sample_rate"):
        clap.encode_audio(np.zeros(100, np.float32), 0)


def test_clap_cannot_pair_with_minilm(clap):
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    with pytest.raises(EncoderMismatchError, match="msclap-2023"):
        check_same_space(clap, MiniLMTextEncoder())


def test_missing_files_are_clear(clap_files, tmp_path):
    ckpt, text_dir = clap_files
    with pytest.raises(AssetError, match="CLAP checkpoint not found"):
        MSClapEncoder(tmp_path / "nope.pth", text_dir)
    with pytest.raises(ConfigError, match="local directory"):
        MSClapEncoder(ckpt, "gpt2")


def test_foreign_checkpoint_is_refused(clap_files, tmp_path):
    _, text_dir = clap_files
    bad = tmp_path / "bad.pth"
    torch.save({"model": {"something.weight": torch.zeros(3)}}, bad)
    with pytest.raises(AssetError, match="does not fit"):
        MSClapEncoder(bad, text_dir)
    pickled = tmp_path / "pickled.pth"
    torch.save({"model": {"a": torch.zeros(1)}, "args": object.__new__(_Opaque)}, pickled)
    with pytest.raises(AssetError, match="trust_checkpoint"):
        MSClapEncoder(pickled, text_dir)


class _Opaque:
    pass

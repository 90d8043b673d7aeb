"""The default audio encoder: frozen YAMNet, pooled, and the committed head into MiniLM's
space; the head file's round trip and the errors that name what is wrong."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import AudioEncoder, check_same_space
from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
from tabletop.mapping.encoders.yamnet import YAMNET_CLASSES, yamnet_class_names
from tabletop.mapping.encoders.yamnet_audio import (
    DEFAULT_HEAD_WEIGHTS,
    POOLED_DIM,
    HeadWeights,
    YamnetAudioEncoder,
    load_head,
    pool_patches,
    save_head,
)
from tabletop.mapping.sound_vocabulary import SoundMatcher
from tabletop.sim.sound_bank import SoundBank


@pytest.fixture(scope="module")
def encoder():
    return YamnetAudioEncoder()


def _tone(f_hz: float, seconds: float, rate: int = 16000) -> np.ndarray:
    t = np.arange(round(seconds * rate)) / rate
    return (0.3 * np.sin(2 * np.pi * f_hz * t)).astype(np.float32)


def test_committed_head_is_small_and_records_its_training():
    assert DEFAULT_HEAD_WEIGHTS.is_file() and DEFAULT_HEAD_WEIGHTS.stat().st_size < 5_000_000
    meta = load_head(DEFAULT_HEAD_WEIGHTS).meta
    assert {"vocabulary", "train_config", "heldout", "backbone"} <= set(meta)
    assert (DEFAULT_HEAD_WEIGHTS.parent / "AUDIO_LICENSES.md").is_file()


def test_protocol_space_shapes_and_determinism(encoder):
    assert isinstance(encoder, AudioEncoder)
    check_same_space(encoder, MiniLMTextEncoder())
    x = np.random.default_rng(0).normal(0, 0.05, 24000).astype(np.float32)
    e = encoder.encode_audio(x, 16000)
    assert e.shape == (384,) and e.dtype == np.float32
    assert abs(float(np.linalg.norm(e)) - 1) < 1e-5
    np.testing.assert_array_equal(e, encoder.encode_audio(x.copy(), 16000))
    batch = encoder.encode_audio_batch([x, x[:3000]], 16000)
    assert batch.shape == (2, 384)
    np.testing.assert_allclose(batch[0], e, atol=1e-6)
    assert encoder.encode_audio_batch([], 16000).shape == (0, 384)


def test_bank_sounds_land_on_their_category(encoder):
    """Mechanism check on training clips (quality is measured on held-out clips by
    ``tabletop check-encoders``): each clip's own category is among its top 3."""
    bank = SoundBank.default()
    matcher = SoundMatcher(encoder.vocabulary, MiniLMTextEncoder(), words={})
    cats = encoder.vocabulary.categories
    for category in ("dog", "cow", "crying_baby"):
        clip = max(bank.clips(category, split="train"), key=lambda c: len(c.load()))
        post = matcher.posteriors(encoder.encode_audio(clip.load(), bank.sample_rate)[None])[0]
        top3 = [cats[i] for i in np.argsort(-post)[:3]]
        assert category in top3, (category, top3)


def test_class_scores_hear_a_beep(encoder):
    s = encoder.class_scores(_tone(1000, 1.5), 16000)
    assert s.shape == (YAMNET_CLASSES,) and 0 <= s.min() and s.max() <= 1
    assert yamnet_class_names()[int(np.argmax(s))] in ("Beep, bleep", "Sine wave")


def _head(hidden=4, seed=0) -> HeadWeights:
    r = np.random.default_rng(seed)
    return HeadWeights(
        mean=r.normal(size=POOLED_DIM),
        std=r.uniform(0.5, 2, POOLED_DIM),
        w1=r.normal(size=(POOLED_DIM, hidden)),
        b1=r.normal(size=hidden),
        w2=r.normal(size=(hidden, 384)),
        b2=r.normal(size=384),
        meta={"note": "test"},
    )


def test_head_round_trip(tmp_path):
    head = _head()
    path = save_head(tmp_path / "h.npz", head)
    back = load_head(path)
    assert back.meta["note"] == "test" and back.meta["format"] == "tabletop-yamnet-head"
    for k in ("mean", "std", "w1", "b1", "w2", "b2"):
        np.testing.assert_allclose(getattr(back, k), getattr(head, k), rtol=1e-3, atol=1e-3)
    x = np.random.default_rng(1).uniform(0, 1, (3, POOLED_DIM)).astype(np.float32)
    np.testing.assert_allclose(back(x), head(x), atol=2e-2)
    assert np.allclose(np.linalg.norm(back(x), axis=1), 1, atol=1e-5)
    assert not back.w1.flags.writeable


def test_head_errors_name_the_problem(tmp_path):
    with pytest.raises(AssetError, match="tabletop train audio"):
        YamnetAudioEncoder(tmp_path / "missing.npz")
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, a=np.zeros(3))
    with pytest.raises(AssetError, match="cannot read"):
        load_head(foreign)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"\0" * 64)
    with pytest.raises(AssetError, match="cannot read"):
        load_head(garbage)
    path = save_head(tmp_path / "h.npz", _head())
    with np.load(path) as z:
        blob = dict(z)
    meta = json.loads(blob["meta"].tobytes())
    blob["meta"] = np.frombuffer(json.dumps({**meta, "version": 99}).encode(), np.uint8)
    np.savez(tmp_path / "v99.npz", **blob)
    with pytest.raises(AssetError, match="version 99"):
        load_head(tmp_path / "v99.npz")
    blob["meta"] = np.frombuffer(json.dumps({**meta, "format": "other"}).encode(), np.uint8)
    np.savez(tmp_path / "other.npz", **blob)
    with pytest.raises(AssetError, match="not a tabletop YAMNet head"):
        load_head(tmp_path / "other.npz")
    with pytest.raises(AssetError, match="w2 has shape"):
        dataclasses.replace(_head(), w2=np.zeros((4, 100)))
    with pytest.raises(AssetError, match="NaN"):
        dataclasses.replace(_head(), b2=np.full(384, np.nan))
    with pytest.raises(ConfigError, match="patch embeddings"):
        pool_patches(np.zeros((0, 1024)))

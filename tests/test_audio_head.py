"""Training the YAMNet head: augmentation, the head fit, the validation split and a tiny run."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tabletop.audio import background_noise
from tabletop.errors import ConfigError
from tabletop.mapping.encoders.yamnet_audio import YamnetAudioEncoder, load_head
from tabletop.sim.sound_bank import SoundBank
from tabletop.train.audio_head import (
    HeadTrainConfig,
    augmented_segment,
    fit_head,
    sum_heads,
    train_audio_head,
    validation_bank,
)


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("copies", 0, "copies"),
        ("segment_s", (2.0, 1.0), "segment_s"),
        ("reverb_fraction", 1.5, "reverb_fraction"),
        ("lr", 0.0, "lr"),
    ],
)
def test_config_errors_name_the_field(field, value, words):
    with pytest.raises(ConfigError, match=words):
        HeadTrainConfig(**{field: value})


def test_augmented_segment_is_seeded_and_in_range():
    rate = 16000
    clip = np.sin(np.arange(rate) * 0.05).astype(np.float32) * 0.5
    other = np.random.default_rng(9).normal(0, 0.2, rate).astype(np.float32)
    noise = background_noise(10 * rate, rate, np.random.default_rng(0))
    cfg = HeadTrainConfig(reverb_fraction=0.9, overlap_fraction=0.9)
    a = augmented_segment(clip, rate, np.random.default_rng(1), cfg, noise, other)
    b = augmented_segment(clip, rate, np.random.default_rng(1), cfg, noise, other)
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.float32 and np.abs(a).max() <= 1.0
    assert cfg.segment_s[0] * rate <= len(a) <= cfg.segment_s[1] * rate + 1
    c = augmented_segment(clip, rate, np.random.default_rng(2), cfg, noise, other)
    assert len(c) != len(a) or not np.array_equal(c, a)


def test_fit_head_learns_separable_classes_and_is_seeded():
    r = np.random.default_rng(0)
    centres = r.uniform(0, 3, (3, 2048))
    labels = np.repeat(np.arange(3), 40)
    feats = (centres[labels] + r.normal(0, 0.3, (120, 2048))).astype(np.float32)
    proto = np.linalg.qr(r.normal(size=(384, 3)))[0].T.astype(np.float32)  # (3, 384)
    cfg = HeadTrainConfig(epochs=8, hidden=16, batch_size=40)
    head, scale = fit_head(feats, labels, proto, cfg)
    assert np.mean(np.argmax(head(feats) @ proto.T, axis=1) == labels) == 1.0
    assert 1.0 < scale <= 100.0
    again, _ = fit_head(feats, labels, proto, cfg)
    np.testing.assert_array_equal(head.w1, again.w1)
    # two members summed: one head whose output is the normalised sum of theirs
    other, _ = fit_head(feats, labels, proto, dataclasses.replace(cfg, seed=1))
    both = sum_heads([head, other])
    assert both.w1.shape == (2048, 32)

    def raw(h, x):
        return np.maximum((x - h.mean) / h.std @ h.w1 + h.b1, 0) @ h.w2 + h.b2

    want = raw(head, feats[:5]) + raw(other, feats[:5])
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    np.testing.assert_allclose(both(feats[:5]), want, atol=1e-4)
    with pytest.raises(ConfigError, match="standardisation"):
        sum_heads([head, dataclasses.replace(other, mean=other.mean + 1)])


def test_validation_split_comes_from_training_clips_only():
    base = SoundBank.default()
    val = validation_bank(base)
    held = {c.id for c in base.clips(split="heldout")}
    assert not held & {c.id for c in val}
    vclips = val.clips(split="heldout")
    assert vclips and all(len(val.clips(c.category, split="train")) >= 2 for c in vclips)


def test_tiny_training_run_writes_a_head_the_encoder_loads(tmp_path):
    base = SoundBank.default()
    clips = [c for k in ("dog", "cow") for c in base.clips(k, split="train")[:3]]
    bank = SoundBank(clips, sample_rate=base.sample_rate, name="tiny")
    cfg = HeadTrainConfig(
        out=tmp_path / "head.npz", copies=2, epochs=2, hidden=16, members=2, open_scorer=False
    )
    path = train_audio_head(cfg, bank, evaluate=False)
    meta = load_head(path).meta
    assert meta["n_train_clips"] == 6 and meta["train_config"]["copies"] == 2
    assert load_head(path).w1.shape == (2048, 32)  # two members of 16 hidden units
    enc = YamnetAudioEncoder(path)
    assert enc.vocabulary.categories == ("cow", "dog")
    assert enc.encode_audio(clips[0].load(), bank.sample_rate).shape == (384,)


def test_a_tiny_tuned_tail_run_gives_a_head_that_reads_its_embeddings(tmp_path):
    from tabletop.mapping.encoders.yamnet import load_tail
    from tabletop.train.audio_tail import TailTrainConfig, train_tail

    base = SoundBank.default()
    clips = [c for k in ("dog", "cow") for c in base.clips(k, split="train")[:3]]
    bank = SoundBank(clips, sample_rate=base.sample_rate, name="tiny")
    tail = tmp_path / "tail.npz"
    cfg = TailTrainConfig(copies=2, epochs=1, batch_segments=4, n_threads=1)
    info = train_tail(bank, tail, cfg)
    assert info["segments"] == 12 and info["patches"] >= 12
    train_tail(bank, tmp_path / "again.npz", cfg)
    a, b = load_tail(tail), load_tail(tmp_path / "again.npz")
    assert all(np.array_equal(a[k], b[k]) for k in a)  # seeded
    head = HeadTrainConfig(
        out=tmp_path / "head.npz", copies=2, epochs=1, hidden=8, members=1, open_scorer=False,
        tail=tail,
    )  # fmt: skip
    path = train_audio_head(head, bank, evaluate=False)
    assert load_head(path).meta["tail"] == "tail.npz"  # beside the head, relative
    enc = YamnetAudioEncoder(path)
    assert enc.backbone.tail == tail.resolve()
    from tabletop.mapping.encoders.yamnet import YamnetBackbone

    frozen = YamnetAudioEncoder(path, backbone=YamnetBackbone())
    x = clips[0].load()
    assert not np.allclose(
        enc.backbone_output(x, bank.sample_rate).embeddings,
        frozen.backbone_output(x, bank.sample_rate).embeddings,
    )

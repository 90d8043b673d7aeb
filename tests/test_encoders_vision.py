"""The embedded default image encoder: the committed weights, their held-out quality, training."""

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import DenseImageEncoder, GlobalImageEncoder
from tabletop.mapping.encoders.lseg import VISION_WEIGHTS_PATH, LSegEncoder
from tabletop.train.vision import (
    HELDOUT_COMBOS,
    SYNONYMS,
    VisionTrainConfig,
    evaluate_vision,
    render_dataset,
    train_vision,
    vision_classes,
)


@pytest.fixture(scope="module")
def encoder():
    return LSegEncoder()


@pytest.fixture(scope="module")
def image():
    rgbs, labels = render_dataset([9_000_123], views=1, heldout=False, seed=0, lit=False)
    return rgbs[0], labels[0]


def test_committed_weights_are_small_and_load(encoder):
    assert VISION_WEIGHTS_PATH.stat().st_size < 5e6
    assert isinstance(encoder, DenseImageEncoder) and isinstance(encoder, GlobalImageEncoder)
    assert encoder.space == "minilm-l6-v2" and encoder.dim == 384 and encoder.stride == 4
    # the checkpoint carries the held-out figures it was trained to
    assert 0 < encoder.metrics["vision_top1_heldout"] <= 1


def test_shapes_normalisation_and_one_pass(encoder, image):
    rgb, _ = image
    d = encoder.encode_dense(rgb)
    assert d.shape == (60, 80, 384) and d.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-4)
    g = encoder.encode_image(rgb)
    assert g.shape == (384,) and abs(np.linalg.norm(g) - 1) < 1e-5
    d2, g2 = encoder.encode_dense_and_global(rgb)
    np.testing.assert_allclose(d2, d, atol=1e-6)
    np.testing.assert_allclose(g2, g, atol=1e-6)
    # the features depend on the image
    assert not np.allclose(encoder.encode_dense(rgb[::-1].copy()), d)


def test_bad_input_is_refused(encoder):
    with pytest.raises(ConfigError, match="uint8"):
        encoder.encode_dense(np.zeros((240, 320, 3), np.float32))
    with pytest.raises(ConfigError, match="divisible"):
        encoder.encode_dense(np.zeros((241, 320, 3), np.uint8))
    with pytest.raises(ConfigError, match="uint8"):
        encoder.encode_image(np.zeros((240, 320), np.uint8))


def test_missing_or_foreign_weights_are_clear(tmp_path):
    with pytest.raises(AssetError, match="not found"):
        LSegEncoder(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"version https://git-lfs.github.com/spec/v1\n")
    with pytest.raises(AssetError, match="unreadable"):
        LSegEncoder(bad)


def test_pixels_split_into_table_background_and_objects(encoder, image):
    """On a held-out layout the committed weights tell the table, the background and the
    objects apart (which object: the held-out figures below)."""
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    rgb, lab = image
    classes = vision_classes()
    T = MiniLMTextEncoder().encode_text([c["name"] for c in classes])
    pred = (encoder.encode_dense(rgb) @ T.T).argmax(-1)
    small = lab[2::4, 2::4]  # the label at each cell's centre
    idx = {c["name"]: i for i, c in enumerate(classes)}
    stuff = [idx["table"], idx["robot"], idx["other"]]
    for name in ("table", "other"):
        m = small == idx[name]
        assert m.sum() > 100 and np.mean(pred[m] == idx[name]) > 0.9, name
    obj = ~np.isin(small, stuff)
    assert obj.sum() > 50
    assert np.mean(~np.isin(pred[obj], stuff)) > 0.8


def test_heldout_quality_on_a_small_sample():
    """CI's check of the committed weights (the full figures: `tabletop check-encoders`)."""
    r = evaluate_vision(layouts=2, views=3)
    assert r["vision_eval_images"] == 6
    assert r["vision_top1_heldout"] > 0.6
    assert r["vision_kind_top1_heldout"] > 0.6
    assert r["vision_synonym_pixel_top1"] > 0.4
    for k, v in r.items():
        if k.startswith("vision_") and isinstance(v, float):
            assert 0.0 <= v <= 1.0, k


def test_heldout_texts_are_never_training_texts():
    from tabletop.sim.catalog import OBJECT_KINDS

    names = {c["name"] for c in vision_classes()} | {k.label for k in OBJECT_KINDS.values()}
    for syns in SYNONYMS.values():
        for s in syns:
            assert s not in names, s  # "cube" may be part of "toy cube", never a label
    for kind, colour in HELDOUT_COMBOS:
        assert any(c["kind"] == kind and c["color"] == colour for c in vision_classes())


def test_training_is_seeded_and_config_checked(tmp_path):
    cfg = dict(train_layouts=1, views_per_layout=2, steps=2, batch_size=2, eval_layouts=1,
               eval_views=1, width=8)  # fmt: skip
    a = train_vision(VisionTrainConfig(out=tmp_path / "a.pt", **cfg))
    b = train_vision(VisionTrainConfig(out=tmp_path / "b.pt", **cfg))
    import torch

    sa = torch.load(a, weights_only=True)["state_dict"]
    sb = torch.load(b, weights_only=True)["state_dict"]
    assert sa.keys() == sb.keys()
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    with pytest.raises(ConfigError, match="steps"):
        VisionTrainConfig(steps=0)
    with pytest.raises(ConfigError, match="multiples of 16"):
        VisionTrainConfig(crop=(250, 192))

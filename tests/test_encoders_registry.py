"""Encoder sets by name: the oracle and the embedded default build maps through one code path."""

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.eval.harness import build_map
from tabletop.mapping import AVLMap
from tabletop.mapping.encoders.base import (
    AudioEncoder,
    DenseImageEncoder,
    GlobalImageEncoder,
    check_same_space,
)
from tabletop.mapping.encoders.registry import ENCODER_SETS, make_encoders


@pytest.fixture(scope="module")
def rec():
    """The session's cached scan of the default scene (``helpers.fast_scan``, shared with the
    other files of its family in tests/conftest.py)."""
    from helpers import fast_scan

    return fast_scan()[0]


def test_unknown_set_names_the_valid_ones():
    with pytest.raises(ConfigError, match="valid") as e:
        make_encoders("clip-large")
    for name in ENCODER_SETS:
        assert name in str(e.value)


def test_oracle_needs_ground_truth():
    with pytest.raises(ConfigError, match="ground truth"):
        make_encoders("oracle", recording=None)


def test_default_set_is_one_space_and_never_the_oracle():
    enc = make_encoders("default")
    assert isinstance(enc.dense, DenseImageEncoder)
    assert isinstance(enc.global_image, GlobalImageEncoder)
    assert isinstance(enc.audio, AudioEncoder)
    for e in (enc.dense, enc.global_image, enc.audio):
        check_same_space(enc.text, e)
    assert "oracle" not in " ".join(enc.names.values())
    assert "default" in enc.names["set"]
    # the committed weights are recorded as "the committed ones", not as this machine's path
    assert enc.rebuild == {"vision_weights": None, "audio_weights": None, "audio_encoder": "yamnet"}
    assert type(enc.audio).__name__ == "YamnetAudioEncoder"


def test_default_audio_encoder_is_chosen_by_name():
    from tabletop.mapping.encoders.registry import AUDIO_ENCODERS, make_encoders_from_rebuild

    old = make_encoders("default", options={"audio_encoder": "melcnn"})
    assert type(old.audio).__name__ == "MelCNNAudioEncoder"
    assert old.rebuild["audio_encoder"] == "melcnn"
    # a map saved before the YAMNet head recorded no audio encoder: it heard with the CNN
    legacy = make_encoders_from_rebuild("default", {"vision_weights": None, "audio_weights": None})
    assert type(legacy.audio).__name__ == "MelCNNAudioEncoder"
    with pytest.raises(ConfigError, match="valid") as e:
        make_encoders("default", options={"audio_encoder": "vggish"})
    assert all(k in str(e.value) for k in AUDIO_ENCODERS)


def test_missing_weights_are_named(tmp_path):
    with pytest.raises(AssetError, match="not found"):
        make_encoders("default", options={"vision_weights": str(tmp_path / "nope.pt")})


@pytest.mark.slow  # a whole default map of a 500-frame scan (34 s): scripts/test -m slow
def test_default_map_builds_saves_and_loads(rec, tmp_path):
    m = build_map(rec, "default")
    assert m.encoder_set == "default"
    assert m.stats.voxels > 1000
    # the learned encoder, not the segmentation, decides: the duck's heat peaks on the duck
    duck = next(o for o in rec.ground_truth["objects"] if o["kind"] == "duck")
    p = m.get_max_pos_3d(m.object_heatmap(duck["label"]))
    lo, hi = np.array(duck["aabb_min"]), np.array(duck["aabb_max"])
    assert np.linalg.norm(np.maximum(lo - p, 0) + np.maximum(p - hi, 0)) < 0.10
    path = m.save(tmp_path / "map.npz")
    m2 = AVLMap.load(path)
    assert m2.encoder_set == "default" and m2.encoder_names == m.encoder_names
    np.testing.assert_array_equal(
        m2.object_heatmap(duck["label"]).values, m.object_heatmap(duck["label"]).values
    )


def test_the_oracle_gives_the_fused_pixels_features_as_its_whole_image_does(rec):
    enc = make_encoders("oracle", recording=rec)
    frame = rec.frame(len(rec) // 2)
    context = {"segmentation": frame.segmentation}
    whole = enc.dense.encode_dense(frame.rgb, context)
    h, w = frame.rgb.shape[:2]
    rng = np.random.default_rng(0)
    px = np.stack([rng.integers(0, h, 500), rng.integers(0, w, 500)], axis=1)
    px = np.concatenate([px, [[h - 1, w - 1], [0, 0], [h - 1, 0]]])
    s = enc.dense.stride
    expect = whole[
        np.minimum(px[:, 0] // s, whole.shape[0] - 1), np.minimum(px[:, 1] // s, whole.shape[1] - 1)
    ]
    table, row = enc.dense.encode_dense_at(frame.rgb, context, px)
    np.testing.assert_array_equal(table[row], expect)
    assert (np.abs(expect).sum(axis=1) > 0).any()  # some pixels see a labelled thing

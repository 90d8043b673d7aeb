"""The shape prior: features of an instance's voxels, the logistic regression, its file, and
the object module using it."""

import dataclasses
import json

import numpy as np
import pytest

from tabletop.errors import AssetError
from tabletop.mapping.shape import (
    FEATURES,
    SHAPE_PRIOR_PATH,
    ShapePrior,
    fit_shape_prior,
    shape_features,
)

VS = 0.01


def _voxels(inside, size=0.08, z0=0.0) -> np.ndarray:
    """Centres of the VS-voxels of a size x size x size block where ``inside(x, y, z)``."""
    ax = np.arange(VS / 2, size, VS)
    g = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    keep = np.array([inside(*p) for p in g])
    return g[keep] + [0.3, 0.0, z0]


def cube(size=0.06):
    return _voxels(lambda x, y, z: x < size and y < size and z < size)


def prism(size=0.06):  # a triangular prism lying on a face: its top is a ridge along y
    return _voxels(lambda x, y, z: y < size and z < size - 2 * abs(x - size / 2))


def _yaw(c, a):
    r = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    m = c.mean(axis=0)
    return (c - m) @ r.T + m


def test_features_tell_a_flat_top_from_a_ridge_and_ignore_yaw():
    fc, fp = shape_features(cube(), VS, 0.0), shape_features(prism(), VS, 0.0)
    assert fc.shape == (len(FEATURES),)
    flat = FEATURES.index("top_flat_share")
    assert fc[flat] > 0.9 and fp[flat] < 0.4
    assert fc[FEATURES.index("log_height")] == pytest.approx(np.log(0.06), abs=0.05)
    turned = shape_features(_yaw(cube(), 0.6), VS, 0.0)
    for name in ("log_height", "minor_over_major", "top_flat_share", "mean_top_over_height"):
        k = FEATURES.index(name)
        assert turned[k] == pytest.approx(fc[k], abs=0.1), name
    # Heights are measured from the table, wherever it is.
    raised = shape_features(cube() + np.array([0, 0, 0.75]), VS, 0.75)
    np.testing.assert_allclose(raised, fc, atol=1e-9)
    with pytest.raises(ValueError, match="without voxels"):
        shape_features(np.zeros((0, 3)), VS, 0.0)


def _training_set(rng):
    xs, ys = [], []
    for _ in range(12):
        a = rng.uniform(0, np.pi)
        s = rng.uniform(0.05, 0.07)
        xs += [shape_features(_yaw(cube(s), a), VS, 0.0), shape_features(_yaw(prism(s), a), VS, 0)]
        ys += ["toy cube", "toy prism"]
    return np.array(xs), ys


def test_a_fitted_prior_separates_shapes_and_survives_its_file(tmp_path):
    x, y = _training_set(np.random.default_rng(0))
    prior = fit_shape_prior(x, y)
    assert prior.kinds == ("toy cube", "toy prism")
    test = np.array([shape_features(cube(0.065), VS, 0), shape_features(prism(0.055), VS, 0)])
    p = prior.probabilities(test)
    assert p[0, 0] > 0.9 and p[1, 1] > 0.9
    # Names it was not trained on get the uniform share, in the order asked.
    named = prior.for_names(test, ("toy prism", "giraffe", "toy cube"))
    np.testing.assert_allclose(named[:, 0], p[:, 1])
    np.testing.assert_allclose(named[:, 1], 0.5)
    path = tmp_path / "shape.json"
    prior.save(path)
    again = ShapePrior.load(path)
    np.testing.assert_allclose(again.probabilities(test), p)


def test_a_bad_prior_file_is_refused_by_name(tmp_path):
    path = tmp_path / "shape.json"
    with pytest.raises(AssetError, match="tabletop train shape"):
        ShapePrior.load(path)  # missing
    x, y = _training_set(np.random.default_rng(1))
    good = fit_shape_prior(x, y).to_dict()
    for bad in (
        {**good, "features": ["log_height"]},  # another version's features
        {**good, "std": [0.0] * len(FEATURES)},
        {**good, "weights": good["weights"][:-1]},
        {k: v for k, v in good.items() if k != "kinds"},
    ):
        path.write_text(json.dumps(bad))
        with pytest.raises(AssetError, match="shape prior"):
            ShapePrior.load(path)


def test_the_committed_prior_loads_and_knows_the_catalogue():
    from tabletop.sim.catalog import OBJECT_KINDS

    prior = ShapePrior.load(SHAPE_PRIOR_PATH)
    assert set(prior.kinds) == {k.label for k in OBJECT_KINDS.values()}
    assert prior.meta["shape_only_val_top1"] > 0.5  # on scenes it was not fitted on
    assert prior.meta["fused_val_top1"] >= prior.meta["image_only_val_top1"]


def test_the_object_module_lets_geometry_decide_what_pixels_cannot():
    from module_helpers import GRID, box_points, text_encoder

    from tabletop.mapping.object_module import ObjectConfig, ObjectModule
    from tabletop.mapping.table_regions import fit_table
    from tabletop.mapping.voxel_map import VoxelMap

    # One object shaped like a cube.
    text = text_encoder()
    table = box_points((0.0, -0.3, 0.0), (0.6, 0.3, 0.01), 0.01)
    obj = cube() + np.array([0, 0, 0.01])
    vm = VoxelMap(GRID, text.dim)
    pts = np.concatenate([table, obj])
    which = np.r_[np.zeros(len(table), np.int64), np.ones(len(obj), np.int64)]
    e = text.encode_text(["table", "toy prism", "toy cube"])
    looks = 0.55 * e[1] + 0.45 * e[2]  # pixels that lean to "prism", as a blue cube's did
    feats = np.stack([e[0], looks / np.linalg.norm(looks)])
    vm.integrate(pts, feats, np.full((len(pts), 3), 120, np.uint8), feature_index=which)
    x, y = _training_set(np.random.default_rng(2))
    prior = fit_shape_prior(x, y)
    vocab = ("toy cube", "toy prism", "mug")

    def module(shape):
        m = ObjectModule(
            vm, text, ObjectConfig(shape=shape), vocab, table=lambda: fit_table(GRID, vm.indices)
        )
        m._shape_prior = prior  # the committed file is tested above; this one is known
        return m

    (inst,) = module(False).instances.items
    plain = module(False).kind_probabilities([inst])[0]
    shaped = module(True).kind_probabilities([inst])[0]
    assert plain[1] > 0.5 > plain[0]  # the pixels alone: a prism
    assert shaped[0] > 0.5 > shaped[1]  # with its shape: a cube
    assert shaped.sum() == pytest.approx(1.0)
    # A prior trained on maps of another resolution does not judge this one.
    prior = dataclasses.replace(prior, voxel_size=0.005)
    np.testing.assert_allclose(module(True).kind_probabilities([inst])[0], plain)


def _scenes(rng, n, lean):
    """Scenes of a cube and a prism each, with image cosines leaning ``lean`` the wrong way."""
    out = []
    for _ in range(n):
        a = rng.uniform(0, np.pi)
        x = np.array(
            [shape_features(_yaw(cube(), a), VS, 0), shape_features(_yaw(prism(), a), VS, 0)]
        )
        cos = np.array([[0.45, 0.45 + lean], [0.45 + lean, 0.45]]) + rng.normal(0, 0.002, (2, 2))
        out.append({"x": x, "y": ["toy cube", "toy prism"], "cos": cos,
                    "vocabulary": ["toy cube", "toy prism"]})  # fmt: skip
    return out


def test_training_weighs_the_shape_against_the_image_and_records_both(tmp_path):
    from tabletop.train.shape import fit_from_scenes

    rng = np.random.default_rng(3)
    # The image encoder is slightly wrong on every instance: the shape must outweigh it.
    path = fit_from_scenes(_scenes(rng, 4, 0.02), _scenes(rng, 2, 0.02), 0.02, tmp_path / "s.json")
    prior = ShapePrior.load(path)
    meta = prior.meta
    assert meta["image_only_val_top1"] == 0.0 and meta["fused_val_top1"] == 1.0
    assert prior.weight == meta["weight"] > 0 and meta["val_instances"] == 4
    with pytest.raises(Exception, match="2 training scenes"):
        fit_from_scenes(_scenes(rng, 1, 0.02), _scenes(rng, 1, 0.02), 0.02, tmp_path / "t.json")


def test_train_shape_takes_its_own_flags_only(tmp_path, capsys):
    from tabletop.cli import main

    for flags in (["--steps", "5"], ["--device", "cuda"], ["--backbone", "small"]):
        assert main(["train", "shape", *flags]) != 0
        assert "not for shape" in capsys.readouterr().err
    other = tmp_path / "notes.json"
    other.write_text('{"a": 1}')
    assert main(["train", "shape", "--out", str(other)]) != 0
    assert "not a shape prior" in capsys.readouterr().err
    assert other.read_text() == '{"a": 1}'

"""The kind reader: its fit, its file, the committed reader, and how the object module uses it."""

import json

import numpy as np
import pytest
from module_helpers import GRID, judge_at, text_encoder

from tabletop.errors import AssetError
from tabletop.mapping.kind_reader import (
    OTHER,
    REFUSAL_FEATURES,
    KindReader,
    RefusalHead,
    fit_kind_reader,
    fit_refusal_head,
)


def _blobs(rng, n=30):
    centres = {"mug": [1, 0, 0, 0], "duck": [0, 1, 0, 0], OTHER: [0, 0, 1, 0]}
    x, y = [], []
    for label, c in centres.items():
        pts = np.asarray(c, float) + 0.2 * rng.standard_normal((n, 4))
        x.append(pts / np.linalg.norm(pts, axis=1, keepdims=True))
        y += [label] * n
    return np.vstack(x), y


def test_a_fit_reads_its_classes_is_deterministic_and_round_trips(tmp_path):
    x, y = _blobs(np.random.default_rng(0))
    a = fit_kind_reader(x, y, "space-a")
    b = fit_kind_reader(x, y, "space-a")
    assert np.array_equal(a.weights, b.weights) and a.classes == ("duck", "mug", OTHER)
    assert a.read(np.array([0.0, 1.0, 0.0, 0.0]))[0] == "duck"
    assert a.read(np.array([0.0, 0.0, 1.0, 0.0]))[0] == OTHER
    p = a.probabilities(x)
    assert p.shape == (len(x), 3) and np.allclose(p.sum(axis=1), 1.0)
    path = tmp_path / "reader.json"
    a.save(path)
    c = KindReader.load(path)
    assert c.classes == a.classes and c.space == "space-a"
    assert np.allclose(c.probabilities(x), p, atol=1e-4)
    assert a.covers(("mug",)) and not a.covers(("mug", "tray")) and not a.covers(())
    with pytest.raises(ValueError, match="dimension 3"):
        a.probabilities(np.zeros((1, 3)))
    with pytest.raises(ValueError, match=OTHER):
        fit_kind_reader(x[:60], y[:60], "space-a")


def test_a_broken_reader_file_says_how_to_make_one(tmp_path):
    bad = tmp_path / "r.json"
    for text in ("not json", '{"format": "something else", "version": 1}', "[1, 2]"):
        bad.write_text(text)
        with pytest.raises(AssetError, match="tabletop train kind-reader"):
            KindReader.load(bad)
    with pytest.raises(AssetError, match="tabletop train kind-reader"):
        KindReader.load(tmp_path / "missing.json")


def test_the_committed_reader_reads_the_labels_and_refuses_other_things():
    from tabletop.eval.paraphrase import HELDOUT_POOLS, TUNE_POOLS
    from tabletop.mapping.encoders.minilm import MINILM_SPACE
    from tabletop.sim.catalog import OBJECT_KINDS

    reader = KindReader.load()
    labels = [k.label for k in OBJECT_KINDS.values()]
    assert reader.space == MINILM_SPACE and reader.covers(labels)
    # trained on tune pools only: no held-out pool's phrasing taught it anything
    assert set(reader.meta["pools"]) <= set(TUNE_POOLS)
    assert not set(reader.meta["pools"]) & set(HELDOUT_POOLS)
    enc = text_encoder()
    for label in labels:
        assert reader.read(enc.encode_text([f"the {label}"])[0])[0] == label
    for thing in ("the laptop", "the giraffe", "the banana", "the car keys"):
        assert reader.read(enc.encode_text([thing])[0])[0] == OTHER, thing
    # its leave-one-pool-out figures are in its file, and no better than possible
    mean = reader.meta["leave_one_pool_out_mean"]
    assert 0.5 < mean["read_as_kind"] <= 1.0 and mean["absent_read_as_kind"] < 0.2


@pytest.fixture(scope="module")
def scenes():
    from module_helpers import coloured_voxels
    from test_object_module import DESCRIPTIONS, SCENE, VOCAB

    from tabletop.mapping.object_module import ObjectConfig, ObjectModule
    from tabletop.mapping.table_regions import fit_table

    vm = coloured_voxels(SCENE)

    def module(**kw):
        return ObjectModule(
            vm,
            text_encoder(),
            ObjectConfig(**kw),
            VOCAB,
            DESCRIPTIONS,
            lambda: fit_table(GRID, vm.indices),
        )

    return module(), module(reader=False)


def test_the_reader_finds_what_the_cosine_refused(scenes):
    ours, plain = scenes
    # no description of the duck here: its cosine is too low, the reader knows the word
    assert not plain.heatmap("the bath buddy", 10.0, judge_at(0.2)).found
    m = ours.match("the bath buddy")
    assert m.read == "duck" and m.read_p >= ours.config.reader_min and m.names == ("duck",)
    assert ours.heatmap("the bath buddy", 10.0, judge_at(0.2)).found
    # a landmark the parser hands over without its article is read the same way
    bare = ours.match("bath buddy")
    assert (bare.read, bare.read_p, bare.names) == (m.read, m.read_p, m.names)
    # what the reader reads as none of the kinds stays refused, with the cosine's reason
    laptop = ours.heatmap("the laptop", 10.0, judge_at(0.2))
    assert ours.match("the laptop").read == OTHER
    assert not laptop.found and "like nothing" in laptop.reason and laptop.peak == 0.0


def test_the_reader_ranks_first_the_name_it_reads_among_several(scenes):
    ours, _ = scenes
    from tabletop.mapping.object_module import ObjectConfig

    # "the footy ball" may be the soccer ball or the ball by its cosine, which ranks the ball
    # first; the reader reads the soccer ball, and "the bouncy ball" the ball: that name's
    # instances come first
    for words, meant, other in (
        ("the footy ball", "soccer ball", "ball"),
        ("the kickable ball", "soccer ball", "ball"),
        ("the bouncy ball", "ball", "soccer ball"),
    ):
        m = ours.match(words)
        assert set(m.names) == {"soccer ball", "ball"}, words
        assert m.read == meant and m.read_p >= ours.config.reader_prefer
        assert m.name_weights[meant] == 1.0 and m.name_weights[other] < 0.2, m.name_weights
    # both stay what the words may mean, and without the preference the cosine alone ranks
    off = type(ours)(ours.voxels, ours.text, ObjectConfig(reader_prefer=1.0), ours.vocabulary)
    for words in ("the footy ball", "the kickable ball"):
        w = off.match(words).name_weights
        assert w["ball"] == 1.0 and w["soccer ball"] < 1.0, (words, w)


def test_where_the_cosines_names_fit_nothing_the_readers_name_is_tried(scenes):
    from test_object_module import DESCRIPTIONS, VOCAB

    from tabletop.mapping.object_module import ObjectConfig
    from tabletop.mapping.table_regions import fit_table

    ours, _ = scenes

    def reading(name, p, **config):
        # a reader that reads every text as ``name`` with probability ``p``
        classes = (*VOCAB, OTHER)
        z = np.full(len(classes), np.log((1 - p) / (len(classes) - 1)))
        z[classes.index(name)] = np.log(p)
        reader = KindReader(classes, ours.text.space, np.zeros((ours.text.dim, len(classes))), z)
        vm = ours.voxels
        module = type(ours)(
            vm,
            ours.text,
            ObjectConfig(**config),
            VOCAB,
            DESCRIPTIONS,
            lambda: fit_table(GRID, vm.indices),
        )
        module._reader = reader
        return module

    # no teddy bear on this table; a reader sure the words mean the duck finds the yellow duck
    # (the fallback, with the reader not overruling the cosine's names; at its default it
    # would: then the words mean the duck from the start)
    assert reading("duck", 0.95).match("the yellow teddy bear").names == ("duck",)
    sure = reading("duck", 0.95, reader_overrule=1.1)
    m = sure.match("the yellow teddy bear")
    assert m.names == ("teddy bear",) and m.read == "duck"
    h = sure.heatmap("the yellow teddy bear", 10.0, judge_at(0.2))
    assert h.found and h.peak > 0.5
    # not below the threshold, nor where it is switched off
    for module in (
        reading("duck", 0.85),
        reading("duck", 0.95, reader_fallback=1.1, reader_overrule=1.1),
    ):
        assert not module.heatmap("the yellow teddy bear", 10.0, judge_at(0.2)).found
    # the reader's name must fit too: no green duck is no green teddy bear either
    assert not sure.heatmap("the green teddy bear", 10.0, judge_at(0.2)).found


def test_a_reader_of_another_space_or_vocabulary_is_not_used():
    from module_helpers import coloured_voxels
    from test_object_module import SCENE

    from tabletop.mapping.object_module import ObjectConfig, ObjectModule

    vm = coloured_voxels(SCENE)
    other_vocab = ObjectModule(vm, text_encoder(), ObjectConfig(), ("mug", "sofa"))
    assert other_vocab.kind_reader() is None and other_vocab.match("the mug").read == ""

    class Renamed:
        space = "another-space"

        def encode_text(self, texts):
            return text_encoder().encode_text(texts)

    assert ObjectModule(vm, Renamed(), ObjectConfig(), ("mug",)).kind_reader() is None


def test_a_refusal_head_learns_which_words_name_nothing_and_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    n = 400
    none = rng.random(n) < 0.3
    # words of no kind: a lower cosine, the reader reading no kind
    text = np.where(none, rng.normal(0.45, 0.08, n), rng.normal(0.65, 0.08, n))
    read_other = np.where(none, rng.uniform(0.6, 1.0, n), rng.uniform(0.0, 0.3, n))
    x = np.column_stack(
        [text, rng.normal(0.4, 0.05, n), np.zeros(n), read_other, 1 - read_other, np.ones(n)]
    )
    head = fit_refusal_head(x, none)
    f = [dict(zip(REFUSAL_FEATURES, row, strict=True)) for row in x]
    refused = np.array([head.refuses(v) for v in f])
    assert (refused == none).mean() > 0.95
    assert head.accept_at == pytest.approx(min(1.0, np.quantile(text[none], 0.99) + 0.05))
    assert head.refuse_below == pytest.approx(np.quantile(text[~none], 0.001))
    # a cosine below refuse_below is refused, unless the reader is sure of a kind
    far = {**f[int(np.argmin(none))], "text_score": head.refuse_below - 0.01, "read_kind": 0.5}
    assert head.logit(far) < 0 and head.refuses(far)
    assert not head.refuses({**far, "read_kind": 0.9})
    again = fit_refusal_head(x, none)  # deterministic
    np.testing.assert_array_equal(again.weights, head.weights)
    # a cosine at accept_at is never refused, whatever the reader says
    sure = {**f[int(np.argmax(none))], "text_score": head.accept_at}
    assert head.logit(sure) > 0 and not head.refuses(sure)
    back = RefusalHead.from_dict(json.loads(json.dumps(head.to_dict())))
    np.testing.assert_allclose(back.weights, head.weights, atol=1e-6)
    with pytest.raises(AssetError, match="must weigh"):
        RefusalHead.from_dict({"features": ["text_score"], "weights": [1.0]})
    with pytest.raises(AssetError, match="finite weights"):
        RefusalHead([1.0, np.nan, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="words of a kind and words of none"):
        fit_refusal_head(x[~none], none[~none])
    # a reader file with a broken head says so
    reader = KindReader.load()
    d = reader.to_dict()
    d["refusal"]["weights"] = [1.0]
    bad = tmp_path / "reader.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(AssetError, match="cannot read the kind reader"):
        KindReader.load(bad)


def test_the_committed_refusal_head_refuses_fewer_names_and_lets_fewer_absent_things_through():
    """Its leave-one-pool-out figures (the head fitted without a pool, on that pool's words
    read by a reader fitted without it) against the fixed rules on the same readings."""
    reader = KindReader.load()
    assert reader.refusal is not None and 0.5 < reader.refusal.accept_at <= 1.0
    assert 0.0 < reader.refusal.refuse_below < 0.4
    fig = reader.meta["refusal_leave_one_pool_out"]
    assert fig["texts"] > 1000
    assert fig["head"]["names_refused"] < fig["rules"]["names_refused"]
    assert fig["head"]["absent_accepted"] < fig["rules"]["absent_accepted"]


def test_the_head_refuses_a_thing_of_no_kind_the_cosine_lets_through():
    from test_object_module import _shipped_kinds_module

    toys = {
        "toy cube": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.07), (200, 30, 30)),
        "toy cylinder": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07), (30, 30, 200)),
    }
    mod, _ = _shipped_kinds_module(toys, ("toy cube", "toy cylinder", "toy prism", "mug"))
    q = "the toy ambulance"  # "toy" carries the cosine past text_min; the reader reads no kind
    m = mod.match(q)
    assert m.text_score >= mod.config.text_min and m.read == OTHER
    h = mod.heatmap(q, 10.0, judge_at(0.2))
    assert not h.found and "names nothing" in h.reason, h.reason
    rules = KindReader.load()
    rules.refusal = None  # the fixed rules alone let it through
    mod.set_kind_reader(rules)
    assert mod.heatmap(q, 10.0, judge_at(0.2)).found
    # names people use still find their kind with the head
    mod.set_kind_reader(KindReader.load())
    for name in ("the block shaped like a dice", "the short tube toy", "the little barrel"):
        assert mod.heatmap(name, 10.0, judge_at(0.2)).found, name


@pytest.mark.slow  # leave-one-pool-out refits on 25 pools: over two minutes of CPU
def test_training_reproduces_the_committed_reader(tmp_path, monkeypatch):
    from tabletop.eval import paraphrase
    from tabletop.eval.harness import map_config
    from tabletop.eval.kind_texts import reader_texts
    from tabletop.eval.paraphrase import TUNE_POOLS
    from tabletop.train.kind_reader import train_kind_reader

    with monkeypatch.context() as m:  # a held-out pool is never training text
        m.setattr(paraphrase, "HELDOUT_POOLS", (TUNE_POOLS[-1],))
        with pytest.raises(ValueError, match="held-out"):
            reader_texts(TUNE_POOLS)
    shipped = KindReader.load()
    rows = reader_texts(TUNE_POOLS)
    config = map_config()
    out = train_kind_reader(
        tmp_path / "reader.json",
        rows,
        cross_validate=False,
        vocabulary=config.objects,
        descriptions=config.descriptions,
    )
    ours = KindReader.load(out)
    # the refusal head too (fitted on readings by readers fitted without each pool)
    np.testing.assert_allclose(ours.refusal.weights, shipped.refusal.weights, atol=1e-3)
    assert ours.refusal.accept_at == pytest.approx(shipped.refusal.accept_at, abs=1e-3)
    assert ours.classes == shipped.classes and ours.meta["pools"] == shipped.meta["pools"]
    assert ours.meta["texts"] == shipped.meta["texts"]
    enc = text_encoder()
    x = enc.encode_text(["the coffee cup", "the plush bear", "the laptop", "the round block"])
    assert np.abs(ours.probabilities(x) - shipped.probabilities(x)).max() < 0.02


def test_train_kind_reader_takes_its_own_flags_and_replaces_only_a_reader(tmp_path, capsys):
    from tabletop.cli import main

    for flags in (["--steps", "5"], ["--backbone", "small"]):
        assert main(["train", "kind-reader", *flags]) != 0
        assert "not for kind-reader" in capsys.readouterr().err
    notes = tmp_path / "notes.json"
    notes.write_text(json.dumps({"a": 1}))
    assert main(["train", "kind-reader", "--out", str(notes)]) != 0
    assert "not a kind reader" in capsys.readouterr().err and notes.read_text() == '{"a": 1}'


def test_a_sure_reading_of_a_name_the_cosine_does_not_give_overrules_it():
    from tabletop.eval.harness import map_config
    from tabletop.grid import VoxelGrid
    from tabletop.mapping.object_module import ObjectConfig, ObjectModule
    from tabletop.mapping.voxel_map import VoxelMap

    config, text = map_config(), text_encoder()

    def module(**kw):
        m = ObjectModule(
            VoxelMap(VoxelGrid(), text.dim),
            text,
            ObjectConfig(**kw),
            config.objects,
            config.descriptions,
        )
        classes = (*config.objects, OTHER)
        bias = np.where(np.array(classes) == "toy cylinder", 8.0, 0.0)  # reads every words so
        m.set_kind_reader(KindReader(classes, "minilm-l6-v2", np.zeros((text.dim, 13)), bias))
        return m

    sure = module().match("the mug")
    assert sure.read == "toy cylinder" and sure.read_p >= 0.9
    assert sure.names == ("toy cylinder",) and sure.name_weights == {"toy cylinder": 1.0}
    # below the reader's operating point the cosine's name stays, the reader's is not added
    assert module(reader_overrule=1.01).match("the mug").names == ("mug",)
    # a reading that is one of the cosine's names only ranks it first (reader_prefer)
    assert module().match("the toy cylinder").names[0] == "toy cylinder"

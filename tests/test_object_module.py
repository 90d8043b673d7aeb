"""The object module on a synthetic map: the right box, the background, the margin."""

import numpy as np
import pytest
from module_helpers import GRID, judge_at, labelled_voxels, text_encoder

from tabletop.errors import ConfigError
from tabletop.mapping.object_module import ObjectConfig, ObjectModule
from tabletop.mapping.targets import max_position

BOXES = {
    "red mug": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.10)),
    "yellow duck": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07)),
}


@pytest.fixture(scope="module")
def module():
    return ObjectModule(labelled_voxels(BOXES), text_encoder())


def test_a_query_lands_on_its_box_and_heat_decays_from_it(module):
    h = module.heatmap("yellow duck", 10.0, judge_at(0.1))
    assert h.found and h.modality == "object" and h.peak == pytest.approx(1.0)
    p = max_position(h, module.voxels.occupancy())
    lo, hi = BOXES["yellow duck"]
    assert np.all(p >= np.subtract(lo, 0.01)) and np.all(p <= np.add(hi, 0.01))
    # heat is 0 beyond 1/decay = 10 cm from the box
    far = GRID.world_to_index(np.array([[0.13, -0.17, 0.05]]))[0][0]
    assert h.values[tuple(far)] == 0.0


def test_the_background_and_the_calibration_can_refuse(module):
    h = module.heatmap("table", 10.0, judge_at(0.1))  # a background concept is no object
    assert not h.found and h.reason and h.peak == 0.0
    strict = module.heatmap("yellow duck", 10.0, judge_at(5.0))
    assert not strict.found and "weak" in strict.reason and strict.evidence > 0


def test_features_follow_the_voxels():
    vm = labelled_voxels({"red mug": BOXES["red mug"]})
    m = ObjectModule(vm, text_encoder())
    n = len(m.features())
    vm.integrate(np.array([[0.5, 0.2, 0.15]]), np.zeros((1, vm.dim), np.float32))
    assert len(m.features()) == n + 1  # the cache was refreshed


def test_config_is_checked():
    with pytest.raises(ConfigError, match="select_margin"):
        ObjectConfig(select_margin=2.0)
    with pytest.raises(ConfigError, match="background"):
        ObjectConfig(background=())


# ---------------------------------------------------------------------- instances

VOCAB = ("mug", "duck", "teddy bear", "tray", "soccer ball", "ball")
DESCRIPTIONS = {"mug": ("a ceramic cup with a handle", "a cup for hot drinks like coffee or tea")}
RED, BLUE, YELLOW = (200, 30, 25), (30, 60, 180), (220, 190, 30)
SCENE = {
    "red mug": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.10), RED),
    "blue mug": ((0.30, -0.20, 0.01), (0.36, -0.14, 0.10), BLUE),
    "yellow duck": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07), YELLOW),
}


def _module_of(boxes, descriptions=None) -> ObjectModule:
    """An object module of a map of coloured boxes (``label -> (lo, hi, rgb)``)."""
    from module_helpers import coloured_voxels

    from tabletop.mapping.table_regions import fit_table

    vm = coloured_voxels(boxes)
    return ObjectModule(
        vm,
        text_encoder(),
        ObjectConfig(),
        VOCAB,
        descriptions or {},
        lambda: fit_table(GRID, vm.indices),
    )


@pytest.fixture(scope="module")
def scene():
    return _module_of(SCENE, DESCRIPTIONS)


def _lands_on(module, h, name, boxes=SCENE):
    p = max_position(h, module.voxels.occupancy())
    lo, hi, _ = boxes[name]
    return bool(
        np.all(p[:2] >= np.subtract(lo[:2], 0.01)) and np.all(p[:2] <= np.add(hi[:2], 0.01))
    )


def test_colour_words_pick_the_instance_by_its_measured_colour(scene):
    for q, name in (
        ("the red mug", "red mug"),
        ("a blue mug", "blue mug"),
        ("scarlet mug", "red mug"),
    ):
        h = scene.heatmap(q, 10.0, judge_at(0.2))
        assert h.found and _lands_on(scene, h, name), (q, h.reason)


def test_a_paraphrase_finds_its_object_through_the_descriptions(scene):
    h = scene.heatmap("the coffee cup", 10.0, judge_at(0.2))
    assert h.found and h.evidence > 0.2
    m = scene.match("the coffee cup")
    assert m.names == ("mug",) and m.text_score > 0.6


def test_both_mugs_stay_hot_for_the_mug(scene):
    h = scene.heatmap("the mug", 10.0, judge_at(0.2))
    hot = {n for n in SCENE if _box_peak(scene, h, n) == pytest.approx(1.0)}
    assert hot == {"red mug", "blue mug"}


def _box_peak(module, h, name):
    lo, hi, _ = SCENE[name]
    idx, _ = GRID.world_to_index(np.array([np.add(lo, hi) / 2]))
    return float(h.values[tuple(idx[0])])


def test_absent_things_are_not_found_with_a_reason(scene):
    out = scene.heatmap("the giraffe", 10.0, judge_at(0.2))
    assert not out.found and "vocabulary" in out.reason and out.peak == 0.0
    colour = scene.heatmap("the purple mug", 10.0, judge_at(0.2))
    assert not colour.found and "purple" in colour.reason
    kind = scene.heatmap("the teddy bear", 10.0, judge_at(0.2))  # known, not in this map
    assert not kind.found and "teddy bear" in kind.reason


def test_a_thing_outside_the_vocabulary_is_refused_by_rank_not_by_a_high_bar(scene):
    from tabletop.eval.harness import catalog_descriptions
    from tabletop.mapping.table_regions import fit_table

    vm = scene.voxels
    desc = {k.replace("_", " "): v for k, v in catalog_descriptions().items()}
    desc = {k: v for k, v in desc.items() if k in VOCAB}

    def module(config):
        return ObjectModule(
            vm, scene.text, config, VOCAB, desc, lambda: fit_table(GRID, vm.indices)
        )

    ours, plain = module(ObjectConfig()), module(ObjectConfig(others=(), reader=False))
    # "wine bottle" reads near "a drinking vessel" (the mug's description), nearer a bottle
    assert ours.match("wine bottle").text_score >= ObjectConfig().text_min
    bottle = ours.heatmap("wine bottle", 10.0, judge_at(0.2))
    assert not bottle.found and "reads as 'wine bottle'" in bottle.reason and bottle.peak == 0.0
    # without the other things (nor the kind reader) the same query reaches the mugs
    assert plain.heatmap("water bottle", 10.0, judge_at(0.2)).found
    # looser words for a mug than its label are still found
    cup = ours.heatmap("the thing you drink tea from", 10.0, judge_at(0.2))
    assert cup.found and (_lands_on(ours, cup, "red mug") or _lands_on(ours, cup, "blue mug"))


def test_no_catalog_description_reads_as_one_of_the_other_things():
    from tabletop.eval.harness import catalog_descriptions
    from tabletop.sim.catalog import OBJECT_KINDS

    text = text_encoder()
    others = text.encode_text(list(ObjectConfig().others))
    for kind, texts in catalog_descriptions().items():
        label = OBJECT_KINDS[kind].label
        for t, e in zip((label, *texts), text.encode_text([label, *texts]), strict=True):
            # none of the other things is another word for a catalog kind
            assert float((others @ e).max()) < 0.75, (kind, t)


def test_a_shorter_name_may_mean_a_longer_one(scene):
    m = scene.match("the ball")
    assert set(m.names) == {"ball", "soccer ball"}


def test_the_best_matching_name_ranks_first_among_those_the_words_may_mean():
    """ "the small rubber ball" may mean the soccer ball too (its head noun is part of the
    name), but the ball matches its words better: the ball is where the robot goes, and both
    stay hot only when the words fit both alike."""
    balls = {
        "soccer ball": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.07), (230, 230, 230)),
        "ball": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07), (30, 60, 180)),
    }
    mod = _module_of(balls)
    m = mod.match("the small rubber ball")
    assert set(m.names) == {"ball", "soccer ball"} and m.nearest == "ball"
    assert m.scores.min() > 0.9  # both are what the words may mean: the evidence is alike
    h = mod.heatmap("the small rubber ball", 10.0, judge_at(0.2))
    assert _lands_on(mod, h, "ball", balls)
    lo, hi, _ = balls["soccer ball"]
    idx, _ = GRID.world_to_index(np.array([np.add(lo, hi) / 2]))
    assert h.values[tuple(idx[0])] < 1.0  # the soccer ball is not hot


def test_instances_off_scores_voxels(scene):
    off = ObjectModule(scene.voxels, text_encoder(), ObjectConfig(instances=False), VOCAB)
    assert not off.uses_instances
    h = off.heatmap("yellow duck", 10.0, judge_at(0.1))
    assert h.found and _lands_on(off, h, "yellow duck")


def test_instance_config_is_checked():
    with pytest.raises(ConfigError, match="text_min"):
        ObjectConfig(text_min=1.5)
    with pytest.raises(ConfigError, match="temperature"):
        ObjectConfig(temperature=0.0)
    with pytest.raises(ConfigError, match="segmentation"):
        ObjectConfig(segmentation=3)


def _instance(rgb, palette=(), share=()):
    from tabletop.mapping.colors import rgb_to_lab
    from tabletop.mapping.instances import ObjectInstance

    z = np.zeros(3)
    pal = rgb_to_lab(np.array(palette, float)) if palette else np.zeros((0, 3))
    return ObjectInstance(
        0, np.arange(1), z, z, z, np.array(rgb, float), rgb_to_lab(np.array(rgb, float)),
        np.zeros(384, np.float32), 1, pal, np.array(share, float),
    )  # fmt: skip


def test_a_shaded_colour_keeps_its_name_and_a_neighbouring_term_does_not_take_it(scene):
    fits = {}
    for q in ("yellow", "green", "orange", "white", "grey"):
        w = scene.colour_weights(q)
        fits[q] = scene.colour_match(w, [_instance((201, 179, 32)), _instance((190, 190, 190))])
    # A yellow mug as the wrist camera sees it: darker and duller than "yellow", still yellow.
    assert fits["yellow"][0] > 0.8 > 0.3 > max(fits["green"][0], fits["orange"][0])
    # Light grey and shaded white are the same pixels: both names fit, no chromatic one does.
    assert min(fits["white"][1], fits["grey"][1]) > 0.6 and fits["yellow"][1] < 0.3


def test_colour_names_people_use_mean_their_basic_colour(scene):
    from tabletop.reader.lexicon.colour_names import BASIC_COLOURS, COLOR_NAMES

    def family(phrase):
        w = scene.colour_weights(phrase)
        per = np.zeros(len(BASIC_COLOURS))
        for wi, v in zip(w, COLOR_NAMES.values(), strict=True):
            per[BASIC_COLOURS.index(v[1])] += wi
        return BASIC_COLOURS[int(np.argmax(per))]

    # names the text encoder alone places elsewhere ("cerulean" nearest "olive")
    for phrase, want in (
        ("cerulean", "blue"),
        ("viridian", "green"),
        ("mauve", "purple"),
        ("onyx", "black"),
        ("slate", "grey"),
        ("vermilion", "red"),
    ):
        assert family(phrase) == want, phrase
    # a compound is a shade of its last word, whatever the first is nearest on its own
    assert family("rose") == "pink" and family("rose red") == "red"
    assert family("teal") == "blue" and family("teal green") == "green"
    # even where a word of the compound names a colour of another family of its own
    # ("navy" a blue, "lemon" a yellow): "navy-flag red" had been read as a blue
    assert family("navy") == "blue" and family("navy-flag red") == "red"
    assert family("lemon") == "yellow" and family("lemon-peel green") == "green"
    # so is a survey name of a basic term after a word that names no colour, though the
    # lexicon name nearest the survey's colour lies in another family
    for phrase, want in (
        ("pale red", "red"),  # nearest "brown"
        ("pure blue", "blue"),  # nearest a purple
        ("pale yellow", "yellow"),  # nearest a green
        ("deep orange", "orange"),  # nearest a brown
    ):
        assert family(phrase) == want, phrase
    # two colour words: the survey's colour decides ("rust red" is a brown)
    assert family("rust red") == "brown"
    # a pale tint is of its hue's family, though its lightness lies far from every name
    for phrase, want in (("butter", "yellow"), ("straw", "yellow"), ("wine", "red")):
        assert family(phrase) == want, phrase
    blue_mug, green_mug = _instance((20, 60, 170)), _instance((30, 140, 40))
    fit = scene.colour_match(scene.colour_weights("cerulean"), [blue_mug, green_mug])
    assert fit[0] > 0.5 > 0.2 > fit[1]


def test_a_two_coloured_object_fits_either_of_its_colours_but_no_other(scene):
    # A domino: black faces, white edges; its mean colour is a grey neither of them is.
    domino = _instance((100, 100, 100), [(25, 25, 25), (225, 225, 225)], [0.7, 0.3])
    plain_grey = _instance((100, 100, 100))
    for q in ("black", "white"):
        w = scene.colour_weights(q)
        fit, plain = scene.colour_match(w, [domino, plain_grey])
        assert fit > 0.8 and fit > plain + 0.3, q
    assert scene.colour_match(scene.colour_weights("red"), [domino])[0] < 0.1


def test_two_basic_colours_ask_for_a_thing_of_both_not_a_shade_of_the_last(scene):
    from tabletop.reader.lexicon.colour_words import two_colours

    assert two_colours("red blue") == ("red", "blue")
    assert two_colours("black white") == ("black", "white")
    # shades, a repeat and one term are no two colours
    assert two_colours("blue green") == two_colours("red red") == two_colours("red") == ()
    # a red mug and a blue mug, none of both colours: no "red blue mug" is on the table, and
    # the reason names the colours asked for
    for q in ("the red blue mug", "the mug that is red and blue"):
        h = scene.heatmap(q, 10.0, judge_at(0.2))
        assert not h.found and "red blue" in h.reason, (q, h.reason)
    # a thing of both colours fits; either plain one does not
    both = _instance((140, 40, 110), [(200, 20, 20), (20, 40, 200)], [0.5, 0.5])
    m = scene.match("the red blue mug")
    assert m.colour == "red blue"
    fits = np.min(
        [scene.colour_match(scene.colour_weights(c), [both, _instance((200, 20, 20))], True)
         for c in ("red", "blue")], axis=0,
    )  # fmt: skip
    assert fits[0] > 0.6 > 0.2 > fits[1]


def test_a_superlative_ranks_the_things_the_rest_of_the_words_find(scene):
    # the red mug stands nearer the robot's base than the blue one; the duck is the smallest
    # and lowest thing, the mugs the tallest
    for q, name in (
        ("the nearest mug", "red mug"),
        ("the farthest mug", "blue mug"),
        ("the mug furthest away", "blue mug"),
        ("the smallest thing", "yellow duck"),
        ("the lowest one", "yellow duck"),
    ):
        h = scene.heatmap(q, 10.0, judge_at(0.2))
        names = [n for n in SCENE if n.endswith(name)]
        assert h.found and any(_lands_on(scene, h, n) for n in names), (q, h.reason)
        assert sum(_box_peak(scene, h, n) == pytest.approx(1.0) for n in SCENE) == 1, q
    # two equal mugs are the tallest alike: neither is picked
    h = scene.heatmap("the tallest object", 10.0, judge_at(0.2))
    assert not h.found and "'tallest' picks none of the 3 things" in h.reason, h.reason
    # seen from elsewhere (a mobile base's place), the nearest is another
    h = scene.heatmap("the nearest mug", 10.0, judge_at(0.2), viewpoint=(0.6, -0.17))
    assert _lands_on(scene, h, "blue mug")
    with pytest.raises(ConfigError, match="a viewpoint is finite"):
        scene.heatmap("the nearest mug", 10.0, judge_at(0.2), viewpoint="here")
    # no superlative where the words relate two things
    from tabletop.reader.lexicon.words import superlative

    assert superlative("the closest to the duck") is None
    assert superlative("the left-most ball").measure == "left"


def test_a_framed_colour_word_no_survey_has_means_the_colour_the_longer_list_gives_it():
    from tabletop.reader.lexicon.colour_words import colour_word, named_colour

    # "quince" and "byzantium": in the longer list of names only; "bear" there too, but no
    # query's word is made a colour by that list
    assert not colour_word("quince") and named_colour("quince") is not None
    assert not colour_word("byzantium") and named_colour("byzantium") is not None
    balls = {
        "red ball": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.07), (200, 30, 30)),
        "yellow ball": ((0.30, -0.20, 0.01), (0.36, -0.14, 0.07), (230, 200, 40)),
        "purple ball": ((0.30, 0.10, 0.01), (0.36, 0.16, 0.07), (110, 40, 140)),
    }
    m = _module_of(balls, DESCRIPTIONS)
    for q, name in (
        ("the quince-coloured ball", "yellow ball"),
        ("the byzantium-colouredish ball", "purple ball"),  # a frame word's "-ish" form
    ):
        h = m.heatmap(q, 10.0, judge_at(0.2))
        assert h.found and _lands_on(m, h, name, balls), (q, h.reason)


def test_the_colour_of_a_part_need_not_cover_much_of_the_thing(scene):
    # A football: white panels and black patches covering a quarter of it.
    ball = _instance((190, 190, 190), [(240, 240, 240), (25, 25, 25)], [0.75, 0.25])
    w = scene.colour_weights("black")
    whole = scene.colour_match(w, [ball])[0]  # "the black ball": not really
    part = scene.colour_match(w, [ball], of_part=True)[0]  # "the ball with black patches"
    assert part > 0.9 and part > whole + 0.2
    assert scene.colour_match(scene.colour_weights("red"), [ball], of_part=True)[0] < 0.1
    m = scene.match("the ball with black patches")
    assert m.colour == "black"


def test_of_two_objects_a_colour_fits_the_nearer_one_is_meant():
    # A grey teddy bear and a white one in shadow: "grey" fits both (light grey is a grey),
    # but the grey one is what a person means, and "white" means the other.
    bears = {
        "grey teddy bear": ((0.10, 0.10, 0.01), (0.17, 0.17, 0.12), (120, 120, 120)),
        "white teddy bear": ((0.35, -0.2, 0.01), (0.42, -0.13, 0.12), (200, 200, 200)),
    }
    m = _module_of(bears)
    for q, name in (("the grey teddy bear", "grey teddy bear"), ("the white teddy bear",
                                                                  "white teddy bear")):  # fmt: skip
        h = m.heatmap(q, 10.0, judge_at(0.2))
        assert h.found and _lands_on(m, h, name, bears), q
        other = next(n for n in bears if n != name)
        olo, ohi, _ = bears[other]
        idx, _ = GRID.world_to_index(np.array([np.add(olo, ohi) / 2]))
        assert h.values[tuple(idx[0])] < 1.0, (q, "the other bear stays hot")
    # Without a colour, both bears are the teddy bear.
    both = m.heatmap("the teddy bear", 10.0, judge_at(0.2))
    for lo, hi, _ in bears.values():
        idx, _ = GRID.world_to_index(np.array([np.add(lo, hi) / 2]))
        assert both.values[tuple(idx[0])] == pytest.approx(1.0)


def test_a_colour_name_far_from_every_object_still_means_the_one_of_its_colour():
    # "electric blue" is a pale cyan in the lexicon: the blue mug lies farther from it than the
    # green one does, but only the blue one fits the phrase, and nearness ranks among those.
    mugs = {
        "mug": ((0.10, 0.10, 0.01), (0.17, 0.17, 0.10), (28, 71, 200)),
        "cup": ((0.35, -0.2, 0.01), (0.42, -0.13, 0.10), (33, 147, 45)),
    }
    m = _module_of(mugs)
    h = m.heatmap("the electric blue mug", 10.0, judge_at(0.2))
    assert h.found and _lands_on(m, h, "mug", mugs)


def test_a_survey_colour_name_the_lexicon_lacks_reads_as_its_colour(scene):
    """ "sapphire" and "cherry" are no lexicon names: the survey's colour for them picks the
    mug, and a thing of no such colour stays not found; "tea" names a drink a mug holds as
    well as a green, so "the tea mug" still finds a mug that is not green."""
    from tabletop.reader.lexicon.colour_names import COLOR_NAMES
    from tabletop.reader.lexicon.colour_words import survey_colours

    assert "sapphire" not in COLOR_NAMES and "sapphire" in survey_colours()
    for q, name in (("the sapphire mug", "blue mug"), ("the cherry mug", "red mug")):
        h = scene.heatmap(q, 10.0, judge_at(0.2))
        assert h.found and _lands_on(scene, h, name), (q, h.reason)
    absent = scene.heatmap("the cherry duck", 10.0, judge_at(0.2))  # the duck is yellow
    assert not absent.found and "cherry" in absent.reason
    assert scene.readings("the cherry duck") == [("cherry", "the duck")]
    tea = scene.readings("the tea mug")
    assert tea[0] == ("tea", "the mug") and ("", "the tea mug") in tea
    assert scene.heatmap("the tea mug", 10.0, judge_at(0.2)).found
    # but where "tea" modifies nothing, it is the drink first, and every mug stays hot
    put = scene.readings("the mug you'd put tea in")
    assert put[0] == ("", "the mug you d put tea in") and put[1][0] == "tea"


def test_other_readings_of_colour_words_are_tried_when_the_first_finds_nothing(scene):
    # "lobster red": one colour, not a lobster; "milk chocolate": a drink, the mug is blue
    h = scene.heatmap("the lobster red coffee mug", 10.0, judge_at(0.2))
    assert h.found and _lands_on(scene, h, "red mug"), h.reason
    h = scene.heatmap("the blue milk chocolate mug", 10.0, judge_at(0.2))
    assert h.found and _lands_on(scene, h, "blue mug"), h.reason
    assert not scene.heatmap("the purple milk chocolate mug", 10.0, judge_at(0.2)).found
    # a word the query frames as a colour is one, though no colour list has it
    for q, mug in [
        ("the tomato-coloured coffee mug", "red mug"),
        ("the mug, colour bluebell", "blue mug"),
        # ... and so is a colour name that modifies the thing, though the encoder calls it fruit
        ("the blueberry coffee mug", "blue mug"),
    ]:
        h = scene.heatmap(q, 10.0, judge_at(0.2))
        assert h.found and _lands_on(scene, h, mug), (q, h.reason)
    # a framed word that names a survey colour is that colour only: no leaf-green mug stands
    # here, so nothing is found (not any mug); a framed word that names no colour may be none
    assert scene.readings("the leaf-coloured mug") == [("leaf", "the mug")]
    h = scene.heatmap("the leaf-coloured mug", 10.0, judge_at(0.2))
    assert not h.found and "leaf" in h.reason, h.reason
    assert ("", "the solid colour mug") in scene.readings("the solid colour mug")


def test_a_colour_word_no_list_has_is_read_where_the_encoder_places_it_near_a_colour(scene):
    from tabletop.reader.lexicon.colour_words import colour_word

    # "bluebird" and "coal" are in neither the lexicon nor the survey
    assert not colour_word("bluebird") and not colour_word("coal")
    assert scene.readings("the bluebird mug")[0] == ("bluebird", "the mug")
    h = scene.heatmap("the bluebird mug", 10.0, judge_at(0.2))
    assert h.found and _lands_on(scene, h, "blue mug"), h.reason
    # no black mug stands here: the reading without the word follows, and finds a mug
    assert scene.readings("the coal mug") == [("coal", "the mug"), ("", "the coal mug")]
    # words the encoder places no nearer a colour than a thing, or not near one, are none
    for q in ("the big mug", "the shiny mug", "the little duck"):
        assert scene.readings(q) == [("", q)], q


def test_a_part_s_colour_does_not_refuse_the_thing(scene):
    # the duck is yellow; its beak's colour is no reason to refuse it, while a duck asked
    # for by its own colour stays not found where none has it
    for q in ("the duck with an orange beak", "the mug with a white handle"):
        assert scene.readings(q)[-1] == ("", q)
    h = scene.heatmap("the duck with an orange beak", 10.0, judge_at(0.2))
    assert h.found and _lands_on(scene, h, "yellow duck"), h.reason
    assert not scene.heatmap("the purple duck", 10.0, judge_at(0.2)).found
    # the whole's colour is still read first: the white mug with a red handle is no blue mug
    h = scene.heatmap("the blue mug with a red handle", 10.0, judge_at(0.2))
    assert h.found and _lands_on(scene, h, "blue mug"), h.reason


def test_a_thing_the_words_liken_the_object_to_is_no_other_thing(scene):
    from tabletop.reader.lexicon.object_words import without_likeness

    assert without_likeness("the tin can shaped toy") == "the toy"
    assert without_likeness("a toy shaped like a barrel") == "a toy"
    assert without_likeness("the wine bottle") == "the wine bottle"
    assert scene.heatmap("the teapot shaped cup", 10.0, judge_at(0.2)).found
    teapot = scene.heatmap("the teapot", 10.0, judge_at(0.2))
    assert not teapot.found and "reads as" in teapot.reason


def test_a_word_of_one_name_only_speaks_for_it_among_names_that_score_alike():
    from module_helpers import coloured_voxels

    from tabletop.mapping.table_regions import fit_table

    toys = {
        "lego brick": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.05), (200, 30, 30)),
        "toy cube": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07), (200, 30, 30)),
    }
    vocab = ("lego brick", "toy cube", "toy prism", "toy cylinder", "mug")
    desc = {
        "lego brick": ("a plastic building brick with studs", "a small lego piece"),
        "toy cube": ("a toy block shaped like a cube", "a box-shaped building block"),
        "toy prism": ("a toy block shaped like a triangular prism",),
        "toy cylinder": ("a toy block shaped like a cylinder",),
    }
    vm = coloured_voxels(toys)
    mod = ObjectModule(
        vm, text_encoder(), ObjectConfig(), vocab, desc, lambda: fit_table(GRID, vm.indices)
    )
    q = "the lego block with bumps on top"
    m = mod.match(q)
    assert {"lego brick", "toy cube"} <= set(m.names)  # the words fit both alike
    p = max_position(mod.heatmap(q, 10.0, judge_at(0.2)), vm.occupancy())
    lo, hi, _ = toys["lego brick"]
    assert np.all(p[:2] >= np.subtract(lo[:2], 0.01)) and np.all(p[:2] <= np.add(hi[:2], 0.01))


def test_descriptions_are_query_time_text_and_can_be_replaced(scene):
    from module_helpers import coloured_voxels

    from tabletop.mapping.table_regions import fit_table

    vm = coloured_voxels(SCENE)
    mod = ObjectModule(
        vm, text_encoder(), ObjectConfig(), VOCAB, {}, lambda: fit_table(GRID, vm.indices)
    )
    before = mod.match("the thing you sip espresso from").text_score
    mod.set_descriptions({"mug": ("a small cup you sip espresso from",)})
    assert mod.match("the thing you sip espresso from").text_score > before + 0.1
    assert mod.heatmap("the thing you sip espresso from", 10.0, judge_at(0.2)).found


def _shipped_kinds_module(toys: dict, vocab: tuple) -> tuple:
    """(module, voxels): ``toys`` (name -> (lo, hi, rgb)) as voxels, the vocabulary described
    by the shipped descriptions (the words people's names for the kinds are scored on)."""
    from module_helpers import coloured_voxels

    from tabletop.eval.harness import catalog_descriptions
    from tabletop.mapping.table_regions import fit_table

    shipped = catalog_descriptions()
    desc = {k: shipped[k.replace(" ", "_")] for k in vocab}
    vm = coloured_voxels(toys)
    mod = ObjectModule(
        vm, text_encoder(), ObjectConfig(), vocab, desc, lambda: fit_table(GRID, vm.indices)
    )
    return mod, vm


def _inside(p, box) -> bool:
    lo, hi, _ = box
    return bool(
        np.all(p[:2] >= np.subtract(lo[:2], 0.01)) and np.all(p[:2] <= np.add(hi[:2], 0.01))
    )


def test_a_word_only_one_candidate_is_described_by_ranks_it_first():
    from tabletop.reader.lexicon.object_words import word_forms

    assert {"boxy", "box", "roundish", "round", "bumps", "bump"} <= word_forms(
        "a boxy, roundish thing with bumps"
    )
    assert not word_forms("the small toy with a shape like")  # filler and tie words
    toys = {
        "toy cube": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.07), (200, 30, 30)),
        "toy cylinder": ((0.40, 0.10, 0.01), (0.46, 0.16, 0.07), (200, 30, 30)),
        "toy prism": ((0.40, -0.20, 0.01), (0.46, -0.14, 0.05), (200, 30, 30)),
    }
    mod, vm = _shipped_kinds_module(toys, ("toy cube", "toy cylinder", "toy prism", "mug"))
    # what a thing is likened to may be one name's own: "a toy like a short tube or can"
    assert mod.match("the can-shaped block").names == ("toy cylinder",)
    for q, want in [("the round block", "toy cylinder")]:
        m = mod.match(q)
        assert want in m.names and len(m.names) >= 2, (q, m.names)  # the words fit several
        p = max_position(mod.heatmap(q, 10.0, judge_at(0.2)), vm.occupancy())
        assert _inside(p, toys[want]), (q, p)
    # a head noun several names share ("toy") widens to them all, unless a word before it is
    # one name's alone ("prism"): with no prism on the table, nothing is found
    assert set(mod.match("the plastic toy").names) >= {"toy cube", "toy cylinder"}
    assert mod.match("the triangular prism toy").names == ("toy prism",)
    no_prism, _ = _shipped_kinds_module(
        {k: v for k, v in toys.items() if k != "toy prism"},
        ("toy cube", "toy cylinder", "toy prism", "mug"),
    )
    assert not no_prism.heatmap("the triangular prism toy", 10.0, judge_at(0.2)).found


def test_words_all_of_one_names_descriptions_find_it_below_the_cosine_floor():
    toys = {
        "toy cube": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.07), (200, 30, 30)),
        "toy prism": ((0.40, -0.20, 0.01), (0.46, -0.14, 0.05), (30, 30, 200)),
    }
    mod, vm = _shipped_kinds_module(toys, ("toy cube", "toy cylinder", "toy prism", "mug", "duck"))
    m = mod.match("the pointy thing")
    assert m.text_score < mod.config.text_min and m.described and m.names == ("toy prism",)
    h = mod.heatmap("the pointy thing", 10.0, judge_at(0.2))
    p = max_position(h, vm.occupancy())
    assert h.found and _inside(p, toys["toy prism"]), p
    # a word no description holds keeps the floor: not found
    hat = mod.heatmap("the pointy hat", 10.0, judge_at(0.2))
    assert not hat.found and "like nothing" in hat.reason


def test_words_all_of_one_names_descriptions_outweigh_a_cosine_that_names_another():
    from tabletop.reader.lexicon.object_words import (
        DEIXIS,
        without_deixis,
        without_likeness,
        word_forms,
    )

    assert {"dot", "angle", "knob", "stuff"} <= word_forms("dotted angled knobbly stuffie")
    assert without_likeness("the can shape") == "the"
    assert without_likeness("in the shape of a can") == ""
    assert without_likeness("the shape") == "the shape"
    assert DEIXIS.sub("", "the cup over there please").split() == ["the", "cup"]
    assert without_deixis("the cup over there please") == "the cup"
    toys = {
        "toy cylinder": ((0.10, -0.20, 0.01), (0.16, -0.14, 0.07), (200, 30, 30)),
        "toy prism": ((0.40, -0.20, 0.01), (0.46, -0.14, 0.05), (30, 30, 200)),
    }
    mod, vm = _shipped_kinds_module(toys, ("toy cube", "toy cylinder", "toy prism", "mug", "duck"))
    for q in ("the column block", "the can shape"):
        m = mod.match(q)
        # "column" is a word of the cylinder's descriptions only, whatever the cosine ranks first
        assert m.names == ("toy cylinder",), (q, m.names, m.nearest)
        p = max_position(mod.heatmap(q, 10.0, judge_at(0.2)), vm.occupancy())
        assert _inside(p, toys["toy cylinder"]), (q, p)

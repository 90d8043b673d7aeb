"""The place reader: an area's words read into an AreaRef by the grammar, the learned
classifier, or as the subject a place is named after; the map scores only the reading."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.eval.paraphrase import HELDOUT_POOLS, TUNE_POOLS
from tabletop.mapping.table_regions import AreaRef, TableRegion
from tabletop.reader.place_words import parse_region
from tabletop.reader.places import (
    DEFAULT_PLACE_WEIGHTS,
    PLACE_CLASSES,
    PlaceReader,
    load_place_classifier,
)
from tabletop.reader.reading import get_reader


def test_a_region_the_grammar_lists_is_read_by_the_grammar():
    a = PlaceReader().read("the far right corner")
    assert a.region == TableRegion("right", "far", "the far right corner") and a.how == "grammar"


# the project's own wordings, which the grammar's lists do not hold
@pytest.mark.parametrize(
    ("text", "region"),
    [
        ("the leftward zone of the table", ("left", None)),
        ("the rightward bit", ("right", None)),
        ("the bit of table that's out towards the far wall", (None, "far")),
    ],
)
def test_region_wording_no_list_holds_is_read_by_the_classifier(text, region):
    assert parse_region(text) is None  # the grammar refuses it
    a = PlaceReader().read(text)
    assert a.region is not None and (a.region.lateral, a.region.depth) == region
    assert a.how.startswith(("learned: ", "grammar, on "))  # the phrase's or its ground's
    assert PlaceReader(learned=False).read(text).region is None  # the rule reader alone


@pytest.mark.parametrize(
    "text",
    ["the kitchen", "the ceiling", "the top shelf", "the garage"],
)
def test_places_off_the_table_are_no_region(text):
    a = PlaceReader().read(text)
    assert a.region is None and a.subject  # the map looks for it as a thing, then a sound


@pytest.mark.parametrize(
    ("text", "pair"),
    [("the left right of the table", ("left", "right")), ("the near far side", ("far", "near"))],
)
def test_two_opposite_directions_are_no_region_and_the_reason_names_them(text, pair):
    # the classifier would pick one of the two: the words contradict each other, so neither
    for reader in (PlaceReader(), PlaceReader(learned=False)):
        a = reader.read(text)
        assert a.region is None and a.subject is None
        assert f"{pair[0]!r} and {pair[1]!r} are opposite directions" in a.how
    # one direction, or two that are not opposite, is a region as before
    assert PlaceReader().read("the far left").region == TableRegion("left", "far", "the far left")


@pytest.mark.parametrize(
    ("text", "depth"),
    [
        ("the half on your side", "near"),  # the robot is the one spoken to
        ("your end of the table", "near"),
        ("the bit of the table you are at", "near"),
        ("the part farthest from where you stand", "far"),
        ("the end away from where the arm is", "far"),
    ],
)
def test_the_robot_s_side_named_from_the_one_spoken_to_is_a_region(text, depth):
    a = PlaceReader(learned=False).read(text)  # the grammar, not the classifier
    assert a.region == TableRegion(None, depth, text) and a.how == "grammar", a


def test_a_place_named_after_a_thing_gives_its_subject():
    a = PlaceReader().read("the area around the tray")
    assert a == AreaRef("the area around the tray", subject="tray", how="subject")
    assert PlaceReader().read("the area over there").subject is None


def test_readers_give_the_map_a_reading_not_words():
    for name in ("rules", "rules+spelling", "rules+learned", "learned"):
        a = get_reader(name).reference("area", "the rightward bit")
        assert isinstance(a, AreaRef)
        learned = name in ("rules+learned", "learned")
        assert (a.region is not None) == learned, name
    assert get_reader().reference("obj", "the red mug") == "the red mug"
    with pytest.raises(ConfigError, match="area= must be a string, got int"):
        get_reader().reference("area", 3)


def test_the_shipped_classifier_never_saw_a_held_out_pool():
    clf = load_place_classifier(DEFAULT_PLACE_WEIGHTS)
    assert clf.classes == PLACE_CLASSES and clf.space == "minilm-l6-v2"
    assert set(clf.meta["pools"]) <= set(TUNE_POOLS)
    assert not set(clf.meta["pools"]) & set(HELDOUT_POOLS)
    lopo = clf.meta["leave_one_pool_out"][str(clf.threshold)]
    # at its threshold, pools left out of the fit: at most 0.5 % of other phrases taken for a
    # region, and some regions the grammar refuses read right
    assert lopo["other_read_as_region"] <= 0.005 * lopo["other"]
    assert lopo["grammar_refused_regions_right"] > lopo["grammar_refused_regions_wrong_region"]


def test_training_is_seeded_and_refuses_held_out_pools(tmp_path):
    from tabletop.eval.place_texts import place_texts
    from tabletop.train.places import train_places

    texts = place_texts(TUNE_POOLS[:3])
    a = train_places(texts, tmp_path / "a.json", seed=0)
    b = train_places(texts, tmp_path / "b.json", seed=0)
    np.testing.assert_array_equal(a.W, b.W)
    assert json.loads((tmp_path / "a.json").read_text())["format"] == "tabletop-place-reader"
    assert load_place_classifier(tmp_path / "a.json").threshold == a.threshold
    with pytest.raises(ConfigError, match="held-out pools .* are never trained on"):
        place_texts([TUNE_POOLS[0], HELDOUT_POOLS[0]])


def test_a_broken_weights_file_is_named(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(AssetError, match="is not a place classifier"):
        load_place_classifier(bad)
    with pytest.raises(AssetError, match="cannot read the place classifier"):
        load_place_classifier(tmp_path / "missing.json")


def test_a_region_on_a_ground_gives_the_region_and_the_ground():
    from tabletop.reader.place_words import region_on_ground

    region, ground = region_on_ground("the far left corner of the potting shed")
    assert (region.lateral, region.depth) == ("left", "far") and ground == "potting shed"
    assert region_on_ground("the desk's right-hand end")[1] == "desk"
    # the grammar's own table names and a phrase without a direction are no ground
    assert region_on_ground("the left side of the table top") is None
    assert region_on_ground("the area around the tray") is None


# work surfaces that neither the grounds file nor a tune pool names: read by their meaning
@pytest.mark.parametrize(
    ("text", "region"),
    [
        ("the far end of the banquet table", (None, "far")),
        ("the left of the computer table", ("left", None)),
        ("the right of the bedside table", ("right", None)),
        ("the middle of the buffet counter", ("middle", "middle")),
    ],
)
def test_a_region_of_a_work_surface_no_list_names_is_a_region_of_the_table(text, region):
    from tabletop.eval.paraphrase import TUNE_POOLS
    from tabletop.eval.place_texts import ground_texts

    listed = {t.text for t in ground_texts(TUNE_POOLS)}
    assert parse_region(text) is None
    a = PlaceReader().read(text)
    assert "the " + a.how.split("'")[1] not in listed  # the ground is in no training list
    assert (a.region.lateral, a.region.depth) == region and a.how.startswith("grammar, on ")
    assert PlaceReader(learned=False).read(text).region is None  # the rule reader alone


@pytest.mark.parametrize(
    "text",
    [
        "the left side of the mug",
        "the far side of the duck",
    ],
)
def test_a_region_of_a_thing_is_no_table_region(text):
    a = PlaceReader().read(text)
    assert a.region is None and a.subject


@pytest.mark.parametrize(
    ("text", "ground"),
    [
        ("the left of the attic room", "attic room"),
        ("the far end of the porch", "porch"),
        ("the middle of the motorway", "motorway"),
        ("the right side of the stadium", "stadium"),
        ("the far left corner of the garage, by the door", "garage"),
        ("the centre of the lawn", "lawn"),
    ],
)
def test_a_region_of_a_place_off_the_table_is_not_on_this_map(text, ground):
    a = PlaceReader().read(text)
    assert a.region is None and a.subject is None
    assert a.how.startswith(f"{ground!r} is not the table"), a.how


@pytest.mark.parametrize(
    "text", ["the far end of the desk from you", "the left part of the worktop, roughly"]
)
def test_a_region_of_a_work_surface_with_more_words_stays_a_region(text):
    assert PlaceReader().read(text).region is not None


def test_a_place_off_the_table_is_off_the_map_but_a_bit_off_to_one_side_is_on_it():
    a = PlaceReader().read("just off the table on the left")
    assert a.region is None and a.subject is None and a.how.startswith("'off' the table")
    assert PlaceReader().read("the bit off to the left").region.lateral == "left"


def test_the_shipped_ground_classifier_was_chosen_on_folds_left_out_of_its_fit():
    from tabletop.train.places import MAX_ELSEWHERE_AS_SURFACE

    g = load_place_classifier(DEFAULT_PLACE_WEIGHTS).ground
    s = g.meta["held_out_folds"][str(g.threshold)]
    assert s["elsewhere_taken_for_surface"] <= MAX_ELSEWHERE_AS_SURFACE * s["elsewhere"]
    assert s["surfaces_taken"] >= 0.7 * s["surfaces"]


def test_a_ground_listed_both_as_surface_and_elsewhere_is_named(tmp_path, monkeypatch):
    from tabletop.eval import place_texts

    bad = tmp_path / "grounds.toml"
    bad.write_text('surfaces = ["desk", "the bench"]\nelsewhere = ["garden", "bench"]\n')
    monkeypatch.setattr(place_texts, "GROUNDS_FILE", bad)
    with pytest.raises(AssetError, match=r"surface and elsewhere: \['bench'\]"):
        place_texts.ground_texts(TUNE_POOLS[:1])
    with pytest.raises(ConfigError, match="held-out pools"):
        place_texts.ground_texts([HELDOUT_POOLS[0]])


def test_a_weights_file_with_a_broken_ground_classifier_is_named(tmp_path):
    d = json.loads(DEFAULT_PLACE_WEIGHTS.read_text())
    d["ground"]["w"] = d["ground"]["w"][:10]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(AssetError, match="malformed place classifier"):
        load_place_classifier(bad)

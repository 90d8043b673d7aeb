"""Colour words and perceptual colour."""

import numpy as np
import pytest

from tabletop.mapping.colors import rgb_to_lab
from tabletop.reader.lexicon.colour_names import BASIC_COLOURS, COLOR_NAMES
from tabletop.reader.lexicon.colour_words import (
    color_parses,
    framed_colours,
    heads,
    modifies,
    split_color_words,
)


def test_lab_of_reference_colours():
    assert np.allclose(rgb_to_lab([255, 255, 255]), [100, 0, 0], atol=0.01)
    assert np.allclose(rgb_to_lab([0, 0, 0]), [0, 0, 0], atol=0.01)
    # sRGB red in CIELAB (D65), the published value
    assert np.allclose(rgb_to_lab([255, 0, 0]), [53.24, 80.09, 67.20], atol=0.05)
    assert rgb_to_lab(np.zeros((2, 5, 3))).shape == (2, 5, 3)


@pytest.mark.parametrize(
    ("text", "colour", "rest"),
    [
        ("the dark blue coffee mug", "dark blue", "the coffee mug"),
        ("a reddish duck", "red", "a duck"),
        # a hedged compound a basic term leads is that term; unhedged it is the thing's word
        ("the greenstone-ish cube", "green", "the cube"),
        ("the redwood tray", "", "the redwood tray"),
        ("the light-grey tray", "light grey", "the tray"),
        ("the red one", "red", "the one"),
        ("the mug", "", "the mug"),
        ("the orange", "", "the orange"),  # a colour name alone is the thing asked for
        ("the orange cube", "orange", "the cube"),
        ("an off-white bear", "off-white", "an bear"),
        # compounds ending in a colour name are one colour phrase
        ("the round toy pillar in grass-green", "grass-green", "the round toy pillar"),
        ("the sage-green block", "sage-green", "the block"),
        # a compound before a colour name names the shade by a thing of that colour: its
        # words are not the thing's
        ("the pillar-box red ball", "pillar-box red", "the ball"),
        ("the ball, fire-truck-red red", "fire-truck-red red", "the ball"),
        ("the tin-can toy", "", "the tin can toy"),  # no colour after it: the thing's words
        # ... or the lexicon's own two-word name, hyphenated
        ("the jet-black domino", "jet black", "the domino"),
        ("the little snow-white duck", "snow white", "the little duck"),
        # a gem, a fruit or a paint name is a colour; a material or a drink stays the thing's
        ("the azure ball", "azure", "the ball"),
        ("the coffee mug", "", "the coffee mug"),
        # words that only tie the colour to the thing go with it
        ("the cube toy in red", "red", "the cube toy"),
        ("red coloured cube-shaped toy", "red", "cube shaped toy"),
        ("the block painted blue", "blue", "the block"),
        # ... and only there
        ("the red mug in the corner", "red", "the mug in the corner"),
        ("the red brick", "red", "the brick"),
        # a noun for the colour itself goes with it, with the word that brings it in
        ("the little duck with white colouring", "white", "the little duck"),
        ("the building piece in a blue finish", "blue", "the building piece"),
        ("the ball of a deep red hue", "deep red", "the ball"),
        ("the mug with a red handle", "red", "the mug with a handle"),
        # superlatives and "appears"
        ("the squeaky thing that appears blackest", "black", "the squeaky thing that"),
        # adjectives in "-y" of a colour name are that colour; other "-y" words are not
        ("the minty stacking brick", "mint", "the stacking brick"),
        ("the cup, kind of chocolatey", "chocolate", "the cup kind of"),
        ("the creamy teddy", "cream", "the teddy"),
        ("the rosy cube", "rose", "the cube"),
        ("the tiny cube", "", "the tiny cube"),
        ("the spotty domino", "", "the spotty domino"),
        ("the fluffy navy bear", "navy", "the fluffy bear"),
        # ... with the suffix hyphenated, or on a word that has one already
        ("the minty-ish brick", "mint", "the brick"),
        ("the navy-y cube", "navy", "the cube"),
        ("the tree-y cube", "", "the treey cube"),
        # a thing likened in size or shape to a fruit is not of its colour
        ("the ball about the size of an orange", "", "the ball about the size of an orange"),
        ("a block shaped like a lemon", "", "a block shaped like a lemon"),
        ("the red ball about the size of an orange", "red", "the ball about the size of an orange"),
    ],
)
def test_colour_words_are_split_from_the_rest(text, colour, rest):
    assert split_color_words(text) == (colour, rest)


@pytest.mark.parametrize(
    ("text", "readings"),
    [
        # a word right before a colour, with more of the thing after it: one colour name too
        ("the lobster red duck", [("red", "the lobster duck"), ("lobster red", "the duck")]),
        # a colour name that is no basic term, after a word: a compound noun too
        (
            "a milk chocolate bear",
            [
                ("chocolate", "a milk bear"),
                ("milk chocolate", "a bear"),
                ("", "a milk chocolate bear"),
            ],
        ),
        # ... and the colour phrase in one piece comes before one a word of the thing splits
        (
            "the blue milk chocolate mug",
            [("blue", "the milk chocolate mug"), ("blue chocolate", "the milk mug")],
        ),
        # nothing before the colour, a modifier, or nothing after it: one reading
        ("the red mug", [("red", "the mug")]),
        ("the dark red mug", [("dark red", "the mug")]),
        ("the mug that is red", [("red", "the mug that is")]),
        ("the cube in red", [("red", "the cube")]),
        # a part's colour after "with": the whole's colour first, then no colour
        (
            "the ball with black patches",
            [("black", "the ball with patches"), ("", "the ball with black patches")],
        ),
        (
            "the white mug with a red handle",
            [("white", "the mug with a red handle"), ("white red", "the mug with a handle")],
        ),
        (
            "the ball with red and white stripes",
            [
                ("red white", "the ball with and stripes"),
                ("", "the ball with red and white stripes"),
            ],
        ),
        # ... but what covers the whole thing has the thing's colour
        ("the bear with brown fur", [("brown", "the bear with fur")]),
        ("the block with white colouring", [("white", "the block")]),
        ("the ball with red in it", [("red", "the ball with it")]),
        ("the orange", [("", "the orange")]),
        # "one" after the colour is the thing too: the word before may join the colour
        (
            "the strawberry pink one",
            [("pink", "the strawberry one"), ("strawberry pink", "the one")],
        ),
        ("the pink-looking one", [("pink", "the one")]),
    ],
)
def test_colour_readings_come_first_and_compounds_after(text, readings):
    assert color_parses(text) == readings
    assert split_color_words(text) == readings[0]


@pytest.mark.parametrize(
    ("text", "framed"),
    [
        ("the tomato-coloured tubey thing", ["tomato"]),
        ("the angled block, colour heliotrope", ["heliotrope"]),
        ("the block that appears bluebell", ["bluebell"]),
        ("the mug in a papaya finish", ["papaya"]),
        ("the red-coloured cube", []),  # a lexicon colour needs no frame
        ("the solid colour ball", ["ball"]),  # a reading to try, not the only one
        ("the block painted like a zebra", []),
    ],
)
def test_words_the_query_frames_as_a_colour(text, framed):
    assert framed_colours(text) == framed


@pytest.mark.parametrize(
    ("place", "text", "name", "there"),
    [
        # before more of the noun phrase, as a modifier
        (modifies, "the heliotrope doorstop-shaped block", "heliotrope", True),
        (modifies, "the tomato one", "tomato", True),
        (modifies, "a ripe tomato", "tomato", False),
        (modifies, "the tomato on the tray", "tomato", False),
        (modifies, "the sky blue mug", "sky blue", True),
        # last in the noun phrase after a word of the thing, as its head noun
        (heads, "the domino stone", "stone", True),
        (heads, "the domino stone near the mug", "stone", True),
        (heads, "the stone domino", "stone", False),
        (heads, "the mug in cherry", "cherry", False),
        (heads, "the cherry", "cherry", False),
    ],
)
def test_where_a_colour_name_stands_in_the_noun_phrase(place, text, name, there):
    assert place(text, name) is there


def test_every_name_belongs_to_a_basic_colour_term():
    assert set(BASIC_COLOURS) <= set(COLOR_NAMES)
    for name, (rgb, family) in COLOR_NAMES.items():
        assert family in BASIC_COLOURS, name
        assert len(rgb) == 3 and all(0 <= c <= 255 for c in rgb), name
        assert COLOR_NAMES[family][1] == family  # a basic term is its own family


def test_shaded_lab_darkens_a_colour_and_keeps_it_at_full_light():
    from tabletop.mapping.colors import shaded_lab

    rgb = np.array([[230.0, 110.0, 20.0], [128.0, 128.0, 128.0]])
    lab = shaded_lab(rgb, [1.0, 0.5])
    assert lab.shape == (2, 2, 3)
    np.testing.assert_allclose(lab[0], rgb_to_lab(rgb), atol=1e-9)
    assert np.all(lab[1, :, 0] < lab[0, :, 0] - 10)  # darker
    hue = np.arctan2(lab[:, 0, 2], lab[:, 0, 1])
    assert abs(hue[1] - hue[0]) < 0.1  # the same hue


def test_the_survey_names_load_without_the_lexicons_and_a_bad_file_is_named(tmp_path):
    from tabletop.errors import AssetError
    from tabletop.reader.lexicon.colour_words import survey_colours, survey_name, survey_words

    names = survey_colours()
    assert len(names) > 500 and not set(names) & set(COLOR_NAMES)
    assert names["aubergine"] == (0x3D, 0x07, 0x34)
    assert survey_words("the peacock blue and aubergine mug") == ["peacock blue", "aubergine"]
    assert survey_words("the red mug") == []
    # an adjective in "-y" of a survey name stands for it
    assert survey_words("the grassy ball") == ["grassy"] and survey_name("grassy") == "grass"
    assert survey_name("muddy") == "mud" and survey_name("icy") == "ice"  # mud(d)-y, ic(e)-y
    assert survey_words("the fuzzy furry ball") == []
    assert survey_name("aubergine") == "aubergine" and survey_name("sandwich") == ""
    bad = tmp_path / "bad.toml"
    bad.write_text('format = "tabletop-colour-names"\nversion = 1\n[names]\nmoss = "green"\n')
    with pytest.raises(AssetError, match="moss"):
        survey_colours(bad)

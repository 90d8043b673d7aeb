"""The spelling pass: slips corrected against the vocabulary, real words left alone."""

import pytest

from tabletop.errors import ConfigError
from tabletop.reader.spelling import Speller, SpellingConfig


@pytest.fixture(scope="module")
def speller():
    return Speller()


@pytest.mark.parametrize(
    ("typed", "meant"),
    [
        ("the gren mug", "the green mug"),  # one letter left out
        ("the teddy bera", "the teddy bear"),  # two letters swapped
        ("the lego brcik", "the lego brick"),
        ("reach the yelow duk", "reach the yellow duck"),
        ("go to thered cube", "go to the red cube"),  # a space left out
        ("gotothe mug", "go to the mug"),  # two spaces left out
        ("the lefft side of the table", "the left side of the table"),  # the reader's words
        ("go behnid the duck", "go behind the duck"),
        ("the red balll", "the red ball"),  # a letter typed three times
        ("the greeeen mug", "the green mug"),
        ("go to the rde mug", "go to the red mug"),  # a swap, not "de" with a letter more
    ],
)
def test_slips_are_corrected_to_the_vocabulary(speller, typed, meant):
    read, fixes = speller.correct(typed)
    assert read == meant
    assert fixes and all(f.why for f in fixes)


@pytest.mark.parametrize(
    "text",
    [
        "the mustard duck",  # colour survey words
        "the teal block",
        "somebody jangling keys",  # real English words the vocabulary lacks
        "the centre of the table",  # British spelling
        "the purple tri prism",  # a short word is no slip of a verb ("try")
        "a quacky toy",  # a known stem with a suffix
        "the kitchen",
        "move 5 cm north",
        "go to /tmp/a_picture.png",
    ],
)
def test_real_words_are_left_alone(speller, text):
    assert speller.correct(text) == (text, ())


def test_punctuation_and_case_around_a_corrected_word_are_kept(speller):
    read, _ = speller.correct("Go to the Gren mug, please.")
    assert read == "Go to the green mug, please."


def test_a_tie_between_vocabulary_words_is_left_alone():
    s = Speller(vocabulary=["cat", "car"], english=[])
    assert s.correct("cax") == ("cax", ())  # one edit from both: no guess
    assert s.correct("catt")[0] == "cat"


def test_bad_input_and_config_are_refused():
    with pytest.raises(ConfigError, match="must be a string"):
        Speller(vocabulary=["cat"], english=[]).correct(3)
    with pytest.raises(ConfigError, match="lengths must increase"):
        SpellingConfig(max_edits=((4, 1), (3, 2)))


@pytest.mark.parametrize(
    "text",
    [
        "tik tik tik went the clock",  # alone, "tik" would be taken for "tick"
        "the phone going brrring-brrring",  # alone, "brrring" would be "bring"
        "a dingg-dingg dingg-dingg",  # alone, "dingg" would be "ding"
    ],
)
def test_a_word_typed_twice_in_a_row_is_an_imitation_and_kept(speller, text):
    assert speller.correct(text) == (text, ())
    # the same words alone are slips
    assert speller.correct("the dingg")[0] == "the ding"
    assert speller.correct("tik")[0] == "tick"


def test_a_british_stem_with_a_suffix_is_a_real_word_not_a_run_together(speller):
    assert speller.correct("the centremost square") == ("the centremost square", ())
    assert speller.correct("the colourful mug") == ("the colourful mug", ())

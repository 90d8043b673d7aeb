"""One reader: understand() by name, the spelling and wrapper passes, every caller asks it."""

import re

import pytest

from tabletop.errors import ConfigError
from tabletop.language import instruction_to_code
from tabletop.reader import ParseError
from tabletop.reader.plan import Between, GoTo
from tabletop.reader.reading import READERS, understand


def test_the_rule_reader_refuses_what_the_default_reads():
    text = "would you be so kind as to move to the gren mug"
    with pytest.raises(ParseError):
        understand(text, reader="rules")
    r = understand(text, reader="rules+spelling")
    assert isinstance(r.steps[0].action, GoTo)
    assert r.steps[0].action.goal.primary.text == "green mug"
    assert r.wrapper == ("would you be so kind as to",)
    assert [(c.typed, c.meant) for c in r.corrections] == [("gren", "green")]


def test_a_word_that_names_something_is_never_dropped_as_a_wrapper():
    with pytest.raises(ParseError):
        understand("the duck, then the blue one: head to the mug")
    # the sound part is not read by the grammar; dropping it would send the arm to any mug
    with pytest.raises(ParseError):
        understand("go to the mug while a dog barks loudly somewhere")


def test_spelling_reaches_every_reference_of_a_plan():
    (step,) = understand("move between thetray and the yelow duk").steps
    assert isinstance(step.action, Between)
    assert (step.action.a.primary.text, step.action.b.primary.text) == ("tray", "yellow duck")


def test_code_generation_asks_the_reader():
    code = instruction_to_code("go to the teddy bera")
    assert '"teddy bear"' in code and "bera" not in code
    with pytest.raises(ParseError):
        instruction_to_code("go to the teddy bera, pretty please with sugar", reader="rules")


def test_unknown_reader_names_the_valid_ones():
    with pytest.raises(
        ConfigError, match=re.escape("unknown reader 'gpt'; valid: " + ", ".join(READERS))
    ):
        understand("go to the mug", reader="gpt")
    with pytest.raises(ConfigError, match="must be a string"):
        understand(None)


@pytest.mark.parametrize(
    "text", ["do not under any circumstances go to the mug", "go to the mug slowly"]
)
def test_words_that_negate_or_qualify_are_never_dropped(text):
    with pytest.raises(ParseError):
        understand(text)


@pytest.mark.parametrize(
    ("reader", "accepts"),
    [
        ("rules+spelling", []),
        # asked only what the grammar refuses, the tagger reads two things joined by "and" as
        # the space between them
        ("rules+learned", ["go to the mug and the duck"]),
    ],
)
def test_what_the_robot_cannot_do_is_refused(reader, accepts):
    from tabletop.language.suite import load_suite

    accepted = []
    for bad in load_suite().unparseable:
        try:
            understand(bad.instruction, reader=reader)
        except ParseError:
            continue
        accepted.append(bad.instruction)
    assert accepted == accepts


def test_the_learned_fallback_still_reads_requests_the_arm_cannot_do():
    # why the default is the grammar with spelling: the tagger has seen no request it must
    # refuse, so an action it does not know, or nonsense, is read as a place to go
    assert understand("dance around the table", reader="rules+learned").steps
    with pytest.raises(ParseError, match="motion verb"):
        understand("dance around the table")

"""The learned reader's generated training texts: labelled per word, held-out pools unread."""

import pytest

from tabletop.errors import ConfigError
from tabletop.eval.paraphrase import HELDOUT_POOLS
from tabletop.eval.reader_texts import reader_texts
from tabletop.reader import ParseError
from tabletop.reader.learned import RELATIONS, ROLES, decode
from tabletop.reader.reading import read_clause


@pytest.fixture(scope="module")
def texts():
    return reader_texts(("tune", "tune-2"), n_per_pool=150, seed=3)


def test_every_word_has_a_role_and_a_relation(texts):
    assert len(texts) == 300
    for t in texts:
        assert len(t.words) == len(t.roles) == len(t.relations) > 0
        assert set(t.roles) <= set(ROLES) and set(t.relations) <= set(RELATIONS)
        for prev, role in zip(("O", *t.roles), t.roles, strict=False):
            if role.startswith("I-"):  # a reference continues only what it began
                assert prev[2:] == role[2:], t


def test_the_labels_decode_into_plans_of_every_relation(texts):
    seen, refused, to_refuse = set(), 0, 0
    for t in texts:
        refuse = "none" in t.relations  # a request the arm must refuse: every word says so
        assert not refuse or set(t.relations) == {"none"}
        to_refuse += refuse
        try:
            steps = decode(t.text, list(t.words), list(t.roles), list(t.relations), "arm",
                           read_clause)  # fmt: skip
        except ParseError:  # a slip typed into a compass move's unit or direction
            refused += not refuse
            continue
        assert not refuse, t
        seen.update(type(s.action).__name__ for s in steps)
    assert {"GoTo", "Between", "Side", "Above", "BackAndForth", "Compass"} <= seen
    assert refused <= 0.03 * len(texts)
    assert 0.05 * len(texts) <= to_refuse <= 0.15 * len(texts)  # REFUSALS = 0.1


def test_seeded_and_held_out_pools_refused(texts):
    again = reader_texts(("tune", "tune-2"), n_per_pool=150, seed=3)
    assert [t.text for t in again] == [t.text for t in texts]
    assert [t.text for t in reader_texts(("tune",), 20, seed=4)] != [t.text for t in texts[:20]]
    with pytest.raises(ConfigError, match="never read for training"):
        reader_texts((HELDOUT_POOLS[0],), n_per_pool=1)


def test_noise_people_add_keeps_the_labels():
    import re

    from tabletop.eval.reader_texts import _plain_words, _templates

    t = _templates()
    rows = reader_texts(("tune", "tune-2"), n_per_pool=1500, seed=5)
    # a side's part named by a word of its own ("the left flank of"): the side still decides
    plain = set(_plain_words())
    parts = [
        r for r in rows
        if (m := re.search(r"\bthe (left|right|front|back) ([a-z]+) of\b", r.text))
        and m.group(2) in plain
    ]  # fmt: skip
    assert len(parts) >= 5
    side = {"left": "left", "right": "right", "front": "front", "back": "behind"}
    for r in parts:
        m = re.search(r"\bthe (left|right|front|back) ([a-z]+) of\b", r.text)
        i = r.words.index(m.group(2)) if m.group(2) in r.words else None
        if i is not None and r.roles[i] == "O":  # a step's own side, not inside a place's words
            assert r.relations[i] in (side[m.group(1)], "none"), r

    # the whole table said after a thing is plain words, and hedges before a near word too
    def plain_at(r, phrase):
        n, ws = len(phrase.split()), [w.lower().strip(",.!?") for w in r.words]
        return any(
            ws[i : i + n] == phrase.split() and set(r.roles[i : i + n]) == {"O"}
            for i in range(len(ws) - n + 1)
        )

    multi = [w for w in t["whole_table"] if len(w.split()) > 1]
    assert sum(any(plain_at(r, w) for w in multi) for r in rows) >= 20
    hedged = [r for r in rows if any(f" {h} near " in f" {r.text} " for h in t["hedges"])]
    assert hedged
    for r in hedged:
        k = r.words.index("near")
        assert r.roles[k] == "O" and r.roles[k - 1] == "O"
    # the words put in carry no structure of their own
    assert not plain & {"left", "right", "not", "mug", "red", "near", "three", "biggest"}

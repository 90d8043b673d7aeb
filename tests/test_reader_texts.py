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

"""The open sound vocabulary: AudioSet class names read by MiniLM, scored through logits."""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
from tabletop.mapping.open_sounds import (
    GENERIC_CLASSES,
    OpenScorer,
    OpenSoundVocabulary,
    _names_digest,
    load_open_scorer,
    name_variants,
    save_open_scorer,
)
from tabletop.mapping.sound_vocabulary import OPEN_PREFIX, SoundMatcher, SoundVocabulary

NAMES = ("Doorbell", "Dog", "Bark", "Siren", "Noise", "Speech", "Kettle whistle", "Rain")


@pytest.fixture(scope="module")
def text():
    return MiniLMTextEncoder()


def _logits(hot: dict[int, dict[str, float]], n: int = 3) -> np.ndarray:
    """(n, K) logits: -6 everywhere, ``hot[segment][name]`` where given."""
    z = np.full((n, len(NAMES)), -6.0)
    for i, d in hot.items():
        for name, v in d.items():
            z[i, NAMES.index(name)] = v
    return z


def test_a_named_class_is_found_where_it_played_and_only_there(text):
    ov = OpenSoundVocabulary(NAMES, text)
    # every segment sounds like a few things; "Noise" names no source and is no competitor
    z = _logits(
        {
            0: {"Dog": 3, "Bark": 3, "Speech": 2},
            1: {"Doorbell": 2, "Speech": 1, "Rain": 0, "Dog": 0, "Noise": 5},
            2: {"Rain": 2, "Speech": 1, "Bark": 0.5},
        }
    )
    q = ov.match("a doorbell", z)
    assert q.known and q.classes == ("Doorbell",) and q.nearest == "Doorbell"
    assert np.argmax(q.scores) == 1 and q.scores[1] > 0.5
    assert q.scores[0] < 0.01 and q.scores[2] < 0.01
    # an absent sound's mass stays near zero on every segment: refused at any operating point
    assert ov.match("a siren wailing", z).scores.max() < 0.01
    np.testing.assert_allclose(q.scores, 1 / (1 + np.exp(-q.log_odds)))
    # the score: the asked logit over the third strongest other source-naming class, less 1
    assert q.log_odds[1] == pytest.approx(2 - 0 - 1)
    with pytest.raises(ConfigError, match="rank"):
        OpenSoundVocabulary(NAMES, text, rank=0)


def test_generic_names_and_far_queries_ask_for_nothing(text):
    ov = OpenSoundVocabulary(NAMES, text)
    z = _logits({0: {"Noise": 4}})
    assert "Noise" in GENERIC_CLASSES
    assert "Noise" not in ov.match("noise", z).classes
    far = ov.match("a spreadsheet of quarterly taxes", z)
    assert not far.known and far.scores.shape == (3,) and far.text_score < ov.text_min
    with pytest.raises(ConfigError, match="class names"):
        OpenSoundVocabulary((), text)


def test_the_matcher_keeps_known_sounds_and_opens_for_others(text):
    vocab = SoundVocabulary({"dog": ("the sound of a dog barking", "woof woof")}, 20.0)
    ov = OpenSoundVocabulary(NAMES, text)
    m = SoundMatcher(vocab, text, words={}, others={}, open_vocabulary=ov)
    emb = np.asarray(text.encode_text(["the sound of a dog barking", "rain", "a bell"]), np.float32)
    z = _logits(
        {
            0: {"Dog": 3, "Bark": 3, "Speech": 1},
            1: {"Rain": 2, "Speech": 1, "Siren": 0},
            2: {"Doorbell": 2, "Speech": 1, "Rain": 0, "Siren": 0},
        }
    )
    dog = m.match("a dog barking", emb, z)
    assert dog.categories == ("dog",)  # the bank answers what it knows
    bell = m.match("a doorbell", emb, z)
    assert bell.categories == (f"{OPEN_PREFIX}Doorbell",) and np.argmax(bell.log_odds) == 2
    # what it read is named by the class's name (a reason quotes it; it had raised KeyError)
    assert vocab.caption(bell.nearest) == "Doorbell" and vocab.caption("dog").startswith("the")
    # without the segments' logits the open vocabulary is not used
    plain = m.match("a doorbell", emb)
    assert not any(c.startswith(OPEN_PREFIX) for c in plain.categories)


def test_name_variants_read_synonyms_and_brackets():
    assert name_variants("Burst, pop") == ("burst, pop", "burst", "pop")
    assert name_variants("Coin (dropping)") == ("coin (dropping)", "coin dropping", "coin")[:2]
    assert "etc." not in name_variants("Bee, wasp, etc.")
    assert name_variants("Dog") == ("dog",)


def _scorer(names, null, **kw):
    args = {"w_rel": 0.0, "w_abs": 1.0, "bias": -1.0, "rank": 1, **kw}
    return OpenScorer(np.asarray(null, np.float32), names_digest=_names_digest(names), **args)


def test_the_fitted_scorer_judges_a_class_against_its_own_level(text, tmp_path):
    # "Speech" sits high on sounds it does not name, "Doorbell" low: the same logit of 1 is
    # far above the doorbell's usual level and below the speech's
    null = np.full(len(NAMES), -6.0)
    null[NAMES.index("Speech")] = 2.0
    null[NAMES.index("Doorbell")] = -4.0
    sc = _scorer(NAMES, null)
    ov = OpenSoundVocabulary(NAMES, text, scorer=sc)
    z = _logits({0: {"Doorbell": 1.0}, 1: {"Speech": 1.0}})
    bell = ov.match("a doorbell", z)
    assert bell.log_odds[0] == pytest.approx(1 - (-4) - 1) and bell.log_odds[2] == pytest.approx(-3)
    assert ov.match("someone talking", z).log_odds[1] == pytest.approx(1 - 2 - 1)
    # written and read back alike; a scorer of other names is refused by name
    back = load_open_scorer(save_open_scorer(tmp_path / "s.json", sc))
    np.testing.assert_array_equal(back.null, sc.null)
    assert (back.w_abs, back.bias, back.names_digest) == (1.0, -1.0, sc.names_digest)
    with pytest.raises(ConfigError, match="other class names"):
        OpenSoundVocabulary(NAMES[:-1], text, scorer=sc)
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(AssetError, match="train audio"):
        load_open_scorer(tmp_path / "bad.json")


def test_the_shipped_scorer_is_yamnets_and_only_yamnets(text):
    from tabletop.mapping.encoders.yamnet import yamnet_class_names

    assert OpenSoundVocabulary(yamnet_class_names(), text).scorer is not None
    assert OpenSoundVocabulary(NAMES, text).scorer is None  # the rank rule
    sc = load_open_scorer()
    assert sc.w_abs > 0 and sc.meta["train_refused"] >= 0.95


def test_a_query_the_bank_reads_as_another_class_opens(text):
    names = ("Glass", "Chink, clink", "Coin (dropping)", "Speech", "Rain")
    vocab = SoundVocabulary({"glass_clinking": ("glasses clinking", "clinking glasses")}, 20.0)
    ov = OpenSoundVocabulary(names, text, scorer=None)
    m = SoundMatcher(vocab, text, words={}, others={}, open_vocabulary=ov)
    assert m.category_classes()[0, names.index("Glass")]
    emb = np.asarray(text.encode_text(["glasses clinking", "coins"]), np.float32)
    z = np.full((2, len(names)), -6.0)
    z[0, 1], z[1, 2] = 3.0, 3.0
    # coins: nearer "Coin (dropping)" than the glasses' texts, which never read as it
    coins = m.match("coins dropping on a table", emb, z)
    assert coins.categories == (f"{OPEN_PREFIX}Coin (dropping)",) and coins.log_odds.argmax() == 1
    # the glasses' own words stay the bank's
    assert m.match("a clinking of glasses", emb, z).categories == ("glass_clinking",)

"""The open sound vocabulary: AudioSet class names read by MiniLM, scored through logits."""

from __future__ import annotations

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.mapping.encoders.minilm import MiniLMTextEncoder
from tabletop.mapping.open_sounds import GENERIC_CLASSES, OpenSoundVocabulary
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
    # without the segments' logits the open vocabulary is not used
    plain = m.match("a doorbell", emb)
    assert not any(c.startswith(OPEN_PREFIX) for c in plain.categories)

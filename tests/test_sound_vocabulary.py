"""Sound queries through the vocabulary an audio encoder knows: words -> categories -> segments,
and "not found" for sounds that are not known or were not heard."""

import numpy as np
import pytest
from module_helpers import GRID, judge_at, text_encoder

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.audio_module import AudioConfig, AudioModule
from tabletop.mapping.encoders.oracle import OracleAudioEncoder
from tabletop.mapping.sound_vocabulary import (
    SOUND_FAMILIES,
    SoundMatcher,
    SoundVocabulary,
    load_other_sounds,
    load_phrasings,
    load_sound_words,
    phrases_for,
)
from tabletop.mapping.targets import max_position
from tabletop.sim.sound_bank import SoundBank

RATE = 16000

VOCAB = SoundVocabulary(
    {
        "dog": tuple(phrases_for("dog", "the sound of a dog barking")),
        "telephone": tuple(phrases_for("telephone", "the sound of a telephone ringing")),
        "chirping_birds": tuple(phrases_for("chirping_birds", "the sound of birds chirping")),
        "owl": tuple(phrases_for("owl", "the sound of an owl hooting")),
        "hammering": tuple(phrases_for("hammering", "the sound of hammering")),
    },
    logit_scale=20.0,
)


def test_every_bank_category_has_phrasings_and_families_name_real_categories():
    phr = load_phrasings()
    bank = SoundBank.default()
    missing = sorted(c for c in bank.categories if c not in phr)
    assert not missing, f"bank categories without phrasings: {missing}"
    assert all(len(v) >= 5 for v in phr.values())
    known = set(phr)
    assert all(f <= known for f in SOUND_FAMILIES)


def test_phrasings_file_errors_name_the_file(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[phrasings]\ndog = "a dog"\n')
    with pytest.raises(AssetError, match=r"\[phrasings\].dog must be a non-empty list"):
        load_phrasings(p)
    p.write_text("dog = [1")
    with pytest.raises(AssetError, match="cannot read sound phrasings"):
        load_phrasings(p)


def test_vocabulary_round_trips_and_refuses_nonsense():
    assert SoundVocabulary.from_meta(VOCAB.to_meta()) == VOCAB
    assert SoundVocabulary.from_meta(None) is None
    assert VOCAB.caption("dog") == "the sound of a dog barking"
    with pytest.raises(ConfigError, match="at least one category"):
        SoundVocabulary({})
    with pytest.raises(ConfigError, match="logit_scale must be > 0"):
        SoundVocabulary({"dog": ("a dog",)}, logit_scale=0.0)
    with pytest.raises(AssetError, match="malformed sound vocabulary"):
        SoundVocabulary.from_meta({"logit_scale": 3})


def test_words_reach_their_category_and_unknown_sounds_none():
    m = SoundMatcher(VOCAB, text_encoder())
    cats = VOCAB.categories
    for query, want in [
        ("a dog woofing", "dog"),
        ("the phone", "telephone"),
        ("someone banging nails in", "hammering"),
        ("an owl at night", "owl"),
    ]:
        assert cats[int(np.argmax(m.category_scores(query)))] == want, query
    far = m.match("a submarine sonar ping", np.zeros((0, 384)))
    assert not far.known and far.text_score < m.text_min


def test_a_source_named_after_of_says_what_made_the_sound():
    vocab = SoundVocabulary(
        {
            c: tuple(phrases_for(c, f"the sound of {w}"))
            for c, w in [
                ("rain", "rain"),
                ("footsteps", "footsteps"),
                ("clapping", "clapping"),
                ("thunderstorm", "a thunderstorm"),
            ]
        },
        logit_scale=20.0,
    )
    m = SoundMatcher(vocab, text_encoder())  # with the query-time words of the shipped file
    none = np.zeros((0, 384))
    # "pitter-patter" alone is rain, and a clap is clapping: the source after "of" decides
    assert m.category_scores("pitter-patter").argmax() == vocab.categories.index("rain")
    assert m.match("the pitter-patter of feet", none).categories == ("footsteps",)
    assert m.match("a clap of thunder", none).categories == ("thunderstorm",)
    assert m.match("the pitter-patter of rain", none).categories == ("rain",)
    # nothing but a pronoun after "of" names no source
    assert m.match("the pitter-patter of it", none).categories == ("rain",)


def test_posteriors_and_log_odds_agree():
    text = text_encoder()
    m = SoundMatcher(VOCAB, text)
    emb = text.encode_text(["a dog barking", "a telephone ringing", "a bird singing"])
    p = m.posteriors(emb)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-9)
    q = m.match("the sound of a dog barking", emb)
    assert q.categories == ("dog",)
    np.testing.assert_allclose(q.scores, p[:, 0], atol=1e-9)
    assert int(np.argmax(q.log_odds)) == 0
    assert np.all(np.argsort(q.log_odds) == np.argsort(q.scores))


def _track(spans, seconds, seed=0):
    rng = np.random.default_rng(seed)
    x = 0.001 * rng.standard_normal(int(seconds * RATE)).astype(np.float32)
    for t0, t1 in spans:
        n = int((t1 - t0) * RATE)
        t = np.arange(n) / RATE
        x[int(t0 * RATE) : int(t0 * RATE) + n] += (0.5 * np.sin(2 * np.pi * 440 * t)).astype(
            np.float32
        )
    return x


@pytest.fixture(scope="module")
def module():
    return _dogs_and_phone(VOCAB)


def _dogs_and_phone(vocabulary, config=None):
    """A dog heard at x = 0.1 m and again at 0.5 m, a phone at 0.3 m."""
    text = text_encoder()
    events = [
        {"caption": "a dog barking", "onset_s": 1.0, "offset_s": 2.0},
        {"caption": "a phone ringing", "onset_s": 5.0, "offset_s": 6.0},
        {"caption": "a dog barking", "onset_s": 9.0, "offset_s": 10.0},
    ]
    m = AudioModule(GRID, config or AudioConfig(), vocabulary)
    t = np.arange(0, 12.0, 1 / 30)
    T = np.repeat(np.eye(4)[None], len(t), axis=0)
    T[:, 0, 3] = np.where(t < 4, 0.1, np.where(t < 8, 0.3, 0.5))
    T[:, 2, 3] = 0.3
    m.add(_track([(1, 2), (5, 6), (9, 10)], 12.0), RATE, t, T, OracleAudioEncoder(text, events))
    return m


def test_a_sound_heard_twice_is_hot_in_both_places(module):
    h = module.heatmap("a barking dog", 10.0, text_encoder(), judge_at(0.5))
    assert h.found and len(module) == 3
    z = GRID.shape[2] // 2
    hot = h.values[:, GRID.shape[1] // 2, z]
    xs = GRID.axes()[0]
    at = {x: float(hot[np.argmin(np.abs(xs - x))]) for x in (0.1, 0.3, 0.5)}
    assert at[0.1] > 0.9 and at[0.5] > 0.9 and at[0.3] < 0.5


@pytest.mark.parametrize("tie_break", [0.05, 0.0])
def test_the_surest_of_saturated_segments_is_the_peak_and_both_stay_hot(tie_break):
    """Two dog segments whose posteriors both round to 1 (a sharp vocabulary): the log-odds
    tell them apart, so the heat's peak is the surer one, not whichever came first, and both
    stay hot. Without the tie-break the first (less sure) one wins the tie."""
    sharp = SoundVocabulary(VOCAB.texts, logit_scale=100.0)
    m = _dogs_and_phone(sharp, AudioConfig(tie_break=tie_break))
    e = m.embeddings[0] + 0.1 * m.embeddings[1]  # the first dog, a little like a phone
    m.embeddings[0] = (e / np.linalg.norm(e)).astype(np.float32)
    q = m.match("a barking dog", text_encoder())
    assert q.scores[0] == q.scores[2] == 1.0  # a tie in the posteriors
    assert q.log_odds[2] > q.log_odds[0]
    h = m.heatmap("a barking dog", 10.0, text_encoder(), judge_at(0.5))
    p = max_position(h, np.zeros(GRID.shape, bool))
    surest = 0.5 if tie_break else 0.1
    assert p[0] == pytest.approx(surest, abs=0.011)  # 0.5: where the surer segment was heard
    z = GRID.shape[2] // 2
    hot = h.values[:, GRID.shape[1] // 2, z]
    xs = GRID.axes()[0]
    assert float(hot[np.argmin(np.abs(xs - 0.1))]) > 0.8  # still hot (the phone: < 0.5)


def test_the_phone_is_found_where_it_rang(module):
    h = module.heatmap("a ringing telephone", 10.0, text_encoder(), judge_at(0.5))
    p = max_position(h, np.zeros(GRID.shape, bool))
    assert h.found and p[0] == pytest.approx(0.3, abs=0.011)


def test_known_but_unheard_and_unknown_sounds_are_not_found(module):
    text = text_encoder()
    unheard = module.heatmap("the sound of hammering", 10.0, text, judge_at(0.5))
    assert not unheard.found and "no sound heard here" in unheard.reason
    assert "hammering" in unheard.reason and unheard.evidence < 0.5
    unknown = module.heatmap("a submarine sonar ping", 10.0, text, judge_at(0.5))
    assert not unknown.found and "names no sound the audio encoder knows" in unknown.reason
    assert float(unknown.values.max()) == 0.0


def test_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="keep_ratio"):
        AudioConfig(keep_ratio=0.0)
    with pytest.raises(ConfigError, match="text_min"):
        AudioConfig(text_min=2.0)


def test_a_sound_the_vocabulary_lacks_is_not_read_as_a_known_one(module):
    """With the phrasings file's other sounds as the alternative, words nearer a sound the
    encoder never learnt (a thunderstorm, a car horn) read as that sound and are refused with
    it named; known sounds in other words still read as themselves."""
    text = text_encoder()
    m = SoundMatcher(VOCAB, text)
    assert "thunderstorm" in m.others and "dog" not in m.others
    storm = m.match("thunder rumbling", np.zeros((1, 384)))
    assert not storm.known and storm.other == "thunderstorm"
    assert storm.other_score > storm.text_score + m.other_margin
    # without the alternative, the same words ask for a known sound
    alone = SoundMatcher(VOCAB, text, others={})
    assert alone.match("thunder rumbling", np.zeros((1, 384))).other == ""
    # known sounds in other words still read as themselves
    for q in ("a dog woofing", "a ringing telephone", "someone banging nails in"):
        assert m.match(q, np.zeros((1, 384))).known, q
    h = module.heatmap("a car horn honking", 10.0, text, judge_at(0.5))
    assert not h.found and "reads as 'car horn'" in h.reason and "not trained" in h.reason
    with pytest.raises(ConfigError, match="other_margin"):
        AudioConfig(other_margin=-0.1)


def test_a_sound_sharing_a_phrasing_with_a_known_one_leads_to_it():
    """Water drops (outside the bank) and water both have "water dripping": water drops'
    words ("a dripping tap") ask for water instead of being refused; a sound that shares
    nothing (a thunderstorm) still reads as itself."""
    vocab = SoundVocabulary(
        {
            "water": tuple(phrases_for("water", "the sound of splashing, dripping water")),
            "rain": tuple(phrases_for("rain", "the sound of rain falling")),
        }
    )
    m = SoundMatcher(vocab, text_encoder())
    assert "a dripping tap" in m.aliases["water"]
    assert "water_drops" not in m.others and "thunderstorm" in m.others
    tap = m.match("a dripping tap", np.zeros((1, 384)))
    assert tap.categories == ("water",) and tap.other == ""
    assert m.match("thunder rumbling", np.zeros((1, 384))).other == "thunderstorm"
    # Pouring (outside the bank) is heard as water, whose clips hold a tap running and a vessel
    # filling (the shipped words say so); a bottle glugging stays a sound the bank lacks.
    assert m.match("water being poured out", np.zeros((1, 384))).categories == ("water",)
    assert m.match("a bottle glugging", np.zeros((1, 384))).other == "pouring_water"
    # the prototypes are the vocabulary's own phrasings' (what the encoder was trained against)
    plain = SoundMatcher(vocab, text_encoder(), others={})
    np.testing.assert_allclose(m.targets()[2], plain.targets()[2])


def test_query_time_words_lead_to_their_category_and_leave_the_posteriors_alone():
    from tabletop.train.audio import HELDOUT_QUERIES

    words = load_sound_words()
    known = set(load_phrasings())  # the bank's categories and the sounds outside it
    assert set(words) <= known, sorted(set(words) - known)
    for cat, q in HELDOUT_QUERIES.items():  # the encoder's held-out queries stay held out
        assert q not in words.get(cat, ()), cat
    enc = text_encoder()
    plain = SoundMatcher(VOCAB, enc, words={})
    told = SoundMatcher(VOCAB, enc, words={"dog": ("arf arf",), "kazoo": ("a kazoo",)})
    # without the word, "arf arf" reads as no sound, or as another animal
    bare = plain.match("arf arf", np.zeros((0, 384)))
    assert not bare.known or "dog" not in bare.categories
    assert told.match("arf arf", np.zeros((0, 384))).categories == ("dog",)
    segs = np.random.default_rng(0).normal(size=(4, 384)).astype(np.float32)
    np.testing.assert_allclose(plain.posteriors(segs), told.posteriors(segs))
    # the shipped file is what a matcher reads by default
    assert set(words["dog"]) <= set(SoundMatcher(VOCAB, enc).aliases["dog"])


def test_sounds_of_people_the_bank_lacks_are_refused_not_taken_for_a_bank_sound():
    from tabletop.train.audio import ABSENT_QUERIES

    others = load_other_sounds()
    bank = set(SoundBank.default().categories)
    assert others and not set(others) & bank and not set(others) & set(load_phrasings())
    # the encoder's absent-sound measure asks sounds no word file may name
    texts = {t.lower() for v in others.values() for t in v}
    assert not {q.lower() for q in ABSENT_QUERIES} & texts
    vocab = SoundVocabulary({"chirping_birds": VOCAB.texts["chirping_birds"]}, logit_scale=20.0)
    m = SoundMatcher(vocab, text_encoder())
    hum = m.match("somebody humming a song", np.zeros((1, 384)))
    assert not hum.known and hum.other == "humming"
    assert m.match("birds singing", np.zeros((1, 384))).categories == ("chirping_birds",)
    # without the file's others the same words are taken for birdsong
    bare = SoundMatcher(vocab, text_encoder(), others={})
    assert bare.match("somebody humming a song", np.zeros((1, 384))).known


def test_sound_words_file_errors_name_the_file(tmp_path):
    p = tmp_path / "w.toml"
    p.write_text('[phrasings]\ndog = ["a pooch"]\n')
    with pytest.raises(AssetError, match=r"expected a \[words\] table"):
        load_sound_words(p)
    assert load_other_sounds(p) == {}  # the [others] table may be left out
    p.write_text('[words]\ndog = ["a pooch"]\n[others]\nhumming = "someone humming"\n')
    with pytest.raises(AssetError, match=r"\[others\].humming must be a non-empty list"):
        load_other_sounds(p)


def test_a_query_for_sound_in_general_is_refused_naming_why(module):
    from tabletop.mapping.sound_vocabulary import GENERAL

    for query in ("a noise", "some sound", "the sound of nothing at all"):
        h = module.heatmap(query, 10.0, text_encoder(), judge_at(0.5))
        assert not h.found, query
        assert "names no particular sound" in h.reason, h.reason
    # a known sound said with "noise" is still that sound
    assert module.heatmap("that barking noise", 10.0, text_encoder(), judge_at(0.5)).found
    # the refusal is the margin's: with none, the vague words ask for known sounds
    m = SoundMatcher(VOCAB, text_encoder())
    assert m.match("a noise", np.zeros((1, 384))).other == GENERAL
    loose = SoundMatcher(VOCAB, text_encoder(), others={}, general_margin=10.0)
    assert loose.match("a noise", np.zeros((1, 384))).known

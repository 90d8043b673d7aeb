"""The audio module: segments from a track, placed where the microphone was."""

import numpy as np
import pytest
from module_helpers import GRID, judge_at, text_encoder

from tabletop.errors import ConfigError
from tabletop.mapping.audio_module import AudioConfig, AudioModule
from tabletop.mapping.audio_segments import NoiseGateConfig
from tabletop.mapping.encoders.oracle import OracleAudioEncoder
from tabletop.mapping.targets import max_position

RATE = 16000


def _track(spans, seconds=12.0, seed=0):
    rng = np.random.default_rng(seed)
    x = 0.001 * rng.standard_normal(int(seconds * RATE)).astype(np.float32)
    for t0, t1 in spans:
        n = int((t1 - t0) * RATE)
        x[int(t0 * RATE) : int(t0 * RATE) + n] += 0.5 * np.sin(
            2 * np.pi * 440 * np.arange(n) / RATE
        ).astype(np.float32)
    return x


def _poses(timestamps, where):
    """Microphone poses: at ``where(t)`` (x, y) [m], 0.3 m above the table."""
    T = np.repeat(np.eye(4)[None], len(timestamps), axis=0)
    for i, t in enumerate(timestamps):
        T[i, :3, 3] = [*where(t), 0.3]
    return T


EVENTS = [
    {"caption": "a dog barking", "onset_s": 1.0, "offset_s": 2.5},
    {"caption": "a phone ringing", "onset_s": 6.0, "offset_s": 7.0},
]


@pytest.fixture(scope="module")
def module():
    text = text_encoder()
    m = AudioModule(GRID)
    t = np.arange(0, 12.0, 1 / 30)
    # the microphone moves along +x: at 0.1 m while the dog barks, at 0.5 m for the phone
    m.add(
        _track([(1.0, 2.5), (6.0, 7.0)]),
        RATE,
        t,
        _poses(t, lambda s: (0.1 if s < 4 else 0.5, 0.0)),
        OracleAudioEncoder(text, EVENTS),
    )
    return m


def test_two_sounds_in_a_row_give_two_segments_where_they_were_heard(module):
    assert len(module) == 2
    (a, b) = module.segments
    assert a.start_s == pytest.approx(1.0, abs=0.3) and b.start_s == pytest.approx(6.0, abs=0.3)
    np.testing.assert_allclose(module.positions[0][:2], [0.1, 0.0])
    np.testing.assert_allclose(module.positions[1][:2], [0.5, 0.0])


def test_a_query_heats_where_its_sound_was_heard(module):
    text = text_encoder()
    h = module.heatmap("the sound of a phone ringing", 10.0, text, judge_at(0.1))
    assert h.found
    p = max_position(h, np.zeros(GRID.shape, bool))
    np.testing.assert_allclose(p[:2], [0.5, 0.0], atol=0.011)


def test_one_segment_is_judged_against_reference_sounds():
    text = text_encoder()
    m = AudioModule(GRID)
    t = np.arange(0, 6.0, 1 / 30)
    m.add(
        _track([(1.0, 2.0)], 6.0),
        RATE,
        t,
        _poses(t, lambda s: (0.2, 0.1)),
        OracleAudioEncoder(text, EVENTS[:1]),
    )
    assert len(m) == 1
    right = m.heatmap("a dog barking", 10.0, text, judge_at(0.3))
    absent = m.heatmap("a submarine sonar ping", 10.0, text, judge_at(0.3))
    assert right.found and not absent.found
    assert right.evidence > 0.5 > absent.evidence


def test_a_sound_heard_in_two_of_three_places_is_found():
    # a room scan: three episodes, one sound heard at two tables; the segments' median is
    # then that sound's own score, and the reference sounds must set the floor instead
    text = text_encoder()
    m = AudioModule(GRID)
    t = np.arange(0, 12.0, 1 / 30)
    events = [
        {"caption": "the sound of hammering", "onset_s": 1.0, "offset_s": 2.0},
        {"caption": "the sound of a violin playing", "onset_s": 5.0, "offset_s": 6.0},
        {"caption": "the sound of hammering", "onset_s": 9.0, "offset_s": 10.0},
    ]
    m.add(
        _track([(1.0, 2.0), (5.0, 6.0), (9.0, 10.0)]),
        RATE,
        t,
        _poses(t, lambda s: (0.1 + 0.04 * s, 0.0)),
        OracleAudioEncoder(text, events),
    )
    assert len(m) == 3
    h = m.heatmap("the sound of hammering", 10.0, text, judge_at(0.3))
    assert h.found and h.evidence > 0.4
    assert not m.heatmap("a submarine sonar ping", 10.0, text, judge_at(0.3)).found


def test_bad_input_names_the_problem():
    with pytest.raises(ConfigError, match="one pose per timestamp"):
        AudioModule(GRID).add(_track([]), RATE, np.arange(3.0), np.zeros((2, 4, 4)), None)
    with pytest.raises(ConfigError, match="NoiseGateConfig"):
        AudioConfig(gate={"threshold_db": -10})
    assert AudioConfig(gate=NoiseGateConfig(hold_s=0.5)).gate.hold_s == 0.5
    h = AudioModule(GRID).heatmap("x", 10.0, text_encoder(), judge_at(0))
    assert not h.found and "no audio segments" in h.reason


def test_the_default_encoder_places_held_out_recordings_and_refuses_unplayed_sounds():
    """Real held-out clips over the scans' background, heard at three places: the embedded
    default encoder and its vocabulary find each where it played and refuse sounds that did
    not play, at the shipped operating point."""
    from tabletop.audio import background_noise, insert_clip
    from tabletop.mapping.calibration import load_calibration
    from tabletop.mapping.encoders.audio import MelCNNAudioEncoder
    from tabletop.sim.sound_bank import SoundBank

    bank, enc, text = SoundBank.default(), MelCNNAudioEncoder(), text_encoder()
    cats = ["dog", "cow", "clapping", "piano"]
    x = background_noise(24 * RATE, RATE, np.random.default_rng(5)).astype(np.float64)
    for k, cat in enumerate(cats):
        insert_clip(x, bank.clips(category=cat, split="heldout")[0].load(), 2 + 5.5 * k, RATE, 15)
    t = np.arange(0, 24.0, 1 / 30)
    where = np.array([0.1, 0.25, 0.4, 0.55])
    m = AudioModule(GRID, AudioConfig(), enc.vocabulary)
    m.add(
        x.astype(np.float32), RATE, t, _poses(t, lambda s: (where[min(int(s // 5.5), 3)], 0.0)), enc
    )
    cal = load_calibration("default")

    def judge(modality, margin):
        return cal.judge(modality, margin, 0.5)

    right = 0
    for k, cat in enumerate(cats):
        h = m.heatmap(bank.caption(cat), 10.0, text, judge)
        if h.found:
            p = max_position(h, np.zeros(GRID.shape, bool))
            right += abs(p[0] - where[k]) <= 0.05
    assert right >= 3, right
    for absent in ("the sound of a horse neighing", "the sound of a trumpet playing"):
        assert not m.heatmap(absent, 10.0, text, judge).found, absent
    assert not m.heatmap("a submarine sonar ping", 10.0, text, judge).found


def test_segments_keep_class_logits_for_sounds_the_bank_never_had():
    """With the YAMNet encoder each segment keeps its AudioSet logits: a sound outside the
    bank (a 440 Hz tone, "a dial tone") is found where it played, one that never played
    (a foghorn) is refused, and a bank sound still goes through the bank's vocabulary."""
    from tabletop.mapping.encoders.yamnet_audio import YamnetAudioEncoder
    from tabletop.sim.sound_bank import SoundBank

    enc, text = YamnetAudioEncoder(), text_encoder()
    x = _track([(1.0, 2.5)], seconds=10.0)
    dog = max(SoundBank.default().clips("dog", split="train"), key=lambda c: len(c.load()))
    bark = dog.load()[: 2 * RATE]
    x[6 * RATE : 6 * RATE + len(bark)] += bark
    m = AudioModule(GRID, vocabulary=enc.vocabulary)
    t = np.arange(0, 10.0, 1 / 30)
    m.add(x, RATE, t, _poses(t, lambda s: (0.1 if s < 4 else 0.5, 0.0)), enc)
    assert len(m.class_logits) == len(m) >= 2 and m.class_logits[0].shape == (521,)
    assert len(m.class_names) == 521
    tone = m.match("a dial tone", text)
    assert tone.categories and all(c.startswith("audioset:") for c in tone.categories)
    assert m.segments[int(np.argmax(tone.scores))].start_s < 4
    assert m.heatmap("a dial tone", 10.0, text, judge_at(0.187)).found
    assert not m.heatmap("a foghorn", 10.0, text, judge_at(0.187)).found
    assert m.match("a dog barking", text).categories == ("dog",)

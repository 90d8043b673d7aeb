"""The learned reader: decoding tags into plans, its weights file, and the committed tagger."""

import numpy as np
import pytest
import torch

from tabletop.errors import AssetError
from tabletop.reader import ParseError
from tabletop.reader.learned import (
    DEFAULT_READER_WEIGHTS,
    RELATIONS,
    ROLES,
    TaggerConfig,
    _net,
    best_roles,
    decode,
    goal_counts,
    load_tagger,
    save_tagger,
    words_of,
)
from tabletop.reader.plan import Above, Between, Compass, Goal, GoTo, Part, Side
from tabletop.reader.rules import parse_instruction


def _decode(tagged: str, relation: str = "goto"):
    """'word/TAG ...' (untagged words are O) -> plan."""
    words, roles = [], []
    for tok in tagged.split():
        w, _, r = tok.partition("/")
        words.append(w)
        roles.append(r or "O")
    rels = relation.split() if " " in relation else [relation] * len(words)
    return decode(" ".join(words), words, roles, rels, "arm", parse_instruction)


def test_a_goal_narrowed_by_a_sound():
    (step,) = _decode(
        "go to the/B-OBJ red/I-OBJ mug/I-OBJ near a/B-NSOUND dog/I-NSOUND barking/I-NSOUND"
    )
    assert step.action == GoTo(Goal(Part("obj", "red mug"), (Part("sound", "dog barking"),)))


def test_relations_pick_the_action_and_steps_split_at_then():
    a, b = _decode(
        "go between the/B-OBJ tray/I-OBJ and the/B-OBJ duck/I-OBJ ,/THEN then/THEN "
        "left of the/B-OBJ ball/I-OBJ",
        "between " * 9 + "left left left left",
    )
    assert a.action == Between(Goal(Part("obj", "tray")), Goal(Part("obj", "duck")))
    assert b.action == Side("left", "ball")
    (c,) = _decode("hover over the/B-OBJ cube/I-OBJ", "above")
    assert c.action == Above("cube")


def test_a_motion_step_is_read_by_the_grammar_and_repetitions_counted():
    (step,) = _decode("move 5 cm north", "motion")
    assert isinstance(step.action, Compass) and step.action.distance_m == pytest.approx(0.05)
    (rep,) = _decode("go to the/B-OBJ duck/I-OBJ three/REP times/REP")
    assert rep.times == 3


def test_a_step_without_the_references_its_relation_takes_is_refused():
    with pytest.raises(ParseError, match="names nothing"):
        _decode("go over there please")
    with pytest.raises(ParseError, match="'between' takes two places"):
        _decode("go between the/B-OBJ tray/I-OBJ and it", "between")
    with pytest.raises(ParseError, match="points back"):
        _decode("go between the/B-OBJ tray/I-OBJ and it/B-OBJ", "between")
    (step,) = _decode("go to the/B-OBJ teddy/B-OBJ bear/B-OBJ")  # one reference, however begun
    assert step.action == GoTo(Goal(Part("obj", "teddy bear")))


def test_weights_round_trip_and_bad_files(tmp_path):
    cfg = TaggerConfig(hidden=8)
    net = _net(cfg)
    path = save_tagger(tmp_path / "r.pt", cfg, net, {"note": 1})
    tagger = load_tagger(path)
    roles, rels = tagger.tag(words_of("go to the mug"))
    assert len(roles) == len(rels) == 4 and tagger.meta == {"note": 1}
    with pytest.raises(AssetError, match="do not exist"):
        load_tagger(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    torch.save({"format": "something else"}, bad)
    with pytest.raises(AssetError, match="is not a reader tagger"):
        load_tagger(bad)


@pytest.mark.skipif(not DEFAULT_READER_WEIGHTS.is_file(), reason="no committed reader weights")
@pytest.mark.parametrize(
    ("text", "kind", "relation"),
    [
        ("go to the red mug", "obj", GoTo),
        ("would you be so kind as to go over to the teddy bear", "obj", GoTo),
        ("move between the mug and the duck", "obj", Between),
        ("go where you heard a dog barking", "sound", GoTo),
        ("head to the left side of the table", "area", GoTo),
    ],
)
def test_the_committed_tagger_reads_plain_requests(text, kind, relation):
    from tabletop.reader.reading import understand

    (step,) = understand(text, reader="learned").steps
    assert isinstance(step.action, relation)
    goal = step.action.goal if relation is GoTo else step.action.a
    assert goal.primary.kind == kind


def _logp(rows: list[dict[str, float]]) -> np.ndarray:
    """(T, len(ROLES)) log-probabilities: each word's given roles' probabilities, the rest
    sharing what is left."""
    out = np.full((len(rows), len(ROLES)), 1e-6)
    for t, row in enumerate(rows):
        for role, p in row.items():
            out[t, ROLES.index(role)] = p
    return np.log(out / out.sum(axis=1, keepdims=True))


def test_goal_counts_gives_the_best_roles_for_each_number_of_goals():
    # "the red mug and the duck": the tagger leans to one reference over all six words
    words = "the red mug and the duck".split()
    logp = _logp([
        {"B-OBJ": 0.9, "O": 0.1},
        {"I-OBJ": 0.9, "O": 0.1},
        {"I-OBJ": 0.9, "O": 0.1},
        {"I-OBJ": 0.55, "O": 0.45},
        {"I-OBJ": 0.55, "B-OBJ": 0.4, "O": 0.05},
        {"I-OBJ": 0.9, "O": 0.1},
    ])  # fmt: skip
    counts = goal_counts(logp)
    assert counts[1][1] == ["B-OBJ"] + ["I-OBJ"] * 5
    assert counts[2][1] == ["B-OBJ", "I-OBJ", "I-OBJ", "O", "B-OBJ", "I-OBJ"]
    assert counts[1][0] > counts[2][0] > counts[3][0]
    assert counts[0][1] == ["O"] * 6
    assert len(words) == len(counts[2][1])
    # a constraint before any goal is that goal; a constraint after one is not counted
    logp = _logp([{"B-NOBJ": 0.9}, {"O": 0.9}, {"B-NSOUND": 0.9}])
    assert goal_counts(logp)[1][1] == ["B-NOBJ", "O", "B-NSOUND"]


def test_the_joint_reading_cuts_references_as_the_relation_takes():
    words = "go between the red mug and the duck".split()
    role_logp = _logp([
        {"O": 0.95},
        {"O": 0.95},
        {"B-OBJ": 0.9, "O": 0.1},
        {"I-OBJ": 0.9, "O": 0.1},
        {"I-OBJ": 0.9, "O": 0.1},
        {"I-OBJ": 0.55, "O": 0.45},
        {"I-OBJ": 0.55, "B-OBJ": 0.4, "O": 0.05},
        {"I-OBJ": 0.9, "O": 0.1},
    ])  # fmt: skip
    rels = np.log(np.full((len(words), len(RELATIONS)), 0.01))
    rels[:, RELATIONS.index("between")] = np.log(0.9)
    # the unconstrained roles join the two things into one: refused without the joint reading
    roles = best_roles(role_logp)
    with pytest.raises(ParseError, match="'between' takes two places"):
        decode(" ".join(words), words, roles, rels, "arm", parse_instruction)
    (step,) = decode(" ".join(words), words, roles, rels, "arm", parse_instruction, role_logp)
    assert step.action == Between(Goal(Part("obj", "red mug")), Goal(Part("obj", "duck")))
    # a step the tagger reads as something the arm does not do is refused, naming it
    rels[:] = np.log(0.01)
    rels[:, RELATIONS.index("none")] = np.log(0.9)
    with pytest.raises(ParseError, match="asks something else"):
        decode(" ".join(words), words, roles, rels, "arm", parse_instruction, role_logp)


def test_a_reading_never_drops_a_named_thing_nor_merges_two_relations():
    # the tagger reads two things; a side takes one: the re-cut that drops "mug" is refused
    words = "go to the mug in front of the duck".split()
    role_logp = _logp([
        {"O": 0.95}, {"O": 0.95}, {"B-OBJ": 0.8, "O": 0.2}, {"I-OBJ": 0.8, "O": 0.2},
        {"O": 0.95}, {"O": 0.95}, {"O": 0.95}, {"B-OBJ": 0.9, "O": 0.1}, {"I-OBJ": 0.9, "O": 0.1},
    ])  # fmt: skip
    rels = np.log(np.full((len(words), len(RELATIONS)), 0.01))
    rels[:, RELATIONS.index("front")] = np.log(0.9)
    args = (" ".join(words), words, best_roles(role_logp), rels, "arm", parse_instruction)
    with pytest.raises(ParseError, match="leave out 'mug'"):
        decode(*args, role_logp)
    # words sure of two sides in one step: two requests without a joining word
    words = "move in front of the duck to the right of it".split()
    roles = ["O"] * 4 + ["B-OBJ", "I-OBJ"] + ["O"] * 5
    rels = np.log(np.full((len(words), len(RELATIONS)), 0.001))
    rels[:6, RELATIONS.index("front")] = np.log(0.99)
    rels[6:, RELATIONS.index("right")] = np.log(0.99)
    with pytest.raises(ParseError, match="front and right at once"):
        decode(" ".join(words), words, roles, rels, "arm", parse_instruction)
    rels[6:, RELATIONS.index("right")] = np.log(0.6)  # unsure words: one relation is read
    (step,) = decode(" ".join(words), words, roles, rels, "arm", parse_instruction)
    assert step.action == Side("front", "duck")
    # words sure of going there beside a side: the side is where to go, not a second request
    rels[6:, :] = np.log(0.001)
    rels[6:, RELATIONS.index("goto")] = np.log(0.99)
    (step,) = decode(" ".join(words), words, roles, rels, "arm", parse_instruction)
    assert step.action == Side("front", "duck")


def test_words_sure_of_a_motion_the_grammar_cannot_read_are_no_second_request():
    # the tagger is sure of a motion on the words before a side: a second request only when
    # the grammar reads those words as a motion
    def sure(words, motion_words, side="front"):
        rels = np.log(np.full((len(words), len(RELATIONS)), 0.001))
        rels[:, RELATIONS.index(side)] = np.log(0.99)
        rels[:motion_words, :] = np.log(0.001)
        rels[:motion_words, RELATIONS.index("motion")] = np.log(0.99)
        return rels

    words = "move 10 cm left in front of the duck".split()
    roles = ["O"] * 7 + ["B-OBJ", "I-OBJ"]
    with pytest.raises(ParseError, match="front and motion at once"):
        decode(" ".join(words), words, roles, sure(words, 4), "arm", parse_instruction)
    words = "wander yonder sideways in front of the duck".split()
    roles = ["O"] * 6 + ["B-OBJ", "I-OBJ"]
    (step,) = decode(" ".join(words), words, roles, sure(words, 3), "arm", parse_instruction)
    assert step.action == Side("front", "duck")

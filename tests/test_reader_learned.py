"""The learned reader: decoding tags into plans, its weights file, and the committed tagger."""

import pytest
import torch

from tabletop.errors import AssetError
from tabletop.reader import ParseError
from tabletop.reader.learned import (
    DEFAULT_READER_WEIGHTS,
    TaggerConfig,
    _net,
    decode,
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
    with pytest.raises(ParseError, match="'between' takes 2 place"):
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

"""The offline instruction parser: a table-top instruction in English becomes a plan.

No model is involved: a small grammar over the instruction families of the paper's prompts
(object, sound, image and area goals; "X near Y" for any two modalities; "between A and B";
left/right/front/behind of an object; compass moves; sequences with "then"; repetition with
"twice" or "3 times"; back and forth between two goals). Requests are read as people word
them: a polite wrapper ("could you ...", "I want you to ...", "..., please"), the arm named or
not ("move your hand to"), a place named by its relation ("the spot between A and B", "the
duck's left", "hover over X"), a goal narrowed by many near words ("right by", "not far from",
"in the vicinity of", "sitting next to") and a sound by what was heard ("where the dog barked",
"the barking you heard", "where the ringing came from", "the noise like a cat"). Manner
words the robot cannot honour ("slowly") are refused, not dropped.

The plan (:mod:`tabletop.reader.plan`) becomes robot code in
:mod:`tabletop.language.codegen`, the code a prompted LLM writes against
:class:`tabletop.robot.RobotAPI`, and goes through the same sandbox. Anything outside the grammar
raises :class:`ParseError` naming the part it did not understand; the parser never guesses.

Typical use::

    from tabletop.language import parse_instruction, plan_to_code

    plan = parse_instruction("go to the mug near the sound of a dog barking, then to the duck")
    code = plan_to_code(plan)
"""

from __future__ import annotations

import functools
import re
import unicodedata

from tabletop.embodiments import embodiment
from tabletop.reader.errors import ParseError
from tabletop.reader.lexicon.words import NEGATIONS, is_negation, negations, ordinal, superlative
from tabletop.reader.plan import (
    Above,
    BackAndForth,
    Between,
    Compass,
    Face,
    Forward,
    Goal,
    GoTo,
    Part,
    Side,
    Step,
    Turn,
)
from tabletop.relations import relation, relation_by_side

__all__ = [
    "GATHERING",
    "MANNER",
    "MAX_DISTANCE_M",
    "MAX_DRIVE_M",
    "MAX_REPEAT",
    "NEGATIONS",
    "QUALIFIERS",
    "REQUEST_EXAMPLES",
    "SEVERAL_WHY",
    "STRUCTURE_WORDS",
    "ends_in_determiner",
    "is_negation",
    "is_verb_phrase",
    "negations",
    "ordinal",
    "parse_instruction",
    "refuse_negated",
    "refuse_nested_relation",
    "refuse_no_words",
    "refuse_non_words",
    "refuse_relation_distance",
    "several",
]

MAX_REPEAT = 20
"""Most repetitions of one step ("20 times")."""
MAX_DISTANCE_M = embodiment("arm").max_move_m
"""Longest compass move of the arm [m]: the table is about a metre across."""
MAX_DRIVE_M = embodiment("mobile").max_move_m
"""Longest move of a mobile base [m] (forward, back, compass): a room is a few metres."""


# ---------------------------------------------------------------------- vocabulary
_NUMBERS = {
    "a": 1,
    "an": 1,
    "one": 1,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "seven": 7,
    "eight": 8,
    "nine": 9,
    "ten": 10,
    "twelve": 12,
    "fifteen": 15,
    "twenty": 20,
    "thirty": 30,
    "forty": 40,
    "fifty": 50,
}
_NUM = r"(?:\d+(?:\.\d+)?|\.\d+|" + "|".join(sorted(_NUMBERS, key=len, reverse=True)) + ")"
_UNITS = {
    "mm": 0.001,
    "millimeter": 0.001,
    "millimetre": 0.001,
    "cm": 0.01,
    "centimeter": 0.01,
    "centimetre": 0.01,
    "m": 1.0,
    "meter": 1.0,
    "metre": 1.0,
    "km": 1000.0,
    "kilometer": 1000.0,
    "kilometre": 1000.0,
    "inch": 0.0254,
    "ft": 0.3048,
    "foot": 0.3048,
    "feet": 0.3048,
    "yd": 0.9144,
    "yard": 0.9144,
    "mile": 1609.344,
}
# longer names first: the alternation takes the first that matches
_UNIT = (
    r"(?:kilomet(?:er|re)s?|km|millimet(?:er|re)s?|mm|centimet(?:er|re)s?|cm|met(?:er|re)s?|"
    r"miles?|m|inch(?:es)?|ft|foot|feet|yards?|yd)"
)


def unit_metres(unit: str) -> float:
    """Metres in one ``unit`` as :data:`_UNIT` reads it ("cm", "inches", "feet", "km")."""
    u = unit.lower()
    for name in (u, u.removesuffix("es"), u.removesuffix("s")):
        if name in _UNITS:
            return _UNITS[name]
    raise KeyError(unit)


_DIST = rf"(-?{_NUM})\s*({_UNIT})"  # a sign is read, to be refused by name
_DIRECTIONS = {
    "north": "north",
    "forward": "north",
    "forwards": "north",
    "ahead": "north",
    "away": "north",
    "south": "south",
    "back": "south",
    "backward": "south",
    "backwards": "south",
    "west": "west",
    "left": "west",
    "east": "east",
    "right": "east",
}
_DIR = "(" + "|".join(sorted(_DIRECTIONS, key=len, reverse=True)) + ")"

#: Words that negate, condition or qualify how a motion is done: a reader never drops one as
#: a wrapper around a request (the robot cannot honour them, so the request is refused).
QUALIFIERS = frozenset(
    """not no never don't dont without avoid except unless until if while quickly slowly
    carefully gently fast""".split()
)
#: The qualifiers that say how to move, not where: the learned reader reads the goal and says
#: these are not honoured (the arm moves at its controller's speed).
MANNER = frozenset("quickly slowly carefully gently fast".split())
#: Words that point back instead of naming: a reference made of one of them names nothing.
POINTERS = frozenset("it its them this that these those there here one".split())
# Words that carry structure: inside an object description they mean the sentence had a
# construction the grammar does not know, so the parser stops instead of guessing.
_RESERVED = (
    frozenset(
        """left right front behind back between middle halfway of and or then near next close
    closest nearest beside times twice thrice once sound sounds noise image picture photo where
    heard hear north south east west below under beneath over above to from
    with into onto towards toward after before again repeat meters metres meter metre cm mm
    grab pick place put push get fetch bring take go move open close turn rotate face look it its
    them there here me you everything all every""".split()
    )
    | QUALIFIERS
)
_ARTICLES = re.compile(r"^(?:(?:the|a|an|some|any|that|this)\s+)+")


#: A reference that counts or gathers several things: "the two mugs", "both ducks", "all
#: the cubes", "3 balls" (a measure, "the 5 cm cube", is one thing's size).
#: Words that gather several things wherever they stand ("each side of", "all the cubes").
GATHERING = ("all", "both", "each", "every")
_SEVERAL = re.compile(
    r"^(?:(?:the|these|those|my|your)\s+)?"
    rf"(?:(?:{'|'.join(GATHERING)})\b(?!\s+the\s+way\b|\s+right\b)|"
    r"(?P<n>" + "|".join(n for n, v in _NUMBERS.items() if v > 1) + rf"|\d+)\s+(?!{_UNIT}\b)"
    # (a digit before a determiner counts nothing: "go 2 the mug" is typed for "to")
    r"(?<!\d\s)(?!(?:the|a|an|this|that|my|your)\b))"
)


def several(text: str) -> str | None:
    """The word by which a reference counts or gathers several things ("the two mugs": "two";
    "both ducks", "all the cubes"), or None: the robot goes to one place."""
    m = _SEVERAL.match(str(text).strip().lower())
    return m.group(0).split()[-1] if m else None


#: Why a reference of several things is refused.
SEVERAL_WHY = (
    "a reference names one thing, and this one names several; the robot goes to one place: "
    "name the one meant (by its colour, or a thing near it), or ask for 'between A and B'"
)


def refuse_negated(text: str) -> None:
    """Refuse a reference that negates what it names ("not the red mug", "the cup that isn't
    red"): ParseError naming the word. ("no" and "without" also describe, and pass: "the mug
    with no handle".)"""
    negated = negations(text, describing=True)
    if negated:
        raise ParseError(
            text,
            negated[0],
            "a reference names what to find; ask for what is there instead of what is not",
        )


#: What a request looks like, for messages that refuse one.
REQUEST_EXAMPLES = (
    "'go to the red mug', 'move 10 cm north, then to the duck', 'go to the image ./goal.png'"
)
#: Code, not words, in a request: punctuation no request needs, a call ("f(", ")(") and a
#: quote closed into a bracket ('")', '("'). A parenthesis after a space is a remark ("the
#: ball (the soccer kind)") and passes; an image path is not looked at.
_CODE_PUNCT = re.compile(r"[`{}\[\]<>=\\|$]|\w\(|\)\(|[\"']\)|\([\"']|\);")
_CONTROL_NAMES = {"\n": "a line break", "\r": "a line break", "\t": "a tab", "\x1b": "an escape"}


#: The longest request read (characters): a few sentences of steps. A longer text is refused
#: before any reading: reading it took tens of seconds, and its error quoted it whole.
MAX_REQUEST_CHARS = 1000


def refuse_non_words(text: str) -> None:
    """Refuse a request that is not one line of words: a control or format character (a line
    break, a tab, a terminal escape, a bidi override) or code punctuation (a backtick, a
    bracket, a call, a quote closed into a parenthesis, ``= | $ \\ < >``); nothing is read
    from such a request, and no reader takes the junk as a thing's words. ParseError naming
    the character and what a request looks like."""
    if not isinstance(text, str):
        return
    if len(text) > MAX_REQUEST_CHARS:
        raise ParseError(
            text[:60] + " ...",
            f"{len(text)} characters",
            f"a request is at most {MAX_REQUEST_CHARS} characters (a few sentences); this one "
            f"holds {len(text)}: ask it in shorter requests",
            out_of_range=True,
        )
    for ch in text.strip():  # a line's own end is no line break inside it
        if unicodedata.category(ch) == "Cs":  # half of a character, no character
            raise ParseError(
                text.encode("utf-8", "replace").decode("utf-8"),
                f"U+{ord(ch):04X}",
                "a request is text, and this one holds half of a character (a lone surrogate, "
                f"U+{ord(ch):04X}); send it as UTF-8 text",
            )
        if unicodedata.category(ch) == "Cc" or (
            unicodedata.category(ch) == "Cf" and ch != "\u200d"
        ):
            what = _CONTROL_NAMES.get(ch, f"a control character (U+{ord(ch):04X})")
            raise ParseError(
                text,
                ch,
                f"a request is one line of words; this one holds {what}. A request looks "
                f"like {REQUEST_EXAMPLES}",
            )
    refuse_no_words(text)
    m = _CODE_PUNCT.search(_PATH.sub(" ", text))
    if m:
        raise ParseError(
            text,
            m.group(0),
            f"a request is words, not code: {m.group(0)!r} is code punctuation, in no thing's "
            f"name. A request looks like {REQUEST_EXAMPLES}",
        )


#: A distance said before a relation to a thing ("5 cm to the left of the mug", "3 inches in
#: front of the duck"): a side goal stands at the relation's own offset, so the number would be
#: dropped without a word.
_RELATION_DISTANCE = re.compile(
    rf"\b{_DIST}\s+(?:(?:over\s+)?to\s+(?:the\s+)?(?:left|right)(?:[\s-]+hand)?(?:\s+side)?\s+of|"
    r"(?:out\s+)?in\s+front\s+of|behind|beside|above|past|beyond|away\s+from)\b",
    re.IGNORECASE,
)


_BETWEEN_WORD = re.compile(r"\bbetween\b", re.IGNORECASE)


def refuse_relation_as_area(ref):
    """``ref`` (an :class:`~tabletop.mapping.table_regions.AreaRef`), unless it names no
    region of the table and its words say a relation to things: the point between two things,
    or a distance from one. Those words would otherwise be looked for as a thing ("between the
    tray and the bear" found the bear); a region's own words may hold "between" (a middle
    named as lying between the table's edges). ParseError naming the words and the
    instruction that says it."""
    if ref.region is not None:
        return ref
    refuse_relation_distance(ref.text)
    if m := _BETWEEN_WORD.search(ref.text):
        raise ParseError(
            ref.text,
            m.group(0),
            "an area is a place of the table, and the point between two things is a relation "
            'between them: ask it as an instruction, e.g. `tabletop run MAP "go between the '
            'tray and the mug"`',
        )
    return ref


def refuse_relation_distance(text: str) -> None:
    """Refuse a distance said for a relation to a thing: the robot goes to the relation's own
    place (beside, in front, behind at their fixed offsets), so a number there would be
    dropped. ParseError naming the words and the two steps that say it."""
    m = _RELATION_DISTANCE.search(text)
    if m:
        raise ParseError(
            text,
            m.group(0),
            "a distance from a thing is not honoured: a side of a thing is at the relation's "
            "own offset. Say it in two steps, e.g. 'go to the left of the mug, then move 5 cm "
            "west'",
        )


def refuse_no_words(text: str) -> None:
    """Refuse text that holds no word at all: only emoji, symbols, punctuation or digits
    ("...", "123"). A letter of any script is a word's (other languages are refused by
    :func:`refuse_not_english`); empty text is left to the caller, which names it empty.
    ParseError naming what it holds instead and what a request looks like."""
    if not isinstance(text, str) or not text.strip():
        return
    if any(unicodedata.category(ch).startswith("L") for ch in text):
        # (an emoji, a pictograph, a dingbat: "other symbols"; code punctuation such as "|"
        # or "$" is named as code by refuse_non_words)
        symbols = [
            w
            for w in text.split()
            if any(unicodedata.category(ch) == "So" for ch in w)
            and all(unicodedata.category(ch).startswith("S") or ch in "\u200d\ufe0f" for ch in w)
        ]
        if symbols:  # "go to the 🦆": the reading had named "the" as naming nothing
            raise ParseError(
                text,
                symbols[0],
                f"{symbols[0]!r} is a symbol, not a word: name the thing, the sound or the "
                f"place in words. A request looks like {REQUEST_EXAMPLES}",
            )
        return
    kinds = sorted(
        {
            "digits"
            if unicodedata.category(ch).startswith("N")
            else "punctuation"
            if unicodedata.category(ch).startswith("P")
            else "symbols or emoji"
            for ch in text
            if not ch.isspace()
        }
    )
    raise ParseError(
        text,
        text.strip(),
        f"a request holds no words, only {' and '.join(kinds)}; name a thing, a sound or a "
        f"place in words. A request looks like {REQUEST_EXAMPLES}",
    )


def _relations_at(text: str):
    """(relation name, its reference's words) for each way the grammar reads ``text`` as
    starting with a spatial relation (:data:`tabletop.relations.RELATIONS`)."""
    text = _HEDGE.sub("", _PLACE_OF.sub("", text))
    for side, rx in _SIDES:
        m = rx.match(text)
        if m:
            yield relation_by_side(side).name, next(g for g in m.groups() if g is not None)
    for name, rx in (("above", _ABOVE), ("between", _BETWEEN), ("between", _FROM_TO)):
        m = rx.match(text)
        if m and not (name == "above" and re.match(r"(?:right\s+|just\s+)?over\b", text)):
            yield name, m.group(1)  # "over" may be a way of going ("over to", "over behind")
    m = _POSSESSIVE_SIDE.match(_POLITE_TAIL.sub("", text).strip(" ,"))
    if m:
        side = {"back": "behind", "rear": "behind"}.get(m.group(2), m.group(2))
        yield relation_by_side(side).name, m.group(1)


def refuse_nested_relation(text: str) -> None:
    """Refuse a spatial relation whose reference is itself a relation ("the left of the right
    of X", "above the left of X", "between the front of A and B"): a plan's relation is taken
    of a thing, so no reader can honour both, and none may drop one. ParseError naming the
    part; table areas ("the left side of the table") are places, not relations, and pass."""
    if not isinstance(text, str):
        return
    low = re.sub(r"\s+", " ", text.lower()).strip()
    low = _TABLE_AREA.sub(" @area@ ", _TABLE_CORNER.sub(" @area@ ", low))
    for clause in _STEP_SPLIT.split(low):
        clause = re.sub(r"[.!?]+$", "", clause.strip(" ,"))
        for start in [0, *(m.end() for m in re.finditer(r"\s+", clause))]:
            for outer, said in _relations_at(clause[start:]):
                said = said.strip(" ,")
                # the reference, and for two references each one after an "and"
                refs = [said]
                if outer == "between":
                    refs += [said[m.end() :] for m in re.finditer(r"\s+(?:and|to)\s+", said)]
                for ref in refs:
                    inner = next(iter(_relations_at(ref)), None)
                    if inner is not None:
                        wording = relation(outer).wording
                        raise ParseError(
                            text,
                            clause[start:],
                            "a spatial relation is taken of a thing, not of another relation: "
                            f"'{outer}' is taken here of {ref!r} (relation '{inner[0]}'); name "
                            f"the thing (e.g. '{wording} the mug'), or make two steps joined "
                            "by 'then'",
                        )
        # "the mug near the left of the duck": what narrows a goal is a thing, a sound or a
        # place, not a relation ("in", "on", "by" also start relations; "go near" is a verb)
        for m in _CONNECT.finditer(clause):
            before = _POLITE_HEAD.sub("", clause[: m.start()], count=1).strip(" ,")
            verb = _VERB.match(before)
            if m.group(1) in ("in", "on", "by", "around") or (verb and verb.end() >= len(before)):
                continue
            inner = next(iter(_relations_at(clause[m.end() :])), None)
            if inner is not None:
                raise ParseError(
                    text,
                    clause[m.start() :].strip(),
                    f"a goal is narrowed by a thing, a sound or a place, not by a relation: "
                    f"{m.group(1)!r} is taken here of {clause[m.end() :]!r} (relation "
                    f"'{inner[0]}'); name the thing (e.g. '{m.group(1)} the duck')",
                )


#: Verbs of motion that take the goal after a particle or a relation ("head to", "move
#: behind"), not as their object: followed at once by a thing ("take the mug", "make me a
#: coffee", "put the duck on the tray"), they ask to do something with it.
_MOTION_VERBS = (
    r"go|move|head|navigate|travel|get|come|drive|bring|take|send|guide|steer|position|"
    r"put|place|set|rest|park|lead|direct|pop|swing|hop|scoot|slide|glide|zip|shift|proceed|"
    r"advance|nip|dash|hurry|wander|make|trundle|nudge|edge|inch|creep|sneak|tuck|slip|duck|"
    r"hide|squeeze|slot|wedge|nestle|stick|pull\s+up|drop\s+back|cent(?:re|er)|point|aim"
)
_VERB = re.compile(
    r"^(?:please\s+)?(?:now\s+)?(?:let's\s+|(?:it's\s+)?time\s+to\s+)?(?:"
    r"lead\s+the\s+way\s+(?:to|towards?)|"  # before "lead" alone takes "the way" as a thing
    rf"(?:{_MOTION_VERBS})"
    # the robot's own part, said with any words before its noun ("your long metal arm")
    r"(?:\s+(?:(?:the|your)\s+(?:[a-z'-]+\s+){0,2})?"
    r"(?:arm|gripper|hand|fingers?|claw|tip|pointer|robot|"
    r"end[\s-]effector|tcp|camera|wrist|grabber|manipulator)|\s+yourself"
    r"|\s+your\s+way|\s+it|\s+me|\s+us)?"
    r"(?:\s+(?:on\s+)?(?:back|over|up|out|down|across|a?round|along|straight|right|directly)"
    r"\s+(?:to|towards?)|\s+as\s+close\s+as\s+(?:you\s+can|possible)\s+to|"
    r"\s+(?:closer|close|near)(?:\s+to)?|\s+next\s+to|\s+beside|\s+to|\s+towards?|"
    r"\s+into|\s+onto|\s+for|\s+at|\s+upon|\s+in\s+on|\s+a\s+beeline\s+for)?"
    r"|(?:make|find)\s+your\s+way\s+to|return\s+to|home\s+in\s+on|reach(?:\s+(?:out|over|across|down)"
    r"\s+to|\s+for)?|approach|visit|find|locate|touch|tap|poke|target|"
    r"(?:seek|search)\s+out|track\s+down|show\s+me|(?:point|aim)\s+(?:at|to|for)"
    r")(?:\s+|$)"
)
#: A motion verb that ends a step's verb phrase with no particle: what follows is its object,
#: not a place (see :data:`_MOTION_VERBS`); after the one it is done for ("bring me", "make
#: us") any noun phrase is.
_BARE_MOTION_VERB = re.compile(rf"(?:^|\s)(?:{_MOTION_VERBS})$")
_MOTION_VERB_FOR = re.compile(rf"(?:^|\s)(?:{_MOTION_VERBS})\s+(?:me|us)$")
#: A noun phrase's first word: a determiner ("a", "one" and "some" also start a measure:
#: "move a bit north", "one step left").
_DETERMINER = re.compile(
    r"^(?:the|a|an|some|my|our|your|his|her|their|this|that|these|those|one|two)\s"
)
_DEFINITE = re.compile(r"^(?:the|my|our|your|his|her|their|this|that|these|those)\s")


_MOTION_VERB = re.compile(rf"(?:{_MOTION_VERBS})")


def is_motion_verb(word: str) -> bool:
    """Whether ``word`` is a verb of going ("go", "head", "nip"), in any of its forms."""
    w = str(word).lower().strip(" ,.;:!?")
    stems = {w, w[:-1], w[:-2], w[:-3], w[:-4], w[:-2] + "e", w[:-3] + "e"}  # goes, nipping, moved
    return any(s and _MOTION_VERB.fullmatch(s) for s in stems)


def is_verb_phrase(text: str) -> bool:
    """Whether ``text`` is all a request's verb phrase, a polite head before it ("go to",
    "could you head over to", "please reach"): it says to go, and nothing of where."""
    said = _POLITE_HEAD.sub("", str(text).lower().strip(" ,"), count=1).strip(" ,")
    verb = _VERB.match(said + " ")
    return bool(said) and verb is not None and verb.end() >= len(said)


def ends_in_determiner(text: str) -> bool:
    """Whether ``text``'s last word is a determiner ("put the"): a cut after it would split a
    noun phrase."""
    words = str(text).lower().split()
    return bool(words) and bool(_DETERMINER.match(words[-1] + " "))


#: What a request may be wrapped in: "could you ...", "I want you to ...", "..., please".
_POLITE_HEAD = re.compile(
    r"^(?:(?:ok(?:ay)?|alright|now|hey|robot)\s*,?\s+)*"
    r"(?:(?:could|can|would|will)\s+you\s+(?:please\s+)?|please\s+|"
    r"i(?:\s+would|'d)?\s+(?:want|like|need)\s+you\s+to\s+|you\s+(?:should|must|need\s+to)\s+|"
    r"(?:try|be\s+sure|make\s+sure)\s+to\s+)?"
)
#: "I want you at the mug", "I'd like you behind the tray": a place without a verb.
_WANT_YOU_AT = re.compile(
    r"^i(?:\s+would|'d)?\s+(?:want|like|need)\s+(?:you|the\s+(?:arm|gripper|robot))\s+"
    r"(?:to\s+be\s+)?(?:at\s+|by\s+)?(?=the\s|behind\s|between\s|in\s|on\s|above\s|over\s|"
    r"next\s|near\s|beside\s|close\s|right\s|left\s)"
)
_POLITE_TAIL = re.compile(r"(?:\s*,?\s+(?:please|for\s+me|now|right\s+away|if\s+you\s+can))+$")
#: "go and touch the ball", "go ahead and reach the mug": the second verb is the step's.
_GO_AND = re.compile(r"^(?:go|come)\s+(?:ahead\s+)?and\s+")
#: "the spot between A and B", "a point behind the mug": a place named by a relation.
_PLACE_OF = re.compile(
    r"^(?:(?:the|a|an)\s+)?(?:empty\s+|free\s+|open\s+)?(?:spot|place|point|space|area|"
    r"position|location|gap|bit|middle\s+ground)\s+"
    r"(?:(?:just|right|directly|somewhere|exactly)\s+)?"
    r"(?=(?:in\s+)?between\b|halfway\b|midway\b|equidistant\b|left\b|right\b|"
    r"(?:in\s+)?front\b|behind\b|(?:to|on)\s+the\s+(?:left|right)\b|above\b|over\b|"
    r"in\s+the\s+middle\b|(?:at\s+)?the\s+(?:middle|midpoint|centre|center)\s+(?:of|between)\b|"
    r"(?:that\s+)?separat(?:es|ing)\b|past\b|beyond\b)"
)
#: "the duck's left (side)": a side of an object, said the other way round.
_POSSESSIVE_SIDE = re.compile(
    r"^(?:the\s+)?(.+?)'s\s+(left|right|front|back|rear)(?:[\s-]*hand)?(?:\s+side)?$"
)
#: "next to the mug, on its left": a side of an object, named after it.
_ON_ITS_SIDE = re.compile(
    r"^(?:(?:next\s+to|beside|by)\s+)?(.+?),?\s+on\s+its\s+(left|right)(?:[\s-]*hand)?"
    r"(?:\s+side)?$"
)
#: "the side of the mug facing you": its side toward the robot (behind it, by the robot's
#: convention) or away from it (in front of it).
_FACING = re.compile(
    r"^(?:the\s+)?side\s+of\s+(.+?)\s+(?:(facing\s+away\s+from|(?:farthest|furthest)\s+from|"
    r"away\s+from)|facing|nearest(?:\s+to)?|closest\s+to|towards?)\s+(?:you|me|the\s+robot)$"
)
#: "hover over X", "go stand next to X", "stop just left of X": staying somewhere is moving there.
_HOVER = re.compile(
    r"^(?:go\s+(?:and\s+)?)?(?:hover|stop|stay|hold|wait|stand|sit|park|settle|hang)"
    r"(?:\s+still)?\s+(?=(?:(?:right|just|directly|somewhere)\s+)?(?:over|above|next\s+to|"
    r"near|beside|by|at|close\s+to|between|in\s+between|(?:half|mid)way|past|beyond|"
    r"(?:to|on)\s+the\s+(?:left|right)|"
    r"left|right|in\s+front|behind|a?round|the\s+\w+\s+(?:side|of)\b))"
)
#: "go find the duck", "go and locate the mug": the second verb is the step's.
_GO_FIND = re.compile(r"^(?:go|come)\s+(?=(?:find|locate|touch|visit|reach|approach|tap)\b)")
#: "over by the mug", "right at the duck": a place said as where to be, after a verb.
_BE_AT = re.compile(
    r"^(?:(?:over|up|down|out|round|around|right|just)\s+)?(?:by|at|on|upon|in|into)\s+"
    r"(?!top\b|front\b|back\s+of\b)(?=\S)"
)
#: Words of posture or placing: "the mug sitting next to X", "where the duck is lying".
_POSTURE = (
    r"sitting|sits|sat|lying|lies|standing|stands|resting|rests|placed|located|positioned|"
    r"kept|parked|perched|set|left"
)
#: Words that only say how near or how exactly ("right next to", "just by", "up against").
_DEGREE = (
    r"right|just|directly|really|somewhere|over|up|down|round|around|kinda|kind\s+of|"
    r"sort\s+of|pretty|fairly|quite|close|more\s+or\s+less"
)
#: The words before a connector, one by one (a degree word of two words kept whole).
_DEGREE_WORD = re.compile(rf"(?:{_DEGREE})(?=\s|$)|\S+")


def says_only_how(text: str) -> bool:
    """Whether ``text`` is made only of words that say how near or how exactly: degree words
    (:data:`_DEGREE`), and adverbs of manner by their form, "-ly" after an English adjective
    ("roughly", "approximately", "precisely"; not "jelly" or "family")."""
    from tabletop.reader.spelling import english_words

    english = english_words()
    words = _DEGREE_WORD.findall(text.strip().lower())
    return bool(words) and all(
        re.fullmatch(_DEGREE, w)
        or (
            len(w) >= 6
            and w.endswith("ly")
            and any(stem in english for stem in (w[:-2], w[:-2] + "e"))
        )
        for w in words
    )


#: "where the dog barked", "the spot where the alarm went off": a sound, told by what was heard
#: ("where the mug is" is the mug).
_WHERE = re.compile(
    r"^(?:(?:the\s+)?(?:place|spot|point|location)\s+)?where\s+(?!(?:you|i|we)\s)(.+?)"
    rf"(\s+(?:(?:is|are|was|were)(?:\s+(?:{_POSTURE}))?|{_POSTURE}|was\s+put))?$"
)
#: A preposition left at the end of a clause of place ("the corner the kettle whistled in",
#: "wherever the rain was loudest at"): the place is the clause's, said before it.
_STRANDED = re.compile(r"\s+(?:at|in|on|from|by)$")
#: What may follow a sound after "where": "where X was playing", "where X started".
_WHERE_SOUND_TAIL = re.compile(
    r"\s+(?:(?:was|were|is)(?:\s+(?:playing|loudest|going\s+on|happening|on))?|happened|started|"
    r"occurred|played|sounded|rang\s+out)$"
)
#: "the spot you heard X", "the corner where X": a place, named before where or what was heard.
_PLACE_NOUN = (
    r"(?:the\s+|that\s+|whatever\s+)?(?:(?:part|bit|side|area|corner)\s+of\s+the\s+table|"
    r"place|spot|point|location|area|bit|part|corner|patch)"
)
_PLACE_HEARD = re.compile(rf"^{_PLACE_NOUN}\s+(?:that\s+)?((?:you|i|we)\s+.+)$")
#: "the place the barking was loudest": where, with "where" left out.
_PLACE_X = re.compile(
    rf"^{_PLACE_NOUN}\s+(?!(?:where|you|i|we|that|which|behind|in|on|near|next|left|right|"
    r"between|above|over|of|to|by|beside|with|for)\b)(.+)$"
)
#: A step may be only its place: "behind the mug, please", "between the mug and the duck".
_RELATION_START = re.compile(
    r"^(?:(?:just|slightly|right|directly)\s+)*(?:(?:to|on)\s+the\s+(?:left|right)|"
    r"(?:left|right)(?:[\s-]*hand)?\s+of|(?:in\s+)?front\s+of|behind|(?:in\s+)?between|"
    r"(?:half|mid)way|above|over|next\s+to|beside)\b"
)
_STEP_SPLIT = re.compile(
    r"\s*(?:[,;.]\s*)?(?:\band\s+)?\b(?:then|after\s+that|afterwards|finally|lastly)\b\s*,?\s*"
    r"|\s*;\s*|\.\s+"
)
_FIRST = re.compile(r"^(?:first(?:ly)?|start\s+by|to\s+begin|next)\s*,?\s*")
#: "try going to X": the verb said as a gerund.
_TRY_ING = re.compile(r"^try\s+(go|mov|head|gett|reach)ing\b")
_REPEAT = re.compile(rf"[\s,]*\b(?:(once|twice|thrice)|({_NUM})\s+times)\s*$")
_LEAD_REPEAT = re.compile(rf"^(?:(once|twice|thrice)|({_NUM})\s+times)\b\s*,?\s*")
_BACK_FORTH = re.compile(
    r"^(?:please\s+)?(?:go|move|travel|shuttle|head)(?:\s+(?:the\s+)?(?:arm|gripper|hand))?"
    r"\s+back\s+and\s+forth\s+(?:between|to|from)\s+(.+)$"
)
#: A compass move's shape with any word where the distance goes (to name a word that is none).
_COMPASS_ANY = [
    re.compile(rf"^(?P<d>\S+)\s*{_UNIT}\s+(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?$"),
    re.compile(
        rf"^(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?\s+(?:by\s+|for\s+)?(?P<d>\S+)\s*{_UNIT}$"
    ),
]
#: A compass move whose number has no unit ("10 north", "north by 10").
_NO_UNIT = re.compile(
    rf"^(?:(?P<n>{_NUM})\s+(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?|"
    rf"(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?\s+(?:by\s+|for\s+)?(?P<n2>{_NUM}))$"
)
#: A compass move between two directions ("10 cm northeast", "north-west by 5 cm").
_DIAGONAL = re.compile(
    rf"^(?:\S+\s*{_UNIT}\s+(?:to(?:wards)?\s+(?:the\s+)?)?)?"
    r"(?P<d>(?:north|south)[\s-]?(?:east|west))(?:wards?)?(?:\s+(?:by\s+)?\S+\s*\S*)?$"
)
#: A distance up or down ("5 cm up", "up by 2 cm", "10 cm higher").
_VERTICAL = re.compile(
    rf"^(?:\S+\s*{_UNIT}\s+(?:straight\s+)?(?P<v>upwards?|downwards?|up|down|higher|lower)|"
    rf"(?:straight\s+)?(?P<v2>upwards?|downwards?|up|down|higher|lower)\s+(?:by\s+|for\s+)?\S+\s*"
    rf"{_UNIT})$"
)
_COMPASS = [
    re.compile(rf"^{_DIST}\s+(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?$"),
    re.compile(rf"^(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?\s+(?:by\s+|for\s+)?{_DIST}$"),
]
_BETWEEN = re.compile(
    r"^(?:to\s+)?(?:(?:in|at)\s+)?(?:the\s+)?(?:(?:in\s+)?between|(?:half|mid)way\s+between|"
    r"equidistant\s+(?:from|between)|"
    r"(?:exact\s+)?(?:middle|midpoint|centre|center|(?:half|mid)way\s+point)\s+(?:of|between))"
    r"\s+(.+)$"
)
#: "(the gap) separating A and B", "that separates A from B": between A and B.
_SEPARATING = re.compile(r"^(?:that\s+)?separat(?:es|ing)\s+(.+)$")
#: "halfway from A to B": between A and B.
_FROM_TO = re.compile(
    r"^(?:to\s+)?(?:(?:half|mid)way|the\s+(?:half|mid)way\s+point)\s+from\s+(.+)$"
)
_SIDES = [
    (
        "left",
        re.compile(r"^(?:(?:to|on)\s+)?(?:the\s+)?left(?:[\s-]*hand)?(?:\s+side)?\s+of\s+(.+)$"),
    ),
    (
        "right",
        re.compile(r"^(?:(?:to|on)\s+)?(?:the\s+)?right(?:[\s-]*hand)?(?:\s+side)?\s+of\s+(.+)$"),
    ),
    # the robot's convention: "in front of" X is X's side away from the robot, so its far
    # side and its other side are the front, its near side the back
    (
        "front",
        re.compile(
            r"^(?:(?:a?round\s+)?(?:to|on)\s+|a?round\s+)?(?:the\s+)?(?:(?:in\s+)?front(?:\s+side)?|"
            r"(?:far|other|opposite)\s+side|ahead)\s+of\s+(.+?)(?:,?\s+away\s+from\s+"
            r"(?:you|me|the\s+robot))?$|^(?:past|beyond)\s+(.+)$"
        ),
    ),
    (
        "behind",
        re.compile(
            r"^(?:(?:to\s+)?behind|(?:(?:a?round\s+)?(?:to|on)\s+|a?round\s+)?(?:the\s+)?"
            r"(?:(?:back|rear)(?:\s+side)?|near\s+side|in\s+back)\s+of)\s+(.+)$"
        ),
    ),
]
_ABOVE = re.compile(r"^(?:right\s+|just\s+)?(?:above|over|on\s+top\s+of|the\s+top\s+of)\s+(.+)$")
_TABLE_AREA = re.compile(
    r"\b(?:the\s+)?(left|right|front|back|far|near|centre|center|middle)"
    r"(?:[\s-]+hand)?(?:\s+(?:side|part|half|edge|end))?\s+of\s+the\s+table\b"
)
#: "the far left corner (of the table)", "the front right corner": a corner, a lateral and a
#: depth word together (the table regions read the phrase itself).
_TABLE_CORNER = re.compile(
    r"\b(?:the\s+)?(?:(?:far|near|front|back)[\s-]+(?:left|right)|(?:left|right)[\s-]+"
    r"(?:far|near|front|back))(?:[\s-]+hand)?\s+corner(?:\s+of\s+the\s+table)?\b"
)
_AREA_PLACEHOLDER = re.compile(r"@area(\d+)@")
_IMAGE_PLACE = re.compile(
    r"\b(?:the\s+)?(?:place|spot|location|view|scene)\s+(?:(?:shown|seen|depicted)\s+)?"
    r"(?:in|at|from|of)\s+(?:the\s+)?(?:(?:image|picture|photo|photograph|snapshot)\s+)?"
    r"(@img\d+@)"
)
_AREA_NAMES = {
    "left": "left side of the table",
    "right": "right side of the table",
    "front": "front of the table",
    "far": "front of the table",
    "back": "back of the table",
    "near": "back of the table",
    "centre": "center of the table",
    "center": "center of the table",
    "middle": "center of the table",
}
_AREA_SUFFIX = re.compile(r"^(?:the\s+)?(.+?)\s+(?:area|region|zone)$")
#: What a sound is called: "the noise of X", "the racket made by X", "a sound like X".
_SOUND_NOUN = r"(?:sound|noise|racket|din|commotion|ruckus|clatter|clamou?r)s?"
_SOUND_OF = re.compile(
    rf"^(?:the\s+|a\s+|that\s+)?{_SOUND_NOUN}\s+(?:(?:that|which)\s+)?"
    r"(?:of|made\s+by|from|coming\s+from|like|resembling|similar\s+to|"
    r"(?:sounded|sounds|was|is)\s+like)\s+(.+)$"
)
_SOUND_SUFFIX = re.compile(rf"^(?:the\s+|a\s+|that\s+)?(.+?)\s+{_SOUND_NOUN}$")
_HEAR = r"(?:heard|could\s+hear|can\s+hear|caught|picked\s+up)"
_HEARD = re.compile(
    r"^(?:(?:the\s+)?(?:place|spot|point|location)\s+)?where\s+(?:you|i|we)\s+"
    rf"(?:just\s+)?{_HEAR}\s+(.+)$"
)
_WAS_HEARD = re.compile(r"\bwhere\s+(.+?)\s+(?:was|were|could\s+be|can\s+be)\s+heard\b")
#: "the barking you heard", "the dog we heard barking", "the sound I heard of a bell": a sound
#: told as what was heard (the words before, and an "-ing" word after, say what).
_HEARD_AFTER = re.compile(
    rf"^(.+?)\s+(?:(?:that|which)\s+)?(?:you|i|we)\s+(?:just\s+)?{_HEAR}"
    r"(?:\s+(?:earlier|before|just\s+now|a\s+(?:moment|minute|while)\s+ago))?"
    r"(?:\s+(\w+ing)|\s+(?:of|from)\s+(.+))?$"
)
#: "where the barking came from", "the spot the ringing was coming from": the sound's place.
_CAME_FROM = re.compile(
    rf"^(?:{_PLACE_NOUN}\s+|(?:the\s+)?direction\s+)?(?:where\s+|that\s+)?(.+?)\s+"
    r"(?:came|comes|was\s+coming|were\s+coming|is\s+coming|originated|seemed\s+to\s+come|"
    r"seems\s+to\s+come)\s+(?:out\s+of|from)$"
)
#: "the location of X", "the whereabouts of X": X itself.
_LOCATION_OF = re.compile(r"^(?:the\s+)?(?:location|position|whereabouts|direction)\s+of\s+(.+)$")
#: What joins a goal to what narrows it: "the mug near / right by / not far from / where you
#: heard / sitting next to X". "where" alone ("the mug where the dog barked") joins a place.
_CONNECT = re.compile(
    # "that's sitting", "which is hanging around": after a relative pronoun and its verb, a
    # present participle (and a particle) says where the thing is, as a posture word does
    # (not "-ed" or "-en": "that is red", "that's striped", "that's golden" describe it)
    r"\s+(?:(?:that|which)(?:\s+(?:is|was|are|were)|'s|'re)\s+"
    r"(?:[a-z]{3,}ing\s+(?:(?:around|about|away|out|up|down|over|there)\s+)?)?)?"
    rf"(?:(?:(?:that|which)\s+)?(?:{_POSTURE})\s+)?"
    rf"(?:(?:{_DEGREE})\s+)*"
    r"(close\s+by|hard\s+by|near\s*by|alongside(?:\s+of)?|adjacent\s+to|"
    r"not\s+(?:too\s+|that\s+|very\s+)?far\s+(?:away\s+)?from|(?:up\s+)?against|"
    r"a\s+(?:short\s+way|little\s+way|stone's\s+throw|few\s+(?:inches|centimet(?:er|re)s|cm))"
    r"\s+(?:away\s+)?from|within\s+(?:reach|arm's\s+reach)\s+of|closer\s+to|"
    r"next\s+door\s+to|in\s+the\s+area\s+of|"
    r"(?:with)?in\s+(?:the\s+)?(?:vicinity|neighbou?rhood)\s+of|neighbou?ring|"
    r"(?:by|at)\s+the\s+side\s+of|in\s+the\s+same\s+(?:area|region|spot|place)\s+as|"
    r"near(?:\s+to)?|next\s+to|close\s+to|closest\s+to|nearest(?:\s+to)?|beside|by|around|"
    rf"in|on|where\s+(?:you|i|we)\s+(?:just\s+)?{_HEAR}|where(?!\s+(?:you|i|we)\s))\s+"
)
_IMAGE_WORDS = frozenset(
    """the a an image picture photo photograph view snapshot goal place spot location shown seen
    in at from of file where""".split()
)
_PLACEHOLDER = re.compile(r"@img(\d+)@")
_PATH = re.compile(
    r"""(?<![\w@])["']?((?:\.{1,2}/|~/|/)[^\s"',;]+|[^\s"',;]+\.(?:png|jpe?g|bmp|webp|tiff?))["']?"""
    r"""(?=[\s,;]|[.!?]?\s*$|[.!?]\s)""",
    re.IGNORECASE,
)


#: "a bit to the left of", "somewhere between", "slightly behind": a hedge before a relation.
_HEDGE = re.compile(
    r"^(?:(?:a\s+(?:little\s+)?bit|a\s+little|slightly|somewhat|somewhere|just|right|directly|"
    r"out|back|a?round|in|up|down)\s+(?:more\s+)?)+"
    r"(?=(?:to|on)\s+the\s+(?:left|right)\b|(?:in\s+)?front\b|behind\b|"
    r"(?:in\s+)?between\b|(?:half|mid)way\b|above\b|over\b|(?:left|right)(?:[\s-]*hand)?\s+of\b|"
    r"past\b|beyond\b)"
)
#: "find the duck and go there": the second half only says to go where the first points.
_AND_GO_THERE = re.compile(
    r"\s*,?\s+and\s+(?:then\s+)?(?:go|move|head|drive)\s+(?:(?:over\s+)?there|to\s+(?:it|that))$"
)
#: "whichever mug is", "the one": words that pick without describing.
_PICK = re.compile(r"^(?:whichever|whatever|which)\s+(.+?)(?:\s+(?:is|are))?$")
#: "the source of the barking", "what sounded like a cat", "the thing that made the ringing":
#: a sound, told by what it was.
_SOUND_SOURCE = re.compile(
    r"^(?:(?:the\s+)?(?:source|origin)\s+of|(?:(?:the\s+)?(?:thing|one|object)\s+"
    r"(?:that|which)|what|whatever|something)\s+(?:sounded\s+like|made|(?:is|was)\s+making|"
    r"makes)|(?:the\s+)?(?:thing|one|object)\s+(?:making|that\s+makes)|"
    r"(?:the\s+)?(?:thing|one|object|animal)\s+(?:that|which)\s+(?:is|was)(?=\s+\w+ing\b))"
    r"\s+(.+)$"
)
#: "the blue block on the left": a side of the table, said short (the arm's table only).
_SHORT_SIDE = re.compile(
    r"\bon\s+the\s+(left|right)(?:[\s-]+hand)?(?:\s+side)?(?![\s-]*(?:hand|side|of)\b)"
)


@functools.cache
def _sound_verbs() -> frozenset[str]:
    """Verbs a person names a sound by ("a dog barking", "the phone ringing"): the -ing words
    of the sound bank's captions and phrasings, so a landmark that ends in one is a sound even
    without "the sound of"."""
    from tabletop.mapping.sound_vocabulary import load_phrasings

    texts = [*_captions().values(), *(t for ts in load_phrasings().values() for t in ts)]
    words = {w.strip(",.") for t in texts for w in t.lower().split()}
    return frozenset(w for w in words if len(w) > 5 and w.endswith("ing"))


@functools.cache
def _sound_names() -> frozenset[str]:
    """The sound bank's categories of several words, as words ("crying baby", "church
    bells"): no object is called so. One-word categories ("duck", "dice") may be objects."""
    return frozenset(c.replace("_", " ") for c in _captions() if "_" in c)


@functools.cache
def _captions() -> dict[str, str]:
    """The sound bank's caption table (category -> caption), read from its data file."""
    from tabletop.reader.spelling import data_toml

    return data_toml("sounds/captions.toml")


# ---------------------------------------------------------------------- parsing
# A mobile base's own motions: turning on the spot, driving along its heading.
_TURN = re.compile(
    rf"^(?:please\s+)?(?:turn|rotate|spin)(?:\s+(?:yourself|the\s+(?:robot|base)))?\s*"
    rf"(?:(?:by\s+)?({_NUM})\s*(?:deg(?:ree)?s?|°)\s*)?"
    r"(?:to\s+(?:the|your)\s+)?(left|right|around|clockwise|counter[\s-]?clockwise|"
    r"anti[\s-]?clockwise)?$"
)
_FACE = re.compile(
    r"^(?:please\s+)?(?:(?:turn|rotate)\s+(?:to\s+)?(?:face|towards?)|face|look\s+(?:at|towards?))"
    r"\s+(.+)$"
)
_DRIVE = re.compile(
    rf"^(?:please\s+)?(?:(?:go|move|drive|roll|head|travel)\s+(forward|forwards|ahead|straight(?:\s+ahead)?|"
    rf"back|backwards?|in\s+reverse)|back\s+up|reverse)"
    rf"(?:\s+(?:by\s+|for\s+)?{_DIST})?$"
)
_DRIVE_LEAD = re.compile(
    rf"^(?:please\s+)?(?:go|move|drive|roll|head|travel)\s+{_DIST}\s+"
    r"(forward|forwards|ahead|straight(?:\s+ahead)?|back|backwards?)$"
)
_TURN_SIGN = {
    "left": 1.0,
    "counterclockwise": 1.0,
    "anticlockwise": 1.0,
    "right": -1.0,
    "clockwise": -1.0,
}


class _Parser:
    def __init__(self, instruction: str, robot: str = "arm") -> None:
        if not isinstance(instruction, str) or not instruction.strip():
            raise ParseError(str(instruction), str(instruction), "the instruction is empty")
        self.body = embodiment(robot)  # names the valid robots
        self.robot = robot
        self.instruction = instruction
        self.paths: list[str] = []
        self.areas: list[tuple[str, str]] = []  # (as written, the map's area name)

    def fail(self, fragment: str, why: str, final: bool = False):
        """Refuse ``fragment``; ``final``: read, and no other reading is to be tried."""
        raise ParseError(self.instruction, self._restore(fragment), why, final=final)

    def out_of_range(self, fragment: str, why: str):
        """Read, but a number beyond what the robot does: final (no other reading is tried)."""
        raise ParseError(self.instruction, self._restore(fragment), why, out_of_range=True)

    def _restore(self, text: str) -> str:
        text = _AREA_PLACEHOLDER.sub(lambda m: self.areas[int(m.group(1))][0], text)
        return _PLACEHOLDER.sub(lambda m: self.paths[int(m.group(1))], text)

    def _hide_areas(self, text: str) -> str:
        def repl(m: re.Match) -> str:
            self.areas.append((m.group(0), _AREA_NAMES[m.group(1)]))
            return f"@area{len(self.areas) - 1}@"

        def corner(m: re.Match) -> str:
            name = _ARTICLES.sub("", m.group(0))
            if "table" not in name:
                name += " of the table"
            self.areas.append((m.group(0), name))
            return f"@area{len(self.areas) - 1}@"

        return _TABLE_AREA.sub(repl, _TABLE_CORNER.sub(corner, text))

    def _hide_paths(self, text: str) -> str:
        def repl(m: re.Match) -> str:
            self.paths.append(m.group(1))
            return f" @img{len(self.paths) - 1}@ "

        return _PATH.sub(repl, text)

    def parse(self) -> tuple[Step, ...]:
        text = self._hide_paths(self.instruction.strip())
        text = re.sub(r"\s+", " ", text.lower()).strip()
        text = re.sub(r"[.!?]+$", "", text).strip()
        text = re.sub(r"\bwherever(?:\s+it\s+(?:was|is)(?:\s+that)?)?\b", "where", text)
        text = re.sub(r"\bwhere\s+there\s+(?:was|were|is)\b", "where", text)
        text = _WAS_HEARD.sub(r"where you heard \1", text)
        text = _IMAGE_PLACE.sub(r"the image \1", text)
        if self.body.workspace == "scene":  # one table: "on the left" is its left side
            text = _SHORT_SIDE.sub(r"on the \1 side of the table", text)
        text = self._hide_areas(text)
        clauses = [c.strip(" ,") for c in _STEP_SPLIT.split(text)]
        if any(not c for c in clauses):
            self.fail(text, "an empty step: 'then' must join two steps")
        return tuple(self.step(c, i == 0) for i, c in enumerate(clauses))

    # --------------------------------------------------------------- one step
    def step(self, clause: str, first: bool) -> Step:
        body = _WANT_YOU_AT.sub("go to ", _FIRST.sub("", clause), count=1)
        body = _POLITE_TAIL.sub("", _POLITE_HEAD.sub("", body, count=1)).strip(" ,")
        body = _GO_AND.sub("", body)
        body = _AND_GO_THERE.sub("", body)
        body = _HOVER.sub("move ", body)
        body = _GO_FIND.sub("", body)
        body = _TRY_ING.sub(lambda m: {"mov": "move", "gett": "get"}.get(m[1], m[1]), body)
        times = 1
        m = _REPEAT.search(body)
        if m:
            times = self.times(m, clause)
            body = body[: m.start()].strip(" ,")
        m = _BACK_FORTH.match(body)
        if m:
            a, b = self.two_goals(m.group(1), "back and forth", sep=r"\s+(?:and|to)\s+")
            return Step(BackAndForth(a, b), times, self._restore(clause))
        base = self.base_motion(body, clause)
        if base is not None:
            return Step(base, times, self._restore(clause))
        m = _LEAD_REPEAT.match(body)
        if m and times == 1:
            times = self.times(m, clause)
            body = body[m.end() :].strip(" ,")
        m = _VERB.match(body)
        if not m and _RELATION_START.match(body):  # "behind the mug, please"
            m = re.match(r"^", body)
        if not m and not first:
            # later steps may leave the verb out: "..., then (to) the duck"
            m = re.match(r"^(?:to(?:wards)?\s+|on\s+to\s+)?", body)
        if not m:
            verbs = (
                "go to, move to, reach, approach, head to, navigate to, return to, move back "
                "and forth between"
            )
            if self.body.drives:  # a base also drives and turns on the spot
                verbs += "; or a base's own move: drive 2 m forward, turn left 90 degrees, face X"
            self.fail(clause, f"a step starts with a motion verb: {verbs}")
        rest = body[m.end() :].strip()
        if not rest:
            self.fail(clause, "the step names no goal")
        said = m.group(0).strip()
        if (_BARE_MOTION_VERB.search(said) and _DEFINITE.match(rest)) or (
            _MOTION_VERB_FOR.search(said) and _DETERMINER.match(rest)
        ):
            self.fail(
                clause,
                f"'{said} {rest}' asks to do something with {rest!r}, not to go to a place; "
                "the robot goes to places (e.g. 'go to the mug', 'move behind the duck')",
                final=True,  # no other reader reads the thing done to as the goal
            )
        return Step(self.action(rest, clause), times, self._restore(clause))

    def base_motion(self, body: str, clause: str):
        """A mobile base's own motion (turn, face, forward, back), or None. The arm's
        instructions never have one: asked of the arm, it is refused by name."""
        m_turn, m_face = _TURN.match(body), _FACE.match(body)
        # the arm reads "move forward 10 cm" as a compass move (north: away from the robot)
        m_drive = (_DRIVE.match(body) or _DRIVE_LEAD.match(body)) if self.body.drives else None
        if not (m_turn or m_face or m_drive):
            return None
        if not self.body.drives:
            self.fail(
                clause,
                "turning on the spot and driving forward or back are a mobile base's motions; "
                "the robot moves to places (e.g. 'move 10 cm north')",
            )
        if m_face:
            return Face(self.landmark(m_face.group(1), "face"))
        if m_turn:
            num, way = m_turn.group(1), (m_turn.group(2) or "").replace(" ", "").replace("-", "")
            if way == "around":
                if num is not None:
                    self.fail(clause, "say 'turn around' or 'turn N degrees left', not both")
                return Turn(180.0)
            if not way and num is None:
                self.fail(clause, "say which way to turn: left, right, around, or N degrees")
            deg = 90.0 if num is None else self.number(num, clause)
            if not 0 < deg <= 360:
                self.out_of_range(clause, "a turn is more than 0 and at most 360 degrees")
            return Turn(_TURN_SIGN.get(way, 1.0) * deg)
        g = m_drive.groups()
        if m_drive.re is _DRIVE_LEAD:
            num, unit, way = g
        else:
            way, num, unit = g
        if num is None:
            self.fail(clause, "say how far, e.g. 'move forward 1 m' or 'back up 50 cm'")
        d = self.number(num, clause) * unit_metres(unit)
        if not 0 < d <= self.body.max_move_m:
            self.out_of_range(
                clause, f"a base drives more than 0 and at most {self.body.max_move_m:g} m at once"
            )
        back = way is None or way.startswith(("back", "in"))
        return Forward(round(-d if back else d, 6))

    def times(self, m: re.Match, clause: str) -> int:
        word = m.group(1) or m.group(2)
        n = {"once": 1, "twice": 2, "thrice": 3}.get(word) or self.number(word, clause)
        if n != int(n) or not 1 <= n <= MAX_REPEAT:
            self.out_of_range(m.group(0).strip(" ,"), f"repeat a step 1 to {MAX_REPEAT} times")
        return int(n)

    def action(self, rest: str, clause: str):
        for rx in _COMPASS:
            m = rx.match(rest)
            if m:
                g = m.groups()
                if g[0] in _DIRECTIONS:
                    direction, num, unit = g
                else:
                    num, unit, direction = g
                d = self.number(num, clause) * unit_metres(unit)
                limit = self.body.max_move_m
                if not 0 < d <= limit:
                    self.out_of_range(
                        rest, f"a compass move goes more than 0 and at most {limit} m"
                    )
                if self.body.drives and direction in ("left", "right"):
                    self.fail(
                        rest,
                        "a base does not move sideways: 'turn left, then move forward 1 m', "
                        "or a compass direction ('move 1 m west')",
                    )
                return Compass(_DIRECTIONS[direction], round(d, 6))
        if re.match(rf"^(?:to(?:wards)?\s+(?:the\s+)?)?{_DIR}(?:wards?)?$", rest):
            self.fail(rest, "a compass move needs a distance, e.g. 'move 10 cm north'")
        m = _NO_UNIT.match(rest)
        if m:  # "move 10 north": a number with no unit
            self.fail(
                m.group("n") or m.group("n2"),
                "a compass move's distance needs a unit, e.g. 'move 10 cm north' (mm, cm, m, "
                "km, inches, feet, yards, miles)",
            )
        m = _DIAGONAL.match(rest)
        if m:  # "move 10 cm northeast": between two compass directions
            self.fail(
                m.group("d"),
                "a compass move goes north, south, east or west (or left, right, forward, "
                "back): make two moves, e.g. 'move 10 cm north, then 10 cm east'",
            )
        m = _VERTICAL.match(rest)
        if m:  # "move 5 cm up": a distance in a direction off the table's plane
            self.fail(
                m.group("v") or m.group("v2"),
                "a move by a distance goes across the table (north, south, east, west, left, "
                "right), not up or down; 'above X' hovers over a thing",
            )
        for rx in _COMPASS_ANY:  # a compass move whose distance is no number ("by nan m")
            m = rx.match(rest)
            if m:
                self.fail(
                    m.group("d"),
                    "a compass move's distance is a number of mm, cm, m or km (or inches, "
                    "feet, yards, miles), e.g. 'move 10 cm north'",
                )
        rest = _HEDGE.sub("", _PLACE_OF.sub("", _BE_AT.sub("", rest)))
        m = _FROM_TO.match(rest)
        if m:
            a, b = self.two_goals(m.group(1), "halfway from", sep=r"\s+to\s+")
            return Between(a, b)
        m = _FACING.match(rest)
        if m:
            side = "front" if m.group(2) else "behind"
            return Side(side, self.landmark(m.group(1), side))
        m = _ON_ITS_SIDE.match(rest)
        if m:
            return Side(m.group(2), self.landmark(m.group(1), m.group(2)))
        m = _SEPARATING.match(rest)
        if m:
            return Between(*self.two_goals(m.group(1), "separating", sep=r"\s+(?:and|from)\s+"))
        m = _POSSESSIVE_SIDE.match(rest)
        if m:
            side = {"back": "behind", "rear": "behind"}.get(m.group(2), m.group(2))
            return Side(side, self.landmark(m.group(1), side))
        m = _BETWEEN.match(rest)
        if m:
            try:
                a, b = self.two_goals(m.group(1), "between")
            except ParseError:
                if not re.match(r"^(?:the\s+)?(?:middle|centre|center)\s+of\s+", rest):
                    raise
            else:
                return Between(a, b)
        for side, rx in _SIDES:
            m = rx.match(rest)
            if m:
                said = next(g for g in m.groups() if g is not None)
                return Side(side, self.landmark(said, side))
        m = _ABOVE.match(rest)
        if m:
            return Above(self.landmark(m.group(1), "above"))
        return GoTo(self.goal(rest))

    def landmark(self, text: str, relation: str) -> str | Goal:
        """A relation's landmark: an object's name, or an object goal narrowed by others ("the
        mug near the sound of X") as the :class:`Goal` itself."""
        goal = self.goal(text)
        if goal.primary.kind != "obj":
            self.fail(
                text,
                f"'{relation}' needs an object as its landmark (e.g. 'the left of the red mug', "
                "'the left of the mug near the sound of S'); sound, image and area goals work "
                "with go to, between and near",
            )
        return goal if goal.near else goal.primary.text

    def two_goals(self, text: str, what: str, sep: str = r"\s+and\s+") -> tuple[Goal, Goal]:
        """Split ``A and B`` at the first 'and' where both sides are goals."""
        errors = []
        for m in re.finditer(sep, text):
            left, right = text[: m.start()], text[m.end() :]
            try:
                return self.goal(left), self.goal(right)
            except ParseError as e:
                errors.append(e)
        if not errors:
            self.fail(text, f"'{what}' needs two goals joined by 'and' ({what} A and B)")
        raise errors[-1]

    # --------------------------------------------------------------- goals
    def goal(self, text: str) -> Goal:
        text = text.strip(" ,")
        pieces = _CONNECT.split(text)
        # pieces = [primary, connector, constraint, connector, constraint, ...]
        if len(pieces) > 2 and superlative(pieces[1]) and not _ARTICLES.sub("", pieces[0] + " "):
            # "the nearest mug": a superlative of the thing, not a connector after nothing
            pieces = [f"{pieces[0]} {pieces[1]} {pieces[2]}", *pieces[3:]]
        if (
            len(pieces) > 2
            and pieces[1].startswith("where")
            and re.fullmatch(_PLACE_NOUN, pieces[0].strip())
        ):  # "the place where you heard S ...", "the spot where S ..." is the place itself
            pieces = [f"{pieces[1]} {pieces[2]}", *pieces[3:]]
        if len(pieces) > 2 and says_only_how(pieces[0]):
            # "just next to the mug", "right up against the duck": the words before the
            # connector say how near and name nothing; the goal is what follows
            said = f"{pieces[1]} {pieces[2]}" if pieces[1].startswith("where") else pieces[2]
            pieces = [said, *pieces[3:]]
        primary = self.part(pieces[0], None)
        near: list[Part] = []
        for i in range(1, len(pieces), 2):
            connector, constraint = pieces[i], pieces[i + 1]
            if connector == "where":  # "the mug where the dog barked": where says what
                near.append(self.part(f"where {constraint}", None))
                continue
            forced = "sound" if connector.startswith("where") else None
            for sub in re.split(r"\s+and\s+", constraint):
                near.append(self.part(sub, forced))
        return Goal(primary, tuple(near))

    def part(self, text: str, forced: str | None) -> Part:
        text = text.strip(" ,'\"")
        if not text:
            self.fail(self.instruction, "a goal is missing")
        if _PLACEHOLDER.search(text):
            return self.image(text)
        if forced == "sound":
            m = _SOUND_OF.match(text) or _SOUND_SUFFIX.match(text)
            return Part("sound", self.description(m.group(1) if m else text, "sound"))
        m = _PLACE_HEARD.match(text) or (_CAME_FROM.match(text) is None and _PLACE_X.match(text))
        if m and len(said := m.group(1).split()) == 1 and said[0] not in _sound_verbs():
            # "the spot flanked by ...": one word after the place, and no sound's, says
            # nothing that was heard there
            self.fail(text, f"{said[0]!r} after a place says nothing heard there")
        if m:  # "the spot you heard X" is "where you heard X"
            text = f"where {m.group(1)}"
        m = _HEARD.match(text)
        if m:
            return Part("sound", self.description(m.group(1), "sound"))
        m = _LOCATION_OF.match(text)
        if m:
            return self.part(m.group(1), forced)
        m = _HEARD_AFTER.match(text)
        if m and not m.group(1).startswith("where "):  # "the barking you heard"
            said = m.group(3) or m.group(1) + (f" {m.group(2)}" if m.group(2) else "")
            return self.part(said, "sound")
        m = _CAME_FROM.match(text)
        if m:  # "where the ringing came from"
            return self.part(m.group(1), "sound")
        m = _WHERE.match(text)
        if m:
            what = m.group(1)
            words = _ARTICLES.sub("", what).split()
            heard = words[-1] in _sound_verbs() or " ".join(words) in _sound_names()
            named = bool(_SOUND_OF.match(what) or _SOUND_SUFFIX.match(what))
            if m.group(2) and not heard and not named:  # "where the mug is (was)"
                return Part("obj", self.description(what, "object"))
            said = _WHERE_SOUND_TAIL.sub("", what)
            if _STRANDED.search(said):  # "... was loudest at": the tail before it
                said = _WHERE_SOUND_TAIL.sub("", _STRANDED.sub("", said))
            return self.part(said, "sound")
        m = _SOUND_OF.match(text) or _SOUND_SUFFIX.match(text) or _SOUND_SOURCE.match(text)
        if m:
            said = m.group(1)  # "whatever is making the ticking (noise)": the ticking
            m = _SOUND_SOURCE.match(said)
            return Part("sound", self.description(m.group(1) if m else said, "sound"))
        m = _PICK.match(text)
        if m:
            text = m.group(1)
        words = _ARTICLES.sub("", text).split()
        if words and words[-1] in _sound_verbs():  # "the dog barking", "the clapping"
            return Part("sound", self.description(text, "sound"))
        if " ".join(words) in _sound_names():  # "the crying baby", "the church bells"
            return Part("sound", self.description(text, "sound"))
        if re.match(r"^(?:the\s+)?(?:image|picture|photo|photograph|snapshot)\b", text):
            self.fail(text, "an image goal needs a file path, e.g. 'the image ./goal.png'")
        m = _AREA_PLACEHOLDER.fullmatch(_ARTICLES.sub("", text))
        if m:
            return Part("area", self.areas[int(m.group(1))][1])
        m = _AREA_SUFFIX.match(text)
        if m:
            return Part("area", self.description(m.group(1), "area") + " area")
        return Part("obj", self.description(text, "object"))

    def image(self, text: str) -> Part:
        found = _PLACEHOLDER.findall(text)
        others = [w for w in _PLACEHOLDER.sub(" ", text).split() if w not in _IMAGE_WORDS]
        if len(found) != 1 or others:
            self.fail(text, "an image goal is 'the image PATH' (one path, nothing else)")
        return Part("img", self.paths[int(found[0])])

    def description(self, text: str, kind: str) -> str:
        words = _ARTICLES.sub("", text.strip() + " ").split()  # "the" alone is no description
        if not words:
            self.fail(text, f"the {kind} description is empty")
        # an object's leading superlative ranks the things the rest names ("nearest mug")
        lead = words[0] if kind == "object" and superlative(words[0]) else None
        bad = [
            w
            for w in words
            if (w in _RESERVED and w != lead) or not re.fullmatch(r"[a-z][a-z0-9'-]*", w)
        ]
        if kind == "sound":  # sounds are free text ("splashing, dripping water"), not structure
            bad = [
                w
                for w in bad
                if w.rstrip(",") in _RESERVED_SOUND or not re.fullmatch(r"[a-z][a-z0-9'-]*,?", w)
            ]
        if bad:
            self.fail(
                text,
                f"{', '.join(repr(w) for w in bad)} cannot be part of {_a(kind)} description; "
                "the offline parser knows: go to/reach/approach X; X near/next to/close to Y; "
                "X where you heard S; between A and B; left/right/in front of/behind/above X; "
                "move 10 cm north/south/east/west/left/right; steps joined by 'then'; "
                "'twice', 'N times'; 'the sound of S'; 'the image PATH'; 'the X area' "
                "(use --backend llm for anything else)",
            )
        if len(words) > 6:
            self.fail(text, f"a {kind} description has at most 6 words")
        return " ".join(words)

    def number(self, word: str, clause: str) -> float:
        if word.startswith("-"):
            return -self.number(word[1:], clause)
        if word in _NUMBERS:
            return float(_NUMBERS[word])
        try:
            return float(word)
        except ValueError:
            self.fail(clause, f"{word!r} is not a number")


_RESERVED_SOUND = frozenset(
    """left right front behind between middle halfway near next close closest nearest beside
    then times twice image picture photo north south east west not no don't dont never without
    avoid except if while until""".split()
)


#: Words that place or order a goal ("right", "near", "between", "then"): a clause holding
#: one says where to go, whatever else it says.
STRUCTURE_WORDS = _RESERVED_SOUND - QUALIFIERS


def _a(noun: str) -> str:
    return ("an " if noun[0] in "aeiou" else "a ") + noun


def parse_instruction(instruction: str, robot: str = "arm") -> tuple[Step, ...]:
    """The steps of ``instruction`` for ``robot`` (an :mod:`~tabletop.embodiments` name:
    "arm", or "mobile", a base that also turns and drives forward and back);
    :class:`ParseError` names what was not understood."""
    return _Parser(instruction, robot).parse()

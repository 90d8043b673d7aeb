"""One place where a request gets its meaning: :func:`understand` and the readers behind it.

A reader turns a request into a :class:`Reading`: the plan's steps (typed references and
relations, :mod:`tabletop.reader.plan`), the words it corrected and the words it read as a
wrapper around the request. Readers are chosen by name (:data:`READERS`), as encoder sets are:

- ``rules``: the grammar of :mod:`tabletop.reader.rules` on the words as typed;
- ``learned`` and ``rules+learned``: the tagger of :mod:`tabletop.reader.learned` alone, or
  on what the grammar (with the spelling pass) refuses;
- ``llm``: an OpenAI-compatible endpoint asked for the typed plan as structured output
  (:mod:`tabletop.reader.llm`; its address from ``TABLETOP_LLM_BASE_URL`` and
  ``TABLETOP_LLM_MODEL``);
- ``rules+spelling`` (the default): the same grammar after typing slips are corrected against
  the map's vocabulary (:mod:`tabletop.reader.spelling`), and reading a request from where it
  starts after a lead-in the grammar does not read ("would you be so kind as to ...") when
  the lead-in names nothing and neither negates nor qualifies.

Every caller asks the same reader: the instruction path (code generation), the robot API's
``get_major_map(obj=/sound=/area=)`` (each reference is corrected the same way), ``tabletop
query`` and the evaluation.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import unicodedata
from typing import Protocol

from tabletop.errors import ConfigError
from tabletop.mapping.table_regions import AreaRef
from tabletop.reader.errors import ParseError
from tabletop.reader.lexicon.counts import count_in, unused_numbers
from tabletop.reader.lexicon.words import (
    AUXILIARIES,
    SUPERLATIVES,
    breaks_off,
    degree_adverb,
    far_from,
    placed_by,
    relation_words,
    superlative,
)
from tabletop.reader.llm import LLMReader
from tabletop.reader.places import PlaceReader, beneath_surface
from tabletop.reader.plan import (
    MOTIONS,
    Above,
    BackAndForth,
    Between,
    Goal,
    GoTo,
    Part,
    Reading,
    Side,
    Step,
)
from tabletop.reader.rules import (
    GATHERING,
    MANNER,
    POINTERS,
    QUALIFIERS,
    SEVERAL_WHY,
    STRUCTURE_WORDS,
    ends_in_determiner,
    is_motion_verb,
    is_negation,
    is_verb_phrase,
    negations,
    ordinal,
    parse_instruction,
    refuse_negated,
    refuse_nested_relation,
    refuse_non_words,
    refuse_relation_distance,
    several,
)
from tabletop.reader.spelling import (
    Speller,
    default_speller,
    english_words,
    head_nouns,
    kind_words,
    name_words,
    not_english,
)
from tabletop.relations import SIDES

__all__ = [
    "DEFAULT_READER",
    "READERS",
    "LearnedReader",
    "Reader",
    "Reading",
    "RulesReader",
    "get_reader",
    "understand",
]

#: Most words a reader drops as a wrapper before or after the request itself.
MAX_WRAPPER_WORDS = 12
#: Query kinds whose text a reader corrects (an image is a path or pixels).
TEXT_KINDS = ("obj", "sound", "area")
#: A side of another thing inside a thing's words ("the mug to the left of the duck"): the map
#: scores one thing's words, so the relation would be dropped and any mug found.
_SIDE_IN_REFERENCE = re.compile(
    r"\b(?:(?:to|on)\s+(?:the\s+)?(?:left|right)(?:[\s-]+hand)?(?:\s+side)?\s+of|"
    r"in\s+front\s+of|behind|between)\s+(?:the|a|an|my|your|that|this)\b",
    re.IGNORECASE,
)


class Reader(Protocol):
    """Turns requests into typed plans (raising :class:`ParseError` naming what it could not
    read) and corrects a single reference's words the same way."""

    name: str

    def understand(self, text: str, robot: str = "arm") -> Reading: ...

    def reference(self, kind: str, text: str) -> str | AreaRef: ...


def _leads(text: str) -> list[tuple[str, str]]:
    """(dropped lead-in, kept) cuts of ``text`` at word boundaries, fewest dropped words
    first; at most :data:`MAX_WRAPPER_WORDS` words dropped. Only words before the request are
    ever dropped: words after it may qualify it ("..., twice", "... slowly")."""
    words = text.split()
    return [
        (" ".join(words[:i]), " ".join(words[i:]))
        for i in range(1, min(len(words), MAX_WRAPPER_WORDS + 1))
    ]


#: A condition put to the one asked, or to nothing in particular ("if you ...", "if it's
#: ...", "if that's ..."), as its own clause before or after the request.
_IF_SUBJECT = r"if\s+(?:you|it|that|this)(?:['\u2019](?:s|re|d|ll|ve))?\s"
_IF_CLAUSE = re.compile(
    rf"^(?P<lead>{_IF_SUBJECT}[^,;]*?)\s*[,;]\s*(?P<kept>\S.*)$|"
    rf"^(?P<before>.*?\S)\s*[,;]\s*(?P<tail>{_IF_SUBJECT}[^,;]*?)\s*[.!?]*$",
    re.IGNORECASE,
)
#: Words that start a noun phrase, or are one ("anything"): a clause with one names a thing.
_NOUN_PHRASE = re.compile(
    r"^(?:the|a|an|any|some|my|our|his|her|their|these|those|each|every|both|"
    r"(?:any|some|no|every)(?:thing|one|body|where))$"
)


def courtesy(text: str) -> tuple[str, str | None]:
    """``text`` without a courtesy clause ("if you don't mind, go to the duck", "go to the
    duck, if it's no trouble"), and the clause (None where it has none). A courtesy is a
    clause of its own, set off by a comma, that puts a condition to the one asked or to
    nothing in particular (its subject "you", "it", "that" or "this") and names nothing: no
    noun phrase and no word of the map's vocabulary after its auxiliaries. So its negation
    ("don't mind") reverses no goal. A condition on the world is kept, to be refused:
    "if you see a mug, ...", "if there is no duck, ...", "if the mug is red, ..."."""
    m = _IF_CLAUSE.match(text.strip())
    if m is None:
        return text, None
    clause = m.group("lead") or m.group("tail")
    kept = m.group("kept") if m.group("lead") else m.group("before")
    return (kept, clause) if is_courtesy(clause) else (text, None)


def is_courtesy(clause: str) -> bool:
    """Whether ``clause`` is a courtesy (:func:`courtesy`): "if" with the one asked, "it",
    "that" or "this" as its subject, and no noun phrase or vocabulary word after the
    subject's auxiliaries ("if you would be so kind as to"; not "if you see a mug")."""
    if not re.match(_IF_SUBJECT, clause.strip(), re.IGNORECASE):
        return False
    words = re.findall(r"[a-z]+(?:['\u2019][a-z]+)?", clause.lower())
    words = [re.sub(r"['\u2019]s$", "", w) for w in words][2:]
    while words and (words[0] in AUXILIARIES or is_negation(words[0])):
        words = words[1:]  # "if you can", "if you wouldn't mind": the verb's own helpers
    names = name_words()
    return not any(
        _NOUN_PHRASE.match(w) or w in names or w in STRUCTURE_WORDS for w in words
    )  # ("if that helps's right": the side of the thing before it, no courtesy)


#: "not far from", "not too far off from", "not that far away from": near.
_LITOTES = re.compile(
    r"(^|[\s,(])not\s+(?:(?:too|that|so|very|all\s+that)\s+)?far\s+(?:(?:off|away)\s+)?from\b",
    re.IGNORECASE,
)
#: Words that make a lead a condition, not an aside.
_CONDITIONS = frozenset("if unless when whenever once until till whether provided".split())
#: Words after a negation that carry it on past the aside ("do not, ...", "never under any
#: circumstances ...", "not ever"): it then negates what follows.
_REACHES_ON = frozenset(", under in at on by ever even until till to for any again yet".split())


def is_negated_aside(lead: str) -> bool:
    """Whether ``lead``, the words before a request, is an aside whose negation stays inside
    it ("no rush,", "don't worry,", "without delay", "not sure where it is, but"): every
    negating word is followed, inside the aside, by a word of its own before any comma (so
    not "do not, under any circumstances,"); the aside names nothing of the vocabulary, no
    relation, side or structure word, and does not end in a word that governs what follows
    ("no need to", "don't", "never": those negate the request) and holds no verb of going
    ("don't go ..." negates the request itself)."""
    words = re.findall(r"[a-z]+(?:['\u2019][a-z]+)?|,", lead.lower())
    plain = [w for w in words if w != ","]
    if not plain or not any(is_negation(w) for w in plain) or set(plain) & _CONDITIONS:
        return False  # (a condition is a courtesy's or a refusal's: "if you don't see ...")
    last = plain[-1]
    if last in AUXILIARIES or is_negation(last) or last in ("to", "and", "or"):
        return False
    for i, w in enumerate(words):
        if is_negation(w) and (i + 1 >= len(words) or words[i + 1] in _REACHES_ON):
            return False  # "do not, ...", "never under any ...": the negation reaches on
    names = name_words()
    return not any(
        w in names
        or w.rstrip("s") in names
        or w in STRUCTURE_WORDS
        or w in SIDES_SAID
        or relation_words(w)
        or is_motion_verb(w)  # "don't go | to the mug": the request's own verb, negated
        for w in plain
    )


def refuse_not_english(text: str, read: str) -> None:
    """Refuse a request in another language (:func:`~tabletop.reader.spelling.not_english`
    of its words after spelling, ``read``): the grammar and the tagger read English only, and
    would name a foreign request as asking something else, or read its words as a thing's."""
    why = not_english(read, typed=text)
    if why is not None:
        raise ParseError(
            text,
            text,
            f"the request is not in English ({why}); only English requests are read, "
            "e.g. 'go to the red mug'",
        )


class RulesReader:
    """The grammar of :mod:`tabletop.reader.rules`, with or without the spelling pass and the
    wrapper pass."""

    def __init__(self, spelling: bool = True, wrappers: bool = True) -> None:
        self.spelling = bool(spelling)
        self.wrappers = bool(wrappers)
        self.name = "rules+spelling" if spelling else "rules"

    @property
    def speller(self) -> Speller:
        return default_speller()

    def reference(self, kind: str, text: str, places: PlaceReader | None = None) -> str | AreaRef:
        """The words of one reference, corrected (``obj``, ``sound``), or an area read into an
        :class:`AreaRef` (``area``: by ``places``, default the grammar alone)."""
        if kind not in TEXT_KINDS:
            raise ConfigError(f"unknown reference kind {kind!r}; valid: {list(TEXT_KINDS)}")
        if not isinstance(text, str):
            raise ConfigError(f"{kind}= must be a string, got {type(text).__name__}")
        text = normalise(text)
        if self.spelling:
            text = self.speller.correct(text)[0]
        refuse_negated(text)
        if kind == "obj" and (word := several(text)) is not None:
            raise ParseError(text, word, SEVERAL_WHY)
        if kind != "area" and (m := _SIDE_IN_REFERENCE.search(text)):
            raise ParseError(
                text,
                m.group(0),
                "a query names one thing or sound (and what it is near, as its own part); a "
                "place beside a thing is an instruction, e.g. 'go to the left of the duck'",
            )
        if kind == "area":
            return (places or _GRAMMAR_PLACES).read(text)
        return text

    def understand(self, text: str, robot: str = "arm") -> Reading:
        if not isinstance(text, str):
            raise ConfigError(f"an instruction must be a string, got {type(text).__name__}")
        text = normalise(text)
        refuse_non_words(text)
        refuse_question(text)
        refuse_beneath_surface(text)
        refuse_relation_distance(text)
        read, fixes = self.speller.correct(text) if self.spelling else (text, ())
        refuse_not_english(text, read)
        refuse_nested_relation(read)  # no reading may drop one of two relations
        read, polite = courtesy(read)
        said = (polite,) if polite else ()
        try:
            steps = parse_instruction(read, robot)
        except ParseError as first:
            if not self.wrappers or first.final:
                raise
            err = first
        else:
            steps = settle_references(text, steps)
            refuse_unused_numbers(text, read, steps)
            return Reading(text, read, steps, fixes, said, self.name)
        # a request after a lead-in the grammar does not read: the fewest dropped words that
        # leave a request it reads
        body = re.sub(r"[.!?]+\s*$", "", read.strip())
        keep = name_words() | QUALIFIERS
        for before, kept in _leads(body):
            if not is_courtesy(before) and any(
                w.strip(",.;:'\"!?").lower() in keep for w in before.split()
            ):
                break  # never drop a word that names something, negates or qualifies
            if ends_in_determiner(before):
                continue  # never cut a noun phrase: "put the | duck on the tray"
            try:
                steps = parse_instruction(kept.strip(" ,;:"), robot)
            except ParseError:
                continue
            steps = settle_references(text, steps)
            refuse_unused_numbers(text, read, steps)
            return Reading(text, kept, steps, fixes, (*said, before), self.name)
        raise err


def read_clause(clause: str, robot: str = "arm") -> tuple[Step, ...]:
    """The grammar's reading of one clause, after a lead-in it does not read (how the learned
    reader reads a step it labels as a motion)."""
    return _CLAUSE_READER.understand(clause, robot).steps


def _reference_texts(value, kinds: tuple[str, ...] | None = None) -> list[str]:
    """The words of every reference in a plan value (a step, an action, a goal, a part); of
    the ``kinds`` of part only, where given (a landmark named by its words is an object's)."""
    if isinstance(value, Part):
        return [value.text] if kinds is None or value.kind in kinds else []
    if isinstance(value, str):
        return [value] if kinds is None or "obj" in kinds else []
    if isinstance(value, tuple):
        return [t for v in value for t in _reference_texts(v, kinds)]
    if dataclasses.is_dataclass(value):
        return [
            t
            for f in dataclasses.fields(value)
            if f.name not in ("text", "side", "direction")
            for t in _reference_texts(getattr(value, f.name), kinds)
        ]
    return []


def refuse_beneath_surface(text: str) -> None:
    """Refuse a request for a place beneath the table's top or the floor ("go under the
    table"): ParseError naming the words; the map holds the top and what stands on it."""
    under = beneath_surface(text)
    if under is not None:
        raise ParseError(
            text,
            f"{under[0]} the {under[1]}",
            f"a place beneath the {under[1]} is off the table's top, and the top and what "
            "stands on it are all the map holds",
        )


def _fold_goal(goal: Goal) -> Goal:
    """``goal`` with each narrowing part that only describes what the primary is made of or
    covered with ("the mug in shiny red plastic": a part whose last word is a material or a
    covering, :data:`~tabletop.reader.lexicon.colour_words.SURFACE_NOUNS`) folded into the primary's
    words, which the map reads as a description; such a part names no thing to be near."""
    from tabletop.reader.lexicon.colour_words import SURFACE_NOUNS

    keep, described = [], goal.primary.text
    for part in goal.near:
        words = re.findall(r"[a-z]+", part.text.lower())
        if (
            part.kind == "obj"
            and goal.primary.kind == "obj"
            and words
            and (words[-1] in SURFACE_NOUNS)
        ):
            described = f"{described} in {part.text}"
        else:
            keep.append(part)
    if len(keep) == len(goal.near):
        return goal
    return dataclasses.replace(
        goal, primary=dataclasses.replace(goal.primary, text=described), near=tuple(keep)
    )


def fold_descriptions(value):
    """``value`` (steps, an action, a goal) with every goal's describing parts folded into
    its primary (:func:`_fold_goal`)."""
    if isinstance(value, Goal):
        return _fold_goal(value)
    if isinstance(value, tuple):
        return tuple(fold_descriptions(v) for v in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        changes = {
            f.name: fold_descriptions(v)
            for f in dataclasses.fields(value)
            if isinstance(v := getattr(value, f.name), tuple) or dataclasses.is_dataclass(v)
        }
        for name, v in changes.items():  # a landmark left unnarrowed is a thing's words
            if name == "landmark" and isinstance(v, Goal) and not v.near:
                changes[name] = v.primary.text
        return dataclasses.replace(value, **changes) if changes else value
    return value


_ALTERNATIVE = re.compile(r"\bor\b(?!\s+so\b)", re.IGNORECASE)
_JOINED = re.compile(r"\band\b|&|\bplus\b", re.IGNORECASE)


#: Words that name the table as a whole ("on the table", "the whole tabletop").
_WHOLE_TABLE = frozenset(("table", "tabletop"))
_WHOLE_TABLE_WORDS = _WHOLE_TABLE | {"the", "a", "top", "surface", "whole", "entire", "of"}


#: The fields of the plan's actions that hold goals.
_GOAL_FIELDS = frozenset(("goal", "a", "b", "landmark"))


def _each_goal(value, change, skip: tuple[str, ...] = ()):
    """``value`` (steps, an action, a goal) with every goal ``g`` in it replaced by
    ``change(g)``; the fields named in ``skip`` are left as they are."""
    if isinstance(value, Goal):
        return change(value)
    if isinstance(value, tuple):
        return tuple(_each_goal(v, change, skip) for v in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        changes = {
            f.name: _each_goal(v, change, skip)
            for f in dataclasses.fields(value)
            if f.name not in skip
            and (isinstance(v := getattr(value, f.name), tuple) or dataclasses.is_dataclass(v))
        }
        return dataclasses.replace(value, **changes) if changes else value
    return value


def _names_whole_table(part: Part) -> bool:
    said = set(re.findall(r"[a-z]+", part.text.lower()))
    return part.kind in ("obj", "area") and bool(said & _WHOLE_TABLE) and said <= _WHOLE_TABLE_WORDS


def _whole_table_dropped(value):
    """``value`` (steps, an action, a goal) without the narrowing parts that name the whole
    table ("where the dog barked on the table"): every goal lies on it, so such a part
    narrows nothing, and asked of the map it is its background, which finds nothing."""

    def drop(goal: Goal) -> Goal:
        keep = tuple(p for p in goal.near if not _names_whole_table(p))
        return goal if keep == goal.near else dataclasses.replace(goal, near=keep)

    return _each_goal(value, drop)


#: Words that name a side themselves (the tagger's side is then taken).
_SIDE_WORDS = frozenset((*SIDES, "back", "rear", "front", "behind"))


def _side_from_words(text: str, steps: tuple[Step, ...], plain: list[str]) -> tuple[Step, ...]:
    """The tagger's one side step checked against the words outside its references
    (``plain``): where they name no side word, the side is the one they place by the robot
    ("the side of the mug nearest you": behind it; "... furthest from you": in front; "the
    left-hand ... side" is named), and where they place none either ("the side of the mug"),
    the request is refused: no word says which side."""
    sides = [s for s in steps if isinstance(s.action, Side)]
    if len(steps) != 1 or len(sides) != 1 or _SIDE_WORDS & set(plain):
        return steps
    from tabletop.reader.place_words import directions

    found = directions(" ".join(plain))
    side = found.get("lateral") or {"near": "behind", "far": "front"}.get(found.get("depth", ""))
    if side not in SIDES:
        raise ParseError(
            text,
            steps[0].text,
            "no word says which side of the thing to go to: say 'left', 'right', 'in front "
            "of' or 'behind' (e.g. 'the left side of the mug')",
        )
    return (dataclasses.replace(steps[0], action=dataclasses.replace(sides[0].action, side=side)),)


def _whole_table_side_dropped(steps: tuple[Step, ...]) -> tuple[Step, ...]:
    """``steps`` with a "between" or a "back and forth" one of whose two goals is the whole
    table alone read as going to the other: the tagger's reading of a thing said to be on the
    table ("the mug near where the dog barked, on the table") as two goals; the table is no
    one place to go between or to and from. The learned reader's only: a grammar that read
    "between" read it from the words."""
    out = []
    for step in steps:
        a = step.action
        if isinstance(a, (Between, BackAndForth)):
            whole = [g for g in (a.a, a.b) if not g.near and _names_whole_table(g.primary)]
            if len(whole) == 1:
                other = a.b if whole[0] is a.a else a.a
                step = dataclasses.replace(step, action=GoTo(other))
        out.append(step)
    return tuple(out)


def _region_as_place(part: Part) -> Part:
    from tabletop.reader.place_words import parse_region

    said = set(re.findall(r"[a-z]+", part.text.lower()))
    if part.kind == "obj" and not said & name_words() and parse_region(part.text):
        return Part("area", part.text)
    return part


def _regions_as_places(value):
    """``value`` (steps, an action, a goal) with each thing's words that name no thing of
    the vocabulary and do name a region of the table ("the centre", "the far left") made a
    place: a reader that took them for a thing would look for a thing called so. A side's or
    above's landmark keeps its own words ("the mug, on the far side" restates the side), and
    a region narrowing it becomes a place ("in front of the ball, on the far side")."""

    def places(goal: Goal) -> Goal:
        near = tuple(_region_as_place(p) for p in goal.near)
        return Goal(_region_as_place(goal.primary), near)

    def narrowing(goal: Goal) -> Goal:  # "in front of the ball, on the far side": a place
        return Goal(goal.primary, tuple(_region_as_place(p) for p in goal.near))

    value = _each_goal(value, places, skip=("landmark",))
    return _each_goal(value, narrowing, skip=tuple(_GOAL_FIELDS - {"landmark"}))


def _goals_in(value) -> list[Goal]:
    """Every goal of a plan value (steps, an action, a goal), landmarks included."""
    found: list[Goal] = []
    _each_goal(value, lambda g: found.append(g) or g)
    return found


def _same_goal(a: Goal, b: Goal) -> bool:
    """Whether two goals are named in the same words (their articles and case aside)."""

    def words(g: Goal) -> tuple:
        parts = (g.primary, *g.near)
        return tuple(
            (p.kind, " ".join(w for w in p.text.lower().split() if w not in ("the", "a", "an")))
            for p in parts
            if isinstance(p, Part)
        )

    return isinstance(a, Goal) and isinstance(b, Goal) and words(a) == words(b) != ()


def offers_alternatives(step: Step) -> str | None:
    """The word "or" where ``step`` reads as "between" two goals that it joins with no "and"
    ("the mug or the duck"; None otherwise): a reader that takes "or" for "and" would send
    the robot between two things asked as alternatives. An "or" inside one reference
    describes ("the mug for tea or coffee") and is left to the map."""
    if isinstance(step.action, Between) and not _JOINED.search(step.text):
        if m := _ALTERNATIVE.search(step.text):
            return m.group(0)
    return None


def _plain(word: str) -> str:
    return word.strip(",.;:!?\"'").lower()


#: Words that join a second request to a first (after the last place named).
_JOINERS = frozenset(("and", "then", "after", "afterwards", "next"))


def _next_to(words: list[str], i: int) -> bool:
    """Whether ``words[i]`` is the "next" of "next to" (a word of nearness, not a step's)."""
    return words[i] == "next" and i + 1 < len(words) and words[i + 1] == "to"


#: Words that say a side or "above" of a thing.
SIDES_SAID = frozenset((*SIDES, "back", "above", "over", "top"))
#: Why a reference that counts or numbers its thing is refused.
COUNTED_WHY = (
    "a reference names one thing, and these words count or number it; the robot goes to one "
    "place: name the one meant (by its colour, or a thing near it)"
)
#: Why a number the reading uses for nothing is refused.
UNUSED_NUMBER_WHY = (
    "the robot reads a number as a distance ('move 5 cm north') or as a repetition ('3 times'), "
    "and this one is neither (a time, a duration or an index is not honoured)"
)


#: Typographic quotes and apostrophes, as typed on a keyboard.
_TYPOGRAPHIC = str.maketrans({"\u2019": "'", "\u2018": "'", "\u201c": '"', "\u201d": '"'})
#: Quotation marks around words ("go to the \"duck\"", "the 'blue' one"): no part of them.
_QUOTED = re.compile(r"(?<![\w'])([\"'])([^\"']+?)\1(?![\w'])")


def normalise(text: str) -> str:
    """``text`` as plain keyboard text: compatibility forms folded (full-width letters, "ｍｕｇ",
    are "mug"), typographic quotes and apostrophes made plain, and quotation marks around words
    dropped. Every reader reads this form, so that a quote or a width never hides a word."""
    if not isinstance(text, str):
        return text
    if any(c.isalpha() for c in text):  # (symbols alone stay symbols: no words to fold)
        text = unicodedata.normalize("NFKC", text)
    text = text.translate(_TYPOGRAPHIC)
    return _QUOTED.sub(r"\2", text)


def refuse_unused_numbers(text: str, read: str, steps: tuple[Step, ...]) -> None:
    """Refuse a request with a number that the reading of ``read`` uses for nothing
    (:func:`~tabletop.reader.lexicon.counts.unused_numbers`): a reader that drops it, or reads
    "for 3 hours" as three repetitions, would do something nobody asked. ParseError naming
    it."""
    used = [*_reference_texts(steps), *(s.text for s in steps if isinstance(s.action, MOTIONS))]
    unused = unused_numbers(read, used, {s.times for s in steps})
    if unused:
        raise ParseError(text, unused[0], UNUSED_NUMBER_WHY, final=True)


def _below_refused(text: str, below: str) -> ParseError:
    """The refusal of a place below a thing (``below``: the word that says so)."""
    return ParseError(
        text,
        below,
        f"a place {below} a thing is inside it or the table, which the robot cannot reach; it "
        "goes above a thing ('above the duck') or beside it",
        final=True,
    )


def settle_references(text: str, steps: tuple[Step, ...]) -> tuple[Step, ...]:
    """What every reader does to the references of the steps it read: parts that describe a
    thing are folded into its words (:func:`fold_descriptions`); a "between" of one thing and
    itself, or of two things offered as alternatives (:func:`offers_alternatives`), is
    refused; then a reference that negates
    what it names ("the cup that isn't red", which a reader would look for as a red cup) or
    starts with an ordinal ("the 3rd mug from the left") is refused, ParseError naming the
    word. "no" and "without" describe and pass ("the mug with no handle"); a negation outside
    every reference is the reader's to read ("not far from" for near)."""
    steps = _regions_as_places(_whole_table_dropped(fold_descriptions(steps)))
    if (far := far_from(text)) is not None:
        raise ParseError(
            text,
            far,
            "a place far from a thing is no one place: the map scores how near things are; "
            "name a place, or a side of the thing ('behind the duck')",
            final=True,
        )
    for goal in _goals_in(steps):
        own = Goal(goal.primary)
        if any(_same_goal(own, Goal(p)) for p in goal.near if p.kind == goal.primary.kind):
            raise ParseError(
                text,
                goal.primary.text,
                "a thing is narrowed by a thing near it, and both are named the same: name "
                "the one meant by its colour, or by another thing near it",
                final=True,
            )
    for step in steps:
        a = step.action
        if isinstance(a, Between) and _same_goal(a.a, a.b):
            raise ParseError(
                text,
                a.a.primary.text,
                "'between' takes two different things, and both are named the same: name each "
                "by its colour or by a thing near it",
            )
        if (alternative := offers_alternatives(step)) is not None:
            raise ParseError(
                text,
                alternative,
                "'or' offers a choice of two goals, and the robot goes to one place; name the "
                "one meant (or 'between A and B' for the point between them)",
            )
    for ref in _reference_texts(steps, ("obj",)):
        if (word := several(ref)) is not None:  # "the two mugs": one place is no two things
            raise ParseError(text, word, SEVERAL_WHY, final=True)
        if (word := count_in(ref, head_nouns())) is not None:  # "zero mugs", "mug #2"
            raise ParseError(text, word, COUNTED_WHY, final=True)
        if (placed := placed_by(ref, head_nouns())) is not None:  # "the duck inside the mug"
            raise ParseError(
                text,
                placed,
                f"{placed!r} places the thing by another, and the reading kept both in one "
                "thing's words; the robot reads a thing near another ('the duck near the mug') "
                "and the sides of one ('behind the mug')",
                final=True,
            )
        if (word := breaks_off(ref)) is not None:  # "the duck, and (pick it up)"
            raise ParseError(
                text,
                word,
                f"the words of one thing, {ref!r}, stop being a thing's name at {word!r}: what "
                "follows it was not read (a condition, a statement or a second request the "
                "robot does not do); name the thing, and join two places with 'then'",
                final=True,
            )
        if ranks := [w for w in superlative_forms(ref) if w not in SUPERLATIVES]:
            raise ParseError(
                text,
                ranks[0],
                f"{ranks[0]!r} ranks things by a measure the map does not hold; it ranks by "
                "size, height, left and right, and nearness ('the biggest mug', 'the tallest "
                "block', 'the leftmost duck', 'the nearest ball')",
                final=True,
            )
    for ref in _reference_texts(steps, ("sound",)):
        ranks = superlative_forms(ref) or [s.word for s in (superlative(ref),) if s is not None]
        # "the rain was loudest": said of the sound's own place, it ranks no sounds
        ranks = [w for w in ranks if not re.search(rf"\b(?:{'|'.join(_COPULAS)})\s+{w}\b", ref)]
        if ranks:  # "the loudest sound": no sound is ranked, and the word would be dropped
            raise ParseError(
                text,
                ranks[0],
                SOUND_RANK_WHY,
                final=True,
            )
    for ref in _reference_texts(steps):
        negated = negations(ref, describing=True)
        if negated:
            raise ParseError(text, negated[0], "the robot cannot honour a negated goal")
        if (nth := _ordinal_within(ref)) is not None:
            raise ParseError(text, nth, ORDINAL_WHY)
    for ref in _reference_texts(steps, ("obj",)):  # "go underneath the ball" as a thing
        if (low := _BELOW.match(ref.strip())) and ref.split()[1:]:
            raise _below_refused(text, low.group(0))
    for step in steps:  # "go below the duck" read as above it: the word says the opposite
        if isinstance(step.action, Above) and (low := _BELOW.search(step.text)):
            if not _ABOVE_SAID.search(step.text):
                raise _below_refused(text, low.group(0))
    for step in steps:  # "back and forth between the duck": one place, and a word for none
        a = step.action
        if isinstance(a, BackAndForth) and any(
            set(re.findall(r"[a-z]+", g.primary.text.lower())) <= {"back", "forth", "and"}
            for g in (a.a, a.b)
        ):
            raise ParseError(
                text,
                step.text,
                "'back and forth between' takes two places, and this step names one",
                final=True,
            )
    return steps


_BELOW = re.compile(r"\b(?:below|under|underneath|beneath)\b", re.IGNORECASE)
_ABOVE_SAID = re.compile(r"\b(?:above|over|on\s+top|atop|hover\w*|up)\b", re.IGNORECASE)
#: A question for information ("where is the red mug?"): no request to go anywhere.
_QUESTION = re.compile(
    r"^\s*(?:where|what|which|who|whose|why|how|when)(?:'s|\s)[^?]*\?\s*$", re.IGNORECASE
)


def refuse_question(text: str) -> None:
    """Refuse a question for information ("where is the red mug?"): ParseError saying what
    to ask instead (a reader would read its thing and move there)."""
    if _QUESTION.match(text):
        raise ParseError(
            text,
            text.split()[0],
            "a question asks for information, and the robot answers by going to places: ask "
            "it to go ('go to the red mug'), or query the map (tabletop query --obj ...)",
        )


#: Why an ordinal is refused.
ORDINAL_WHY = (
    "an ordinal picks one of several things (or times) by their order, which the map does not "
    "rank; name the one meant by its colour, or by a thing near it"
)


def _ordinal_within(words: str) -> str | None:
    """The ordinal that starts ``words`` or any noun phrase in them after an article ("the
    duck for the third time", "the second time you heard ..."), or None."""
    if (nth := ordinal(words)) is not None:
        return nth
    for m in re.finditer(r"\b(?:the|a|an|my|your)\s", words, re.IGNORECASE):
        if (nth := ordinal(words[m.start() :])) is not None:
            return nth
    return None


#: Why a sound said with a superlative is refused.
SOUND_RANK_WHY = (
    "a sound is found by what was heard, and no measure ranks the sounds heard; name the sound "
    "('where you heard the dog bark')"
)


def superlative_forms(text: str) -> list[str]:
    """The words of ``text`` that are superlatives by their form: "-est" after a stem whose
    comparative ("-er") is a common English word ("loudest", "shiniest", "biggest"; not
    "forest" or "interest"). Which of them the map ranks by is
    :data:`~tabletop.reader.lexicon.words.SUPERLATIVES`'s to say."""
    english = english_words()
    words = re.findall(r"[a-z]+", str(text).lower())
    return [w for w in words if len(w) >= 6 and w.endswith("est") and f"{w[:-3]}er" in english]


#: Verbs after which a superlative says where one thing was most so ("was loudest").
_COPULAS = frozenset(("is", "was", "were", "are", "sounded", "seemed", "got", "sounds", "seems"))
#: After a superlative of nearness, what it is near: "the mug closest in distance to the
#: duck", "the side nearest you" relate two things, and rank nothing (see
#: :func:`~tabletop.reader.lexicon.words.superlative`).
_NEAREST_TO = re.compile(r"\b(?:to|from|you|me|us)\b")


def _interjection(words: list[str], i: int) -> bool:
    """Whether the word at ``i`` opens the request as an interjection ("Right, ...", "Right
    then, ...", "All right, ..."), not a side."""
    first = i == 0 or (i == 1 and words[0].lower() == "all")
    after = words[i + 1].lower() if i + 1 < len(words) else ""
    return first and (words[i].endswith((",", ";", "!", ".")) or after in ("then", "so", "then,"))


def _keeps_named_words(fragment: str, steps: tuple[Step, ...]) -> bool:
    """Whether a reading keeps, in its references, the words a refusal named (one or two
    words: "nearest", "all"): another labelling that reads past the word a check stopped at
    must read it, not drop it. A longer fragment names no word in particular."""
    named = [w for w in (_plain(w) for w in str(fragment).split()) if w]
    if not named or len(named) > 2:
        return True
    kept = {_plain(w) for ref in _reference_texts(steps) for w in str(ref).split()}
    return all(w in kept for w in named)


#: How many labellings of the tagger the learned reader tries when the best is refused, and
#: how far below the best one's log-probability (nats) one may be (measured on read pools).
ALTERNATIVE_READINGS = 8
ALTERNATIVE_MARGIN = 4.0


class LearnedReader:
    """The learned tagger (:mod:`tabletop.reader.learned`) on the words after the spelling
    pass; a step it labels as a motion (compass moves, a base's own motions) is read by the
    grammar. ``fallback``: read with the rule reader first, and with the tagger only what the
    grammar refuses (``learned`` alone when False)."""

    def __init__(self, weights=None, fallback: bool = False) -> None:
        self.weights = weights
        self.fallback = bool(fallback)
        self.name = "rules+learned" if fallback else "learned"
        self._rules = RulesReader(spelling=True, wrappers=False)

    def reference(self, kind: str, text: str) -> str | AreaRef:
        return self._rules.reference(kind, text, _LEARNED_PLACES)

    def understand(self, text: str, robot: str = "arm") -> Reading:
        from tabletop.reader.learned import (
            DEFAULT_READER_WEIGHTS,
            best_roles,
            k_best_roles,
            load_tagger,
            words_of,
        )

        if not isinstance(text, str):
            raise ConfigError(f"an instruction must be a string, got {type(text).__name__}")
        text = normalise(text)
        refuse_non_words(text)
        refuse_question(text)
        refuse_beneath_surface(text)
        refuse_relation_distance(text)
        refuse_nested_relation(text)  # the tagger would keep one relation of the two
        if self.fallback:
            try:
                return self._rules.understand(text, robot)
            except ParseError as e:
                if e.final:  # read, and refused by name: no other reading
                    raise
        read, fixes = self._rules.speller.correct(text)
        refuse_not_english(text, read)
        refuse_nested_relation(read)
        read, polite = courtesy(read)
        # "not far from" (a litotes) says near: read as the word it means, so that neither
        # its negation nor its "far" (a side's word elsewhere) is taken at face value
        read = _LITOTES.sub(lambda m: m.group(1) + "near", read)
        words = words_of(read)
        if not words:
            raise ParseError(text, text, "the instruction is empty")
        tagger = load_tagger(self.weights or DEFAULT_READER_WEIGHTS)
        role_logp, rels = tagger.scores(words)
        roles = best_roles(role_logp)
        try:
            return self._read(text, read, fixes, polite, words, roles, rels, role_logp, robot)
        except ParseError as first:
            # constrained decoding: the most likely labelling that the checks below accept,
            # among the few nearly as likely as the best; the best one's refusal otherwise
            ranked = k_best_roles(role_logp, ALTERNATIVE_READINGS)
            for logp, other in ranked[1:]:
                if logp < ranked[0][0] - ALTERNATIVE_MARGIN:
                    break
                try:
                    reading = self._read(
                        text, read, fixes, polite, words, other, rels, role_logp, robot, True
                    )
                except ParseError:
                    continue
                if _keeps_named_words(first.fragment, reading.steps):
                    return reading
            raise first

    def _read(
        self, text, read, fixes, polite, words, roles, rels, role_logp, robot, other=False
    ) -> Reading:
        """The reading of ``words`` with the tagger's ``roles``, or ParseError where a check
        finds that it drops, ranks, negates or adds what the words say. ``other``: the roles
        are not the tagger's best, and a negation left out of the references is refused
        outright (no courtesy or aside around it is looked for)."""
        # the words left out of the references
        plain = [
            _plain(w)
            for i, (w, r) in enumerate(zip(words, roles, strict=True))
            if r in ("O", "THEN", "REP")
        ]
        for i, (w, r) in enumerate(zip(words, roles, strict=True)):
            # "all the cubes", "both ducks", "each side of the mug": a word left out of the
            # references that gathers several of what follows
            follows = i + 1 < len(roles) and roles[i + 1] != "O"
            if r == "O" and (follows or w.lower() in GATHERING) and several(" ".join(words[i:])):
                raise ParseError(text, w, SEVERAL_WHY)
            # "half a cube", "zero balls": a count left out of the thing's words
            counted = count_in(" ".join(words[i:]), head_nouns()) if r == "O" and follows else None
            if counted is not None and counted == _plain(w):
                raise ParseError(text, w, COUNTED_WHY)
        ranks = [
            w
            for i, (said, r) in enumerate(zip(words, roles, strict=True))
            if r in ("O", "THEN", "REP")
            and (superlative(w := said.strip(",.;:!?\"'").lower()) or superlative_forms(w))
            and not (
                SUPERLATIVES.get(w, ("",))[0] == "reach"
                and _NEAREST_TO.search(read.lower().split(w, 1)[-1])
            )
            # "where the rain was loudest": said of one thing's place, it ranks nothing
            and not (i and words[i - 1].lower() in _COPULAS)
        ]
        if ranks:  # "the nearest dog barking" read as the dog barking: the rank dropped
            raise ParseError(
                text,
                ranks[0],
                f"{ranks[0]!r} ranks things, and the reading leaves it out of every reference: "
                "a thing ranks by size, height, left and right, or nearness ('the nearest "
                f"mug'); {SOUND_RANK_WHY}",
            )
        # an ordinal left out of the references ("the second time you heard a dog")
        for i, r in enumerate(roles):
            if r in ("O", "REP") and i and (nth := _ordinal_within(" ".join(words[i - 1 : i + 2]))):
                if _plain(words[i]) == nth.split()[0].lower():
                    raise ParseError(text, nth, ORDINAL_WHY)
        negated = [w for w in plain if is_negation(w)]
        if negated and not other and (reading := self._after_courtesy(text, words, roles, robot)):
            return reading
        if negated:  # the tagger refuses these too; a word that reverses a goal never slips
            raise ParseError(text, " ".join(negated), "the robot cannot honour a negated goal")
        # a thing's name the tagger left out of every reference ("go to the mug left of the
        # duck" read as left of the duck): the reading would drop the thing asked for
        left_out = [w for w in plain if w in kind_words()]
        if left_out:
            raise ParseError(
                text,
                left_out[0],
                f"{left_out[0]!r} names a thing the reading leaves out (a thing picked by where "
                "it stands, 'the mug left of the duck', is not read): ask for the place, 'go to "
                "the left of the duck', or the thing near another, 'go to the mug near the duck'",
            )
        from tabletop.reader.learned import decode

        # the tagger's "between" of a thing and the whole table is one thing said to be on it
        steps = settle_references(
            text,
            _whole_table_side_dropped(
                decode(text, words, roles, rels, robot, read_clause, role_logp)
            ),
        )
        steps = _side_from_words(text, steps, plain)
        # a side word left out of the references where no step goes to a side ("..., the
        # one in yellow's right" read as the duck): the reading would drop the side asked for
        said = {s.action.side for s in steps if isinstance(s.action, Side)}
        sides = [
            w.strip(",.;:!?\"'").lower()
            for i, (w, r) in enumerate(zip(words, roles, strict=True))
            if r in ("O", "THEN", "REP")
            and (side := w.strip(",.;:!?\"'").lower()) in SIDES
            and side not in said
            and not _interjection(words, i)  # "Right, off you go to the mug"
            and not degree_adverb(words, i)  # "right behind the mug": exactly there
        ]
        if sides and not any(isinstance(s.action, MOTIONS) for s in steps):
            raise ParseError(
                text,
                sides[0],
                f"{sides[0]!r} says a side, and the reading leaves it out: say the side of "
                "what, e.g. 'go to the right of the duck'",
            )
        for ref in _reference_texts(steps):
            # (", the blue one" after a name says which: no list)
            if re.search(r",\s*(?:and\s+)?(?:the|a|an)\s(?!.*\bones?\b)", ref):
                raise ParseError(
                    text,
                    ref,
                    "a list of things is no one place: name one goal per step, joined by 'then'",
                )
        refuse_unused_numbers(text, read, steps)
        # a second request after the last reference that the tagger left out ("..., and then
        # put it down"): a joining word, then words that point back at what was named
        last = max((i for i, r in enumerate(roles) if r not in ("O", "THEN", "REP")), default=-1)
        after = [_plain(w) for w in words[last + 1 :]]
        joined = next(
            (i for i, w in enumerate(after) if w in _JOINERS and not _next_to(after, i)), None
        )
        rest = after[joined + 1 :] if joined is not None else []
        # (unless it says the side the reading goes to, "..., and stop on its right", or only
        # to go there, "..., and go there")
        going = is_verb_phrase(" ".join(w for w in rest if w not in POINTERS))
        if POINTERS.intersection(rest) and not SIDES_SAID.intersection(rest) and not going:
            raise ParseError(
                text,
                " ".join(words[last + 1 + joined :]),
                "a second request after the place was not read: the robot goes to places, and a "
                "second place is joined with 'then' ('go to the mug, then to the duck')",
            )
        manner = tuple(w for w in plain if w in MANNER)
        said = (polite,) if polite else ()
        return Reading(text, read, steps, fixes, said, self.name, manner)

    def _after_courtesy(self, text: str, words: list[str], roles: list[str], robot: str):
        """The reading of what follows a courtesy that runs into the request with no comma
        ("if you wouldn't mind heading to the mug") or an aside whose negation stays inside it
        ("no rush, go to the mug", :func:`is_negated_aside`): the longest such lead among the
        words before the first reference whose rest reads; None where none does."""
        lead = next((i for i, r in enumerate(roles) if r != "O"), 0)
        for k in range(lead, 0, -1):
            before, rest = " ".join(words[:k]), " ".join(words[k:])
            if is_negated_aside(before):
                if k < lead and any(is_negation(_plain(w)) for w in words[k:lead]):
                    continue  # the request after the aside negates too
            elif k < 3 or not is_courtesy(before):
                continue
            elif any(w.endswith((",", ";")) for w in words[k:lead]):
                continue  # (a cut inside a clause: "if you don't hear | anything, go ...")
            try:
                reading = self.understand(rest, robot)
            except ParseError:
                continue
            wrapper = (before, *reading.wrapper)
            return dataclasses.replace(reading, text=text, wrapper=wrapper)
        return None


_CLAUSE_READER = RulesReader(spelling=False, wrappers=True)
_GRAMMAR_PLACES = PlaceReader(learned=False)
_LEARNED_PLACES = PlaceReader(learned=True)

#: Readers by name; the first is the default.
READERS: dict[str, type | functools.partial] = {
    "rules+learned": functools.partial(LearnedReader, fallback=True),
    "learned": LearnedReader,
    "rules+spelling": functools.partial(RulesReader, spelling=True, wrappers=True),
    "rules": functools.partial(RulesReader, spelling=False, wrappers=False),
    "llm": LLMReader,
}
DEFAULT_READER = "rules+learned"


@functools.cache
def get_reader(name: str = DEFAULT_READER) -> Reader:
    """The reader called ``name`` (one instance per name and process)."""
    if name not in READERS:
        raise ConfigError(f"unknown reader {name!r}; valid: {', '.join(READERS)}")
    return READERS[name]()


def understand(text: str, robot: str = "arm", reader: str = DEFAULT_READER) -> Reading:
    """What ``text`` asks of ``robot`` ("arm" or "mobile"), as the reader ``reader`` reads it.

    Raises:
        ParseError: the reader could not read it; the error names the part.
        ConfigError: an unknown reader or robot.
    """
    return get_reader(reader).understand(text, robot)

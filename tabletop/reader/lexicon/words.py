"""Word classes of English that carry structure, not a thing's name: negations, ordinals,
superlatives and the words that relate one thing to another.

Both the reader (which refuses or reads them) and the map's own text API (which scores one
thing's words, and so must not drop them silently) ask these; they are closed classes of the
language, not anybody's phrasings.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from tabletop.reader.lexicon.colour_names import COLOR_NAMES

__all__ = [
    "AUXILIARIES",
    "NEGATIONS",
    "SUPERLATIVES",
    "Superlative",
    "breaks_off",
    "degree_adverb",
    "far_from",
    "is_negation",
    "negations",
    "ordinal",
    "placed_by",
    "relation_words",
    "superlative",
]

#: The qualifiers that reverse or exclude a goal: no reader goes to a goal said with one of
#: them outside its references ("don't go to the mug").
NEGATIONS = frozenset("not no never don't dont without avoid except unless".split())


#: Auxiliaries whose contraction with "not" may be typed without its apostrophe ("isnt").
AUXILIARIES = _AUXILIARIES = frozenset(
    "is are was were do does did can could would should will wo has have had must need might "
    "ai sha".split()
)


def is_negation(word: str) -> bool:
    """Whether ``word`` negates: one of :data:`NEGATIONS`, or a verb contracted with "not"
    ("isn't", "doesn't", "isnt", "won't")."""
    w = word.lower().replace("\u2019", "'").strip(",.;:!?\"'")
    if w in NEGATIONS or w.endswith("n't"):
        return True
    return w.endswith("nt") and w[:-2] in _AUXILIARIES


#: Words after which "but" excludes ("anything but the duck").
_EXCEPT_AFTER = frozenset("anything everything anywhere everywhere any all".split())


def negations(text: str, describing: bool = False) -> list[str]:
    """The negating words of ``text`` in order; ``describing``: without "no" and "without",
    which also describe ("the mug with no handle"), unless "no" opens the words ("no mug").
    "non-" before a colour ("the non-red mug"; "non-stick" describes) and "but" after a word of
    all ("anything but the duck") negate too."""
    low = text.lower()
    words = re.findall(r"[a-z'\u2019]+(?:-[a-z]+)*", low)
    out = []
    for i, w in enumerate(words):
        if (w.startswith("non-") and w[4:] in COLOR_NAMES) or (
            w == "but" and i and words[i - 1] in _EXCEPT_AFTER
        ):
            out.append(w)
            continue
        for part in w.split("-"):
            if is_negation(part) and not (
                describing and part in ("no", "without") and not (part == "no" and i == 0)
            ):
                out.append(part)
    return out


#: An ordinal at the start of a reference ("the 3rd mug", "the second duck from the left", "the
#: last one"): it picks one of several things by their order, which no map scores.
_ORDINAL = re.compile(
    r"^(?:(?:the|a|an|your|my)\s+)?(?:very\s+)?(?P<o>\d+\s*(?:st|nd|rd|th)|first|second|third|"
    r"fourth|fifth|sixth|seventh|eighth|ninth|tenth|last|penultimate|(?:second|next)[\s-]+to[\s-]+"
    r"last)\b(?!\s+of\b)",  # "the fourth of July" is a date, not a pick
    re.IGNORECASE,
)


def ordinal(text: str) -> str | None:
    """The ordinal a reference starts with ("3rd", "second", "last"), or None."""
    m = _ORDINAL.match(text.strip())
    return m.group("o") if m else None


class Superlative(NamedTuple):
    """A superlative of a reference: its ``word``, the ``measure`` it ranks by
    (:data:`SUPERLATIVES`), ``sign`` +1 for the most and -1 for the least of it, the
    reference's words without it (``rest``), and where distances are measured from."""

    word: str
    measure: str
    sign: int
    rest: str
    viewpoint: tuple[float, float] = (0.0, 0.0)
    """(x, y) [m] from which ``reach`` is measured: the robot's place (the arm's base by
    default)."""


#: Superlatives that pick one of several things by a measure a map has: ``size`` (the volume of
#: its box), ``height`` (its top), ``left`` (along the robot's left, +y), ``reach`` (the
#: horizontal distance from the robot's base). word -> (measure, +1 most / -1 least).
SUPERLATIVES: dict[str, tuple[str, int]] = {
    **dict.fromkeys(("biggest", "largest", "bulkiest", "hugest"), ("size", 1)),
    **dict.fromkeys(("smallest", "tiniest", "littlest", "teeniest"), ("size", -1)),
    **dict.fromkeys(("tallest", "highest"), ("height", 1)),
    **dict.fromkeys(("shortest", "lowest", "flattest"), ("height", -1)),
    "leftmost": ("left", 1),
    "rightmost": ("left", -1),
    **dict.fromkeys(("nearest", "closest"), ("reach", -1)),
    **dict.fromkeys(("farthest", "furthest", "remotest"), ("reach", 1)),
}
_SUPERLATIVE = re.compile(
    r"\b(?:(?P<dir>left|right)[\s-]*most|most[\s-]+(?P<dir2>left|right)|(?P<w>"
    + "|".join(sorted(SUPERLATIVES, key=len, reverse=True))
    + r"))\b(?!\s+(?:to|from)\b)",  # "the closest to the duck" relates two things
    re.IGNORECASE,
)


def superlative(text: str) -> Superlative | None:
    """The superlative a reference ranks by ("the biggest mug", "the left-most duck"), or None.
    A nearest or farthest thing *to* another ("closest to the duck") relates two things and is
    none."""
    m = _SUPERLATIVE.search(str(text))
    if m is None:
        return None
    side = m.group("dir") or m.group("dir2")
    word = f"{side.lower()}most" if side else m.group("w").lower()
    measure, sign = SUPERLATIVES[word]
    rest = " ".join((text[: m.start()] + " " + text[m.end() :]).split())
    return Superlative(m.group(0), measure, sign, rest)


#: Words that relate one thing to another ("the mug near the duck", "the ball left of the
#: tray", "where you heard ..."): one thing's words hold none.
_RELATION = re.compile(
    r"\b(?:near(?:\s+to)?|next\s+to|close\s+to|beside|behind|in\s+front\s+of|between|"
    r"(?:to\s+the\s+)?(?:left|right)(?:[\s-]*hand)?\s+(?:side\s+)?of|"
    r"(?:nearest|closest|farthest|furthest)\s+(?:to|from)|"
    r"where\s+(?:you|i|we)\s+(?:just\s+)?(?:heard|hear))\b",
    re.IGNORECASE,
)


def relation_words(text: str) -> str | None:
    """The first words of ``text`` that relate one thing to another, or None."""
    m = _RELATION.search(str(text))
    return " ".join(m.group(0).split()) if m else None


#: Words that join or introduce what follows them: a thing's words that end in one were cut
#: off before the rest of their phrase ("the duck then", "the mug which is the"). (A
#: preposition may end a thing's words: "the mug you drink out of".)
_JOINING = frozenset(
    "the a an and or but then which who whose is are was were be been being if".split()
)
#: Words that open a relative clause: after one, a verb describes the thing ("the mug that is
#: red"); without one, a verb in a thing's words makes a statement ("the mug is red").
_RELATIVES = frozenset("that which who whose where one ones".split())
_COPULA_FORMS = frozenset("is are was were isn't aren't wasn't weren't".split())


def breaks_off(ref: str) -> str | None:
    """The word at which one thing's words ``ref`` stop being a noun phrase, or None: a last
    word that joins or introduces more ("the duck, and", "the mug which is the"), or a verb
    "to be" with no relative word before it ("the mug is red": a statement, or a condition,
    about the thing)."""
    words = [w.strip(",.;:!?\"'()").lower() for w in str(ref).split()]
    words = [w for w in words if w]
    if len(words) > 1 and words[-1] in _JOINING:
        return words[-1]
    for i, w in enumerate(words[1:], 1):
        if w in _COPULA_FORMS and not _RELATIVES.intersection(words[:i]):
            return w
    return None


#: A place away from a thing ("far from the duck", "a long way from the mug", "the mug farthest
#: from the duck"): a map scores nearness, and no reading may turn it into near. "not far
#: from" is near, and far from the robot is a side.
_FAR_FROM = re.compile(
    r"(?<!not )(?<!n't )(?<!not too )(?<!not that )(?<!not very )(?<!not so )"
    r"\b(?:(?:far|farther|farthest|further|furthest)(?:\s+away)?|a\s+long\s+way|well\s+away|"
    r"miles)\s+from\b"
    # (far from the robot is a side of a thing, or of the table: "its side furthest from you")
    r"(?!\s+(?:the\s+)?(?:robot|you|me|us|arm|base|yourself)\b)",
    re.IGNORECASE,
)


def far_from(text: str) -> str | None:
    """The words that ask for a place far from a thing, or None (see :data:`_FAR_FROM`)."""
    m = _FAR_FROM.search(str(text))
    return " ".join(m.group(0).split()) if m else None


#: Prepositions that place one thing by another ("in", "inside", "on top of" ends in "of" and is
#: read by the grammar).
_PLACING = frozenset(
    """in inside into within on onto atop under underneath beneath below behind beside above
    over at by against among amid""".split()
)


#: Words that open a place phrase after a degree adverb ("right behind the mug", "right next
#: to it", "right in front"): the prepositions that place a thing, and the other openers of
#: a place.
_PLACE_OPENERS = _PLACING | frozenset(
    """next near close beside between alongside around across past beyond opposite off
    outside toward towards to up down there here where""".split()
)
#: Side words that English also uses as degree adverbs ("right": exactly, immediately).
_DEGREE_SIDES = frozenset({"right"})


def degree_adverb(words: list[str], i: int) -> bool:
    """Whether the word at ``i`` of ``words`` is a side word used as a degree adverb: "right"
    directly before a word that opens a place phrase ("right behind the mug", "right next to
    it"), not before "of", "side" or "hand" ("right of the mug") and not cut off by
    punctuation."""
    word = words[i]
    if word.strip(",.;:!?\"'").lower() not in _DEGREE_SIDES or word.endswith((",", ";", ".")):
        return False
    after = words[i + 1].strip(",.;:!?\"'").lower() if i + 1 < len(words) else ""
    return after in _PLACE_OPENERS


def placed_by(ref: str, heads: frozenset[str] | set[str]) -> str | None:
    """The words by which one thing's words ``ref`` place it by another thing, or None: a
    preposition of place, an article and a phrase that ends in one of ``heads`` (a kind's
    noun: "the duck inside the mug"). Such words relate two things, and one thing's words are
    scored as one."""
    words = [w.strip(",.;:!?\"'()").lower() for w in str(ref).split()]
    for i in range(1, len(words) - 2):
        if words[i] in _PLACING and words[i + 1] in ("the", "a", "an"):
            rest = words[i + 2 : i + 5]
            for j, w in enumerate(rest):
                if w in heads:
                    return " ".join(words[i : i + 3 + j])
    return None

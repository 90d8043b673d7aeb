"""The words of a thing's description that name no thing: what a likeness likens it to ("the
tin can shaped toy"), pointing and politeness ("the cup over there, please"), and the words
that tell no name of a map's vocabulary from another; and the plain forms of a description's
words ("boxy" as "box"), by which a query's words are matched with a name's descriptions.

Read by the object module (:mod:`tabletop.mapping.object_module`) at query time.
"""

from __future__ import annotations

import re

from tabletop.reader.lexicon.colour_words import FILLER_WORDS

__all__ = ["DEIXIS", "LIKENESS_WORDS", "without_deixis", "without_likeness", "word_forms"]

#: The words of a likeness that name nothing.
LIKENESS_WORDS = frozenset("shaped shape like looks look in of the a an".split())
#: "X-shaped", "shaped like X", "in the shape of X", "like X", "the X shape": words that liken
#: the thing to another (hyphens are spaces here; X is one or two words, or up to a joining
#: word).
_LIKENESS = re.compile(
    r"\b(?:shaped\s+like|in\s+the\s+shape\s+of|looks?\s+like|like)\s+(?:(?:a|an|the)\s+)?"
    r"[a-z']+(?:\s+(?!with\b|and\b|near\b|on\b|by\b)[a-z']+)?"
    r"|(?:\b(?!a\b|an\b|the\b)[a-z']+\s+)?\b[a-z']+\s+shaped\b(?!\s+like)"
    r"|(?:\b(?!a\b|an\b|the\b)[a-z']+\s+)?\b(?!a\b|an\b|the\b)[a-z']+\s+shape\b(?!\s+of)"
)


def without_likeness(words: str) -> str:
    """``words`` without what they liken the thing to ("the tin can shaped toy" -> "the toy",
    "a toy shaped like a barrel" -> "a toy"); the words themselves when they liken nothing."""
    return (
        " ".join(_LIKENESS.sub(" ", words).split())
        if "shape" in words or "like" in words
        else words
    )


#: Words that point or ask politely, and describe nothing: "the cup over there", "the red one
#: please", "the duck for me".
DEIXIS = re.compile(
    r"\b(?:(?:over|right|just|up|down)\s+)?(?:there|here)\b|\bplease\b|\bfor\s+me\b"
)


def without_deixis(words: str) -> str:
    """``words`` without what points or asks politely ("the cup over there" -> "the cup");
    the words themselves when nothing else is left."""
    return " ".join(DEIXIS.sub(" ", words).split()) or words


#: Words that tie a description together, or name a thing only loosely ("the bath buddy"),
#: and tell no name from another.
_FORM_STOP = frozenset(
    "and with for from you like shaped shape one small little big piece bit thing object toy plain "
    "buddy pal friend fella chap guy".split()
)
#: Endings a word's plain form drops: "roundish", "boxes", "bumps", "boxy", "stuffie",
#: "dotted", "knobbly".
_ENDINGS = ("ish", "es", "s", "y", "ie", "ed", "ly")


def word_forms(text: str) -> set[str]:
    """The plain forms of ``text``'s words, filler and words of two letters aside: each word,
    without a plural "s", and "boxy" as "box", "roundish" as "round", "dotted" as "dot",
    "angled" as "angle", "knobbly" as "knob", "stuffie" as "stuff"."""
    out = set()
    for w in re.findall(r"[a-z]+", str(text).lower()):
        if len(w) < 3 or w in FILLER_WORDS or w in _FORM_STOP:
            continue
        out.add(w)
        for suffix in _ENDINGS:
            if w.endswith(suffix) and len(w) - len(suffix) >= 3:
                stem = w[: -len(suffix)]
                out.add(stem)
                if suffix in ("ed", "ly") and stem[-1] == stem[-2]:
                    out.add(stem[:-1])  # "dotted" is "dot", "knobbly" "knob"
                elif suffix == "ed":
                    out.add(stem + "e")  # "angled" is "angle"
    return out

"""Numbers and counts in a request: what a number says, and where it says nothing the robot
does.

A request uses a number in two ways only: a distance ("move 5 cm north") and a repetition
("3 times", read by the step's count). Anywhere else a number says something the robot cannot
honour (a time, "in 5 seconds"; a duration, "for 3 hours"; an index, "mug #2"), and a count
in a thing's own words ("zero mugs", "half a mug", "the mugs") asks for a number of things,
where the robot goes to one place. These functions find such numbers by their form, so that
a reader refuses them instead of dropping them or reading them as something else.
"""

from __future__ import annotations

import re

__all__ = [
    "COUNT_WORDS",
    "count_in",
    "is_number",
    "number_value",
    "unused_numbers",
]

#: Number words and the quantity words that count things, with their value (None: a quantity
#: with no one value). "one", "a" and "an" are left out: one thing is what a reference names.
COUNT_WORDS: dict[str, float | None] = {
    "zero": 0,
    "none": 0,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "seven": 7,
    "eight": 8,
    "nine": 9,
    "ten": 10,
    "eleven": 11,
    "twelve": 12,
    "thirteen": 13,
    "fourteen": 14,
    "fifteen": 15,
    "sixteen": 16,
    "seventeen": 17,
    "eighteen": 18,
    "nineteen": 19,
    "twenty": 20,
    "thirty": 30,
    "forty": 40,
    "fifty": 50,
    "sixty": 60,
    "seventy": 70,
    "eighty": 80,
    "ninety": 90,
    "hundred": 100,
    "thousand": 1000,
    "million": 1e6,
    "billion": 1e9,
    "dozen": 12,
    "half": 0.5,
    "couple": 2,
    "pair": 2,
    "several": None,
    "few": None,
    "many": None,
    "multiple": None,
    "numerous": None,
}
#: Words after which a number counts no thing: a numeral never stands before a determiner or
#: a pronoun, so "2" or "4" there is a word typed as a digit ("go 2 the mug", "4 me").
_NO_COUNT_AFTER = frozenset(
    "the a an this that these those my your our his her their me you us it".split()
)
#: Words that end the part of a thing's words before its head noun's complements (a count
#: there counts the thing; "the domino with six dots" counts its parts).
_COMPLEMENT = frozenset(
    """with of in on at by near next beside behind under over above below from to for
    that which who whose where when like than and or but having has showing""".split()
)
#: Units of length, size and time: a number before one measures, it counts no thing ("the 5 cm
#: cube").
_MEASURE = re.compile(
    r"^(?:mm|cm|m|km|in|inch(?:es)?|ft|foot|feet|yards?|millimet(?:er|re)s?|centimet(?:er|re)s?"
    r"|met(?:er|re)s?|kilomet(?:er|re)s?|%|percent|degrees?|deg)$"
)
_STRIP = ",.;:!?\"'()[]{}"
#: Words before a count in a noun phrase.
_DETERMINERS = frozenset("the a an these those my your our his her their some any".split())
#: Quantities with no one value: in a thing's words they count it ("several ducks"); outside
#: them they say how much, loosely ("a few cm left of the mug"), and are no number left over.
_LOOSE = frozenset(w for w, v in COUNT_WORDS.items() if v is None) | {"couple", "pair", "half"}
#: An index after a thing's name: "mug #2", "the duck number 3", "cup no. 2".
_INDEX = re.compile(r"(?:#\s*\d|\b(?:number|no\.?|num\.?)\s*#?\s*\d)", re.IGNORECASE)


def _plain(word: str) -> str:
    return word.strip(_STRIP).lower()


def is_number(word: str) -> bool:
    """Whether ``word`` is a number: it holds a digit ("3", "-1", "#2", "3pm", "1e9") or is one
    of :data:`COUNT_WORDS`."""
    w = _plain(word)
    return bool(w) and (any(c.isdigit() for c in w) or w in COUNT_WORDS)


def number_value(word: str) -> float | None:
    """The value of a number word or a plain decimal ("3", "2.5", "twelve"); None for any
    other form ("3pm", "#2", "several")."""
    w = _plain(word)
    if re.fullmatch(r"[+-]?\d+(?:\.\d+)?", w):
        return float(w)
    v = COUNT_WORDS.get(w)
    return float(v) if v is not None else None


def _singular(word: str) -> tuple[str, ...]:
    """The singular forms a plural ``word`` may have ("mugs" -> "mug", "boxes" -> "box")."""
    if len(word) < 4 or not word.endswith("s") or word.endswith(("ss", "us", "is")):
        return ()
    forms = [word[:-1]]
    if word.endswith("es"):
        forms.append(word[:-2])
    if word.endswith("ies"):
        forms.append(word[:-3] + "y")
    return tuple(forms)


def count_in(ref: str, names: frozenset[str] | set[str] = frozenset()) -> str | None:
    """The words by which one thing's words ``ref`` count or number it, or None:

    - a number before its head noun that measures nothing ("zero mugs", "-1 mugs", "half a
      mug", "a couple of mugs", "several ducks"; not "the 5 cm cube");
    - an index after it ("mug #2", "the duck number 3");
    - a head noun in the plural of a word of ``names`` that is not itself one ("the mugs").

    What follows the head noun's complements is the thing's description and counts its parts
    ("the domino with six dots")."""
    if m := _INDEX.search(ref):
        return m.group(0).strip()
    words = [w for w in (_plain(w) for w in ref.split()) if w]
    head: list[str] = []
    for w in words:
        if w in _COMPLEMENT and head and head[-1] not in ("couple", "pair", "half", "dozen"):
            break
        head.append(w)
    # a count is a noun phrase's first word after its determiner ("the two mugs", "zero
    # mugs"); after another word a number describes ("the double six", "the size five ball")
    first = next((i for i, w in enumerate(head) if w not in _DETERMINERS), len(head))
    if first < len(head):
        w = head[first]
        nxt = head[first + 1] if first + 1 < len(head) else ""
        counts = w in COUNT_WORDS or number_value(w) not in (None, 1.0)  # one thing is named
        after_word = nxt in _NO_COUNT_AFTER - {"a", "an"}  # ("half a cube" counts)
        if is_number(w) and counts and not _MEASURE.match(nxt) and not after_word:
            if "-" not in w.strip("-"):  # a compound ("6-dot") describes the thing
                return w
    if head and head[-1] not in names and any(s in names for s in _singular(head[-1])):
        return head[-1]
    return None


def unused_numbers(read: str, used: list[str], times: set[int]) -> list[str]:
    """The numbers of ``read`` that no part of the reading uses: not inside one of the ``used``
    texts (the references, and the steps read as moves by a distance), not a repetition the
    reading counts ("N times" with N among ``times``), and not a digit typed for a word ("go 2
    the mug")."""
    inside = {_plain(w) for t in used for w in str(t).split()}
    words = read.split()
    out = []
    for i, word in enumerate(words):
        if not is_number(word):
            continue
        nxt = _plain(words[i + 1]) if i + 1 < len(words) else ""
        w = _plain(word)
        if (nxt in _NO_COUNT_AFTER and w not in COUNT_WORDS) or w in _LOOSE:
            continue
        after = _plain(words[i + 2]) if i + 2 < len(words) else ""
        if nxt == "times" or (nxt == "more" and after == "times"):
            if (v := number_value(word)) is not None and v in times:
                continue
            out.append(word.strip(_STRIP))
            continue
        if w in inside:
            continue
        out.append(word.strip(_STRIP))
    return out

"""Colour words of a query: which words name a colour, and which name the thing.

:func:`split_color_words` splits a query into its colour phrase and the rest ("the dark blue
coffee mug" -> "dark blue", "the coffee mug"); :func:`color_parses` adds the other readings a
noun phrase allows ("tomato red" one colour; "hot chocolate" a drink, not a colour), for the
object module to try in order. The colour names are
:data:`~tabletop.reader.lexicon.colour_names.COLOR_NAMES`.

Read at query time only (a map holds nothing this module computes).
"""

from __future__ import annotations

import re
import tomllib
from functools import cache
from pathlib import Path

from tabletop.errors import AssetError
from tabletop.paths import DATA_DIR
from tabletop.reader.lexicon.colour_names import BASIC_COLOURS, COLOR_MODIFIERS, COLOR_NAMES

__all__ = [
    "COLOR_LINK_WORDS",
    "COLOUR_NOUNS",
    "FILLER_WORDS",
    "SURVEY_PATH",
    "color_parses",
    "colour_word",
    "framed_colours",
    "heads",
    "modifies",
    "named_colour",
    "split_color_words",
    "survey_colours",
    "survey_name",
    "survey_words",
    "two_colours",
    "unlisted_modifiers",
]

#: More colour names, beside the lexicon's: the xkcd colour survey's (CC0).
SURVEY_PATH = DATA_DIR / "colours" / "survey.toml"
#: One-word colour names the survey lacks (color-name-list, MIT): read only to say which colour
#: a word means once the query's words or the text encoder have made it a colour
#: (:func:`named_colour`); the list also names everyday things ("bear", "tea").
NAMES_PATH = DATA_DIR / "colours" / "names.toml"

_THING = frozenset(("one", "thing", "object", "something", "item"))
#: Words that name no particular thing: "the red one", "something red".
FILLER_WORDS = _THING | {"the", "a", "an", "that", "is", "this", "its", "it"}
_WORD = re.compile(r"[a-z]+(?:-[a-z]+)*")


def _plain_words(text: str) -> list[str]:
    """``text``'s lower-case words, hyphens as spaces (a hyphen that joins a suffix, "-ish",
    "-y", "-ey", joins: "moss-y" is "mossy")."""
    return _WORD.findall(_suffixes_joined(text).replace("-", " "))


def _suffixes_joined(text: str) -> str:
    """``text`` in lower case, a hyphen that joins a suffix ("-ish", "-y", "-ey") dropped."""
    return re.sub(r"-(ish|e?y)\b", r"\1", str(text).lower())


def _places(words: list[str], name: str):
    """(start, end) of each place ``name``'s words (one or two) stand in ``words``."""
    parts = name.split()
    for k in range(len(words) - len(parts) + 1):
        if words[k : k + len(parts)] == parts:
            yield k, k + len(parts)


#: Words that only tie a colour to the thing: "the cube in red", "a red-coloured cube", "the
#: block painted blue". Dropped with the colour phrase when they stand next to it.
COLOR_LINK_WORDS = frozenset(
    """in coloured colored colour color painted tinted hued shaded toned looking appears
    appearing""".split()
)
#: Nouns that name a thing's colour itself: "with white colouring", "in a blue finish", "of a
#: red hue". Right after the colour phrase they go with it, and so do the "with", "in" or "of"
#: (and article) that bring the phrase in.
COLOUR_NOUNS = frozenset(
    """colouring coloring colouration coloration finish paint paintwork tint hue shade tone
    colour color""".split()
)
#: Words a colour phrase leans on that say the word next to them is a colour, whatever it is
#: ("tomato-coloured", "colour heliotrope", "that appears papaya"); see :func:`framed_colours`.
_FRAME_AFTER = frozenset("coloured colored hued tinted toned".split()) | (
    COLOUR_NOUNS - {"colour", "color"}
)
_FRAME_BEFORE = frozenset("colour color painted appears appearing".split())


def split_color_words(text: str) -> tuple[str, str]:
    """(colour phrase, the rest) of a query: "the dark blue coffee mug" -> ("dark blue",
    "the coffee mug"). Colour words are lexicon names (one or two words), their "-ish" forms
    ("reddish", "bluish"), the :data:`COLOR_MODIFIERS` before one and hyphenated compounds
    that end in one, whatever their first word ("grass-green", "sky-blue"); words that only tie
    the colour to the thing ("in red", "red-coloured": :data:`COLOR_LINK_WORDS`) go with the
    colour. The colour phrase is "" when the query names none, or when nothing but a colour
    name is left ("the orange", "a lemon": then the name is the thing asked for)."""
    return color_parses(text)[0]


#: Words that join the parts of a noun phrase; never the first word of a compound.
_JOINING = frozenset(
    """with of on in at to and or near by from for like as than that which who has have
    having""".split()
)
#: Words before a colour name that are no word of the thing (see :func:`heads`).
_NOT_THING = _JOINING | FILLER_WORDS | COLOR_LINK_WORDS


def _read_colour_names(path: str | Path, words: str) -> dict[str, tuple[int, int, int]]:
    """Name -> sRGB (0-255) of a ``tabletop-colour-names`` file whose names are ``words``
    ("one or two", or "one", lower-case words). AssetError: a malformed file (naming the
    entry)."""
    try:
        d = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"colour names {path} are unreadable: {e}") from None
    if d.get("format") != "tabletop-colour-names" or not isinstance(d.get("names"), dict):
        raise AssetError(f"{path}: expected format 'tabletop-colour-names' with a [names] table")
    shape = r"[a-z]+(?: [a-z]+)?" if words == "one or two" else r"[a-z]+"
    out = {}
    for name, hexa in d["names"].items():
        if not (isinstance(hexa, str) and re.fullmatch(r"#[0-9a-f]{6}", hexa)):
            raise AssetError(f"{path} [names].{name!r}: expected '#rrggbb', got {hexa!r}")
        if not re.fullmatch(shape, name):
            raise AssetError(f"{path} [names].{name!r}: expected {words} lower-case words")
        out[name] = (int(hexa[1:3], 16), int(hexa[3:5], 16), int(hexa[5:7], 16))
    return out


@cache
def survey_colours(path: str | Path = SURVEY_PATH) -> dict[str, tuple[int, int, int]]:
    """Colour name -> sRGB (0-255) of the colour survey (:data:`SURVEY_PATH`), less the
    lexicon's own names, the colour modifiers and the filler words. AssetError: a malformed
    file (naming the entry)."""
    return {
        name: rgb
        for name, rgb in _read_colour_names(path, "one or two").items()
        if name not in COLOR_NAMES and name not in COLOR_MODIFIERS and name not in FILLER_WORDS
    }


@cache
def _more_colours(path: str | Path = NAMES_PATH) -> dict[str, tuple[int, int, int]]:
    """Name -> sRGB of :data:`NAMES_PATH` (one-word names, the survey's format)."""
    return _read_colour_names(path, "one")


def named_colour(word: str) -> tuple[int, int, int] | None:
    """The sRGB colour a word named as a colour means where neither the lexicon nor the survey
    has it ("quince", "marigold"; its "-y" or "-ish" form too), from :data:`NAMES_PATH`; None
    where no list has it. Never a test of whether the word *is* a colour."""
    more = _more_colours()
    w = str(word).lower()
    for suffix in ("-ish", "-y", "-ey"):  # "quince-y": the hyphen only joins the suffix
        if w.endswith(suffix) and len(w) > len(suffix) + 2:
            w = w[: -len(suffix)]
            break
    for cand in (w, w[:-3] if w.endswith("ish") else "", w[:-1] if w.endswith("y") else ""):
        if cand and cand in more:
            return more[cand]
    return None


def survey_words(text: str) -> list[str]:
    """The survey's colour names in ``text`` that the lexicon does not have (two-word names
    first, then the single words not inside one), in the order they stand."""
    names = survey_colours()
    words = _plain_words(text)
    out, skip = [], set()
    for i in range(len(words)):
        pair = " ".join(words[i : i + 2])
        if i + 1 < len(words) and pair in names and pair not in COLOR_NAMES:
            out.append(pair)
            skip |= {i, i + 1}
        elif i not in skip and (words[i] in names or _ish(words[i]) in names):
            out.append(words[i])  # "grassy": the survey's "grass"
    return out


def unlisted_modifiers(text: str) -> list[str]:
    """Words of ``text`` that may be colours no list has: each modifies more of the noun
    phrase (:func:`modifies`: "the smoke bear", not "the bear in the smoke"), has three
    letters or more, and is no colour of the lexicon or the survey, no colour modifier and no
    filler, joining or link word. Whether one *is* a colour is for the text encoder to say."""
    out = []
    for w in _plain_words(text):
        if (
            len(w) > 2
            and w.isalpha()
            and w not in out
            and not colour_word(w)
            and w not in COLOR_MODIFIERS
            and w not in FILLER_WORDS
            and w not in _JOINING
            and w not in COLOR_LINK_WORDS
            and w not in COLOUR_NOUNS
            and modifies(text, w)
        ):
            out.append(w)
    return out


def two_colours(phrase: str) -> tuple[str, ...]:
    """The basic colour terms of a colour phrase that names a thing of several colours: two or
    more different basic terms ("red blue", "black white" from "black and white") that are
    together no colour name of the lexicon or the survey ("blue green" and "red brown" are
    shades). () for any other phrase."""
    words = str(phrase).lower().split()
    if (
        len(words) < 2
        or not all(w in BASIC_COLOURS for w in words)
        or len(set(words)) < 2
        or " ".join(words) in COLOR_NAMES
        or " ".join(words) in survey_colours()
    ):
        return ()
    return tuple(dict.fromkeys(words))


def colour_word(word: str) -> bool:
    """Whether ``word`` (one word) names a colour of the lexicon or the survey, itself or as
    its "-ish" / "-y" adjective ("reddish", "grassy"); modifiers ("pale", "deep") do not."""
    return _ish(word) in COLOR_NAMES or bool(survey_name(word))


def survey_name(word: str) -> str:
    """The survey's colour name ``word`` (one or two words) stands for: itself, or the name
    its "-y" adjective is made of ("grassy": "grass"); "" for none."""
    names = survey_colours()
    return word if word in names else (_ish(word) if _ish(word) in names else "")


def color_parses(text: str, extra=frozenset()) -> list[tuple[str, str]]:
    """The ways to read a query's colour words, most likely first: (colour phrase, the rest)
    pairs, the first being :func:`split_color_words`'s. Two other readings follow where a word
    stands right before a colour name with more of the noun phrase after it:

    - the word and the colour are one colour name ("tomato red", "peacock blue", "soot
      black"): the word joins the colour phrase, rather than being read as the thing;
    - a colour name that is not a basic term is part of a compound noun with the word before
      it ("hot chocolate" in "the hot chocolate mug"): it stays with the thing.

    A colour of a part after "with" (:func:`_part_colours`: "the mug with a red handle") is
    not the thing's: where the query also names the thing's own colour, the reading with that
    colour alone comes first; where it names only a part's, the reading without any colour
    comes last.

    A caller tries them in order and keeps the first that finds something: the first
    reading when it does (a reading whose colour words a word of the thing splits comes
    after those whose colour phrase is in one piece), so that words the lexicon calls
    colours stay colours. ``extra``: more colour names (of :func:`survey_colours`) to read
    as colours in this query."""
    words, where = _colour_positions(text, frozenset(extra))
    first = _reading(words, where)
    if not where:
        return [first]
    content = [
        k
        for k, w in enumerate(words)
        if k not in where and w not in FILLER_WORDS and w not in COLOR_LINK_WORDS
    ]
    options = [(tuple(where), False)]
    i = min(where)
    prev = i - 1
    # more of the noun phrase after the colour: a word of the thing, or "one" ("the
    # strawberry pink one")
    after = [k for k in content if k > max(where)] or [
        k for k in range(max(where) + 1, len(words)) if words[k] in _THING
    ]
    if (
        prev >= 0
        and prev in content
        and words[prev] not in _JOINING
        and words[prev] not in COLOR_MODIFIERS
        and after
        and first[0]
    ):
        options.append((tuple(sorted({prev, *where})), False))
    for k in sorted(where):
        name = _ish(words[k])
        single = name in COLOR_NAMES and " " not in name and name not in BASIC_COLOURS
        if (
            single
            and k - 1 in content
            and words[k - 1] not in _JOINING
            and [j for j in content if j > k]
        ):
            options.append((tuple(j for j in where if j != k), True))

    def split(pos) -> bool:  # colour words with a word of the thing between them
        inside = (k for k in range(min(pos), max(pos)) if k not in pos)
        return any(k in content and words[k] not in _JOINING for k in inside)

    # a colour phrase in one piece before one split by a word of the thing ("blue" before
    # "blue ... chocolate" in "the blue hot chocolate mug")
    options.sort(key=lambda o: bool(o[0]) and split(o[0]))
    # a part's colour ("with a red handle") is not the thing's: where the query names the
    # thing's own colour too ("the blue mug with a red handle"), that is read first; where it
    # names only a part's, reading it as the thing's comes first (a lego brick's studs are
    # its colour) and no colour at all last ("the domino with white spots" where no white
    # domino stands: the dots are white, the domino need not be)
    part = _part_colours(words, where)
    whole = tuple(k for k in where if k not in part)
    if part and whole:
        options.insert(0, (whole, False))
    elif part:
        options.append(((), False))
    out = [_reading(words, pos, keep_names=keep) for pos, keep in options]
    seen: set[tuple[str, str]] = set()
    return [r for r in out if not (r in seen or seen.add(r))]


#: Nouns after "with <colour>" that name what covers the whole thing, whose colour is the
#: thing's ("the bear with brown fur", "the ball with a shiny red surface").
SURFACE_NOUNS = frozenset(
    """fur feathers feather coat skin body surface surfaces outside exterior shell plastic
    rubber wood fabric cloth material all over everywhere""".split()
)
#: Words that may stand between "with" and a part's colour ("with two big white spots").
_PART_LEAD = frozenset(
    """a an the some its two three four five six many lots of little small big large tiny
    bright dark light pale deep""".split()
)


def _part_colours(words: list[str], where) -> set[int]:
    """Positions among ``where`` of colour words that name a part's colour: after "with",
    "having" or "has" (articles, counts and sizes between), before a noun that is no colour
    noun and no :data:`SURFACE_NOUNS` ("with white spots", "with a black nose", "with red and
    white stripes"; not "with white colouring" nor "with brown fur")."""
    where = set(where)
    out: set[int] = set()
    for k, w in enumerate(words):
        if w not in ("with", "having", "has"):
            continue
        j = k + 1
        while j < len(words) and words[j] in _PART_LEAD and j not in where:
            j += 1
        run = []
        while j < len(words) and (j in where or (words[j] in ("and", "or") and run)):
            if j in where:
                run.append(j)
            j += 1
        if not run or j >= len(words):
            continue
        noun = words[j]
        if noun in COLOUR_NOUNS or noun in SURFACE_NOUNS or noun in _JOINING:
            continue
        if noun in FILLER_WORDS and noun not in _THING:
            continue
        out |= set(run)
    return out


def framed_colours(text: str) -> list[str]:
    """The words of ``text`` that its words name as a colour though no lexicon has them: the
    word before "coloured", "colour" or a colour noun ("tomato-coloured", "a papaya finish")
    or after "colour", "painted" or "appears" ("colour heliotrope", "that appears bluebell").
    A word of one or two letters, a filler or a joining word is none."""
    words = _plain_words(text)
    out = []
    for k, w in enumerate(words):
        after = words[k + 1] if k + 1 < len(words) else ""
        framed = after in _FRAME_AFTER or after.removesuffix("ish") in _FRAME_AFTER  # "-ish"
        framed = framed or (k > 0 and words[k - 1] in _FRAME_BEFORE)
        if (
            framed
            and len(w) > 2
            and w not in FILLER_WORDS
            and w not in _JOINING
            and w not in COLOR_LINK_WORDS
            and w not in COLOUR_NOUNS
            and _ish(w) not in COLOR_NAMES
            and w not in out
        ):
            out.append(w)
    return out


def modifies(text: str, name: str) -> bool:
    """Whether colour name ``name`` (one or two words) stands in ``text`` before more of the
    noun phrase, as a modifier does: another word follows it that joins nothing ("the
    heliotrope block", "the tomato one"; not "a ripe tomato", "the tomato on the tray")."""
    words = _plain_words(text)
    for _, end in _places(words, name):
        after = words[end] if end < len(words) else ""
        if after and after not in _JOINING and (after not in FILLER_WORDS or after in _THING):
            return True
    return False


def heads(text: str, name: str) -> bool:
    """Whether colour name ``name`` (one or two words) ends the noun phrase after a word of the
    thing, as its head noun does: "the domino stone", "the rubber duck's lemon" (not "the mug
    in cherry", where a link word ties the colour to the thing)."""
    words = _plain_words(text)
    for start, end in _places(words, name):
        last = end == len(words) or words[end] in _JOINING
        if start > 0 and last and words[start - 1] not in _NOT_THING:
            return True
    return False


def _colour_positions(text: str, extra: frozenset[str]) -> tuple[list[str], list[int]]:
    """The query's words (hyphenated colour compounds one word, others split) and the
    positions of its colour words (lexicon names and ``extra``)."""
    raw = _WORD.findall(_suffixes_joined(text))
    words: list[str] = []
    shades: set[int] = set()
    for j, w in enumerate(raw):
        parts = w.split("-")
        if w in COLOR_NAMES or len(parts) == 1:
            words.append(w)
        elif " ".join(parts) in COLOR_NAMES or parts[0] in COLOR_MODIFIERS:
            words += parts  # "light-grey" is "light grey"
        elif _ish(parts[-1]) in COLOR_NAMES or "-".join(parts[-2:]) in COLOR_NAMES:
            words.append(w)  # "grass-green", "sky-blue", "jet-black": one colour word
        elif j + 1 < len(raw) and _ish(raw[j + 1]) in COLOR_NAMES and raw[j + 1] not in _THING:
            # a compound before a colour name names its shade by a thing of that colour
            # ("pillar-box red", "egg-yolk yellow"): its words are no words of the thing
            shades.add(len(words))
            words.append(w)
        else:
            words += parts
    names = set(COLOR_NAMES) | extra | {_ish(w) for w in extra}

    def is_colour(word: str) -> bool:
        parts = word.split("-")
        return _ish(word) in names or (len(parts) > 1 and _ish(parts[-1]) in names)

    where: list[int] = []
    i = 0
    while i < len(words):
        if _sized_after(words, i):  # "the ball about the size of an orange": no colour
            i += 1
            continue
        if i + 1 < len(words) and " ".join(words[i : i + 2]) in names:
            where += [i, i + 1]
            i += 2
            continue
        w = words[i]
        if (
            i in shades
            or is_colour(w)
            or (w in COLOR_MODIFIERS and i + 1 < len(words) and is_colour(words[i + 1]))
        ):
            where.append(i)
        i += 1
    return words, where


#: Word pairs that liken a thing's size or shape, not its colour, to what follows.
_SIZE_LIKENESS = frozenset(
    ("size of", "shape of", "shaped like", "sized like", "big as", "small as", "large as")
)


def _sized_after(words: list[str], k: int) -> bool:
    """Whether the word at ``k`` follows a likeness of size or shape ("the size of an
    orange", "shaped like a lemon"), articles between."""
    j = k - 1
    while j >= 0 and words[j] in ("a", "an", "the"):
        j -= 1
    return j >= 1 and f"{words[j - 1]} {words[j]}" in _SIZE_LIKENESS


def _reading(words: list[str], where, keep_names: bool = False) -> tuple[str, str]:
    """(colour phrase, the rest) with the words at ``where`` as the colour. With
    ``keep_names`` a lone colour name left in the rest is not taken for the thing asked."""
    where = sorted(where)
    colour = [_ish(words[k]) for k in where]
    rest = [w for k, w in enumerate(words) if k not in where]
    if not colour:
        return "", " ".join(words)
    if not keep_names and not [w for w in rest if w not in FILLER_WORDS]:
        if not [w for w in rest if w in _THING]:
            return "", " ".join(words)  # "the orange", "a lemon": the colour name is the noun
    near = {j for k in where for j in (k - 1, k + 1)}
    drop = set(where) | {k for k in near if 0 <= k < len(words) and words[k] in COLOR_LINK_WORDS}
    after = max(where) + 1
    if after < len(words) and words[after] in COLOUR_NOUNS:  # "with white colouring"
        drop.add(after)
        k = min(where) - 1
        while k >= 0 and words[k] in ("a", "an", "the"):
            k -= 1
        if k >= 0 and words[k] in ("with", "in", "of", "having"):
            drop |= set(range(k, min(where)))
    return " ".join(colour), " ".join(w for k, w in enumerate(words) if k not in drop)


def _ish(word: str) -> str:
    """ "reddish" -> "red", "bluish" -> "blue", "greyish" -> "grey", a hedged compound led by a
    basic colour term ("greenstoneish" -> "green"), the superlatives
    ("blackest" -> "black", "bluest" -> "blue") and the adjectives in "-y" of a colour name
    ("minty" -> "mint", "creamy" -> "cream", "chocolatey" -> "chocolate", "rosy" -> "rose",
    "grassy" -> "grass", "icy" -> "ice", "muddy" -> "mud" of the survey), also with the suffix
    hyphenated and on a word that already has one ("moss-y", "minty-ish" -> "mint"); other
    words unchanged."""
    if (joined := _suffixes_joined(word)) != word.lower():  # "moss-y" is "mossy"
        return inner if (inner := _ish(joined)) != joined else word
    for suffix in ("ish", "est"):
        if word.endswith(suffix) and len(word) > 5:
            stem = word[:-3]
            for cand in (stem, stem[:-1], stem + "e"):  # redd-ish, blu-ish, purpl-ish
                if cand in COLOR_NAMES:
                    return cand
            if suffix == "ish" and (inner := _ish(stem)) != stem:  # "minty-ish": mint
                return inner
    if word.endswith("ish") and word[:-3] not in survey_colours():
        # a hedged compound that a basic colour term leads ("greenstone-ish", "redcurrant-ish"):
        # the hedge says its colour is the compound's, and no list has the compound
        stem = word[:-3]
        for basic in BASIC_COLOURS:
            if stem.startswith(basic) and len(stem) - len(basic) >= 3:
                return basic
    if word.endswith("y") and len(word) > 2 and word not in COLOR_NAMES:
        stem = word[:-1]  # mint-y, chocolate-y, smok(e)-y, ic(e)-y, clay-ey, mud(d)-y
        doubled = stem[:-1] if len(stem) > 2 and stem[-1] == stem[-2] else ""
        for cand in (stem, stem + "e", stem[:-1] if stem.endswith("e") else "", doubled):
            if cand in COLOR_NAMES or cand in survey_colours():
                return cand
    return word

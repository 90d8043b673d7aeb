"""Paraphrase suites: the shipped suites' goals asked the way people ask, on new scenes, and goals
for things that are not there.

The shipped suites (:mod:`tabletop.eval.suites`) ask every object by its catalog label ("the blue
jenga block") and every sound by its bank caption. These suites draw the same goals from the
same machinery (:func:`~tabletop.eval.suites.generate_suite`, a seeded scan's ground truth) on
generated scenes no other experiment uses, and word them from a *paraphrase bank*: synonyms,
shorter and longer names, other word orders, shape, material and use, colour synonyms, sounds
by what people hear. Each suite adds ``absent`` goals: objects outside the catalog, catalog
kinds the scene lacks, a colour no object of a present kind has, sounds the scan did not play,
places that are not on a table top (asked as areas). Instructions are kept as the bank words
them, not filtered through the reader: one it refuses is a miss.

The bank is data, disjoint pools in ``tabletop/data/paraphrases/``: ``<pool>.toml`` words the
suites in ``tabletop/data/tasks/paraphrase-<pool>/``. Tune on the tune pools' suites
(:data:`TUNE_POOLS`); do not read the held-out pools (:data:`HELDOUT_POOLS`) or their suites
while tuning: evaluate them at the end. No held-out phrasing equals a tune phrasing or a training
text (``tests/test_paraphrase.py``). Regenerate::

    python -m tabletop.eval.paraphrase --out tabletop/data/tasks     # every pool
    python -m tabletop.eval.paraphrase --out tabletop/data/tasks --pool tune-2

Seeded: the same scans give the same files (the scans come through the evaluation cache).
"""

from __future__ import annotations

import argparse
import json
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.eval.suites import (
    _FULL,
    _SCAN,
    RELATION_WORDS,
    SIDE_RELATIONS,
    Wording,
    generate_suite,
    to_toml,
)
from tabletop.eval.tasks import parse_tasks
from tabletop.mapping.sound_vocabulary import SOUND_FAMILIES
from tabletop.paths import DATA_DIR
from tabletop.sim.catalog import COLORS, OBJECT_KINDS
from tabletop.sim.ground_truth import AreaTruth, GroundTruth, ObjectTruth, SoundEventTruth
from tabletop.sim.sound_bank import is_category_name

__all__ = [
    "ABSENT_COUNTS",
    "BANK_DIR",
    "CONFUSABLE_KINDS",
    "HELDOUT_POOLS",
    "HELDOUT_SEEDS",
    "POOLS",
    "POOL_SEEDS",
    "READ_HELDOUT_POOLS",
    "SOUND_FAMILIES",
    "SUITE_DIRS",
    "TUNE_POOLS",
    "TUNE_SEEDS",
    "ParaphraseBank",
    "ParaphraseWording",
    "absent_goals",
    "load_bank",
    "paraphrase_suite",
    "suite_sections",
    "write_paraphrase_suites",
]

#: The pools of phrasings, and the suites each words. A pool is a tune pool (tune on its suites)
#: or a held-out pool (never read, evaluated at the end). The later pools were written by
#: authors who had read neither the parser, the lexicons nor the other banks, so that they word
#: goals in ways the first pair did not think of.
POOLS = (
    "tune",
    "heldout",
    "tune-2",
    "heldout-2",
    "heldout-3",
    "heldout-4",
    "heldout-5",
    "heldout-6",
    "heldout-7",
    "heldout-8",
    "heldout-9",
    "heldout-10",
    "heldout-11",
    "heldout-12",
    "heldout-13",
    "heldout-14",
    "heldout-15",
    "heldout-16",
    "heldout-17",
    "heldout-18",
    "heldout-19",
    "heldout-20",
    "heldout-21",
    "heldout-22",
    "heldout-23",
    "heldout-24",
    "heldout-25",
    "heldout-26",
    "heldout-27",
    "heldout-28",
    "heldout-29",
    "heldout-30",
    "heldout-31",
    "heldout-32",
    "heldout-33",
)
#: Held-out pools: evaluated once, for a report ("heldout-13", "heldout-14", "heldout-15",
#: "heldout-17", "heldout-30" ... "heldout-33"), written without reading the
#: parser, the lexicons or the other pools; their suites generated unread. The misses of
#: heldout-30 ... heldout-32 were read after their reports; they stay out of training until the
#: readers are next refitted, so that the committed ones reproduce (:data:`READ_HELDOUT_POOLS`);
#: the next judge is a new pool. A held-out pool whose suites were read after its report
#: ("heldout", "heldout-2" ... "heldout-12", "heldout-16", and "heldout-18" ... "heldout-29":
#: :data:`READ_HELDOUT_POOLS`) is tuned on from then on, like a tune pool, and every newer
#: held-out pool must differ from it and from every training text (tests/test_paraphrase.py
#: names the entries that do not, by index only).
HELDOUT_POOLS: tuple[str, ...] = (
    "heldout-13",
    "heldout-14",
    "heldout-15",
    "heldout-17",
    "heldout-30",
    "heldout-31",
    "heldout-32",
    "heldout-33",
)
TUNE_POOLS = tuple(p for p in POOLS if p not in HELDOUT_POOLS)
#: Held-out pools read after their report, judged once each before that; from heldout-18 on
#: they were kept out of training until the reader was retrained on them (heldout-18 ...
#: heldout-29 are tune pools now): a newer held-out pool must differ
#: from them as from the tune pools.
READ_HELDOUT_POOLS: tuple[str, ...] = (
    "heldout-18",
    "heldout-19",
    "heldout-20",
    "heldout-21",
    "heldout-22",
    "heldout-23",
    "heldout-24",
    "heldout-25",
    "heldout-26",
    "heldout-27",
    "heldout-28",
    "heldout-29",
    "heldout-30",
    "heldout-31",
    "heldout-32",
)
BANK_DIR = DATA_DIR / "paraphrases"
SUITE_DIRS = {p: f"paraphrase-{p}" for p in POOLS}
#: Generator seeds of the scenes (and their scans), used by no other experiment: not the shipped
#: suites (11-15), the calibration (700-705), eval-map (10-12), the instance evaluation
#: (900-902), the clutter suites (950-953), vision training (layout seeds
#: ``seed * 100_000 + i``: 0-219) or its held-out layouts (from 9,000,000). In use here: 750-752,
#: 760-762, 800-803 ... 890-893 (by tens), 910-913, 920-923, 930-933, 940-943, 960-963,
#: 970-973, 980-983, 990, 992-994 (991 gave no multimodal goal), 995-998, 1010-1013,
#: 1020-1023, 1030-1033, 1040-1043, 1050-1053, 1060-1063, 1070-1073, 1080-1083, 1090-1093,
#: 1100-1103, 1110-1113, 1120-1123, 1130-1133 and 1140-1143.
TUNE_SEEDS = (750, 751, 752)
HELDOUT_SEEDS = (800, 801, 802, 803)
POOL_SEEDS = {
    "tune": TUNE_SEEDS,
    "heldout": HELDOUT_SEEDS,
    "tune-2": (760, 761, 762),
    "heldout-2": (810, 811, 812, 813),
    "heldout-3": (820, 821, 822, 823),
    "heldout-4": (830, 831, 832, 833),
    "heldout-5": (840, 841, 842, 843),
    "heldout-6": (850, 851, 852, 853),
    "heldout-7": (860, 861, 862, 863),
    "heldout-8": (870, 871, 872, 873),
    "heldout-9": (880, 881, 882, 883),
    "heldout-10": (890, 891, 892, 893),
    "heldout-11": (910, 911, 912, 913),
    "heldout-12": (920, 921, 922, 923),
    "heldout-13": (930, 931, 932, 933),
    "heldout-14": (940, 941, 942, 943),
    "heldout-15": (960, 961, 962, 963),
    "heldout-16": (970, 971, 972, 973),
    "heldout-17": (980, 981, 982, 983),
    "heldout-18": (990, 992, 993, 994),
    "heldout-19": (995, 996, 997, 998),
    "heldout-20": (1010, 1011, 1012, 1013),
    "heldout-21": (1020, 1021, 1022, 1023),
    "heldout-22": (1030, 1031, 1032, 1033),
    "heldout-23": (1040, 1041, 1042, 1043),
    "heldout-24": (1050, 1051, 1052, 1053),
    "heldout-25": (1060, 1061, 1062, 1063),
    "heldout-26": (1070, 1071, 1072, 1073),
    "heldout-27": (1080, 1081, 1082, 1083),
    "heldout-28": (1090, 1091, 1092, 1093),
    "heldout-29": (1100, 1101, 1102, 1103),
    "heldout-30": (1110, 1111, 1112, 1113),
    "heldout-31": (1120, 1121, 1122, 1123),
    "heldout-32": (1130, 1131, 1132, 1133),
    "heldout-33": (1140, 1141, 1142, 1143),
}

#: Absent goals per scene: objects outside the catalog, catalog kinds the scene lacks, a colour
#: no object of a present kind has, bank sounds the scan did not play, sounds outside the bank,
#: places that are not on a table top (asked as areas; from pools that have them).
ABSENT_COUNTS = {"object": 3, "kind": 2, "colour": 2, "sound": 2, "sound_other": 2, "area": 2}
#: At least this many absent goals per scene (shortfalls of one group filled from the others).
MIN_ABSENT = 8

#: Kinds a person could take for one another ("the ball", "a block"): an absent kind is not
#: asked while one it could be taken for is in the scene.
CONFUSABLE_KINDS: Mapping[str, frozenset[str]] = MappingProxyType(
    {
        "ball": frozenset({"soccer_ball"}),
        "soccer_ball": frozenset({"ball"}),
        "toy_cube": frozenset({"lego_brick", "jenga_block"}),
        "lego_brick": frozenset({"toy_cube"}),
        "jenga_block": frozenset({"toy_cube", "domino"}),
        "domino": frozenset({"jenga_block"}),
    }
)
#: Colours a person could take for one another: an absent colour is none of these of a colour
#: that kind has in the scene.
_NEAR_COLOURS = {
    "red": {"pink", "orange"},
    "pink": {"red", "purple"},
    "orange": {"red", "yellow", "brown"},
    "yellow": {"orange"},
    "white": {"grey"},
    "grey": {"white", "black"},
    "black": {"grey"},
    "blue": {"purple"},
    "purple": {"blue", "pink"},
    "brown": {"orange"},
    "green": set(),
}
#: Area keys of the bank, and how a ground-truth area maps to one.
AREA_KEYS = ("left", "right", "front", "back", "center", "tray")
_AREA_KEY = {
    "left side of the table": "left",
    "right side of the table": "right",
    "front of the table": "front",
    "back of the table": "back",
    "center of the table": "center",
}
#: Instruction templates of the bank: verbs, a sound's wrapper, the "near" word, relations.
INSTRUCTION_KEYS = (
    "verbs",
    "sound",
    "near",
    "between",
    *[r for r in RELATION_WORDS if r != "between"],
)
_PLACEHOLDERS = {"sound": ("{s}",), "between": ("{a}", "{b}"), "verbs": (), "near": ()}
_SIDES = SIDE_RELATIONS


# ---------------------------------------------------------------------------- the bank
@dataclass(frozen=True)
class ObjectPhrases:
    """How people name one catalog kind: ``names`` ("{c}" marks a colour's place; a name
    without it is used only when no colour is needed) and ``vague`` names, each with the other
    kinds it could also name (used only when none of those is in the scene)."""

    names: tuple[str, ...]
    vague: tuple[tuple[str, frozenset[str]], ...] = ()


@dataclass(frozen=True)
class ParaphraseBank:
    """One pool of phrasings (``tabletop/data/paraphrases/<pool>.toml``); see that file's header
    for the layout. Read-only mappings of tuples."""

    pool: str
    objects: Mapping[str, ObjectPhrases]
    colours: Mapping[str, tuple[str, ...]]
    colour_forms: tuple[str, ...]
    sounds: Mapping[str, tuple[str, ...]]
    areas: Mapping[str, tuple[str, ...]]
    absent_objects: Mapping[str, frozenset[str]]
    absent_sounds: Mapping[str, frozenset[str]]
    instructions: Mapping[str, tuple[str, ...]]
    source: str = ""
    absent_areas: tuple[str, ...] = ()
    """Places that are not on a table top ("the garden shed"), asked as areas: the map must
    refuse them (``[absent.areas] phrases``; a pool may have none)."""

    def phrasings(self) -> dict[str, str]:
        """Every phrasing of the pool, keyed by where it is ("objects.mug", "sounds.dog", ...):
        object names without their colour slot, colour words, sounds, areas, absent names
        (the disjointness tests compare these)."""
        out = {}
        for k, ph in self.objects.items():
            for i, n in enumerate(ph.names):
                out[f"objects.{k}.names[{i}]"] = _strip_colour(n)
            for i, (n, _) in enumerate(ph.vague):
                out[f"objects.{k}.vague[{i}]"] = _strip_colour(n)
        for c, ws in self.colours.items():
            for i, w in enumerate(ws):
                out[f"colours.{c}[{i}]"] = w
        for section in ("sounds", "areas"):
            for k, ps in getattr(self, section).items():
                for i, p in enumerate(ps):
                    out[f"{section}.{k}[{i}]"] = p
        for section in ("absent_objects", "absent_sounds", "absent_areas"):
            for i, p in enumerate(getattr(self, section)):
                out[f"{section}[{i}]"] = p
        return out


def _strip_colour(name: str) -> str:
    return re.sub(r"\s+", " ", name.replace("{c}", "")).strip()


def _strings(v: object, where: str, placeholders: tuple[str, ...] = ()) -> tuple[str, ...]:
    if not isinstance(v, list) or not v or not all(isinstance(x, str) and x.strip() for x in v):
        raise AssetError(f"{where}: expected a non-empty list of phrases, got {v!r}")
    for x in v:
        missing = [p for p in placeholders if x.count(p) != 1]
        if missing:
            raise AssetError(f"{where}: {x!r} must hold each of {list(placeholders)} once")
    return tuple(v)


def _table(d: object, where: str, required: tuple = (), optional: tuple = ()) -> dict:
    if not isinstance(d, dict):
        raise AssetError(f"{where}: expected a table, got {type(d).__name__}")
    valid = (*required, *optional)
    unknown = sorted(set(d) - set(valid))
    if unknown:
        raise AssetError(f"{where}: unknown keys {unknown}; valid: {list(valid)}")
    missing = [k for k in required if k not in d]
    if missing:
        raise AssetError(f"{where}: missing keys {missing}")
    return d


def _names_to(d: object, where: str, valid) -> dict[str, frozenset[str]]:
    """A table phrase -> list of names (kinds or categories), each one ``valid(name)``."""
    if not isinstance(d, dict):
        raise AssetError(f"{where}: expected a table, got {type(d).__name__}")
    out = {}
    for phrase, names in d.items():
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise AssetError(f"{where}.{phrase!r}: expected a list of names, got {names!r}")
        bad = [n for n in names if not valid(n)]
        if bad:
            raise AssetError(f"{where}.{phrase!r}: unknown names {bad}")
        out[phrase] = frozenset(names)
    return out


def _bank(d: dict, source: str, pool: str) -> ParaphraseBank:
    d = _table(
        d,
        source,
        (
            "format",
            "version",
            "pool",
            "objects",
            "colours",
            "colour_forms",
            "sounds",
            "areas",
            "absent",
            "instructions",
        ),
    )
    if d["format"] != "tabletop-paraphrases" or d["version"] != 1:
        raise AssetError(f"{source}: expected format 'tabletop-paraphrases' version 1")
    if d["pool"] != pool:
        raise AssetError(f"{source}: pool is {d['pool']!r}, expected {pool!r}")
    objs = _table(d["objects"], f"{source} [objects]", tuple(sorted(OBJECT_KINDS)))
    objects = {}
    for kind, v in objs.items():
        w = f"{source} [objects.{kind}]"
        v = _table(v, w, ("names",), ("vague",))
        names = _strings(v["names"], f"{w}.names")
        for n in names:
            if n.count("{c}") > 1 or re.search(r"\{(?!c\})", n):
                raise AssetError(f"{w}.names: {n!r} may hold one '{{c}}' and no other braces")
        if len(OBJECT_KINDS[kind].colors) > 1 and not any("{c}" in n for n in names):
            raise AssetError(
                f"{w}.names: {kind!r} comes in several colours; give a name with '{{c}}'"
            )
        vague = _names_to(v.get("vague", {}), f"{w}.vague", OBJECT_KINDS.__contains__)
        objects[kind] = ObjectPhrases(names, tuple(sorted(vague.items())))
    cols = _table(d["colours"], f"{source} [colours]", (), tuple(COLORS))
    colours = {c: _strings(v, f"{source} [colours].{c}") for c, v in cols.items()}
    forms = _table(d["colour_forms"], f"{source} [colour_forms]", ("forms",))
    colour_forms = _strings(forms["forms"], f"{source} [colour_forms].forms", ("{n}", "{c}"))
    snd = d["sounds"]
    if not isinstance(snd, dict):
        raise AssetError(f"{source} [sounds]: expected a table, got {type(snd).__name__}")
    bad = [k for k in snd if not is_category_name(k)]
    if bad:
        raise AssetError(f"{source} [sounds]: {bad} are not sound category names (snake_case)")
    sounds = {k: _strings(v, f"{source} [sounds].{k}") for k, v in snd.items()}
    ar = _table(d["areas"], f"{source} [areas]", AREA_KEYS)
    areas = {k: _strings(v, f"{source} [areas].{k}") for k, v in ar.items()}
    bad = [x for v in areas.values() for x in v if not x.startswith("the ")]
    if bad:
        raise AssetError(f"{source} [areas]: {bad} must be noun phrases starting with 'the '")
    absent = _table(d["absent"], f"{source} [absent]", ("objects", "sounds"), ("areas",))
    absent_objects = _names_to(
        absent["objects"], f"{source} [absent.objects]", OBJECT_KINDS.__contains__
    )
    absent_sounds = _names_to(absent["sounds"], f"{source} [absent.sounds]", is_category_name)
    absent_areas: tuple[str, ...] = ()
    if "areas" in absent:
        a = _table(absent["areas"], f"{source} [absent.areas]", ("phrases",))
        absent_areas = _strings(a["phrases"], f"{source} [absent.areas].phrases")
    ins = _table(d["instructions"], f"{source} [instructions]", INSTRUCTION_KEYS)
    instructions = {
        k: _strings(v, f"{source} [instructions].{k}", _PLACEHOLDERS.get(k, ("{a}",)))
        for k, v in ins.items()
    }
    ro = MappingProxyType
    return ParaphraseBank(
        pool=pool,
        objects=ro(objects),
        colours=ro(colours),
        colour_forms=colour_forms,
        sounds=ro(sounds),
        areas=ro(areas),
        absent_objects=ro(absent_objects),
        absent_sounds=ro(absent_sounds),
        instructions=ro(instructions),
        source=source,
        absent_areas=absent_areas,
    )


def load_bank(pool: str, path: str | Path | None = None) -> ParaphraseBank:
    """The paraphrase bank of ``pool`` (one of :data:`POOLS`), from ``path`` (default
    ``tabletop/data/paraphrases/<pool>.toml``), validated.

    Raises:
        ConfigError: an unknown pool. AssetError: a malformed bank (naming the entry).
    """
    if pool not in POOLS:
        raise ConfigError(f"unknown paraphrase pool {pool!r}; valid: {list(POOLS)}")
    p = Path(path) if path is not None else BANK_DIR / f"{pool}.toml"
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"paraphrase bank {p} is unreadable: {e}") from None
    return _bank(data, str(p), pool)


# ---------------------------------------------------------------------------- wording
class ParaphraseWording(Wording):
    """Words a scene's goals from one pool of a :class:`ParaphraseBank`, seeded.

    An object is named so that the scene has one thing it can be: with its colour when another
    object of its kind is there (else now and then), never by a vague name while a kind it could
    be taken for is there. Every instruction is kept as the pool's templates word it, whether
    or not the reader understands it: the suites measure the reader, they are not filtered
    through it."""

    #: Share of names that get a colour they do not need; of colours that are a synonym; of
    #: coloured names in another word order; of queries with a leading "the".
    P_COLOUR, P_SYNONYM, P_FORM, P_ARTICLE = 0.35, 0.45, 0.3, 0.5

    def __init__(self, bank: ParaphraseBank, ground_truth: GroundTruth, seed) -> None:
        self.bank = bank
        self.gt = ground_truth
        self.rng = np.random.default_rng(seed)
        self.present_kinds = {o.kind for o in ground_truth.objects}

    # ---------------------------------------------------------------- pieces
    def _choice(self, options):
        options = list(options)
        if not options:
            raise ConfigError("nothing to choose from")  # callers make sure there is
        return options[int(self.rng.integers(len(options)))]

    def _names(self, kind: str, coloured: bool = False) -> list[str]:
        """Names of ``kind`` that name nothing else in this scene (with a colour slot when
        ``coloured``)."""
        try:
            ph = self.bank.objects[kind]
        except KeyError:
            raise ConfigError(f"{self.bank.source}: no names for kind {kind!r}") from None
        names = list(ph.names) + [
            n for n, others in ph.vague if not (others & (self.present_kinds - {kind}))
        ]
        return [n for n in names if "{c}" in n] if coloured else names

    def colour_word(self, colour: str) -> str:
        """The catalog colour or, now and then, one of the pool's other words for it."""
        syn = self.bank.colours.get(colour, ())
        return self._choice(syn) if syn and self.rng.random() < self.P_SYNONYM else colour

    def _compose(self, name: str, colour: str | None) -> str:
        if colour is None:
            return _strip_colour(name)
        c = bare_colour_word(self.colour_word(colour))
        if "{c}" in name and self.rng.random() < self.P_FORM:
            form = self._choice(self.bank.colour_forms)
            return _one_determiner(form.format(n=_strip_colour(name), c=c))
        return _one_determiner(name.replace("{c}", c))

    def _article(self, phrase: str) -> str:
        # the draw is made either way, so that a phrase with its own determiner ("a kiwi
        # fruit", "my car keys") leaves every later draw as it was
        add = self.rng.random() < self.P_ARTICLE
        own = phrase.split(" ", 1)[0].lower() in _DETERMINERS
        return f"the {phrase}" if add and not own else phrase

    def object_phrase(self, kind: str, colour: str | None, need_colour: bool) -> str:
        """A name of ``kind`` (without article), coloured ``colour`` when ``need_colour`` and
        now and then otherwise: never a kind that keeps its mesh's texture (a domino, a jenga
        block: the simulator ignores their colour, so nobody would see it) unless needed."""
        name = self._choice(self._names(kind, coloured=need_colour))
        optional = "{c}" in name and not OBJECT_KINDS[kind].keep_texture
        with_colour = need_colour or (optional and self.rng.random() < self.P_COLOUR)
        return self._compose(name, colour if with_colour else None)

    # ---------------------------------------------------------------- Wording
    def object(self, o: ObjectTruth) -> str:
        need = len(self.gt.objects_of_kind(o.kind)) > 1
        return self._article(self.object_phrase(o.kind, o.color, need))

    def kind(self, o: ObjectTruth) -> str:
        return self._article(_strip_colour(self._choice(self._names(o.kind))))

    def sound(self, event: SoundEventTruth) -> str:
        try:
            return self._choice(self.bank.sounds[event.category])
        except KeyError:
            raise ConfigError(
                f"{self.bank.source}: no phrasings for sound category {event.category!r}"
            ) from None

    def area(self, area: AreaTruth) -> str:
        key = _AREA_KEY.get(area.name) or ("tray" if area.name.endswith("tray area") else None)
        if key is None:
            raise ConfigError(f"{self.bank.source}: no phrasings for area {area.name!r}")
        return self._choice(self.bank.areas[key])

    def instruction(self, j: int, form: str, *args) -> str:
        """An instruction in the pool's words, as its templates word it: kept whether or not
        the reader understands it (the suite's truth comes from the goal it words; a refused
        instruction is a miss when the suite is evaluated)."""
        ins = self.bank.instructions
        if form == "between":
            a, b = self.object(args[0]), self.object(args[1])
            return _fill(self._choice(ins["between"]), a=a, b=b)
        if form in _SIDES:
            return _fill(self._choice(ins[form]), a=self.object(args[0]))
        verb = self._choice(ins["verbs"])
        if form == "object":
            return f"{verb} {_the(self.object(args[0]))}"
        if form == "sound":
            return f"{verb} " + self._choice(ins["sound"]).format(s=self.sound(args[0]))
        if form == "near":
            k, s = self.kind(args[0]), self.sound(args[1])
            wrapped = self._choice(ins["sound"]).format(s=s)
            return f"{verb} {_the(k)} {self._choice(ins['near'])} {wrapped}"
        raise ConfigError(f"unknown instruction form {form!r}")


#: Words that open a phrase with its own determiner: no "the" goes before them.
_DETERMINERS = frozenset("the a an my your our his her their this that these those some".split())


def bare_colour_word(word: str) -> str:
    """A colour word as it goes into a name: without its own article ("the chunky {c} mug"
    with "a bubblegum colour" is "the chunky bubblegum colour mug")."""
    return re.sub(r"^(?:a|an|the)\s+", "", word, flags=re.I)


def _the(phrase: str) -> str:
    return phrase if phrase.split(" ", 1)[0].lower() in _DETERMINERS else f"the {phrase}"


_DOUBLED = re.compile(rf"\b(?:the|a|an)\s+(?=(?:{'|'.join(sorted(_DETERMINERS))})\s)", re.I)


def _one_determiner(text: str) -> str:
    """``text`` without a determiner that stands before another ("the the colour of ..."
    where a pattern's "the" meets a colour word with its own)."""
    return _DOUBLED.sub("", text)


def _fill(template: str, **things: str) -> str:
    """``template`` with each thing's placeholder filled by the thing's name, with "the" before
    it unless the template or the name has a determiner there ("next to the {a}")."""
    out = {}
    for key, name in things.items():
        ahead = re.search(rf"(\w+)\s+\{{{key}\}}", template)
        own = ahead is not None and ahead.group(1).lower() in _DETERMINERS
        out[key] = name if own else _the(name)
    return template.format(**out)


# ---------------------------------------------------------------------------- absent goals
def absent_goals(
    wording: ParaphraseWording, counts: Mapping[str, int] = ABSENT_COUNTS
) -> list[dict]:
    """Goals (task-file dicts, type ``absent``) for things the scene and its scan do not have,
    worded from ``wording``'s pool: ``counts`` per group, at least :data:`MIN_ABSENT` in all."""
    from tabletop.eval.tasks import Landmark
    from tabletop.eval.truth import check_absent
    from tabletop.sim.sound_bank import SoundBank

    w, bank, gt, rng = wording, wording.bank, wording.gt, wording.rng
    present = w.present_kinds
    played = {e.category for e in gt.sound_events}
    near_played = played | {c for f in SOUND_FAMILIES if f & played for c in f}
    groups: dict[str, list] = {}
    groups["object"] = [
        (f"absent-object-{i}", "obj", p)
        for i, (p, kinds) in enumerate(bank.absent_objects.items())
        if not kinds & present
    ]
    groups["kind"] = [
        (f"absent-kind-{k}", "obj", k)
        for k in sorted(OBJECT_KINDS)
        if k not in present and not CONFUSABLE_KINDS.get(k, frozenset()) & present
    ]
    colour_pairs = []
    for k in sorted(present):
        if OBJECT_KINDS[k].keep_texture:
            continue  # a textured kind looks its texture, whatever its colour name
        # colours of this kind and of kinds it could be taken for ("a white ball": the
        # soccer ball), and colours near those
        kin = {k} | (CONFUSABLE_KINDS.get(k, frozenset()) & present)
        have = {o.color for x in sorted(kin) for o in gt.objects_of_kind(x)}
        avoid = have | {c for h in have for c in _NEAR_COLOURS.get(h, ())}
        colour_pairs += [(k, c) for c in sorted(COLORS) if c not in avoid]
    groups["colour"] = [(f"absent-colour-{c}-{k}", "obj", (k, c)) for k, c in colour_pairs]
    bank_cats = sorted(SoundBank.default().categories)
    groups["sound"] = [
        (f"absent-sound-{c}", "sound", c)
        for c in bank_cats
        if c not in near_played and c in bank.sounds
    ]
    groups["sound_other"] = [
        (f"absent-sound-other-{i}", "sound", p)
        for i, (p, cats) in enumerate(bank.absent_sounds.items())
        if not cats & near_played
    ]
    groups["area"] = [(f"absent-area-{i}", "area", p) for i, p in enumerate(bank.absent_areas)]
    chosen: list[tuple] = []
    spare: list[tuple] = []
    for g, n in counts.items():
        cands = groups[g]
        order = [cands[i] for i in rng.permutation(len(cands))]
        chosen += order[:n]
        spare += order[n:]
    spare = [spare[i] for i in rng.permutation(len(spare))]
    while len(chosen) < MIN_ABSENT and spare:
        chosen.append(spare.pop())
    if len(chosen) < MIN_ABSENT:
        raise ConfigError(
            f"only {len(chosen)} absent goals for this scene; the bank needs more absent names"
        )
    goals = []
    for gid, modality, what in chosen:
        if gid.startswith("absent-kind-"):
            text = w._article(w.object_phrase(what, None, need_colour=False))
        elif gid.startswith("absent-colour-"):
            text = w._article(w.object_phrase(what[0], what[1], need_colour=True))
        elif gid.startswith("absent-sound-") and not gid.startswith("absent-sound-other-"):
            text = w._choice(bank.sounds[what])
        elif modality == "obj":
            text = w._article(what)
        else:  # a sound outside the bank, a place off the table: as the pool words it
            text = what
        goal = {
            "id": gid,
            "type": "absent",
            "text": text,
            "query": {modality: text},
            "truth": {"absent": True},
        }
        check_absent(Landmark(((modality, text),), modality), gt, f"absent goal {gid!r}")
        goals.append(goal)
    return goals


# ---------------------------------------------------------------------------- suites
def suite_sections(pool: str) -> list[tuple[str, dict, dict]]:
    """(file stem, [scene], [scan]) of the pool's suites: generated scenes of
    :data:`POOL_SEEDS`, scanned like the shipped random suites (the scan
    seed is the scene seed)."""
    if pool not in POOLS:
        raise ConfigError(f"unknown paraphrase pool {pool!r}; valid: {list(POOLS)}")
    return [
        (
            f"scene-random-{s}",
            {"random": {"seed": s, "count": 9, "duplicates": 2}},
            {"seed": s, **_SCAN},
        )
        for s in POOL_SEEDS[pool]
    ]


def paraphrase_suite(
    pool: str,
    stem: str,
    scene: dict,
    scan: dict,
    ground_truth: GroundTruth,
    seed: int,
    bank: ParaphraseBank | None = None,
    counts: Mapping[str, int] | None = None,
) -> dict:
    """A paraphrased task document for one scene: the goals :func:`generate_suite` draws with
    ``seed`` (the shipped suites' counts, or ``counts``), worded from ``pool``'s bank, plus
    :func:`absent_goals`. Validated before it is returned."""
    bank = bank if bank is not None else load_bank(pool)
    wording = ParaphraseWording(bank, ground_truth, [seed, 1])
    doc = generate_suite(
        f"paraphrase-{pool}-{stem}",
        scene,
        scan,
        ground_truth,
        dict(counts or _FULL),
        seed=seed,
        description=(
            f"paraphrase suite ({pool} pool): every goal type worded the way people ask, and "
            "goals for things that are not there, on a scene no other experiment uses"
        ),
        wording=wording,
        generator={"seed": seed, "module": "tabletop.eval.paraphrase", "pool": pool},
    )
    doc["goals"] += absent_goals(wording)
    parse_tasks(json.loads(json.dumps(doc)), source=doc["name"])
    return doc


def _header(pool: str) -> str:
    made = (
        "Generated by `python -m\ntabletop.eval.paraphrase` from the scene's ground truth, "
        f"the seeded scan below and\ntabletop/data/paraphrases/{pool}.toml."
    )
    if pool in HELDOUT_POOLS:
        return (
            "Paraphrase suite, HELD-OUT pool: DO NOT READ OR TUNE ON THIS FILE; evaluate it at "
            f"the\nend (`tabletop eval {SUITE_DIRS[pool]}`). {made}"
        )
    name = "" if pool == "tune" else f" ({pool})"
    return f"Paraphrase suite, TUNE pool{name}: tune on these. {made}"


def write_paraphrase_suites(
    out_dir, pools=POOLS, cache_dir="out/eval-cache", only=None
) -> list[Path]:
    """Write ``<out_dir>/paraphrase-tune/*.toml`` and ``<out_dir>/paraphrase-heldout/*.toml``
    (the pools given; ``only``: file stems). Scans each scene once through the cache."""
    from tabletop.eval.suites import _scan_ground_truth

    written = []
    for pool in pools:
        bank = load_bank(pool)
        d = Path(out_dir) / SUITE_DIRS[pool]
        d.mkdir(parents=True, exist_ok=True)
        for stem, scene, scan in suite_sections(pool):
            if only and stem not in only:
                continue
            gt = _scan_ground_truth(scene, scan, cache_dir)
            doc = paraphrase_suite(pool, stem, scene, scan, gt, seed=scan["seed"], bank=bank)
            p = d / f"{stem}.toml"
            p.write_text(to_toml(doc, _header(pool)))
            written.append(p)
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--out",
        default="out/tasks",
        help="tasks directory (default: out/tasks); the shipped suites: tabletop/data/tasks",
    )
    ap.add_argument("--pool", choices=POOLS, action="append", help="pools (default: all)")
    ap.add_argument("--cache-dir", default="out/eval-cache")
    ap.add_argument("--only", nargs="*", help="file stems to write (default: all)")
    args = ap.parse_args(argv)
    pools = tuple(args.pool) if args.pool else POOLS
    for p in write_paraphrase_suites(Path(args.out), pools, args.cache_dir, args.only):
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

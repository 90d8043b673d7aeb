"""Labelled place phrases for the learned place reader (``tabletop train places``).

Every phrase comes from a paraphrase pool's own entries, written by people who named the
table's regions in their own words (``[areas]``), with the pool's other phrasings as places
that are no region of the table: a place named after a thing (``[areas].tray``), places that
are not on a table top (``[absent.areas]``), and things, present or absent, asked as a place
(``[objects.*]`` names without their colour, ``[absent.objects]``). Held-out pools
(:data:`~tabletop.eval.paraphrase.HELDOUT_POOLS`) are never read here: the caller passes the
tune pools.

A region named on something else is no region of this table either: each region phrase of the
table ("the left side of the table", "the table's far end") gives one "other" phrase with the
table replaced by one of the pool's places off the table or things it lacks ("the left side of
the garden shed"), so that words of direction alone do not make a region.

An author who slipped on the project's front / back convention (front is the half away from
the robot) wrote entries that the grammar reads as the opposite depth ("the near side" under
``front``); those entries are dropped, not relabelled.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass

from tabletop.errors import AssetError, ConfigError
from tabletop.eval.paraphrase import HELDOUT_POOLS, load_bank
from tabletop.paths import DATA_DIR
from tabletop.reader.places import PLACE_CLASSES

__all__ = ["GROUNDS_FILE", "PlaceText", "ground_texts", "place_texts"]
#: Object names per kind taken from a pool as "other" (the first ones: the plainest names).
NAMES_PER_KIND = 3


@dataclass(frozen=True)
class PlaceText:
    text: str
    label: str
    pool: str
    source: str  # "areas.<key>", "absent.areas", "objects.<kind>", "absent.objects", "elsewhere"


#: How a pool's region phrases name the table, and how the same phrase names something else.
_ON_TABLE = (
    (re.compile(r"\bof (?:the )?(?:table ?top|table)\b"), "of {}"),
    (re.compile(r"\bthe (?:table ?top|table)'s\b"), "{}'s"),
)


def _elsewhere(phrase: str, place: str) -> str | None:
    """``phrase`` with its table replaced by ``place`` ("the garden shed"), or None when the
    phrase does not name the table in either form."""
    for rx, form in _ON_TABLE:
        if rx.search(phrase):
            return rx.sub(form.format(place), phrase, count=1)
    return None


def _grammar_depth(text: str) -> str | None:
    from tabletop.reader.place_words import parse_region

    r = parse_region(text)
    if r is None or r.lateral is not None:
        return None
    return {"far": "front", "near": "back"}.get(r.depth)


def place_texts(pools) -> list[PlaceText]:
    """The labelled phrases of ``pools`` (tune pools only), in pool order."""
    held = sorted(set(pools) & set(HELDOUT_POOLS))
    if held:
        raise ConfigError(f"held-out pools {held} are never trained on")
    out: list[PlaceText] = []
    for pool in pools:
        bank = load_bank(pool)
        for key, phrases in bank.areas.items():
            label = "other" if key == "tray" else key
            if label not in PLACE_CLASSES:
                raise ConfigError(f"pool {pool!r}: area key {key!r} is no place class")
            for p in phrases:
                depth = _grammar_depth(p)
                if label in ("front", "back") and depth is not None and depth != label:
                    continue  # the author's convention slip
                out.append(PlaceText(p, label, pool, f"areas.{key}"))
        out += [PlaceText(p, "other", pool, "absent.areas") for p in bank.absent_areas]
        elsewhere = [*bank.absent_areas, *(f"the {n}" for n in bank.absent_objects)]
        regions = [t for t in out if t.pool == pool and t.label != "other"]
        for i, t in enumerate(regions):
            moved = _elsewhere(t.text, elsewhere[i % len(elsewhere)]) if elsewhere else None
            if moved is not None and moved != t.text:
                out.append(PlaceText(moved, "other", pool, "elsewhere"))
        for kind, ph in bank.objects.items():
            for name in ph.names[:NAMES_PER_KIND]:
                n = " ".join(name.replace("{c}", " ").split())
                n = n if n.lower().startswith(("the ", "a ", "an ")) else f"the {n}"
                out.append(PlaceText(n, "other", pool, f"objects.{kind}"))
        out += [PlaceText(f"the {n}", "other", pool, "absent.objects") for n in bank.absent_objects]
    return out


#: Surfaces, and grounds that are not the arm's surface, written for the ground classifier.
GROUNDS_FILE = DATA_DIR / "reader" / "place_grounds.toml"


def _bare(phrase: str) -> str:
    """``phrase`` without a leading article or possessive ("the fridge" -> "fridge")."""
    return re.sub(r"^(?:the|a|an|my|our|your)\s+", "", " ".join(phrase.lower().split()))


def ground_texts(pools) -> list[PlaceText]:
    """What a region may be named on, labelled "surface" (the arm's work surface) or
    "elsewhere": the surfaces and other grounds of :data:`GROUNDS_FILE`, the catalog's other
    objects (``other_objects.toml``), and the tune ``pools``' names of things and places off
    the table. Each text is a noun phrase with "the" ("the workbench"); duplicates are kept
    once, a surface winning over nothing (the file's lists must not share an entry)."""
    held = sorted(set(pools) & set(HELDOUT_POOLS))
    if held:
        raise ConfigError(f"held-out pools {held} are never trained on")
    from tabletop.mapping.object_module import load_other_objects

    try:
        doc = tomllib.loads(GROUNDS_FILE.read_text(encoding="utf-8"))
        surfaces, elsewhere = list(doc["surfaces"]), list(doc["elsewhere"])
    except (OSError, KeyError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"cannot read the place grounds {str(GROUNDS_FILE)!r}: {e}") from None
    things = load_other_objects()
    both = sorted({_bare(s) for s in surfaces} & {_bare(e) for e in elsewhere})
    if both:
        raise AssetError(f"{str(GROUNDS_FILE)!r}: grounds listed as surface and elsewhere: {both}")
    rows = [("surface", _bare(s), "surfaces") for s in surfaces]
    rows += [("elsewhere", _bare(e), "elsewhere") for e in elsewhere]
    rows += [("elsewhere", _bare(t), "other_objects") for t in things]
    for pool in pools:
        bank = load_bank(pool)
        rows += [("elsewhere", _bare(a), f"{pool}:absent.areas") for a in bank.absent_areas]
        rows += [("elsewhere", _bare(o), f"{pool}:absent.objects") for o in bank.absent_objects]
        for kind, ph in bank.objects.items():
            for name in ph.names[:NAMES_PER_KIND]:
                rows.append(("elsewhere", _bare(name.replace("{c}", " ")), f"{pool}:{kind}"))
    out: dict[str, PlaceText] = {}
    for label, text, source in rows:
        if text and text not in out:
            out[text] = PlaceText(f"the {text}", label, source.split(":")[0], source)
    return list(out.values())

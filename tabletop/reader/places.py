"""Places: the words of an area query read into an :class:`~tabletop.mapping.table_regions.
AreaRef` that the map scores.

Four readings, in this order:

1. the grammar of :mod:`tabletop.reader.place_words`: a region of the table's own geometry
   named in words it lists ("the far right corner", "the robot's left");
2. with ``learned=True``, a region the grammar names on something it does not take for the
   table ("the far end of the workbench", :func:`~tabletop.reader.place_words.region_on_ground`)
   is that region when the ground classifier, a logistic regression on the ground's MiniLM
   embedding fitted on surfaces, places and things (``tabletop/data/reader/place_grounds.toml``
   and the tune pools), takes the ground for the surface the arm works on, at its
   ``threshold``;
3. a learned classifier (``learned=True``): the phrase's MiniLM sentence embedding, one
   linear layer and a softmax over the regions that people name (left, right, front: the half
   away from the robot, back: the half by it, the centre) and "other" (no region of the
   table). It was fitted by ``tabletop train places`` on the tune pools' own area phrasings and
   on their names of things and of places off the table (:mod:`tabletop.eval.place_texts`), so
   it reads region wording that no list holds; a region is taken only at a probability of at
   least its ``threshold``, chosen on pools left out of its fit;
4. otherwise the place's subject: what a place named after its contents is named after ("the
   area around the tray" -> "tray"), which the map looks for as a thing or a sound; a phrase of
   place words only names nothing.
"""

from __future__ import annotations

import functools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.table_regions import AreaRef, TableRegion
from tabletop.paths import DATA_DIR
from tabletop.reader.place_words import (
    area_subject,
    directions,
    ground_phrases,
    ground_preposition,
    opposite_directions,
    parse_region,
    region_on_ground,
)
from tabletop.reader.rules import refuse_relation_as_area
from tabletop.reader.spelling import kind_words

__all__ = [
    "DEFAULT_PLACE_WEIGHTS",
    "PLACE_CLASSES",
    "PLACE_FORMAT",
    "REGION_OF_CLASS",
    "GroundClassifier",
    "PlaceClassifier",
    "PlaceReader",
    "beneath_surface",
    "load_place_classifier",
    "text_encoder",
]

DEFAULT_PLACE_WEIGHTS = DATA_DIR / "weights" / "place_reader.json"
PLACE_FORMAT = "tabletop-place-reader"
#: The classifier's classes: the five regions people name, and "other" (no region of the
#: table: a thing, a place elsewhere, or words for a place only).
PLACE_CLASSES = ("left", "right", "front", "back", "center", "other")
#: A class of the classifier -> the region it names: (lateral, depth).
REGION_OF_CLASS = {
    "left": ("left", None),
    "right": ("right", None),
    "front": (None, "far"),
    "back": (None, "near"),
    "center": ("middle", "middle"),
}


@dataclass(frozen=True)
class GroundClassifier:
    """P(the ground names the arm's work surface) = sigmoid(embedding @ w + b); taken at
    ``threshold``, chosen on folds left out of the fit."""

    w: np.ndarray  # (dim,)
    b: float
    threshold: float
    meta: dict = field(default_factory=dict)

    def probability(self, embeddings: np.ndarray) -> np.ndarray:
        z = np.asarray(embeddings, np.float64) @ self.w + self.b
        return 1.0 / (1.0 + np.exp(-z))

    def to_json(self) -> dict:
        return {
            "w": np.round(self.w, 6).tolist(),
            "b": round(float(self.b), 6),
            "threshold": self.threshold,
            "meta": self.meta,
        }


@dataclass(frozen=True)
class PlaceClassifier:
    """Softmax over ``classes`` of ``embedding @ W + b``; ``space``: the text encoder."""

    classes: tuple[str, ...]
    W: np.ndarray  # (dim, classes)
    b: np.ndarray  # (classes,)
    threshold: float
    space: str
    meta: dict = field(default_factory=dict)
    #: whether a region's ground names the work surface (None: a classifier fitted without one)
    ground: GroundClassifier | None = None

    def __post_init__(self) -> None:
        unknown = [c for c in self.classes if c != "other" and c not in REGION_OF_CLASS]
        if unknown or "other" not in self.classes:
            raise AssetError(
                f"place classifier classes {list(self.classes)}: each must be one of "
                f"{[*REGION_OF_CLASS, 'other']}, with 'other' among them"
            )
        if self.W.shape != (self.W.shape[0], len(self.classes)) or self.b.shape != (
            len(self.classes),
        ):
            raise AssetError(
                f"place classifier shapes W {self.W.shape}, b {self.b.shape} do not match "
                f"{len(self.classes)} classes"
            )

    def probabilities(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, classes) probabilities of (N, dim) unit text embeddings."""
        z = np.asarray(embeddings, np.float64) @ self.W + self.b
        z -= z.max(axis=1, keepdims=True)
        p = np.exp(z)
        return p / p.sum(axis=1, keepdims=True)

    def to_json(self) -> dict:
        return {
            "format": PLACE_FORMAT,
            "classes": list(self.classes),
            "space": self.space,
            "threshold": self.threshold,
            "W": np.round(self.W, 6).tolist(),
            "b": np.round(self.b, 6).tolist(),
            "meta": self.meta,
            **({"ground": self.ground.to_json()} if self.ground is not None else {}),
        }


def _text_encoder(space: str):
    from tabletop.mapping.encoders.minilm import MINILM_SPACE

    if space != MINILM_SPACE:
        raise AssetError(
            f"the place classifier was fitted in the text space {space!r}; this reader embeds "
            f"with {MINILM_SPACE!r}: refit it with `tabletop train places`"
        )
    return text_encoder()


@functools.cache
def text_encoder():
    """The place reader's text encoder (MiniLM; one per process, its embeddings cached)."""
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    return MiniLMTextEncoder()


@functools.cache
def load_place_classifier(path: str | Path = DEFAULT_PLACE_WEIGHTS) -> PlaceClassifier:
    """The classifier ``tabletop train places`` wrote to ``path`` (cached per path)."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except OSError as e:
        raise AssetError(
            f"cannot read the place classifier {str(path)!r} ({e.strerror}); write one with "
            f"`tabletop train places`"
        ) from None
    except ValueError as e:
        raise AssetError(f"{str(path)!r} is not a place classifier (not JSON: {e})") from None
    if not isinstance(d, dict) or d.get("format") != PLACE_FORMAT:
        raise AssetError(f"{str(path)!r} is not a place classifier (format {PLACE_FORMAT!r})")
    try:
        g = d.get("ground")
        ground = None
        if g is not None:
            ground = GroundClassifier(
                np.asarray(g["w"], np.float64),
                float(g["b"]),
                float(g["threshold"]),
                dict(g.get("meta", {})),
            )
            if ground.w.shape != (np.asarray(d["W"]).shape[0],):
                raise ValueError(f"ground weights of shape {ground.w.shape}")
        return PlaceClassifier(
            tuple(d["classes"]),
            np.asarray(d["W"], np.float64),
            np.asarray(d["b"], np.float64),
            float(d["threshold"]),
            str(d["space"]),
            dict(d.get("meta", {})),
            ground,
        )
    except (KeyError, TypeError, ValueError) as e:
        raise AssetError(f"{str(path)!r}: a malformed place classifier ({e!r})") from None


#: Words that put a place beneath something.
_BENEATH = re.compile(r"\b(?:under(?:neath)?|beneath|below)\b", re.IGNORECASE)
#: The surfaces of a table-top map's background (``object_module.BACKGROUND``): a place
#: beneath one of them is off the table's top.
SURFACES = ("table", "floor")


def _beneath_surface(words: str) -> str:
    """The surface (of :data:`SURFACES`) that ``words`` (what follows "under") name first,
    "" when they name none ("the tray")."""
    for w in re.findall(r"[a-z]+", words.lower()):
        for s in SURFACES:
            if w == s or (w.startswith(s) and w[len(s) :] in ("s", "top", "tops")):
                return s
    return ""


#: "off the table": a place that is not on the table's top.
_OFF_TABLE = re.compile(r"\boff\s+(?:of\s+)?(?:the\s+|this\s+|that\s+)?(table(?:\s*top)?)\b", re.I)


def beneath_surface(text: str) -> tuple[str, str] | None:
    """("under", "table") where ``text`` asks for a place beneath one of :data:`SURFACES`
    ("go under the table") or off the table ("off the table to the left": ("off",
    "table")), None otherwise ("under the tray" is where the tray stands; "the bit off to your
    left" is on the table)."""
    if (m := _BENEATH.search(text)) and (below := _beneath_surface(text[m.end() :])):
        return m.group(0), below
    if m := _OFF_TABLE.search(text):
        return "off", m.group(1)
    return None


class PlaceReader:
    """Reads an area query's words (see the module docstring); ``learned``: with the
    classifier after the grammar."""

    def __init__(self, learned: bool = True, weights: str | Path | None = None) -> None:
        self.learned = bool(learned)
        self.weights = Path(weights) if weights is not None else DEFAULT_PLACE_WEIGHTS

    def classifier(self) -> PlaceClassifier:
        return load_place_classifier(self.weights)

    def read(self, text: str) -> AreaRef:
        """``text`` read into an :class:`AreaRef` (the readings of the module docstring, in
        order); words that name no region and say a relation to things are refused
        (:func:`~tabletop.reader.rules.refuse_relation_as_area`)."""
        return refuse_relation_as_area(self._reading(text))

    def _reading(self, text: str) -> AreaRef:
        if not isinstance(text, str):
            raise ConfigError(f"an area must be a string, got {type(text).__name__}")
        if (under := beneath_surface(text)) is not None:
            # the map holds the table's top and what stands on it: a place beneath the table
            # or the floor is none of it (beneath a tray is where the tray stands: read on)
            off = "a place off it" if under[0] == "off" else "a place beneath the top is off it"
            return AreaRef(text, how=f"{under[0]!r} the {under[1]}: {off}; the table's top "
                           "is all this map holds")  # fmt: skip
        region = parse_region(text)
        if region is not None:
            return AreaRef(text, region=region, how="grammar")
        if clash := opposite_directions(text):
            # no classifier's guess picks one of the two: the words contradict each other
            return AreaRef(text, how=f"{clash[0]!r} and {clash[1]!r} are opposite directions, "
                           "and a region lies in one: name one of them")  # fmt: skip
        if not directions(text) and area_subject(text) is None:
            # place words alone ("the area over there") name no one place: no classifier asked
            return AreaRef(text, how="place words only")
        if self.learned and text.strip():
            clf = self.classifier()
            if (off := self._elsewhere(clf, text)) is not None:
                return off
            on = region_on_ground(text)
            if on is not None and clf.ground is not None:
                region, ground = on
                g = clf.ground
                x = _text_encoder(clf.space).encode_text([f"the {ground}"])
                pg = float(g.probability(x)[0])
                if pg >= g.threshold:
                    how = f"grammar, on {ground!r}: the work surface at {pg:.2f}"
                    return AreaRef(text, region=region, how=how)
            p = clf.probabilities(_text_encoder(clf.space).encode_text([text]))[0]
            k = int(np.argmax(p))
            name = clf.classes[k]
            if name != "other" and p[k] >= clf.threshold:
                lateral, depth = REGION_OF_CLASS[name]
                how = f"learned: {name} at {p[k]:.2f}"
                return AreaRef(text, region=TableRegion(lateral, depth, text), how=how)
        subject = area_subject(text)
        return AreaRef(text, subject=subject, how="subject" if subject else "place words only")

    @staticmethod
    def _elsewhere(clf: PlaceClassifier, text: str) -> AreaRef | None:
        """A region named on grounds the ground classifier takes, each, for somewhere other
        than the work surface ("the far corner of the room": P(surface) below one minus its
        threshold) is off this map: an :class:`AreaRef` with no region and the reason. None
        where ``text`` does not start with a region followed by what it is named on ("the far
        corner | of the room"; not "the spot near the sound of a hen"), where one ground may be
        the surface, or where one names a kind of thing the map knows."""
        g = clf.ground
        at = ground_preposition(text)
        if g is None or at is None or parse_region(text[: at.start()]) is None:
            return None  # no region said right before what it is named on
        grounds = ground_phrases(text)
        if not grounds:
            return None
        if any(w in kind_words() for gr in grounds for w in gr.split()):
            return None  # "the left side of the mug": a side of a thing, looked up as one
        p = g.probability(_text_encoder(clf.space).encode_text([f"the {w}" for w in grounds]))
        if float(p.max()) >= 1.0 - g.threshold:
            return None
        return AreaRef(text, how=f"{grounds[0]!r} is not the table the robot works on (the work "
                       f"surface at {float(p.max()):.2f}), and the table's top is all this map "
                       "holds")  # fmt: skip

"""Sounds the bank never had: AudioSet's 521 class names as a text-side vocabulary.

An audio encoder with an AudioSet classifier behind it (the YAMNet backbone of the default
encoder) gives each heard segment 521 class logits beside its embedding. A sound query that
names a class far better than any sound the bank taught ("a doorbell", "a kettle whistling",
"a siren") is read against the class names by MiniLM text similarity and scored on each
segment through those logits:

1. **Words -> classes.** The query's MiniLM embedding is compared with every class name (as
   "the sound of <name>" and as the bare name; the better counts). The classes within
   ``text_margin`` of the best are asked for. A query below ``text_min`` to every name names
   no AudioSet class.
2. **Segments -> classes.** A segment's log-odds for the query are the asked classes' logit
   (their log-sum-exp) minus the segment's ``rank``-th strongest *other* explanation (the
   ``rank``-th largest logit among the classes not asked that name a source), minus
   ``offset``: relative to what else the segment sounds like, never one absolute score.
   AudioSet's labels nest ("Music", "Musical instrument", "Tabla"; "Explosion" beside
   "Gunshot, gunfire"), so the asked class need not be the single strongest, only near the
   strongest few. A sound that did not play sits far below them, and the map's calibrated
   operating point refuses it like any absent sound. ``rank = 3`` and ``offset = 1`` were
   chosen on the bank's training clips, each queried by its caption through the class names
   (found where it played 0.45, refused where it did not 0.95, in seeded maps of six;
   plain softmax mass over all 521 classes: 0.18 and 0.985), never on out-of-bank recordings.

Names that say only "some sound" ("Sound effect", "Noise", "Silence", ...) are never asked
for: a query read as one of them names nothing the map can find.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from tabletop.errors import ConfigError

__all__ = ["GENERIC_CLASSES", "OpenSoundQuery", "OpenSoundVocabulary"]

#: AudioSet names that describe no source: never asked for.
GENERIC_CLASSES = frozenset(
    (
        "Silence",
        "Sound effect",
        "Noise",
        "Environmental noise",
        "Static",
        "Inside, small room",
        "Inside, large room or hall",
        "Inside, public space",
        "Outside, urban or manmade",
        "Outside, rural or natural",
        "Reverberation",
        "Echo",
        "Cacophony",
        "Field recording",
        "White noise",
        "Pink noise",
        "Hubbub, speech noise, speech babble",
        "Mains hum",
        "Distortion",
        "Sidetone",
        "Hum",
        "Buzz",
        "Throbbing",
        "Vibration",
        "Whoosh, swoosh, swish",
    )
)


@dataclass(frozen=True)
class OpenSoundQuery:
    """How a query reads against the AudioSet class names, scored on segments."""

    query: str
    classes: tuple[str, ...]
    """The classes the query asks for (empty: no name is near enough)."""
    text_score: float
    """The query's best cosine with a class name."""
    nearest: str
    """That class."""
    scores: np.ndarray = field(repr=False)
    """(n_segments,) in [0, 1]: ``sigmoid(log_odds)``."""
    log_odds: np.ndarray = field(repr=False)
    """(n_segments,) float64: the asked classes' logit over the segment's ``rank``-th
    strongest other explanation, less ``offset`` (module docstring)."""

    @property
    def known(self) -> bool:
        return bool(self.classes)


class OpenSoundVocabulary:
    """AudioSet class ``names`` (in logit order) read by ``text`` (a MiniLM text encoder).

    ``text_min``: a query's best cosine below this names no class; ``text_margin``: classes
    within this of the best are asked for too; ``rank`` and ``offset``: the segment score of
    the module docstring.
    """

    def __init__(
        self,
        names: tuple[str, ...],
        text,
        text_min: float = 0.5,
        text_margin: float = 0.05,
        rank: int = 3,
        offset: float = 1.0,
    ) -> None:
        if not names:
            raise ConfigError("an open sound vocabulary needs class names")
        if isinstance(rank, bool) or int(rank) != rank or not 1 <= rank < len(names):
            raise ConfigError(f"rank must be an integer in 1..{len(names) - 1}, got {rank!r}")
        self.rank = int(rank)
        self.offset = float(offset)
        self.names = tuple(str(n) for n in names)
        self.text = text
        self.text_min = float(text_min)
        self.text_margin = float(text_margin)
        self._usable = np.array([n not in GENERIC_CLASSES for n in self.names])
        self._emb: np.ndarray | None = None

    def embeddings(self) -> np.ndarray:
        """(2, K, dim) float32: each name embedded as "the sound of <name>" and bare."""
        if self._emb is None:
            self._emb = _name_embeddings(self.names, self.text)
        return self._emb

    def class_scores(self, query_embedding: np.ndarray) -> np.ndarray:
        """(K,) float32: the query's best cosine with each name (-inf for generic names)."""
        s = (self.embeddings() @ np.asarray(query_embedding, np.float32)).max(axis=0)
        return np.where(self._usable, s, -np.inf).astype(np.float32)

    def match(
        self, query: str, class_logits: np.ndarray, query_embedding: np.ndarray | None = None
    ) -> OpenSoundQuery:
        """``query`` against segments with these AudioSet logits (N, K)."""
        logits = np.asarray(class_logits, np.float64).reshape(-1, len(self.names))
        if query_embedding is None:
            query_embedding = self.text.encode_text([query])[0]
        per = self.class_scores(query_embedding)
        best = int(np.argmax(per))
        n = len(logits)
        if per[best] < self.text_min:
            return OpenSoundQuery(
                query, (), float(per[best]), self.names[best], np.zeros(n), np.full(n, -np.inf)
            )
        want = per >= per[best] - self.text_margin
        others = np.where(want | ~self._usable, -np.inf, logits)  # (N, K) competitors
        kth = -np.partition(-others, self.rank - 1, axis=1)[:, self.rank - 1] if n else 0.0
        lo = logsumexp(logits[:, want], axis=1) - kth - self.offset if n else np.zeros(0)
        classes = tuple(self.names[i] for i in np.flatnonzero(want))
        scores = 1.0 / (1.0 + np.exp(-lo))
        return OpenSoundQuery(query, classes, float(per[best]), self.names[best], scores, lo)


@functools.lru_cache(maxsize=4)
def _name_embeddings(names: tuple[str, ...], text) -> np.ndarray:
    """(2, K, dim) float32 (see :meth:`OpenSoundVocabulary.embeddings`), once per text
    encoder: every map's matcher shares them."""
    plain = [n.lower() for n in names]
    e = np.asarray(text.encode_text([f"the sound of {n}" for n in plain] + plain), np.float32)
    e = e.reshape(2, len(names), -1)
    e.setflags(write=False)
    return e

"""Sounds the bank never had: AudioSet's 521 class names as a text-side vocabulary.

An audio encoder with an AudioSet classifier behind it (the YAMNet backbone of the default
encoder) gives each heard segment 521 class logits beside its embedding. A sound query that
names a class far better than any sound the bank taught ("a doorbell", "a kettle whistling",
"a siren") is read against the class names by MiniLM text similarity and scored on each
segment through those logits:

1. **Words -> classes.** The query's MiniLM embedding is compared with every class name (its
   variants below, as "the sound of <variant>" and bare; the best counts). The classes within
   ``text_margin`` of the best are asked for. A query below ``text_min`` to every name names
   no AudioSet class.
2. **Segments -> classes.** A segment's log-odds for the query come from its logits ``z``
   for the asked classes (:class:`OpenScorer`): how far the asked class rises above its own
   level on sounds it does not name (YAMNet's classes sit at very different levels: "Music"
   high everywhere, "Cash register" low), and how it stands against the segment's third
   strongest other source-naming class (AudioSet's labels nest: "Music", "Musical
   instrument", "Tabla"; "Explosion" beside "Gunshot, gunfire"). The two are weighed by a
   logistic fit on the bank's training clips, each category asked for by its caption as if
   the bank lacked it, and its bias lowered until 0.97 of the sounds not played there are
   refused at the map's operating point (:func:`~tabletop.train.audio_open.fit_open_scorer`,
   run by ``tabletop train audio``; ``tabletop/data/weights/audio_open_scorer.json``).
   Without a fitted scorer (class names other than YAMNet's) the score is the rank rule:
   the asked logit over the third strongest other class, less ``offset``.

A class name is read by its variants (:func:`name_variants`: "Burst, pop" as "burst" and
"pop" too; "Coin (dropping)" as "coin dropping"), each as "the sound of <variant>" and bare.

Names that say only "some sound" ("Sound effect", "Noise", "Silence", ...) are never asked
for: a query read as one of them names nothing the map can find.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

from tabletop.atomic import atomic_path
from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR

__all__ = [
    "DEFAULT_OPEN_SCORER",
    "GENERIC_CLASSES",
    "OpenScorer",
    "OpenSoundQuery",
    "OpenSoundVocabulary",
    "load_open_scorer",
    "name_variants",
    "save_open_scorer",
]

#: The shipped segment scorer of YAMNet's class names (``tabletop train audio`` writes it).
DEFAULT_OPEN_SCORER = DATA_DIR / "weights" / "audio_open_scorer.json"
OPEN_SCORER_FORMAT = "tabletop-open-sound-scorer"

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


def name_variants(name: str) -> tuple[str, ...]:
    """The ways an AudioSet display name is read (lower case, without repeats): the name,
    the name without its brackets ("coin dropping" for "Coin (dropping)") and each of its
    comma-separated synonyms ("burst" and "pop" for "Burst, pop"; "etc." is none)."""
    out = [name, re.sub(r"[()]", "", name).strip()]
    parts = [p.strip() for p in re.sub(r"\(.*?\)", "", name).split(",")]
    if len(parts) > 1:
        out += [p for p in parts if p and p.lower() != "etc."]
    return tuple(dict.fromkeys(" ".join(v.lower().split()) for v in out if v.strip()))


def _names_digest(names: tuple[str, ...]) -> str:
    return hashlib.sha256("\n".join(names).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class OpenScorer:
    """A segment's log-odds that it holds the asked classes, from its class logits.

    Two features of a segment's logits ``z`` (K,) for the asked classes ``A``:

    - ``rel``: ``logsumexp(z[A])`` over the segment's ``rank``-th strongest other
      source-naming class (how the asked classes stand against what else it sounds like);
    - ``abs``: ``max over a in A of z[a] - null[a]``, where ``null`` (K,) is each class's
      ``null_quantile`` logit over segments of sounds that are not that class (the bank's
      training clips as a scan cuts them, and the scans' background noise): how far the class
      rises above where it sits on other sounds. YAMNet's classes sit at very different
      levels on sounds they do not name ("Music" high, "Cash register" low), so one absolute
      level for every class cannot tell.

    ``log_odds = w_rel * rel + w_abs * abs + bias``; fitted by :func:`~tabletop.train.audio_open.
    fit_open_scorer` on the bank's training clips, each category asked for by its caption
    through the class names (never on the out-of-bank set or the held-out clips).
    """

    null: np.ndarray
    """(K,) float32: each class's reference logit."""
    w_rel: float
    w_abs: float
    bias: float
    rank: int
    names_digest: str
    """Which class names (in order) ``null`` is of."""
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        null = np.asarray(self.null, np.float32).reshape(-1)
        if not len(null) or not np.all(np.isfinite(null)):
            raise AssetError("open sound scorer: null must be finite values, one per class")
        null.setflags(write=False)
        object.__setattr__(self, "null", null)
        if int(self.rank) < 1:
            raise AssetError(f"open sound scorer: rank must be >= 1, got {self.rank}")

    def features(self, logits: np.ndarray, want: np.ndarray, usable: np.ndarray) -> np.ndarray:
        """(N, 2) float64: ``rel`` and ``abs`` of segments' (N, K) logits for ``want`` (K,)."""
        z = np.asarray(logits, np.float64)
        others = np.where(want | ~usable, -np.inf, z)
        kth = -np.partition(-others, self.rank - 1, axis=1)[:, self.rank - 1]
        rel = logsumexp(z[:, want], axis=1) - kth
        ab = (z[:, want] - self.null[want].astype(np.float64)).max(axis=1)
        return np.stack([rel, ab], axis=1)

    def log_odds(self, logits: np.ndarray, want: np.ndarray, usable: np.ndarray) -> np.ndarray:
        """(N,) float64 (class docstring)."""
        f = self.features(logits, want, usable)
        return self.w_rel * f[:, 0] + self.w_abs * f[:, 1] + self.bias


def save_open_scorer(path: str | Path, scorer: OpenScorer) -> Path:
    """Write ``scorer`` as JSON to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    d = {
        "format": OPEN_SCORER_FORMAT,
        "version": 1,
        "names_digest": scorer.names_digest,
        "rank": int(scorer.rank),
        "w_rel": float(scorer.w_rel),
        "w_abs": float(scorer.w_abs),
        "bias": float(scorer.bias),
        "null": [round(float(v), 4) for v in scorer.null],
        "meta": scorer.meta,
    }
    with atomic_path(path) as tmp:
        Path(tmp).write_text(json.dumps(d, indent=1) + "\n")
    return path


def load_open_scorer(path: str | Path | None = None) -> OpenScorer:
    """The scorer stored at ``path`` (default :data:`DEFAULT_OPEN_SCORER`)."""
    path = Path(path) if path is not None else DEFAULT_OPEN_SCORER
    try:
        d = json.loads(path.read_text())
        if d.get("format") != OPEN_SCORER_FORMAT or d.get("version") != 1:
            raise AssetError(f"{path} is not an open sound scorer ({OPEN_SCORER_FORMAT!r} v1)")
        return OpenScorer(
            np.asarray(d["null"], np.float32),
            float(d["w_rel"]),
            float(d["w_abs"]),
            float(d["bias"]),
            int(d["rank"]),
            str(d["names_digest"]),
            dict(d.get("meta") or {}),
        )
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise AssetError(
            f"cannot read open sound scorer {path}: {e}; `tabletop train audio` writes it"
        ) from None


@functools.lru_cache(maxsize=4)
def _shipped_scorer(path: str, mtime_ns: int) -> OpenScorer | None:
    return load_open_scorer(path) if mtime_ns >= 0 else None


def _default_scorer(names: tuple[str, ...]) -> OpenScorer | None:
    """The shipped scorer where it is of these class names, else None."""
    p = DEFAULT_OPEN_SCORER
    sc = _shipped_scorer(str(p), p.stat().st_mtime_ns if p.is_file() else -1)
    if sc is None or sc.names_digest != _names_digest(names) or len(sc.null) != len(names):
        return None
    return sc


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
        scorer: OpenScorer | str | None = "default",
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
        self._emb: tuple[np.ndarray, np.ndarray] | None = None
        if isinstance(scorer, str):
            if scorer != "default":
                raise ConfigError(
                    f"scorer must be an OpenScorer, 'default' or None, got {scorer!r}"
                )
            scorer = _default_scorer(self.names)
        elif scorer is not None and (
            scorer.names_digest != _names_digest(self.names) or len(scorer.null) != len(names)
        ):
            raise ConfigError("the open sound scorer was fitted on other class names")
        self.scorer = scorer
        """The fitted segment score (:class:`OpenScorer`), or None: the rank rule (module
        docstring), which needs no fit."""

    def embeddings(self) -> tuple[np.ndarray, np.ndarray]:
        """((V, dim) float32, (V,) class index): each name's :func:`name_variants`, embedded
        as "the sound of <variant>" and bare."""
        if self._emb is None:
            self._emb = _name_embeddings(self.names, self.text)
        return self._emb

    def class_scores(self, query_embedding: np.ndarray) -> np.ndarray:
        """(K,) float32: the query's best cosine with each name (-inf for generic names)."""
        emb, owner = self.embeddings()
        s = emb @ np.asarray(query_embedding, np.float32)
        out = np.full(len(self.names), -np.inf, np.float32)
        np.maximum.at(out, owner, s)
        return np.where(self._usable, out, -np.inf).astype(np.float32)

    def asked(self, query_embedding: np.ndarray) -> np.ndarray:
        """(K,) bool: the classes a query with this embedding asks for (none when it is
        below ``text_min`` to every name)."""
        per = self.class_scores(query_embedding)
        best = float(per.max())
        if best < self.text_min:
            return np.zeros(len(self.names), bool)
        return per >= best - self.text_margin

    def segment_log_odds(self, logits: np.ndarray, want: np.ndarray) -> np.ndarray:
        """(N,) float64: segments' log-odds of holding the ``want`` classes (the fitted
        :attr:`scorer`, else the rank rule)."""
        z = np.asarray(logits, np.float64).reshape(-1, len(self.names))
        if not len(z):
            return np.zeros(0)
        if self.scorer is not None:
            return self.scorer.log_odds(z, want, self._usable)
        others = np.where(want | ~self._usable, -np.inf, z)  # (N, K) competitors
        kth = -np.partition(-others, self.rank - 1, axis=1)[:, self.rank - 1]
        return logsumexp(z[:, want], axis=1) - kth - self.offset

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
        lo = self.segment_log_odds(logits, want)
        classes = tuple(self.names[i] for i in np.flatnonzero(want))
        scores = 1.0 / (1.0 + np.exp(-lo))
        return OpenSoundQuery(query, classes, float(per[best]), self.names[best], scores, lo)


@functools.lru_cache(maxsize=4)
def _name_embeddings(names: tuple[str, ...], text) -> tuple[np.ndarray, np.ndarray]:
    """((V, dim) float32, (V,) int) (see :meth:`OpenSoundVocabulary.embeddings`), once per
    text encoder: every map's matcher shares them."""
    texts, owner = [], []
    for i, n in enumerate(names):
        for v in name_variants(n):
            texts += [f"the sound of {v}", v]
            owner += [i, i]
    e = np.asarray(text.encode_text(texts), np.float32)
    e.setflags(write=False)
    o = np.array(owner)
    o.setflags(write=False)
    return e, o

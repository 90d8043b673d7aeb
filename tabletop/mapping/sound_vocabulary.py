"""The sounds an audio encoder knows, and how a sound query is scored against heard segments.

A learned audio encoder is trained on a bank of named sound categories; each category has a
caption ("the sound of a dog barking") and a set of phrasings ("a barking dog", "woof woof",
...) in ``tabletop/data/sound_phrasings.toml``. The encoder's checkpoint records the categories
and texts it was trained against, and the temperature it learned (:class:`SoundVocabulary`).

A sound query is answered in two steps (:class:`SoundMatcher`):

1. **Words -> categories.** The query's text embedding is compared with every phrasing of
   every category, and with the query-time words of ``tabletop/data/sound_words.toml`` ("bawk
   bawk" for a hen; they lead to a category but shape no prototype), the best phrasing
   counting (a prompt ensemble). The categories within
   ``text_margin`` of the best are what the query asks for ("a bird" may be chirping birds, an
   owl or a crow). A query below ``text_min`` to every phrasing names no sound the encoder knows:
   it is not found, and the reason names the nearest known sound. A query nearer (by more
   than ``other_margin``) to a phrasing of a sound the vocabulary lacks (the phrasings file
   names 14 sounds outside the bank) than to every known one reads as that sound ("thunder
   rumbling" is a thunderstorm, not rain): not found, since the encoder was never taught to
   hear it.
2. **Segments -> categories.** Each heard segment's embedding gives a posterior over the known
   categories: a softmax, at the learned temperature, of its cosine with each category's
   prototype (the normalised mean of the category's phrasing embeddings). A segment's score
   for the query is the posterior mass on the asked categories, in [0, 1].

The best segment's score is the evidence the calibration judges: a query for a known sound that
never played ("a chainsaw" when none did) finds every segment's mass elsewhere.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.special import expit, logsumexp

from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR
from tabletop.reader.lexicon.sound_words import source_after_of

__all__ = [
    "OPEN_PREFIX",
    "PHRASINGS_PATH",
    "SOUND_FAMILIES",
    "WORDS_PATH",
    "SoundMatcher",
    "SoundQuery",
    "SoundVocabulary",
    "load_other_sounds",
    "load_phrasings",
    "load_sound_words",
    "phrases_for",
]

#: Sound categories close enough to be heard as one another: a category is not asked as absent
#: while one of its family was played (the paraphrase suites, the absent-sound measure).
SOUND_FAMILIES: tuple[frozenset[str], ...] = tuple(
    frozenset(f)
    for f in (
        {"water", "toilet_flush", "washing_machine"},
        {"clock_alarm", "telephone", "church_bells"},
        {"duck", "goose"},
        {"drums", "cymbals"},
        {"piano", "xylophone"},
        {"airplane", "helicopter", "engine", "train"},
        {"crickets", "insects", "chirping_birds"},
        {"hen", "rooster"},
        {"crow", "chirping_birds", "owl"},
        {"laughing", "crying_baby"},
        {"coughing", "sneezing"},
        {"camera_shutter", "keyboard_typing", "clock_tick"},
        {"wolf", "dog"},
        {"lion", "elephant"},
        {"hand_saw", "hammering"},
        {"vacuum_cleaner", "washing_machine"},
        {"trumpet", "elephant"},
        {"violin", "guitar"},
        {"flute", "trumpet"},
        {"trumpet", "trombone", "tuba", "french_horn"},
        {"violin", "cello"},
        {"flute", "clarinet", "saxophone", "harmonica"},
        {"piano", "organ", "accordion"},
        {"drums", "bongos", "timpani"},
        {"cymbals", "triangle", "cowbell"},
        {"maracas", "tambourine"},
        {"guitar", "banjo", "harp"},
        {"clapping", "finger_snapping", "castanets"},
        {"sheep", "goat"},
        {"rain", "thunderstorm"},
        {"water", "sea_waves"},
    )
)

#: Prefix of the AudioSet class names a query asks for through an open vocabulary.
OPEN_PREFIX = "audioset:"

#: Phrasings of every sound category beside its caption.
PHRASINGS_PATH = DATA_DIR / "sound_phrasings.toml"


#: Words people use for a sound that the encoder was not trained against ("bawk bawk", "a
#: moggy"), read at query time only: they lead a query to their category, and change neither
#: the prototypes nor a segment's posteriors.
WORDS_PATH = DATA_DIR / "sound_words.toml"


def load_phrasings(
    path: str | Path | None = None, table: str = "phrasings", required: bool = True
) -> dict[str, tuple[str, ...]]:
    """category -> its phrasings, from the ``[table]`` of ``path`` (default
    :data:`PHRASINGS_PATH`); with ``required=False`` a file without the table gives none."""
    p = Path(path) if path is not None else PHRASINGS_PATH
    try:
        d = tomllib.loads(p.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"cannot read sound phrasings {p}: {e}") from None
    entries = d.get(table)
    if entries is None and not required:
        return {}
    if not isinstance(entries, dict):
        raise AssetError(f"{p}: expected a [{table}] table of category = [texts]")
    out = {}
    for k, v in entries.items():
        if not isinstance(v, list) or not v or not all(isinstance(t, str) and t for t in v):
            raise AssetError(f"{p}: [{table}].{k} must be a non-empty list of texts")
        out[k] = tuple(v)
    return out


def load_sound_words(path: str | Path | None = None) -> dict[str, tuple[str, ...]]:
    """category -> the query-time words for it, from ``path`` (default :data:`WORDS_PATH`)."""
    return load_phrasings(path if path is not None else WORDS_PATH, "words")


def load_other_sounds(path: str | Path | None = None) -> dict[str, tuple[str, ...]]:
    """Sounds neither the bank nor the phrasings file has -> words for them, from the
    ``[others]`` table of ``path`` (default :data:`WORDS_PATH`; none where it has no such
    table): a query nearest one reads as that sound, which no segment can be."""
    return load_phrasings(path if path is not None else WORDS_PATH, "others", required=False)


_PHRASINGS: dict[str, tuple[str, ...]] | None = None


def phrases_for(category: str, caption: str) -> list[str]:
    """The caption of ``category`` and its phrasings (generic ones for a category without an
    entry in :data:`PHRASINGS_PATH`), without repeats."""
    global _PHRASINGS
    if _PHRASINGS is None:
        _PHRASINGS = load_phrasings()
    words = category.replace("_", " ")
    extra = _PHRASINGS.get(category) or (words, f"a {words}", f"{words} sound", f"{words} noise")
    return list(dict.fromkeys([caption, *extra]))


@dataclass(frozen=True)
class SoundVocabulary:
    """The sound categories an encoder knows: ``texts`` maps each category to its caption and
    phrasings (caption first); ``logit_scale`` is the inverse temperature of its posteriors."""

    texts: Mapping[str, tuple[str, ...]]
    logit_scale: float = 30.0

    def __post_init__(self) -> None:
        if not self.texts:
            raise ConfigError("a sound vocabulary needs at least one category")
        for k, v in self.texts.items():
            if not isinstance(v, (list, tuple)) or not v:
                raise ConfigError(f"sound category {k!r} needs at least one text")
        if not self.logit_scale > 0:
            raise ConfigError(f"logit_scale must be > 0, got {self.logit_scale}")
        object.__setattr__(self, "texts", {str(k): tuple(v) for k, v in self.texts.items()})

    @property
    def categories(self) -> tuple[str, ...]:
        return tuple(self.texts)

    def caption(self, category: str) -> str:
        """The caption of a bank category, or the class name of an AudioSet class a match
        read the words as (``"audioset:<name>"``, :data:`OPEN_PREFIX`)."""
        if category.startswith(OPEN_PREFIX) and category not in self.texts:
            return category[len(OPEN_PREFIX) :]
        return self.texts[category][0]

    def to_meta(self) -> dict:
        """A JSON-like dict (what a checkpoint stores)."""
        return {
            "texts": {k: list(v) for k, v in self.texts.items()},
            "logit_scale": self.logit_scale,
        }

    @classmethod
    def from_meta(cls, d: Mapping | None) -> SoundVocabulary | None:
        """The vocabulary a checkpoint's meta records, or None when it records none."""
        if not d:
            return None
        try:
            return cls(dict(d["texts"]), float(d.get("logit_scale", 30.0)))
        except (KeyError, TypeError, ValueError) as e:
            raise AssetError(f"malformed sound vocabulary in checkpoint: {e}") from None

    @classmethod
    def from_bank(cls, bank, logit_scale: float = 30.0) -> SoundVocabulary:
        """Every category of a :class:`~tabletop.sim.sound_bank.SoundBank` with its caption and
        phrasings."""
        return cls(
            {c: tuple(phrases_for(c, bank.caption(c))) for c in bank.categories}, logit_scale
        )


@dataclass(frozen=True)
class SoundQuery:
    """How a sound query reads against a vocabulary."""

    query: str
    categories: tuple[str, ...]
    """The categories the query asks for (empty: none is near enough)."""
    text_score: float
    """Best cosine of the query with any phrasing of any category."""
    nearest: str
    """The category of that best phrasing."""
    scores: np.ndarray = field(repr=False)
    """(n_segments,) in [0, 1]: each segment's posterior mass on ``categories``."""
    log_odds: np.ndarray = field(repr=False)
    """(n_segments,) float64: ``log(scores / (1 - scores))``, computed without rounding to 1
    (what ranks segments whose posteriors all round to 1)."""
    other: str = ""
    """A sound of the phrasings file that the vocabulary lacks and the query reads as (then
    ``categories`` is empty: the encoder was never taught to hear it)."""
    other_score: float = -1.0
    """The query's best cosine with ``other``'s phrasings."""

    @property
    def known(self) -> bool:
        return bool(self.categories)


#: AudioSet's names of sound in general (its ontology's "Sound effect", "Noise" and
#: "Silence"): a query nearer to them than to every known sound names no particular sound.
GENERAL_SOUNDS = ("Sound effect", "Noise", "Silence")
#: :attr:`SoundQuery.other` of such a query.
GENERAL = "sound in general"


class SoundMatcher:
    """Scores sound queries against segment embeddings through a :class:`SoundVocabulary`
    (see the module docstring). ``text`` embeds the query and the vocabulary's texts in the
    audio encoder's space. ``others``: sounds the vocabulary lacks (default: the phrasings
    file's); ``words``: query-time words per category (default: :data:`WORDS_PATH`'s)."""

    def __init__(
        self,
        vocabulary: SoundVocabulary,
        text,
        text_min: float = 0.42,
        text_margin: float = 0.05,
        others: Mapping[str, tuple[str, ...]] | None = None,
        other_margin: float = 0.12,
        words: Mapping[str, tuple[str, ...]] | None = None,
        open_vocabulary=None,
        open_margin: float = 0.2,
        general_margin: float = 0.1,
    ) -> None:
        self.vocabulary = vocabulary
        self.general_margin = float(general_margin)
        """A query nearer by more than this to sound in general (:data:`GENERAL_SOUNDS`) than
        to every known phrasing names no particular sound ("a noise", "some sound"): not found,
        whatever the segments hold. On the tune pools' 4464 sound phrasings the largest lead of
        sound in general is 0.09 ("...noise" phrasings of a known sound)."""
        self._general: np.ndarray | None = None
        self.open_vocabulary = open_vocabulary
        """An :class:`~tabletop.mapping.open_sounds.OpenSoundVocabulary` (AudioSet's class
        names) for sounds the vocabulary lacks, or None."""
        self.open_margin = float(open_margin)
        """A query nearer by more than this to a class name than to every known phrasing is
        read against the class names, not the vocabulary."""
        self.text = text
        self.text_min = float(text_min)
        self.text_margin = float(text_margin)
        if others is None:  # the phrasings file's sounds this vocabulary lacks, and more
            others = {c: v for c, v in load_phrasings().items() if c not in vocabulary.categories}
            others.update(
                {c: v for c, v in load_other_sounds().items() if c not in vocabulary.categories}
            )
        # A sound that shares a phrasing with a known category is a kind of it (water drops and
        # water both "water dripping"): its phrasings lead to that category, not to a refusal.
        own = {t.lower(): c for c in vocabulary.categories for t in vocabulary.texts[c]}
        self.aliases: dict[str, tuple[str, ...]] = {}
        self.others = {}
        for c, v in others.items():
            shared = [own[t.lower()] for t in v if t.lower() in own]
            if shared:
                self.aliases[shared[0]] = (*self.aliases.get(shared[0], ()), *v)
            elif v:
                self.others[str(c)] = tuple(v)
        # Words for a known sound the encoder was not trained against lead to it too; words
        # for a sound it lacks make a query read as that sound.
        if words is None:
            words = load_sound_words()
        for c, v in words.items():
            new = tuple(t for t in v if t.lower() not in own)
            if c in vocabulary.categories:
                self.aliases[c] = (*self.aliases.get(c, ()), *new)
            elif c in self.others:
                self.others[c] = (*self.others[c], *new)
        self.other_margin = float(other_margin)
        self._targets: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._other_targets: tuple[np.ndarray, list[str]] | None = None
        self._category_classes: np.ndarray | None = None

    def targets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(phrasing embeddings (T, dim), their category index (T,), prototypes (C, dim)). The
        phrasings are the vocabulary's, then its :attr:`aliases` (which words lead to a
        category); the prototypes are the vocabulary's phrasings' alone (what the encoder was
        trained against)."""
        if self._targets is None:
            texts, owner = [], []
            for i, c in enumerate(self.vocabulary.categories):
                texts += list(self.vocabulary.texts[c])
                owner += [i] * len(self.vocabulary.texts[c])
            n = len(texts)
            for c, v in self.aliases.items():
                texts += list(v)
                owner += [self.vocabulary.categories.index(c)] * len(v)
            emb = np.asarray(self.text.encode_text(texts), np.float32)
            owner = np.array(owner)
            own, mine = emb[:n], owner[:n]
            proto = np.stack([own[mine == i].mean(axis=0) for i in range(mine.max() + 1)])
            proto /= np.linalg.norm(proto, axis=1, keepdims=True)
            self._targets = (emb, owner, proto)
        return self._targets

    def logits(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, C) float64: each segment's logit for each category (scaled prototype cosine)."""
        _, _, proto = self.targets()
        e = np.asarray(embeddings, np.float64).reshape(-1, proto.shape[1])
        return self.vocabulary.logit_scale * (e @ proto.T.astype(np.float64))

    def posteriors(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, C): each segment embedding's posterior over the vocabulary's categories."""
        z = self.logits(embeddings)
        z -= z.max(axis=1, keepdims=True)
        p = np.exp(z)
        return p / p.sum(axis=1, keepdims=True)

    def log_odds(self, embeddings: np.ndarray, want: np.ndarray) -> np.ndarray:
        """(N,) float64: log of (posterior mass on the ``want`` categories) / (the rest)."""
        z = self.logits(embeddings)
        if want.all():
            return np.full(len(z), np.inf)
        return logsumexp(z[:, want], axis=1) - logsumexp(z[:, ~want], axis=1)

    def category_scores(self, query: str, embedding: np.ndarray | None = None) -> np.ndarray:
        """(C,): the query's best cosine with each category's texts."""
        emb, owner, proto = self.targets()
        if embedding is None:
            embedding = self.text.encode_text([query])[0]
        s = emb @ np.asarray(embedding, np.float32)
        out = np.full(len(proto), -np.inf)
        np.maximum.at(out, owner, s)
        return out

    def category_classes(self) -> np.ndarray:
        """(C, K) bool: the :attr:`open_vocabulary` classes each category's texts (caption
        and phrasings) ask for, read as queries (once per matcher)."""
        if self._category_classes is None:
            ov = self.open_vocabulary
            emb, owner, _ = self.targets()
            n = sum(len(self.vocabulary.texts[c]) for c in self.vocabulary.categories)
            out = np.zeros((len(self.vocabulary.categories), len(ov.names)), bool)
            for e, i in zip(emb[:n], owner[:n], strict=True):
                out[i] |= ov.asked(e)
            self._category_classes = out
        return self._category_classes

    def nearest_other(self, embedding: np.ndarray) -> tuple[str, float]:
        """The sound of :attr:`others` whose phrasing is nearest a query's ``embedding``, and
        that cosine (``("", -1.0)`` without others)."""
        if not self.others:
            return "", -1.0
        if self._other_targets is None:
            texts, owner = [], []
            for c, v in self.others.items():
                texts += list(v)
                owner += [c] * len(v)
            self._other_targets = (np.asarray(self.text.encode_text(texts), np.float32), owner)
        emb, owner = self._other_targets
        s = emb @ np.asarray(embedding, np.float32)
        j = int(np.argmax(s))
        return owner[j], float(s[j])

    def general_score(self, embedding: np.ndarray) -> float:
        """The query's best cosine with sound in general (:data:`GENERAL_SOUNDS`, each name
        bare and as "the sound of ...")."""
        if self._general is None:
            from tabletop.mapping.open_sounds import name_variants

            names = [v for n in GENERAL_SOUNDS for v in name_variants(n)]
            texts = [t for v in names for t in (v, f"the sound of {v}")]
            self._general = np.asarray(self.text.encode_text(texts), np.float32)
        return float((self._general @ np.asarray(embedding, np.float32)).max())

    def match(
        self, query: str, embeddings: np.ndarray, class_logits: np.ndarray | None = None
    ) -> SoundQuery:
        """``query`` against segments with these embeddings (N, dim). A query that names its
        source after "of" ("the pitter-patter of feet", "a clap of thunder") scores each
        category by the better of the whole query and the source alone: the source says what
        made the sound, the word before it only how it sounded.

        ``class_logits`` (N, K): the segments' AudioSet logits, when the encoder gives them
        and the matcher has an :attr:`open_vocabulary`. A query the vocabulary cannot answer
        (it names no known sound, or reads as a sound the vocabulary lacks), that names a
        class name better than every known phrasing by :attr:`open_margin`, or better at all
        while none of its asked categories' own texts reads as one of its classes
        (:meth:`category_classes`), is then read against the class names and scored through
        the logits; its ``categories`` are the
        asked class names, prefixed ``"audioset:"``."""
        e = np.asarray(self.text.encode_text([query])[0], np.float32)
        bank = self._match_vocabulary(query, embeddings, e)
        if self.open_vocabulary is None or class_logits is None or bank.other == GENERAL:
            return bank
        ov = self.open_vocabulary.match(query, class_logits, e)
        if not ov.known:
            return bank
        if bank.known and ov.text_score < bank.text_score + self.open_margin:
            # Nearer a class name than every known phrasing, but less so than open_margin:
            # the bank answers where its asked categories read as one of the query's classes
            # ("a hound": the dog's texts read as "Dog" too); a query whose classes none of
            # them reads as names another sound ("glass breaking" asks for "Shatter", which
            # glass clinking is not).
            asked = np.isin(self.open_vocabulary.names, ov.classes)
            covers = self.category_classes()[
                [self.vocabulary.categories.index(c) for c in bank.categories]
            ]
            if ov.text_score <= bank.text_score or (covers & asked).any():
                return bank
        return SoundQuery(
            query,
            tuple(f"{OPEN_PREFIX}{c}" for c in ov.classes),
            ov.text_score,
            f"{OPEN_PREFIX}{ov.nearest}",
            ov.scores,
            ov.log_odds,
        )

    def _match_vocabulary(self, query: str, embeddings: np.ndarray, e: np.ndarray) -> SoundQuery:
        """:meth:`match` through the vocabulary alone (``e``: the query's embedding)."""
        per = self.category_scores(query, e)
        source = source_after_of(query)
        if source:
            per = np.maximum(per, self.category_scores(source))
        best = int(np.argmax(per))
        cats = self.vocabulary.categories
        n = len(embeddings)
        if per[best] < self.text_min:
            return SoundQuery(
                query, (), float(per[best]), cats[best], np.zeros(n), np.full(n, -np.inf)
            )
        general = self.general_score(e)
        if general > per[best] + self.general_margin:
            return SoundQuery(
                query, (), float(per[best]), cats[best], np.zeros(n), np.full(n, -np.inf),
                GENERAL, general,
            )  # fmt: skip
        other, other_score = self.nearest_other(e)
        if other and other_score > per[best] + self.other_margin:
            return SoundQuery(
                query,
                (),
                float(per[best]),
                cats[best],
                np.zeros(n),
                np.full(n, -np.inf),
                other,
                other_score,
            )
        want = per >= per[best] - self.text_margin
        lo = self.log_odds(embeddings, want) if n else np.zeros(0)
        scores = expit(lo)
        chosen = tuple(c for c, w in zip(cats, want, strict=True) if w)
        return SoundQuery(query, chosen, float(per[best]), cats[best], scores, lo)

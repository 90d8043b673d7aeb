"""The object module: a text query scored against the map's object instances.

The unit is the object instance (:mod:`tabletop.mapping.instances`: segmented from the map's
geometry, each with a fused embedding and a measured colour). A query is answered in three
steps, each with its own reason when it fails:

1. **Words to the vocabulary.** The query is split into a colour phrase and the rest
   (:func:`~tabletop.reader.lexicon.colour_words.color_parses`: its readings are tried in order, and
   the first that finds something answers). The rest is scored by the text encoder against
   every name of the map's vocabulary and that name's descriptions (what it is, its
   shape, material, use): a person's word for a thing ("coffee cup", "plush bear") lands on the
   name ("mug", "teddy bear") even where the image network never saw that word. The words are
   also scored against ``others``, everyday things none of the vocabulary is
   (``tabletop/data/other_objects.toml``: "bottle", "laptop", "teapot", ...). The query names
   nothing this map knows — not found — when its best vocabulary cosine is below ``text_min``,
   or when one of those other things lies nearer its words than every vocabulary name and
   description does ("the wine bottle" is a bottle, though "a drinking vessel" describes the
   mug too). Deciding by rank rather than by a high absolute cosine keeps a person's looser
   words ("the round thing you kick") while refusing things that are not there. Every name
   within ``text_margin`` of the best is what the query may mean. Where the cosine refuses
   the words, the kind reader (:mod:`tabletop.mapping.kind_reader`, a classifier of the
   words' embedding trained on how people named each kind) may still name one: at
   ``reader_min`` or more, the query means that name ("the tin can toy" is the toy
   cylinder, though it lies nearer "tin can").
2. **Instances to the vocabulary.** Each instance's fused embedding is scored against every
   vocabulary name (the name alone and with each basic colour term, as the image encoder was
   trained) and the background concepts; a softmax at ``temperature`` gives how much the
   instance looks like each. With ``shape``, those probabilities are multiplied by the shape
   prior's (:mod:`tabletop.mapping.shape`: what the instance's voxels' geometry says it is) to
   the prior's fitted weight. An instance's kind score is the probability of the query's names.
3. **Colour, composed.** A colour phrase is compared with the instance's *measured* colour:
   the colour words are matched by the text encoder to the colour lexicon's names
   (:data:`~tabletop.reader.lexicon.colour_names.COLOR_NAMES`), and each name's colour, lit at
   any gain down to ``shading_gain_min`` (shaded faces are darker and duller), is compared with the
   instance's by ΔE (CIELAB); a basic colour term means its whole family of names. The fit
   falls with how much nearer another basic colour term lies (``colour_scale``) and with the
   distance itself (``colour_abs_scale``). A two-coloured instance (its palette: a domino's
   black faces and white edges) also fits what either of its colours fits. Any colour word
   the text encoder knows works ("scarlet", "navy"), not a list of the simulator's colours.
   Where the image encoder did learn the colour (its embedding prefers "red mug" to the other
   colour variants of "mug"), that counts too: the colour score is the better of the two.

An instance's score is kind score x colour score; the best is the query's evidence (the map's
calibration makes it a confidence and decides found). A colour word no object of the kind
shows (a textured object's nominal colour included) is not found. Every instance scoring within
``keep_ratio`` of the best stays hot — two mugs for "the mug", so that "the mug near the sound
of X" still disambiguates by multiplication — and the heat decays from their voxels in 3D.

With ``instances=False`` (or a map without a vocabulary) the module scores single voxels as
before instances existed: the voxels where the query beats the background and scores within
``select_margin`` of the best, evidence the best score's margin over the median.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.mapping.colors import delta_e, delta_e94, rgb_to_lab, shaded_lab
from tabletop.mapping.heatmaps import Heatmap, Judge, point_heatmap_3d_at
from tabletop.mapping.instances import InstanceConfig, InstanceSet, ObjectInstance, support_of
from tabletop.mapping.kind_reader import OTHER, KindReader
from tabletop.mapping.voxel_map import VoxelMap
from tabletop.paths import DATA_DIR
from tabletop.reader.lexicon.colour_names import BASIC_COLOURS, COLOR_MODIFIERS, COLOR_NAMES
from tabletop.reader.lexicon.colour_words import (
    FILLER_WORDS,
    color_parses,
    colour_word,
    framed_colours,
    heads,
    modifies,
    named_colour,
    split_color_words,
    survey_colours,
    survey_name,
    survey_words,
    two_colours,
    unlisted_modifiers,
)
from tabletop.reader.lexicon.object_words import (
    LIKENESS_WORDS,
    without_deixis,
    without_likeness,
    word_forms,
)
from tabletop.reader.lexicon.words import Superlative, superlative

__all__ = [
    "BACKGROUND",
    "OTHER_OBJECTS_PATH",
    "InstanceMatch",
    "ObjectConfig",
    "ObjectModule",
    "load_other_objects",
]

#: Concepts every object query competes against: what a tabletop map holds besides objects.
BACKGROUND = ("table", "floor", "robot arm", "other")
OTHER_OBJECTS_PATH = DATA_DIR / "other_objects.toml"
#: A word no colour list has is a colour where its best cosine with a lexicon colour name is
#: at least this (MiniLM: "smoke" 0.62, "coal" 0.71, "ash" 0.80; "shiny" 0.47, "big" 0.40)...
UNLISTED_COLOUR_MIN = 0.55
#: ... and beats its best cosine with every vocabulary name, description and other thing by
#: this much ("night" 0.62 against the night light's 0.59 is no colour).
UNLISTED_COLOUR_MARGIN = 0.10


def load_other_objects(path: str | Path = OTHER_OBJECTS_PATH) -> tuple[str, ...]:
    """The everyday things of ``path`` (``others = [...]``) that a query's words are compared
    with besides the map's vocabulary (see :class:`ObjectConfig`)."""
    p = Path(path)
    try:
        d = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"cannot read the other objects {p}: {e}") from None
    others = d.get("others")
    if not isinstance(others, list) or not all(isinstance(t, str) and t for t in others):
        raise AssetError(f"{p}: expected others = [non-empty texts]")
    return tuple(dict.fromkeys(others))


@dataclass(frozen=True)
class ObjectConfig:
    """How the object module answers a query."""

    select_margin: float = 0.1
    """Voxel scoring (``instances=False``): target voxels score within this fraction of
    (best - median) of the best."""
    background: tuple[str, ...] = BACKGROUND
    """Concepts a query competes against."""
    instances: bool = True
    """Score object instances (False: single voxels)."""
    segmentation: InstanceConfig = field(default_factory=InstanceConfig)
    """How the voxels are split into instances."""
    text_min: float = 0.5
    """A query's words must reach this cosine with some vocabulary name or description."""
    others: tuple[str, ...] = field(default_factory=load_other_objects)
    """Everyday things none of the vocabulary is: a query whose words lie nearer one of them
    (by more than ``other_margin``) than every vocabulary name and description names nothing
    in the map. Empty: no such check."""
    other_margin: float = 0.0
    """How much nearer [cosine] one of ``others`` must lie than the vocabulary's best."""
    text_margin: float = 0.04
    """Vocabulary names within this cosine of the query's best are all what it may mean."""
    temperature: float = 0.02
    """Softmax temperature of an instance's scores against the vocabulary (and of its colour
    variants)."""
    colour_scale: float = 12.0
    """CIELAB ΔE by which another basic colour term lying nearer than the asked one cuts the
    fit to 1/e (a blue mug is not the purple one)."""
    colour_abs_scale: float = 60.0
    """CIELAB ΔE from the asked colour itself at which the fit falls to 1/e."""
    closeness_scale: float = 5.0
    """Among instances that fit a colour phrase, one whose colour lies this much CIELAB ΔE
    farther from the asked colour itself than the nearest one's ranks 1/e as high (both mugs
    fit "grey" when one is grey and one white in shadow; the grey one is meant)."""
    shading_gain_min: float = 0.6
    """A measured colour may be a named colour lit down to this factor of linear light (a
    shaded face of a yellow mug is darker and less saturated than "yellow")."""
    reader: bool = True
    """Consult the kind reader (:mod:`tabletop.mapping.kind_reader`) where it fits the map's
    text encoder and vocabulary."""
    reader_min: float = 0.7
    """The reader's probability of one vocabulary name at which words the cosine refused
    find that name."""
    reader_fallback: float = 0.9
    """Where no instance fits the names the words' cosine gives, and the reader reads another
    vocabulary name at this probability or more, instances of the reader's name are tried
    ("the rolling block in kind of a green": no green prism, the cosine's name; the reader
    reads a cylinder). Above 1: never."""
    reader_prefer: float = 0.8
    """Where the words may mean several vocabulary names and the reader reads one of them at
    this probability or more, that name's instances come first, ahead of the best of the others
    by ``text_margin`` ("the spool-shaped block" may be the cube, the cylinder or the prism;
    the reader reads the cylinder). The others stay what the words may mean (found where the
    scene has none of the reader's). Above 1: never."""
    reader_overrule: float = 0.9
    """Where the reader reads a vocabulary name the words' cosine does not give at this
    probability or more, that name is what they mean (a name of the jenga block whose words
    lie nearer the domino's descriptions than its own). Chosen on the
    readings of authors the reader had not seen (each tune pool read by a reader fitted
    without it): at 0.9 such a reading named the thing meant in 30 of 34 names, the cosine's
    names in 4. Above 1: never."""
    shape: bool = True
    """Multiply each instance's kind probabilities by the shape prior's
    (:mod:`tabletop.mapping.shape`: what its voxels' geometry says it is)."""
    keep_ratio: float = 0.5
    """Instances scoring at least this fraction of the best stay hot."""
    name_temperature: float = 0.02
    """Among the names a query may mean, instances of the names its words match best come
    first: each name weighs ``exp((its cosine - the best's) / name_temperature)`` when the
    instances are ranked ("the small rubber ball" prefers the ball to the soccer ball). Whether
    anything is found is decided on the unweighted scores."""

    def __post_init__(self) -> None:
        if not 0 <= self.select_margin <= 1:
            raise ConfigError(f"select_margin must be in [0, 1], got {self.select_margin}")
        if not self.background or not all(isinstance(b, str) and b for b in self.background):
            raise ConfigError(f"background must be non-empty strings, got {self.background!r}")
        object.__setattr__(self, "background", tuple(self.background))
        if isinstance(self.others, str) or not all(isinstance(t, str) and t for t in self.others):
            raise ConfigError(f"others must be non-empty strings, got {self.others!r}")
        object.__setattr__(self, "others", tuple(self.others))
        if not -1 <= self.other_margin <= 1:
            raise ConfigError(f"other_margin must be in [-1, 1], got {self.other_margin}")
        if isinstance(self.segmentation, Mapping):
            object.__setattr__(self, "segmentation", InstanceConfig(**self.segmentation))
        if not isinstance(self.segmentation, InstanceConfig):
            raise ConfigError(
                f"segmentation must be an InstanceConfig, got {type(self.segmentation).__name__}"
            )
        for name in ("text_min", "keep_ratio", "reader_min"):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        for name in (
            "text_margin",
            "temperature",
            "colour_scale",
            "colour_abs_scale",
            "closeness_scale",
            "name_temperature",
            "reader_prefer",
            "reader_fallback",
            "reader_overrule",
        ):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 < self.shading_gain_min <= 1:
            raise ConfigError(f"shading_gain_min must be in (0, 1], got {self.shading_gain_min}")


@dataclass(frozen=True)
class InstanceMatch:
    """How a query scored against the map's instances."""

    words: str
    """The query without its colour phrase."""
    colour: str
    """The query's colour phrase ("" for none)."""
    names: tuple[str, ...]
    """Vocabulary names the words may mean."""
    text_score: float
    """The words' best cosine with a vocabulary name or description."""
    nearest: str
    """The vocabulary name of that best cosine."""
    kind: np.ndarray
    """(n_instances,) probability that each instance is one of ``names``."""
    colour_match: np.ndarray
    """(n_instances,) how well each instance's measured colour fits ``colour`` (1 without)."""
    preference: np.ndarray
    """(n_instances,) in [0, 1]: each instance's probability mass on ``names`` weighted by how
    well each name matches the words, over ``kind`` (1 where the best-matching name is all
    of it)."""
    closeness: np.ndarray | None = None
    """(n_instances,) in [0, 1]: how near each instance's colour is to the asked colour
    itself, against the nearest of the instances that fit the query (``kind`` times
    ``colour_match`` at least half the best; 1 without a colour phrase)."""
    other: str = ""
    """The nearest of the config's ``others`` to the words ("" for none)."""
    other_score: float = -1.0
    """The words' cosine with ``other``."""
    described: bool = False
    """Every word of the query is a word of one name's label or descriptions and of no other
    name's ("the pointy thing": the prism is described as pointy): that name is what it means
    even where the words' cosine falls short of ``text_min``."""
    read: str = ""
    """The kind reader's reading of the words: a vocabulary name,
    :data:`~tabletop.mapping.kind_reader.OTHER`, or "" (no reader)."""
    read_p: float = 0.0
    """The reader's probability of ``read``."""
    name_weights: dict[str, float] = field(default_factory=dict)
    """How much each of ``names`` counts when the instances are ranked (1 for the names the
    words match best, see ``ObjectConfig.name_temperature`` and ``reader_prefer``)."""
    forced: bool = False
    """The names were given (``match(..., only=)``), or the words name no thing ("something
    red": any object), so none were read from them: nothing refuses them."""

    @property
    def scores(self) -> np.ndarray:
        """(n_instances,) how well each instance is what the query asks: the evidence."""
        return self.kind * self.colour_match

    @property
    def ranked(self) -> np.ndarray:
        """(n_instances,) the scores with the better-matching names, and the colours nearer the
        asked one, first: the ranking."""
        r = self.scores * self.preference
        return r if self.closeness is None else r * self.closeness


class ObjectModule:
    """Object queries on a :class:`~tabletop.mapping.voxel_map.VoxelMap`.

    Args:
        voxels: the map's voxels (read at query time; derived data is cached until they change).
        text: the text encoder (``encode_text(list[str]) -> (n, dim)``, unit rows).
        config: the module's parameters.
        vocabulary: the object names the map knows (``MapConfig.objects``); empty: voxel
            scoring only.
        descriptions: name -> descriptions of it, extra text targets of the name.
        table: () -> what the map's objects stand on (:meth:`AVLMap.supports`: its fitted
            table, or a room's raised surfaces), for the segmentation.
    """

    def __init__(
        self,
        voxels: VoxelMap,
        text,
        config: ObjectConfig | None = None,
        vocabulary: tuple[str, ...] = (),
        descriptions: Mapping[str, tuple[str, ...]] | None = None,
        table: Callable | None = None,
    ) -> None:
        self.voxels = voxels
        self.text = text
        self.config = config or ObjectConfig()
        self.vocabulary = tuple(vocabulary)
        self.descriptions = {k: tuple(v) for k, v in (descriptions or {}).items()}
        self.instances = InstanceSet(voxels, table or (lambda: None), self.config.segmentation)
        """The map's object instances (segmented on first use, again after new frames)."""
        self._key: tuple[int, int] | None = None
        self._features: np.ndarray | None = None
        self._background: np.ndarray | None = None
        self._targets: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._lexicon: tuple[np.ndarray, np.ndarray] | None = None
        self._others: np.ndarray | None = None
        self._senses: dict[str, tuple[float, float, float]] = {}
        self._name_words: list[set[str]] | None = None
        self._shape_prior = None
        self._reader: KindReader | bool | None = None
        self._shape_cache: tuple[tuple[int, int] | None, dict] = (None, {})

    def set_descriptions(self, descriptions: Mapping[str, tuple[str, ...]]) -> None:
        """Replace the names' descriptions (query-time text: no voxel or instance changes)."""
        self.descriptions = {k: tuple(v) for k, v in (descriptions or {}).items()}
        self._targets = None
        self._name_words = None
        self._senses.clear()

    # ------------------------------------------------------------------ single voxels
    def _refresh(self) -> None:
        key = (self.voxels.n, self.voxels.version)
        if self._key != key:
            self._features = self.voxels.mean_features()
            bg = self.text.encode_text(list(self.config.background))
            self._background = (self._features @ bg.T).max(axis=1)
            self._key = key

    def features(self) -> np.ndarray:
        """(n, dim) float32: the normalised mean feature of each occupied voxel."""
        self._refresh()
        return self._features

    def scores(self, query: str) -> tuple[np.ndarray, np.ndarray]:
        """Per occupied voxel: the query's cosine score, and whether the query beats the
        background concepts there."""
        self._refresh()
        s = self._features @ self.text.encode_text([query])[0]
        # a tie is no win: a query that is a background concept scores that concept's own
        # value, give or take the float noise of encoding it alone or in a batch
        return s, s > self._background + BACKGROUND_TIE

    # ------------------------------------------------------------------ instances
    @property
    def uses_instances(self) -> bool:
        return self.config.instances and bool(self.vocabulary)

    def _vocab_targets(self):
        """(text targets (T, dim), their name index (T,), vision targets (V, dim), their class
        index (V,)); classes are the vocabulary then the background."""
        if self._targets is None:
            texts, owner = [], []
            for i, name in enumerate(self.vocabulary):
                for t in (name, f"a {name}", *self.descriptions.get(name, ())):
                    texts.append(t)
                    owner.append(i)
            vis, vowner = [], []
            for i, name in enumerate(self.vocabulary):
                for t in (name, *(f"{c} {name}" for c in BASIC_COLOURS)):
                    vis.append(t)
                    vowner.append(i)
            for j, b in enumerate(self.config.background):
                vis.append(b)
                vowner.append(len(self.vocabulary) + j)
            emb = self.text.encode_text(texts + vis)
            self._targets = (
                emb[: len(texts)],
                np.array(owner),
                emb[len(texts) :],
                np.array(vowner),
            )
        return self._targets

    def class_scores(self, instances: list[ObjectInstance] | None = None) -> np.ndarray:
        """(n_instances, vocabulary + background): each instance's best cosine with each
        class's vision targets."""
        inst = self.instances.items if instances is None else instances
        _, _, V, vowner = self._vocab_targets()
        n_cls = len(self.vocabulary) + len(self.config.background)
        if not inst:
            return np.zeros((0, n_cls))
        s = np.stack([i.embedding for i in inst]) @ V.T
        out = np.full((len(inst), n_cls), -np.inf)
        for c in range(n_cls):
            out[:, c] = s[:, vowner == c].max(axis=1)
        return out

    def kind_probabilities(self, instances: list[ObjectInstance] | None = None) -> np.ndarray:
        """(n_instances, vocabulary + background): how much each instance looks like each class
        (a softmax of :meth:`class_scores` at ``temperature``), times the shape prior's
        probability of each vocabulary name (the background classes: its uniform share) to
        its fitted weight, normalised again, when ``config.shape`` (and the prior was trained
        on maps of this map's voxel size)."""
        inst = self.instances.items if instances is None else instances
        z = self.class_scores(inst) / self.config.temperature
        prior = self.shape_prior() if self.config.shape and len(inst) else None
        if prior is not None and prior.applies_to(self.voxels.grid.voxel_size):
            return prior.fuse(z, self.shape_features(inst), self.vocabulary)
        p = np.exp(z - z.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)

    def shape_prior(self):
        """The committed :class:`~tabletop.mapping.shape.ShapePrior` (read once)."""
        from tabletop.mapping.shape import ShapePrior

        if self._shape_prior is None:
            self._shape_prior = ShapePrior.load()
        return self._shape_prior

    def shape_features(self, instances: list[ObjectInstance]) -> np.ndarray:
        """(n, F) :func:`~tabletop.mapping.shape.shape_features` of ``instances`` on the map's
        fitted table."""
        from tabletop.mapping.shape import FEATURES, shape_features

        supports = self.instances.table()
        if not supports or not instances:
            return np.zeros((len(instances), len(FEATURES)))
        key = (self.voxels.n, self.voxels.version)
        if self._shape_cache[0] != key:  # once per instance until the voxels change
            self._shape_cache = (key, {})
        done = self._shape_cache[1]
        vs = self.voxels.grid.voxel_size
        missing = [i for i in instances if i not in done]
        centers = self.voxels.centers if missing else None  # every voxel's: only when needed
        for i in missing:
            base = support_of(supports, np.array([*i.center[:2], i.lo[2] + vs]))
            done[i] = shape_features(centers[i.rows], vs, base.z)
        return np.stack([done[i] for i in instances])

    @staticmethod
    def _query_words(query: str, reading: tuple[str, str] | None = None) -> tuple[str, str]:
        """(colour phrase, the words :meth:`match` reads as the thing's name)."""
        colour, words = reading if reading is not None else split_color_words(query)
        return colour, without_deixis(words)  # "the cup over there"

    def prefetch(self, queries: list[str]) -> None:
        """Embed at once, in batches, the texts :meth:`match` embeds for each of ``queries``
        (their names as read, with "the", without what they are likened to): with a text
        encoder that keeps what it embedded (MiniLM's does), many queries then cost one batched
        pass instead of one pass each."""
        texts: dict[str, None] = {}
        for q in queries:
            words = self._query_words(q)[1]
            if [w for w in words.split() if w not in FILLER_WORDS]:
                texts.update(dict.fromkeys((words, _said(words), without_likeness(words))))
        if texts:
            self.text.encode_text(list(texts))

    def match(
        self, query: str, reading: tuple[str, str] | None = None, only: str | None = None
    ) -> InstanceMatch:
        """Score ``query`` against every instance (see the module docstring), its words read
        as ``reading`` ((colour phrase, the rest): default :func:`split_color_words`'s);
        ``only``: the vocabulary name the words mean, whatever their cosine says (the kind
        reader's fallback, see :meth:`heatmap`)."""
        cfg = self.config
        colour, words = self._query_words(query, reading)
        inst = self.instances.items
        n = len(inst)
        T, owner, _, _ = self._vocab_targets()
        nv = len(self.vocabulary)
        content = [w for w in words.split() if w not in FILLER_WORDS]
        if content:
            e = self.text.encode_text([words])[0]
            per = np.array([float((T[owner == i] @ e).max()) for i in range(nv)])
            best = int(np.argmax(per))
            text_score, nearest = float(per[best]), self.vocabulary[best]
            # The names within the margin, and those the query's head noun is part of where
            # the best name is too (a shorter name: "the ball" may be the soccer ball, "the
            # bear" the teddy bear; but "the wedge block" is no jenga block, nor "the
            # barrel-shaped toy" any toy: the words before the head decide).
            want = per >= per[best] - cfg.text_margin
            plain = without_likeness(words)
            head = content[-1]
            # (unless a word before the head is the best name's alone: "the triangular prism
            # toy" is the prism, not any toy)
            pinned = _names_a_word_of(content[:-1], self.vocabulary[best], self.vocabulary)
            if plain == words and head in self.vocabulary[best].split() and not pinned:
                want |= np.array([head in name.split() for name in self.vocabulary])
            # What the thing is likened to may be one name's own ("the can-shaped block": the
            # cylinder is "a toy like a short tube or can"): then it is that name.
            kept = set(plain.split()) | LIKENESS_WORDS
            likened = [w for w in words.split() if w not in kept]
            if likened and (d := self._described_fully(likened)) >= 0:
                want = np.arange(nv) == d
            names = tuple(str(x) for x in np.array(self.vocabulary)[want])
            # A word of the query that is a word of one name only ("lego", "cube") speaks for
            # that name when the names the words may mean score alike ("the lego block with
            # bumps on top" is nearly as close to "toy cube" as to "lego brick").
            named = np.array(
                [_names_a_word_of(content, name, self.vocabulary) for name in self.vocabulary]
            )
            # So does a word that only one of those names' descriptions holds ("the round
            # block": of the cube, the cylinder and the prism, only the cylinder is round).
            named |= self._described_by(content, want)
            # the words are one name's own: it, not the cosine, decides where the cosine finds
            # no name or names others ("the column block" is the cylinder's, though its cosine
            # lies nearer the prism's)
            d = self._described_fully(content)
            described = d >= 0 and bool(per[best] < cfg.text_min or not want[d])
            if described:
                want = np.arange(nv) == d
                names = (self.vocabulary[d],)
            rank = per + cfg.text_margin * named
            # the reader learnt names as "the ...": a landmark the parser hands over bare
            # ("puck block") is read the same way
            said = _said(words)
            read, read_p = self._read(e if said == words else self.text.encode_text([said])[0])
            if read in self.vocabulary and read not in names and read_p >= cfg.reader_overrule:
                want = np.array([v == read for v in self.vocabulary])
                names, rank = (read,), np.where(want, rank.max(), rank)
            elif len(names) > 1 and read in names and read_p >= cfg.reader_prefer:
                # the reader's name first, by the margin ("the footy ball": the soccer ball)
                r = self.vocabulary.index(read)
                rank[r] = rank[want].max() + cfg.text_margin
            weight = np.exp((rank - rank[want].max()) / cfg.name_temperature)
            # "the tin-can-shaped toy" is a toy: a thing it is likened to is no other thing
            if plain == words:
                other, other_score = self._nearest_other(e)
            elif [w for w in plain.split() if w not in FILLER_WORDS]:
                other, other_score = self._nearest_other(self.text.encode_text([plain])[0])
            else:
                other, other_score = "", -1.0
            # words that are all one name's own read as another thing only by a word of it
            # ("the bath buddy" is the duck's, though its cosine lies nearer "toilet")
            if described and not word_forms(other) & word_forms(" ".join(content)):
                other, other_score = "", -1.0
            # the reader names what the cosine refused ("the tin can toy": nearer "tin can")
            refused = bool(
                self._cosine_refusal(words, text_score, nearest, described, other, other_score)
            )
            if refused and read in self.vocabulary and read_p >= cfg.reader_min:
                want = np.array([v == read for v in self.vocabulary])
                names, weight = (read,), np.ones(nv)
            if only is not None:
                want = np.array([v == only for v in self.vocabulary])
                names, weight = (only,), np.ones(nv)
                described, other, other_score = True, "", -1.0  # nothing refuses it
        else:  # "something red": any object
            described, read, read_p = False, "", 0.0
            names, text_score, nearest = self.vocabulary, 1.0, ""
            other, other_score = "", -1.0
            want = np.ones(nv, bool)
            weight = np.ones(nv)
        if n:
            p = self.kind_probabilities(inst)
            kind = p[:, :nv][:, want].sum(axis=1)
            weighted = p[:, :nv][:, want] @ weight[want]
            preference = np.divide(weighted, kind, out=np.zeros(n), where=kind > 0)
        else:
            kind = preference = np.zeros(0)
        close = None
        if colour:
            of_part = _colour_of_a_part(query, colour)
            # two basic colour terms that make no colour name together ("red blue", "black
            # and white") ask for a thing of both colours, not a shade of the last: each
            # must fit, and nearness is the farther term's
            per_term = [self.colour_weights(c) for c in two_colours(colour) or (colour,)]
            cm = np.min(
                [
                    np.maximum(
                        self.colour_match(w, inst, of_part or len(per_term) > 1),
                        self.learned_colour(w, inst, want),
                    )
                    for w in per_term
                ],
                axis=0,
            )
            if n:
                # nearness ranks among the instances that fit the phrase: a name far from
                # every object ("electric blue", a pale cyan, for a mid blue mug) must not
                # hand the lead to a nearer one of another colour
                d = np.max([self.colour_distance(w, inst) for w in per_term], axis=0)
                fits = kind * cm  # >= 0: with no fit at all, every instance counts
                among = fits >= 0.5 * fits.max()
                close = np.exp(-np.maximum(d - d[among].min(), 0.0) / cfg.closeness_scale)
        else:
            cm = np.ones(n)
        return InstanceMatch(
            words,
            colour,
            names,
            text_score,
            nearest,
            kind,
            cm,
            preference,
            close,
            other,
            other_score,
            described,
            read,
            read_p,
            {v: float(w) for v, w, k in zip(self.vocabulary, weight, want, strict=True) if k},
            only is not None or not content,
        )

    def kind_reader(self) -> KindReader | None:
        """The kind reader, where the config asks for it and it reads this map's text encoder's
        space and every vocabulary name (None otherwise)."""
        if self._reader is None:
            reader = KindReader.load() if self.config.reader and self.vocabulary else None
            fits = reader is not None and reader.covers(self.vocabulary)
            self._reader = (
                reader if fits and getattr(self.text, "space", None) == reader.space else False
            )
        return self._reader or None

    def set_kind_reader(self, reader: KindReader | None) -> None:
        """Use ``reader`` (None: no reader) instead of the committed one (its training
        measures readers fitted without a pool this way)."""
        self._reader = reader if reader is not None else False

    def _read(self, embedding: np.ndarray) -> tuple[str, float]:
        """The kind reader's reading of the words' ``embedding`` ("" and 0 without a reader)."""
        reader = self.kind_reader()
        return reader.read(embedding) if reader is not None else ("", 0.0)

    def refusal(self, m: InstanceMatch) -> str:
        """Why the words of ``m`` name nothing of the map's vocabulary ("" where they do).

        Where the kind reader has a refusal head
        (:class:`~tabletop.mapping.kind_reader.RefusalHead`), it decides from the same
        evidence the fixed rules look at (the cosine, the nearest other thing, whether the
        words are one name's own, the reader's reading); otherwise the rules do: the cosine
        refuses (:meth:`_cosine_refusal`) unless the reader reads one of the names at
        ``reader_min`` or more."""
        if m.forced:
            return ""
        cosine = self._cosine_refusal(
            m.words, m.text_score, m.nearest, m.described, m.other, m.other_score
        )
        reader = self.kind_reader()
        head = reader.refusal if reader is not None else None
        if head is None:
            if m.read in m.names and m.read_p >= self.config.reader_min:
                return ""  # the reader named what the cosine refused
            return cosine
        features = self.refusal_features(m)
        if not head.refuses(features, self.config.reader_min):
            return ""
        z = head.logit(features)
        if cosine:
            return cosine
        what = "no kind" if m.read == OTHER else f"{m.read!r} ({m.read_p:.2f})"
        return (
            f"{m.words!r} names nothing of this map's vocabulary (nearest: {m.nearest!r}, "
            f"cosine {m.text_score:.2f}; the kind reader reads {what}; refusal log-odds "
            f"{z:.2f} > 0)"
        )

    def refusal_features(self, m: InstanceMatch) -> dict[str, float]:
        """The evidence the refusal head weighs
        (:data:`~tabletop.mapping.kind_reader.REFUSAL_FEATURES`) for the words of ``m``."""
        return {
            "text_score": float(m.text_score),
            "other_score": float(m.other_score),
            "described": float(m.described),
            "read_other": float(m.read_p) if m.read == OTHER else 0.0,
            "read_kind": float(m.read_p) if m.read in self.vocabulary else 0.0,
        }

    def _cosine_refusal(
        self,
        words: str,
        text_score: float,
        nearest: str,
        described: bool,
        other: str,
        other_score: float,
    ) -> str:
        """Why the cosine alone refuses ``words`` ("" where it does not): nearer no name
        than ``text_min`` (unless the words are one name's own), or nearer a thing of the
        config's ``others`` than the nearest name by more than ``other_margin``."""
        cfg = self.config
        if text_score < cfg.text_min and not described:
            said = " ".join(w for w in words.split() if w not in FILLER_WORDS)
            background = self.config.background
            if said in background:  # "the table", "the floor": what holds the things
                return (
                    f"{words!r} is the map's background ({', '.join(background)}), not a thing "
                    "on the table: ask for a thing on it, or for a place as an area ('the "
                    "middle of the table')"
                )
            return (
                f"{words!r} is like nothing in this map's vocabulary (nearest: "
                f"{nearest!r}, cosine {text_score:.2f} < {cfg.text_min})"
            )
        if other and other_score > text_score + cfg.other_margin:
            return (
                f"{words!r} reads as {other!r} (cosine {other_score:.2f}), which this "
                f"map's vocabulary does not have (nearest: {nearest!r}, {text_score:.2f})"
            )
        return ""

    def _described_fully(self, content: list[str]) -> int:
        """The index of the one vocabulary name whose label and descriptions hold every
        telling word of ``content`` (:func:`~tabletop.reader.lexicon.object_words.word_forms`),
        or -1 (none, or several)."""
        telling = [f for f in (word_forms(w) for w in content) if f]
        if not telling:
            return -1
        words = self._name_word_forms()
        have = [i for i, n in enumerate(words) if all(f & n for f in telling)]
        return have[0] if len(have) == 1 else -1

    def _name_word_forms(self) -> list[set[str]]:
        """Per vocabulary name, the word forms of its label and descriptions."""
        if self._name_words is None:
            self._name_words = [
                {f for t in (name, *self.descriptions.get(name, ())) for f in word_forms(t)}
                for name in self.vocabulary
            ]
        return self._name_words

    def _described_by(self, content: list[str], want: np.ndarray) -> np.ndarray:
        """(vocabulary,) bool: the names of ``want`` whose label or descriptions hold a word
        of ``content`` (its plain form: "boxy" is "box") that no other name of ``want``'s do."""
        name_words = self._name_word_forms()
        out = np.zeros(len(self.vocabulary), bool)
        wanted = np.nonzero(want)[0]
        if len(wanted) < 2:
            return out
        for w in content:
            forms = word_forms(w)
            have = [i for i in wanted if forms & name_words[i]]
            if len(have) == 1:
                out[have[0]] = True
        return out

    def _nearest_other(self, embedding: np.ndarray) -> tuple[str, float]:
        """The config's ``others`` nearest the words' ``embedding``, and its cosine."""
        others = self.config.others
        if not others:
            return "", -1.0
        if self._others is None:
            self._others = self.text.encode_text(list(others))
        c = self._others @ embedding
        j = int(np.argmax(c))
        return others[j], float(c[j])

    def colour_weights(self, colour: str) -> np.ndarray:
        """(len(COLOR_NAMES),) summing to 1: the lexicon names the colour phrase means (their
        text embeddings' cosine with the phrase's, sharpened). A survey colour name the
        lexicon lacks ("aubergine") means its basic colour term, that of the lexicon name
        nearest its colour (CIE94, lightness at half weight: "butter" is a yellow, not the
        olive :func:`~tabletop.mapping.colors.delta_e` puts nearest): the names people give
        a colour vary more than its family does;
        but one made of a basic colour term after a word that names no colour ("pale red",
        "pure blue") is a shade of that term, the words nearest it within the term's family."""
        embeddings, lab = self._colour_lexicon()
        # a survey name made of a basic colour term and a word that is no colour ("pale red",
        # "pure blue", "deep orange") is a shade of that term, as people read it: the nearest
        # lexicon name may lie in another family (brown for "pale red", purple for "pure blue")
        survey = [s for s in survey_words(colour) if not _shade_of_basic(s)]
        # a word no lexicon or survey has, read as a colour ("quince"), is the colour the
        # longer list of colour names gives it
        more = [w for w in colour.split() if not colour_word(w) and w not in COLOR_MODIFIERS]
        named = next((c for w in more if (c := named_colour(w)) is not None), None)
        head = re.split(r"[\s-]+", colour.strip())[-1]
        basic_head = colour not in COLOR_NAMES and head in BASIC_COLOURS
        if survey or named is not None:  # a name means its basic colour term: the nearest's
            rgb = np.array(survey_colours()[survey_name(survey[0])] if survey else named, float)
            de = delta_e94(rgb_to_lab(rgb), lab[-1])  # the names at full light (gain 1)
            term = COLOR_NAMES[list(COLOR_NAMES)[int(np.argmin(de))]][1]
            # ... unless a thing's compound ("navy-flag", "pillar-box": one of its words no
            # colour) stands before a basic colour term, saying which shade of it: the term
            # decides ("rust red", two colour words, stays the survey's brown)
            if not (basic_head and term != head and _compound_before(colour)):
                return self.colour_weights(term)
        sim = embeddings @ self.text.encode_text([colour])[0]
        if basic_head:
            # "rose red", "teal green", "grass-green": a shade of the last word's colour,
            # whatever the word before it is nearest to on its own ("rose" is a pink)
            sim = np.where(self._family_id == BASIC_COLOURS.index(head), sim, -np.inf)
        w = np.exp((sim - sim.max()) / 0.02)
        return w / w.sum()

    def _colour_lexicon(self) -> tuple[np.ndarray, np.ndarray]:
        """(text embeddings (len(COLOR_NAMES), dim), CIELAB (gains, len(COLOR_NAMES), 3) lit at
        gains from ``shading_gain_min`` up to 1) of the lexicon's names, computed once."""
        if self._lexicon is None:
            names = list(COLOR_NAMES)
            gains = np.linspace(self.config.shading_gain_min, 1.0, 8)
            lab = shaded_lab(np.array([v[0] for v in COLOR_NAMES.values()], float), gains)
            self._lexicon = (self.text.encode_text(names), lab)
            self._basic = [names.index(c) for c in BASIC_COLOURS]
            self._family = [names.index(v[1]) for v in COLOR_NAMES.values()]
            self._family_id = np.array([BASIC_COLOURS.index(v[1]) for v in COLOR_NAMES.values()])
        return self._lexicon

    def learned_colour(
        self, weights: np.ndarray, instances: list[ObjectInstance], want: np.ndarray
    ) -> np.ndarray:
        """(n,) in [0, 1]: how strongly each instance's *embedding* says the colour, for the
        query's names: a softmax over the basic colour variants of each name ("red mug",
        "blue mug", ...) at the module's temperature, at the phrase's basic colour terms; the
        best of the names. What the image encoder learned of colour, beside the measured one."""
        if not instances or not want.any():
            return np.zeros(len(instances))
        _, _, V, vowner = self._vocab_targets()
        nc = len(BASIC_COLOURS)
        fam = np.zeros(nc)  # the phrase's weight on each basic colour term
        for wi, f in zip(weights, self._family, strict=True):
            fam[self._basic.index(f)] += wi
        g = np.stack([i.embedding for i in instances])
        out = np.zeros(len(instances))
        for c in np.nonzero(want)[0]:
            variants = V[vowner == c][1 : 1 + nc]  # the name with each basic colour term
            z = g @ variants.T / self.config.temperature
            p = np.exp(z - z.max(axis=1, keepdims=True))
            p /= p.sum(axis=1, keepdims=True)
            out = np.maximum(out, p @ fam)
        return out

    def colour_fit(self, lab: np.ndarray) -> np.ndarray:
        """(m, len(COLOR_NAMES)) in [0, 1]: how well measured colours ``lab`` ((m, 3) CIELAB)
        fit each lexicon name (call :meth:`colour_weights` first).

        A name's distance is the ΔE (:func:`delta_e`) from the measured colour to the name's
        colour lit at any gain down to ``shading_gain_min``, and never more than the distance
        to the nearest name of its basic colour term ("navy" asks for a blue). The fit is
        ``exp(-(that - the nearest basic term's) / colour_scale)``, how much nearer another
        basic colour term lies, times ``exp(-distance / colour_abs_scale)``."""
        cfg = self.config
        de = self._lexicon_distance(lab)
        fam = self._family_id
        per_term = np.stack([de[:, fam == f].min(axis=1) for f in range(len(BASIC_COLOURS))], 1)
        own = per_term[:, fam]  # each name's basic colour term
        rel = np.maximum(own - per_term.min(axis=1, keepdims=True), 0.0)
        return np.exp(-rel / cfg.colour_scale - np.minimum(de, own) / cfg.colour_abs_scale)

    def colour_distance(self, weights: np.ndarray, instances: list[ObjectInstance]) -> np.ndarray:
        """(n,) CIELAB ΔE from each instance's colour (its mean, or the nearer of its palette
        colours) to the colours the phrase names themselves, lit at any allowed gain (not their
        whole family: "grey" is nearer a grey teddy bear than a white one that looks light
        grey), weighted by ``weights``."""
        out = self._lexicon_distance(np.stack([i.lab for i in instances])) @ weights
        for k, inst in enumerate(instances):
            colours, _ = _palette_parts(inst)
            if len(colours):
                out[k] = min(out[k], float((self._lexicon_distance(colours) @ weights).min()))
        return out

    def _lexicon_distance(self, lab: np.ndarray) -> np.ndarray:
        """(m, len(COLOR_NAMES)): ΔE from colours ``lab`` ((m, 3) CIELAB) to each lexicon
        name's colour lit at the nearest allowed gain."""
        return delta_e(np.asarray(lab)[None, :, None, :], self._lexicon[1][:, None, :, :]).min(0)

    def colour_match(
        self, weights: np.ndarray, instances: list[ObjectInstance], of_part: bool = False
    ) -> np.ndarray:
        """(n,) in [0, 1]: how well each instance's measured colour fits the colour phrase
        (``weights``: the lexicon names it means, :meth:`colour_weights`).

        The instance's mean colour is scored by :meth:`colour_fit`; an instance of two
        distinct colours (its palette: a domino's black faces and white edges) also fits a
        colour that one of them fits, scaled down where that colour covers less than a third
        of it (under a quarter: not at all) — unless the phrase names the colour of a part
        (``of_part``: "the ball with black patches"), which need not cover much."""
        if not instances:
            return np.zeros(0)
        fit = self.colour_fit(np.stack([i.lab for i in instances])) @ weights
        for k, inst in enumerate(instances):
            colours, shares = _palette_parts(inst)
            if len(colours):
                part = self.colour_fit(colours) @ weights
                scale = 1.0 if of_part else np.minimum(shares / (1 / 3), 1.0)
                fit[k] = max(fit[k], float((part * scale).max()))
        return fit

    def heatmap(self, query: str, decay: float, judge: Judge, viewpoint=None) -> Heatmap:
        """Heat around the instances (or voxels) that best match ``query``; not found, with the
        reason, when nothing does. ``viewpoint``: (x, y) [m] from which a superlative of
        distance ranks ("the nearest mug"; default the map frame's origin, the arm's base)."""
        grid = self.voxels.grid
        if self.voxels.n == 0:
            return Heatmap.not_found(grid, query, "object", decay, "the map is empty")
        if not self.uses_instances:
            return self._voxel_heatmap(query, decay, judge)
        # "the biggest mug": the mugs are found by the words without the superlative, and the
        # one it ranks first is kept
        sup = superlative(query)
        said, query = query, sup.rest if sup is not None else query
        if sup is not None and viewpoint is not None:
            sup = sup._replace(viewpoint=check_viewpoint(viewpoint))
        # where none finds anything, the reason given is the lexicon's reading's ("'bottle'
        # reads as 'bottle'" for "wine bottle", not the reading of "wine" as a colour)
        plain, first = color_parses(query)[0], None
        matches = []  # kept for the fallback below
        for reading in self.readings(query):
            m = self.match(query, reading)
            h = self._instance_heatmap(said, m, decay, judge, sup)
            if h.found:
                return h
            first = h if first is None or reading == plain else first
            matches.append((reading, m))
        # nothing the cosine's names fits: the kind reader's name, where it reads another
        # ("the rolling block in kind of a green": no green prism; the reader reads a cylinder)
        for reading, m in matches:
            fallback = m.read in self.vocabulary and m.read not in m.names
            if fallback and m.read_p >= self.config.reader_fallback and not self.refusal(m):
                h = self._instance_heatmap(
                    said, self.match(query, reading, only=m.read), decay, judge, sup
                )
                if h.found:
                    return h
        return first

    def readings(self, query: str) -> list[tuple[str, str]]:
        """The readings of ``query``'s colour words to try, in order
        (:func:`~tabletop.reader.lexicon.colour_words.color_parses`). Where the query has no colour
        word of the lexicon, a colour name of the survey
        (:func:`~tabletop.reader.lexicon.colour_words.survey_words`: "aubergine", "cherry") is a
        colour where the text encoder places it nearer a lexicon colour than every vocabulary
        name, description and other thing ("cherry" is, "tomato" and "coffee" are not); where
        it also names something of the vocabulary's (its cosine with one reaches
        ``text_min``: "tea" for a mug), the readings without it follow. So they do where the
        encoder places it nearer a thing, but one of no vocabulary name, and it modifies the
        rest of the noun phrase (:func:`~tabletop.reader.lexicon.colour_words.modifies`: "the
        heliotrope block" is no flower block, "the tomato one" no tomato); and they follow a
        colour name that ends the noun phrase as its head noun ("the domino stone",
        :func:`~tabletop.reader.lexicon.colour_words.heads`); they come first where such a word
        names something of the vocabulary's and stands where no modifier does ("the mug
        you'd put tea in": tea, not its green). A word the query's
        own words call a colour (:func:`~tabletop.reader.lexicon.colour_words.framed_colours`:
        "tomato-coloured", "colour heliotrope") is one, whatever the text encoder says; the
        readings without it follow only where such a word names no colour of the lexicon or
        the survey ("the solid colour ball"; not "the leaf-coloured block", which where no
        green block stands is not found)."""
        lexicon = color_parses(query)
        if lexicon[0][0]:  # the lexicon's colour words are the colour
            return lexicon
        content = [w for w in lexicon[0][1].split() if w not in FILLER_WORDS]
        if len(content) == 1 and content[0] in COLOR_NAMES:
            # a colour name alone names the thing where it names one ("the orange", a
            # fruit); where it names none ("purple") it asks for something of that colour
            _, thing, other = self._cosines(content[0])
            if max(thing, other) < self.config.text_min:
                return [(content[0], "something")]
        framed = framed_colours(query)  # "tomato-coloured", "colour heliotrope": colours
        colourish, unsure, plain_first = [], False, False
        for w in survey_words(query):
            colour, thing = self._word_sense(w)
            if w in framed:
                continue
            modifier = modifies(query, w)
            if colour or (not thing and modifier):
                colourish.append(w)  # "the heliotrope block": no flower block
                unsure |= thing or not colour or heads(query, w)  # "the domino stone"
                # a word for something a vocabulary thing holds or is, standing where no
                # modifier stands, is that something: "the mug you'd put tea in"
                plain_first |= thing and not modifier
        for w in unlisted_modifiers(query):  # "the smoke bear": a colour no list has
            if w not in framed and self._unlisted_colour(w):
                colourish.append(w)
                unsure = True
        if not colourish and not framed:
            return lexicon
        readings = color_parses(query, frozenset(colourish + framed))
        # a framed word that names a colour of the survey ("leaf-coloured") is that colour
        # and nothing else; one that names none ("the solid colour ball") may be no colour
        if plain_first and not framed:
            return lexicon + [r for r in readings if r not in lexicon]
        if unsure or [w for w in framed if not colour_word(w)]:
            readings += [r for r in lexicon if r not in readings]
        return readings

    def _word_sense(self, word: str) -> tuple[bool, bool]:
        """(a colour?, a word for something of the vocabulary?) of a survey colour name."""
        colour, thing, other = self._cosines(word)
        return colour > max(thing, other), thing >= self.config.text_min

    def _unlisted_colour(self, word: str) -> bool:
        """Whether a word no colour list has is a colour, as the text encoder places it: near
        a lexicon colour name (:data:`UNLISTED_COLOUR_MIN`) and clearly nearer it than every
        vocabulary name, description and other thing (:data:`UNLISTED_COLOUR_MARGIN`): "smoke",
        "coal", "ash" are; "shiny", "big", "little", "sleepy" are not."""
        colour, thing, other = self._cosines(word)
        margin = colour - max(thing, other)
        return colour >= UNLISTED_COLOUR_MIN and margin >= UNLISTED_COLOUR_MARGIN

    def _cosines(self, word: str) -> tuple[float, float, float]:
        """A word's best cosine with the lexicon's colour names, with the vocabulary's names
        and descriptions, and with the other things (computed once per word)."""
        if word not in self._senses:
            T, _, _, _ = self._vocab_targets()
            e = self.text.encode_text([word])[0]
            colour = float((self._colour_lexicon()[0] @ e).max())
            thing = float((T @ e).max()) if len(T) else -1.0
            _, other = self._nearest_other(e)
            self._senses[word] = (colour, thing, other)
        return self._senses[word]

    def _instance_heatmap(
        self,
        query: str,
        m: InstanceMatch,
        decay: float,
        judge: Judge,
        sup: Superlative | None = None,
    ):
        """Heat around the instances ``m`` ranks best (of those, only the one that ``sup``
        ranks first: "the biggest mug"); not found, with the reason, when none is what the
        query asks."""
        grid = self.voxels.grid
        if why := self.refusal(m):
            return Heatmap.not_found(grid, query, "object", decay, why, 0.0)
        inst = self.instances.items
        if not inst:
            return Heatmap.not_found(
                grid, query, "object", decay, "no object stands on the map's table", 0.0
            )
        s = m.scores
        best = float(s.max())
        conf, found = judge("object", best)
        if not found:
            k = int(np.argmax(s))
            what = f"{m.colour} " if m.colour else ""
            return Heatmap.not_found(
                grid,
                query,
                "object",
                decay,
                f"no {what}{' / '.join(m.names)} in the map: the best instance scores {best:.2f} "
                f"(looks like {m.names[0] if m.kind[k] > 0.5 else 'something else'}"
                f"{f', colour fit {m.colour_match[k]:.2f}' if m.colour else ''}; "
                f"confidence {conf:.2f})",
                best,
            )
        r = m.ranked
        if not r.max() > 0:  # every preferred name's weight underflowed: rank by the evidence
            r = s
        lin = self.voxels.linear_indices
        keep = np.nonzero(r >= self.config.keep_ratio * float(r.max()))[0]
        if sup is not None:
            value = np.array([sup.sign * superlative_measure(inst[i], sup) for i in keep])
            order = np.argsort(-value)
            if len(keep) > 1 and _alike(value[order[0]], value[order[1]], sup.measure):
                return Heatmap.not_found(
                    grid, query, "object", decay,
                    f"{sup.word!r} picks none of the {len(keep)} things the words name: the "
                    f"first two are alike by it ({SUPERLATIVE_TIES[sup.measure][1]}); name the "
                    "one meant by its colour or by a thing near it", best,
                )  # fmt: skip
            keep = keep[[int(order[0])]]
        rows = np.concatenate([inst[i].rows for i in keep])
        values = point_heatmap_3d_at(grid, grid.unravel(lin[rows]), decay)
        return Heatmap(grid, values, query, "object", decay, conf, True, "", best)

    def _voxel_heatmap(self, query: str, decay: float, judge: Judge) -> Heatmap:
        grid = self.voxels.grid
        s, beats = self.scores(query)
        cand = np.nonzero(beats)[0]
        if not len(cand):
            return Heatmap.not_found(
                grid,
                query,
                "object",
                decay,
                f"no voxel matches {query!r} better than the background",
            )
        best = float(s[cand].max())
        margin = best - float(np.median(s))
        keep = cand[s[cand] >= best - self.config.select_margin * margin]
        values = point_heatmap_3d_at(grid, grid.unravel(self.voxels.linear_indices[keep]), decay)
        conf, found = judge("object", margin)
        reason = "" if found else f"best match {best:.2f} is weak (confidence {conf:.2f})"
        return Heatmap(grid, values, query, "object", decay, conf, found, reason, margin)


#: A voxel's score must beat its best background concept by more than this to count.
BACKGROUND_TIE = 1e-4

#: A palette colour covering less of an instance than this share does not speak for it.
PALETTE_MIN_SHARE = 0.25


def _names_a_word_of(content: list[str], name: str, vocabulary) -> bool:
    """Whether a word of ``content`` is a word of ``name`` and of no other vocabulary name."""
    return any(
        w in name.split() and not any(w in other.split() for other in vocabulary if other != name)
        for w in content
    )


def _said(words: str) -> str:
    """The words as the kind reader learnt names: after "the" ("puck block" -> "the puck
    block")."""
    return "the " + re.sub(r"^(?:the|a|an)\s+", "", words)


def _compound_before(colour: str) -> bool:
    """Whether a hyphenated word before the colour phrase's last word holds a word that names
    no colour ("navy-flag red": "flag"): a thing's compound naming a shade, not two colours."""
    tokens = colour.lower().split()[:-1]
    names = survey_colours()
    return any(
        "-" in t and any(p and not colour_word(p) and p not in names for p in t.split("-"))
        for t in tokens
    )


def _shade_of_basic(name: str) -> bool:
    """Whether a survey colour name is a basic colour term after a word that names no colour
    ("pale red", "pure blue"; not "blue purple", "rust red")."""
    words = name.split()
    return (
        len(words) == 2
        and words[1] in BASIC_COLOURS
        and words[0] not in BASIC_COLOURS
        and not colour_word(words[0])
    )


def _colour_of_a_part(query: str, colour: str) -> bool:
    """Whether the query's colour phrase describes a part of the thing: it follows "with" or
    "having" ("the ball with black pentagons", "a mug with a red handle")."""
    words = str(query).lower().replace("-", " ").split()
    first = colour.replace("-", " ").split()[0] if colour else ""
    if first not in words:
        return False
    at = words.index(first)
    return any(w in ("with", "having") for w in words[:at])


def _palette_parts(inst: ObjectInstance) -> tuple[np.ndarray, np.ndarray]:
    """((k, 3) CIELAB, (k,) shares): the instance's palette colours that cover at least
    :data:`PALETTE_MIN_SHARE` of it."""
    big = inst.palette_share >= PALETTE_MIN_SHARE
    return inst.palette[big], inst.palette_share[big]


#: Two things a superlative cannot tell apart: (how alike by its measure, as said) — volumes
#: within 15 % of the larger, tops, sides or distances within 1.5 cm (about a voxel and a half:
#: what a map of identical things measures differently).
SUPERLATIVE_TIES = {
    "size": (0.15, "volumes within 15 %"),
    "height": (0.015, "tops within 1.5 cm"),
    "left": (0.015, "within 1.5 cm across the table"),
    "reach": (0.015, "within 1.5 cm of the same distance"),
}


def _alike(a: float, b: float, measure: str) -> bool:
    """Whether two superlative values (signed, :func:`superlative_measure`) are a tie."""
    tol = SUPERLATIVE_TIES[measure][0]
    if measure == "size":
        return abs(a - b) <= tol * max(abs(a), abs(b))
    return abs(a - b) <= tol


def superlative_measure(inst: ObjectInstance, sup: Superlative) -> float:
    """What a superlative ranks an instance by
    (:data:`~tabletop.reader.lexicon.words.SUPERLATIVES`): its box's volume [m^3], its top [m],
    how far left it stands (+y [m]), or its horizontal distance [m] from the superlative's
    viewpoint."""
    if sup.measure == "size":
        return float(np.prod(inst.extent))
    if sup.measure == "height":
        return float(inst.hi[2])
    if sup.measure == "left":
        return float(inst.center[1])
    if sup.measure == "reach":
        return float(np.hypot(*(inst.center[:2] - np.asarray(sup.viewpoint, float))))
    raise ConfigError(
        f"unknown superlative measure {sup.measure!r}; valid: size, height, left, reach"
    )


def check_viewpoint(viewpoint) -> tuple[float, float]:
    """``viewpoint`` as (x, y) [m]; ConfigError for anything else."""
    try:
        xy = np.asarray(viewpoint, float).reshape(-1)
    except (TypeError, ValueError):
        xy = np.zeros(0)
    if xy.shape not in ((2,), (3,)) or not np.isfinite(xy).all():
        raise ConfigError(f"a viewpoint is finite (x, y) or (x, y, z) in metres, got {viewpoint!r}")
    return float(xy[0]), float(xy[1])

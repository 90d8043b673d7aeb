"""The sound bank: labelled, captioned, licensed sound clips with a train / held-out split.

The shipped bank lives in ``tabletop/data/sounds/`` (``manifest.json`` + ``clips/*.wav``, built
by ``tools/build_sound_bank.py``; see ``docs/sound_bank.md``). Users who have the ESC-50 data set
can load it instead with :func:`tabletop.sim.esc50.load_esc50`.

A clip's audio is mono float32 in [-1, 1] at the bank's sample rate [Hz]. A category is a short
snake_case name ("dog", "clock_alarm"); its caption is the phrase a sound query is matched
against ("the sound of a dog barking").
"""

from __future__ import annotations

import difflib
import functools
import json
import re
import tomllib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from tabletop.audio import loudest_window, read_wav, resample
from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR

__all__ = [
    "CAPTIONS",
    "CAPTIONS_PATH",
    "DEFAULT_BANK_DIR",
    "OUT_OF_BANK_DIR",
    "SPLITS",
    "SoundBank",
    "SoundClip",
    "caption_for",
    "is_category_name",
]

#: Where the shipped bank lives.
DEFAULT_BANK_DIR = DATA_DIR / "sounds"
#: The out-of-bank set: recordings of sound categories the bank lacks, in the bank's format,
#: every clip "heldout". It is for evaluation only (hearing sounds never taught) and must never
#: be trained on.
OUT_OF_BANK_DIR = DEFAULT_BANK_DIR / "out_of_bank"
#: The two splits: clips for training encoders, and clips no training ever sees.
SPLITS = ("train", "heldout")
#: The caption table: category -> caption, for all 50 ESC-50 categories and the shipped bank's.
CAPTIONS_PATH = DEFAULT_BANK_DIR / "captions.toml"
MANIFEST_FORMAT = "tabletop-sound-bank"
MANIFEST_VERSION = 1

_CATEGORY_RE = re.compile(r"^[a-z0-9]+(_[a-z0-9]+)*$")


def is_category_name(name: str) -> bool:
    """Whether ``name`` is a category name: snake_case of ``[a-z0-9]`` ("dog", "clock_alarm")."""
    return bool(_CATEGORY_RE.match(name))


def _load_captions(path: Path) -> Mapping[str, str]:
    """The caption table of ``path`` (TOML: ``category = "caption"`` lines), read-only."""
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise AssetError(f"sound caption table {path} is unreadable: {e}") from None
    bad = [k for k, v in doc.items() if not is_category_name(k) or not isinstance(v, str)]
    if bad:
        raise AssetError(f'{path}: entries {bad} are not `snake_case_category = "caption"` lines')
    return MappingProxyType(doc)


#: Captions of the ESC-50 categories and of the shipped bank's extra ones (read once from
#: :data:`CAPTIONS_PATH`). Other categories get "the sound of <category with spaces>".
CAPTIONS: Mapping[str, str] = _load_captions(CAPTIONS_PATH)


def caption_for(category: str) -> str:
    """The caption of ``category``: from :data:`CAPTIONS`, else "the sound of <category>"."""
    if category in CAPTIONS:
        return CAPTIONS[category]
    return "the sound of " + category.replace("_", " ").replace("-", " ").strip()


@dataclass(frozen=True)
class SoundClip:
    """One sound clip of a bank, with where it came from and under which licence."""

    id: str
    """Unique within its bank, e.g. "dog-scratch-dog1" or "esc50-1-100032-A-0"."""
    category: str
    """Snake_case category name, e.g. "dog"."""
    caption: str
    """Natural-language description of the category, e.g. "the sound of a dog barking"."""
    path: Path
    """The WAV file (integer PCM, any rate and channel count)."""
    sample_rate: int
    """Rate [Hz] of the audio :meth:`load` returns (the file is resampled if it differs)."""
    duration_s: float
    """Length [s] of the audio :meth:`load` returns."""
    licence: str
    """SPDX licence identifier of the clip, e.g. "CC-BY-SA-3.0"; "NOASSERTION" if unknown."""
    source: str
    """Where the clip came from: a Debian/PyPI package name, or "ESC-50"."""
    author: str
    """Author(s) or copyright holder(s) as the source records them; "" if unknown."""
    split: str
    """"train" or "heldout" (never used in training)."""
    source_version: str = ""
    """Version of the source package ("" if not applicable)."""
    source_path: str = ""
    """The original file inside the source (installed path or data-set file name)."""
    max_duration_s: float | None = None
    """If set, :meth:`load` keeps only the loudest window of this length [s]."""

    def __post_init__(self) -> None:
        if self.split not in SPLITS:
            raise ConfigError(
                f"clip {self.id!r}: split must be one of {SPLITS}, not {self.split!r}"
            )
        if not is_category_name(self.category):
            raise ConfigError(
                f"clip {self.id!r}: category must be snake_case ([a-z0-9_]), got {self.category!r}"
            )
        if int(self.sample_rate) != self.sample_rate or self.sample_rate <= 0:
            raise ConfigError(f"clip {self.id!r}: sample_rate must be a positive integer [Hz]")
        if not self.duration_s > 0:
            raise ConfigError(f"clip {self.id!r}: duration_s must be > 0, got {self.duration_s}")
        if self.max_duration_s is not None and not self.max_duration_s > 0:
            raise ConfigError(f"clip {self.id!r}: max_duration_s must be > 0 or None")
        object.__setattr__(self, "path", Path(self.path))

    def load(self) -> np.ndarray:
        """The clip's audio: (S,) float32 mono in [-1, 1] at :attr:`sample_rate` Hz (a copy)."""
        audio, rate = read_wav(self.path)
        if rate != self.sample_rate:
            audio = resample(audio, rate, self.sample_rate)
        if self.max_duration_s is not None:
            audio = loudest_window(audio, self.sample_rate, self.max_duration_s)
        return np.clip(audio, -1.0, 1.0).astype(np.float32)


class SoundBank:
    """A set of :class:`SoundClip` grouped by category, each category with one caption."""

    def __init__(
        self,
        clips: Iterable[SoundClip],
        *,
        sample_rate: int,
        captions: Mapping[str, str] | None = None,
        name: str = "custom",
        scan_categories: Iterable[str] | None = None,
    ) -> None:
        self._clips: tuple[SoundClip, ...] = tuple(clips)
        self.name = str(name)
        self.scan_categories = frozenset(scan_categories) if scan_categories is not None else None
        """The categories a scan may insert (None: any). The shipped bank pins them
        (``scan_categories.toml``) so that growing the bank leaves every seeded scan, and so
        every suite generated from one, as it was."""
        self._sample_rate = int(sample_rate)
        if not self._clips:
            raise ConfigError(f"sound bank {self.name!r} has no clips")
        by_id: dict[str, SoundClip] = {}
        for c in self._clips:
            if not isinstance(c, SoundClip):
                raise ConfigError(f"a sound bank holds SoundClip values, got {type(c).__name__}")
            if c.id in by_id:
                raise ConfigError(f"sound bank {self.name!r}: clip id {c.id!r} appears twice")
            if c.sample_rate != self._sample_rate:
                raise ConfigError(
                    f"clip {c.id!r} is at {c.sample_rate} Hz; the bank is at {self._sample_rate} Hz"
                )
            by_id[c.id] = c
        self._by_id = by_id
        cats = sorted({c.category for c in self._clips})
        given = dict(captions or {})
        self._captions = {c: given.get(c) or caption_for(c) for c in cats}
        for c in self._clips:
            if c.caption != self._captions[c.category]:
                raise ConfigError(
                    f"clip {c.id!r} has caption {c.caption!r}; its category {c.category!r} "
                    f"has {self._captions[c.category]!r}"
                )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def default(cls) -> SoundBank:
        """The bank shipped in ``tabletop/data/sounds`` (loaded once, then shared)."""
        return _default_bank()

    @classmethod
    def out_of_bank(cls) -> SoundBank:
        """The out-of-bank set shipped in ``tabletop/data/sounds/out_of_bank``: categories the
        bank lacks, for evaluation only (loaded once, then shared)."""
        return _out_of_bank()

    @classmethod
    def from_manifest(cls, path: str | Path) -> SoundBank:
        """Load a bank from its ``manifest.json`` (format in ``docs/sound_bank.md``)."""
        return _load_manifest(Path(path))

    # ------------------------------------------------------------------ queries
    @property
    def sample_rate(self) -> int:
        """Rate [Hz] of every clip's loaded audio."""
        return self._sample_rate

    @property
    def categories(self) -> list[str]:
        """Category names, sorted."""
        return list(self._captions)

    def __len__(self) -> int:
        return len(self._clips)

    def __iter__(self) -> Iterator[SoundClip]:
        return iter(self._clips)

    def __repr__(self) -> str:
        return (
            f"SoundBank(name={self.name!r}, {len(self._clips)} clips, "
            f"{len(self._captions)} categories, {self._sample_rate} Hz)"
        )

    def _check_category(self, category: str) -> None:
        if category not in self._captions:
            close = difflib.get_close_matches(str(category), self.categories, n=3)
            hint = f"; did you mean {close}?" if close else ""
            raise ConfigError(
                f"no sound category {category!r} in bank {self.name!r}{hint} "
                f"available: {self.categories}"
            )

    def clips(self, category: str | None = None, split: str | None = None) -> list[SoundClip]:
        """Clips in bank order, optionally only one ``category`` and/or one ``split``."""
        if category is not None:
            self._check_category(category)
        if split is not None and split not in SPLITS:
            raise ConfigError(f"split must be one of {SPLITS} or None (both), not {split!r}")
        return [
            c
            for c in self._clips
            if (category is None or c.category == category) and (split is None or c.split == split)
        ]

    def caption(self, category: str) -> str:
        """The natural-language caption of ``category``."""
        self._check_category(category)
        return self._captions[category]

    @property
    def captions(self) -> dict[str, str]:
        """Category -> caption (a copy)."""
        return dict(self._captions)

    def get(self, clip_id: str) -> SoundClip:
        """The clip with this id."""
        try:
            return self._by_id[clip_id]
        except KeyError:
            close = difflib.get_close_matches(str(clip_id), list(self._by_id), n=5)
            hint = f"; closest: {close}" if close else ""
            raise ConfigError(
                f"no clip {clip_id!r} in bank {self.name!r} ({len(self._clips)} clips){hint}"
            ) from None

    # ------------------------------------------------------------------ summaries
    def summary(self) -> dict:
        """A JSON-ready summary: counts per category and split, licences, sources, total length."""
        cats = {}
        for cat in self.categories:
            clips = self.clips(category=cat)
            cats[cat] = {
                "caption": self._captions[cat],
                "train": sum(c.split == "train" for c in clips),
                "heldout": sum(c.split == "heldout" for c in clips),
                "licences": sorted({c.licence for c in clips}),
            }
        licences: dict[str, int] = {}
        sources: dict[str, int] = {}
        for c in self._clips:
            licences[c.licence] = licences.get(c.licence, 0) + 1
            sources[c.source] = sources.get(c.source, 0) + 1
        return {
            "name": self.name,
            "sample_rate": self._sample_rate,
            "n_clips": len(self._clips),
            "n_categories": len(cats),
            "n_train": sum(c.split == "train" for c in self._clips),
            "n_heldout": sum(c.split == "heldout" for c in self._clips),
            "total_duration_s": round(sum(c.duration_s for c in self._clips), 3),
            "categories": cats,
            "licences": dict(sorted(licences.items())),
            "sources": dict(sorted(sources.items())),
        }


# --------------------------------------------------------------------------- manifest
_CLIP_KEYS = (
    "id",
    "category",
    "file",
    "duration_s",
    "sample_rate",
    "licence",
    "source_package",
    "source_version",
    "source_path",
    "author",
    "split",
)


def _load_manifest(path: Path) -> SoundBank:
    if not path.is_file():
        raise AssetError(f"sound bank manifest not found: {path}")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise AssetError(f"sound bank manifest {path} is unreadable: {e}") from None
    if not isinstance(doc, dict) or doc.get("format") != MANIFEST_FORMAT:
        raise AssetError(f"{path} is not a sound bank manifest (format {MANIFEST_FORMAT!r})")
    if doc.get("version") != MANIFEST_VERSION:
        raise AssetError(
            f"{path}: manifest version {doc.get('version')!r}; this code reads version "
            f"{MANIFEST_VERSION}"
        )
    for key in ("sample_rate", "categories", "clips"):
        if key not in doc:
            raise AssetError(f"{path}: manifest has no {key!r}")
    captions = {cat: entry["caption"] for cat, entry in doc["categories"].items()}
    root = path.parent
    for i, entry in enumerate(doc["clips"]):
        missing = [k for k in _CLIP_KEYS if k not in entry]
        if missing:
            raise AssetError(
                f"{path}: clip #{i} lacks {missing}; required keys: {list(_CLIP_KEYS)}"
            )
    clips = []
    for entry in doc["clips"]:
        cat = entry["category"]
        if cat not in captions:
            raise AssetError(f"{path}: clip {entry['id']!r} has category {cat!r} with no caption")
        clip_path = root / entry["file"]
        if not clip_path.is_file():
            raise AssetError(f"{path}: clip {entry['id']!r} file not found: {clip_path}")
        try:
            clips.append(
                SoundClip(
                    id=entry["id"],
                    category=cat,
                    caption=captions[cat],
                    path=clip_path,
                    sample_rate=int(entry["sample_rate"]),
                    duration_s=float(entry["duration_s"]),
                    licence=entry["licence"],
                    source=entry["source_package"],
                    author=entry["author"],
                    split=entry["split"],
                    source_version=entry["source_version"],
                    source_path=entry["source_path"],
                )
            )
        except ConfigError as e:
            raise AssetError(f"{path}: {e}") from None
    return SoundBank(
        clips, sample_rate=int(doc["sample_rate"]), captions=captions, name=doc.get("name", "")
    )


#: The categories scans insert from the shipped bank (see :attr:`SoundBank.scan_categories`).
SCAN_CATEGORIES_PATH = DEFAULT_BANK_DIR / "scan_categories.toml"


@functools.lru_cache(maxsize=1)
def _default_bank() -> SoundBank:
    bank = _load_manifest(DEFAULT_BANK_DIR / "manifest.json")
    if SCAN_CATEGORIES_PATH.is_file():
        doc = tomllib.loads(SCAN_CATEGORIES_PATH.read_text(encoding="utf-8"))
        pinned = [str(c) for c in doc.get("categories", [])]
        unknown = sorted(set(pinned) - set(bank.categories))
        if unknown:
            raise AssetError(f"{SCAN_CATEGORIES_PATH}: categories {unknown} are not in the bank")
        bank.scan_categories = frozenset(pinned)
    return bank


@functools.lru_cache(maxsize=1)
def _out_of_bank() -> SoundBank:
    return _load_manifest(OUT_OF_BANK_DIR / "manifest.json")

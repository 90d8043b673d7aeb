"""The sound bank: labelled, captioned, licensed sound clips with a train / held-out split.

The shipped bank lives in ``tabletop/data/sounds/`` (``manifest.json`` + ``clips/*.wav``, built
by ``tools/build_sound_bank.py``; see ``docs/sound_bank.md``). Users who have the ESC-50 data set
can load it instead with :func:`load_esc50`.

A clip's audio is mono float32 in [-1, 1] at the bank's sample rate [Hz]. A category is a short
snake_case name ("dog", "clock_alarm"); its caption is the phrase a sound query is matched
against ("the sound of a dog barking").
"""

from __future__ import annotations

import csv
import difflib
import functools
import json
import logging
import re
import wave
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tabletop.errors import AssetError, ConfigError
from tabletop.paths import DATA_DIR
from tabletop.sim.audio import loudest_window, read_wav, resample

__all__ = [
    "CAPTIONS",
    "DEFAULT_BANK_DIR",
    "ESC50_COLUMNS",
    "SPLITS",
    "SoundBank",
    "SoundClip",
    "caption_for",
    "load_esc50",
]

log = logging.getLogger(__name__)

#: Where the shipped bank lives.
DEFAULT_BANK_DIR = DATA_DIR / "sounds"
#: The two splits: clips for training encoders, and clips no training ever sees.
SPLITS = ("train", "heldout")
#: Columns an ESC-50 ``meta/esc50.csv`` must have.
ESC50_COLUMNS = ("filename", "fold", "target", "category", "esc10", "src_file", "take")
MANIFEST_FORMAT = "tabletop-sound-bank"
MANIFEST_VERSION = 1

#: Captions of the ESC-50 categories and of the shipped bank's extra ones. Other categories
#: get "the sound of <category with spaces>".
CAPTIONS: Mapping[str, str] = {
    # ESC-50 (all 50 categories)
    "dog": "the sound of a dog barking",
    "rooster": "the sound of a rooster crowing",
    "pig": "the sound of a pig oinking",
    "cow": "the sound of a cow mooing",
    "frog": "the sound of a frog croaking",
    "cat": "the sound of a cat meowing",
    "hen": "the sound of a hen clucking",
    "insects": "the sound of buzzing insects",
    "sheep": "the sound of a sheep bleating",
    "crow": "the sound of a crow cawing",
    "rain": "the sound of rain falling",
    "sea_waves": "the sound of sea waves",
    "crackling_fire": "the sound of a crackling fire",
    "crickets": "the sound of crickets chirping",
    "chirping_birds": "the sound of birds chirping",
    "water_drops": "the sound of water dripping",
    "wind": "the sound of wind blowing",
    "pouring_water": "the sound of water pouring",
    "toilet_flush": "the sound of a toilet flushing",
    "thunderstorm": "the sound of thunder",
    "crying_baby": "the sound of a baby crying",
    "sneezing": "the sound of someone sneezing",
    "clapping": "the sound of hands clapping",
    "breathing": "the sound of someone breathing",
    "coughing": "the sound of someone coughing",
    "footsteps": "the sound of footsteps",
    "laughing": "the sound of someone laughing",
    "brushing_teeth": "the sound of teeth being brushed",
    "snoring": "the sound of someone snoring",
    "drinking_sipping": "the sound of someone slurping a drink",
    "door_wood_knock": "the sound of knocking on a wooden door",
    "mouse_click": "the sound of a computer mouse clicking",
    "keyboard_typing": "the sound of typing on a keyboard",
    "door_wood_creaks": "the sound of a wooden door creaking",
    "can_opening": "the sound of a can being opened",
    "washing_machine": "the sound of a washing machine",
    "vacuum_cleaner": "the sound of a vacuum cleaner",
    "clock_alarm": "the sound of an alarm clock ringing",
    "clock_tick": "the sound of a clock ticking",
    "glass_breaking": "the sound of glass breaking",
    "helicopter": "the sound of a helicopter",
    "chainsaw": "the sound of a chainsaw",
    "siren": "the sound of a siren",
    "car_horn": "the sound of a car horn honking",
    "engine": "the sound of an engine running",
    "train": "the sound of a train",
    "church_bells": "the sound of church bells ringing",
    "airplane": "the sound of an airplane flying",
    "fireworks": "the sound of fireworks exploding",
    "hand_saw": "the sound of a hand saw cutting wood",
    # extra categories of the shipped bank
    "duck": "the sound of a duck quacking",
    "horse": "the sound of a horse neighing",
    "owl": "the sound of an owl hooting",
    "goose": "the sound of a goose honking",
    "monkey": "the sound of a monkey chattering",
    "wolf": "the sound of a wolf howling",
    "elephant": "the sound of an elephant trumpeting",
    "lion": "the sound of a lion roaring",
    "water": "the sound of splashing, dripping water",
    "telephone": "the sound of a telephone ringing",
    "camera_shutter": "the sound of a camera shutter clicking",
    "zipper": "the sound of a zipper",
    "glass_clinking": "the sound of glass clinking",
    "hammering": "the sound of hammering",
    "scissors": "the sound of scissors snipping",
    "dice": "the sound of dice rolling",
    "writing": "the sound of writing with a pen or chalk",
    "trumpet": "the sound of a trumpet playing",
    "guitar": "the sound of a guitar playing",
    "piano": "the sound of a piano playing",
    "violin": "the sound of a violin playing",
    "drums": "the sound of drums playing",
    "cymbals": "the sound of a cymbal crashing",
    "xylophone": "the sound of a xylophone playing",
    "flute": "the sound of a flute playing",
}

_CATEGORY_RE = re.compile(r"^[a-z0-9]+(_[a-z0-9]+)*$")


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
        if not _CATEGORY_RE.match(self.category):
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
    ) -> None:
        self._clips: tuple[SoundClip, ...] = tuple(clips)
        self.name = str(name)
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

    def format_table(self) -> str:
        """A human-readable table: one row per category (clips per split, licences, caption)."""
        s = self.summary()
        width = max(len("category"), *(len(c) for c in s["categories"]))
        lines = [
            f"sound bank {s['name']!r}: {s['n_clips']} clips in {s['n_categories']} categories "
            f"({s['n_train']} train, {s['n_heldout']} heldout), {s['sample_rate']} Hz mono, "
            f"{s['total_duration_s']:.1f} s in all",
            "",
            f"{'category':<{width}}  train  heldout  licences / caption",
        ]
        for cat, row in s["categories"].items():
            lines.append(
                f"{cat:<{width}}  {row['train']:>5}  {row['heldout']:>7}  "
                f"{', '.join(row['licences'])} / {row['caption']}"
            )
        lines += ["", "licences:"]
        lines += [f"  {lic:<20} {n:>4} clips" for lic, n in s["licences"].items()]
        lines += ["sources:"]
        lines += [f"  {src:<28} {n:>4} clips" for src, n in s["sources"].items()]
        return "\n".join(lines)


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


@functools.lru_cache(maxsize=1)
def _default_bank() -> SoundBank:
    return _load_manifest(DEFAULT_BANK_DIR / "manifest.json")


# --------------------------------------------------------------------------- ESC-50
def _wav_info(path: Path) -> tuple[int, int]:
    """(n_frames, sample_rate) of a PCM WAV, or AssetError."""
    try:
        with wave.open(str(path), "rb") as w:
            return w.getnframes(), w.getframerate()
    except (wave.Error, EOFError, OSError) as e:
        raise AssetError(f"{path} is not a readable PCM WAV file ({e})") from None


def load_esc50(
    directory: str | Path,
    *,
    sample_rate: int = 16000,
    heldout_folds: Sequence[int] = (5,),
    max_duration_s: float | None = None,
    categories: Sequence[str] | None = None,
) -> SoundBank:
    """A bank of a local ESC-50-format data set: ``audio/*.wav`` and ``meta/esc50.csv``.

    The CSV needs the columns of :data:`ESC50_COLUMNS` (``filename``, ``fold`` in 1..5,
    ``target``, ``category``, ``esc10``, ``src_file``, ``take``). Clips in ``heldout_folds``
    form the "heldout" split, the rest "train". Clips are resampled to ``sample_rate`` [Hz] when
    loaded; with ``max_duration_s`` only their loudest window of that length [s] is kept.
    ``categories`` keeps only those categories. Captions come from :data:`CAPTIONS`.
    Licences are recorded as "NOASSERTION": ESC-50 carries its own licence terms.
    """
    root = Path(directory)
    if not root.is_dir():
        raise AssetError(
            f"ESC-50 directory not found: {root}; expected audio/*.wav and meta/esc50.csv in it"
        )
    meta = root / "meta" / "esc50.csv"
    if not meta.is_file():
        raise AssetError(f"ESC-50 metadata not found: {meta} (expected meta/esc50.csv)")
    audio_dir = root / "audio"
    if not audio_dir.is_dir():
        raise AssetError(f"ESC-50 audio directory not found: {audio_dir} (expected audio/*.wav)")
    rate = int(sample_rate)
    if rate != sample_rate or not 1000 <= rate <= 384_000:
        raise ConfigError(f"sample_rate must be an integer in [1000, 384000] Hz, got {sample_rate}")
    folds = {int(f) for f in heldout_folds}
    if not folds <= {1, 2, 3, 4, 5}:
        raise ConfigError(f"heldout_folds must be among ESC-50's folds 1..5, got {sorted(folds)}")
    if max_duration_s is not None and not max_duration_s > 0:
        raise ConfigError(f"max_duration_s must be > 0 or None, got {max_duration_s}")
    wanted = None if categories is None else set(categories)

    with meta.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header = reader.fieldnames or []
        missing = [c for c in ESC50_COLUMNS if c not in header]
        if missing:
            raise AssetError(
                f"{meta} lacks column(s) {missing}; an ESC-50 CSV has {list(ESC50_COLUMNS)}, "
                f"this one has {header}"
            )
        rows = list(reader)
    if not rows:
        raise AssetError(f"{meta} lists no clips")

    clips = []
    absent = []
    seen_categories = set()
    for line, row in enumerate(rows, start=2):
        cat = (row["category"] or "").strip()
        if not _CATEGORY_RE.match(cat):
            raise AssetError(f"{meta}:{line}: category {cat!r} is not a snake_case name")
        seen_categories.add(cat)
        if wanted is not None and cat not in wanted:
            continue
        try:
            fold = int(row["fold"])
        except (TypeError, ValueError):
            fold = -1
        if fold not in (1, 2, 3, 4, 5):
            raise AssetError(f"{meta}:{line}: fold must be 1..5, got {row['fold']!r}")
        name = (row["filename"] or "").strip()
        wav = audio_dir / name
        if not name or not wav.is_file():
            absent.append(name or f"<empty filename on line {line}>")
            continue
        n_frames, file_rate = _wav_info(wav)
        if n_frames == 0:
            raise AssetError(f"{wav} holds no samples")
        duration = round(n_frames * rate / file_rate) / rate
        if max_duration_s is not None:
            duration = min(duration, round(max_duration_s * rate) / rate)
        clips.append(
            SoundClip(
                id="esc50-" + Path(name).stem,
                category=cat,
                caption=caption_for(cat),
                path=wav,
                sample_rate=rate,
                duration_s=duration,
                licence="NOASSERTION",
                source="ESC-50",
                author="",
                split="heldout" if fold in folds else "train",
                source_path=name,
                max_duration_s=max_duration_s,
            )
        )
    if absent:
        shown = ", ".join(absent[:5]) + (f" and {len(absent) - 5} more" if len(absent) > 5 else "")
        raise AssetError(
            f"{len(absent)} clip(s) listed in {meta} are missing from {audio_dir}: {shown}"
        )
    if wanted is not None and not wanted <= seen_categories:
        raise ConfigError(
            f"categories {sorted(wanted - seen_categories)} are not in {meta}; "
            f"available: {sorted(seen_categories)}"
        )
    log.info("loaded %d ESC-50 clips from %s", len(clips), root)
    return SoundBank(clips, sample_rate=rate, name=f"ESC-50 ({root.name})")

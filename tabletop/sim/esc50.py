"""The ESC-50 adapter: a local ESC-50-format data set as a :class:`~tabletop.sim.SoundBank`.

ESC-50 (Piczak, 2015) holds 2000 five-second clips in 50 categories and five folds:
``audio/*.wav`` and ``meta/esc50.csv``. It is not shipped; users who have it load it with
:func:`load_esc50` (``tabletop sounds --esc50 DIR`` describes it).
"""

from __future__ import annotations

import csv
import logging
import wave
from collections.abc import Sequence
from pathlib import Path

from tabletop.errors import AssetError, ConfigError
from tabletop.sim.sound_bank import SoundBank, SoundClip, caption_for, is_category_name

__all__ = ["ESC50_COLUMNS", "load_esc50"]

log = logging.getLogger(__name__)

#: Columns an ESC-50 ``meta/esc50.csv`` must have.
ESC50_COLUMNS = ("filename", "fold", "target", "category", "esc10", "src_file", "take")


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
    ``categories`` keeps only those categories. Captions come from
    :data:`~tabletop.sim.sound_bank.CAPTIONS`.
    Licences are recorded as "NOASSERTION": ESC-50 carries its own licence terms.
    """
    if not str(directory).strip():
        raise AssetError(
            f"ESC-50 directory is empty ({str(directory)!r}): give a directory with "
            "audio/*.wav and meta/esc50.csv in it"
        )
    root = Path(directory)
    if not root.is_dir():
        what = "is a file, not a directory" if root.exists() else "not found"
        raise AssetError(
            f"ESC-50 directory {what}: {root}; expected a directory with audio/*.wav and "
            "meta/esc50.csv in it"
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
        if not is_category_name(cat):
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

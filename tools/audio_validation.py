"""A validation run of an audio training recipe, for choosing one without the held-out clips.

The bank's held-out clips are not loaded. Of its training clips, the last (in bank order) of
every category with at least three training clips is a validation clip (52 of 313 on the
shipped bank); the recipe trains on the others, and :func:`tabletop.train.audio.evaluate_audio`
measures it on the validation clips (its ``*_heldout`` figures are then validation figures).

Usage (``--set`` overrides fields of :class:`tabletop.train.audio.AudioTrainConfig`, as JSON)::

    python tools/audio_validation.py --out out/audval/cheap.pt \\
        --set '{"n_mels": 64, "max_segment_s": 1.5}'

The 64-band, 1.5 s recipe takes about 1.2 s per step on one CPU thread (3000 steps: about an
hour), the committed recipe (128 bands, 3 s) about 5 s. The figures are logged at the end and
stored in the checkpoint's ``meta["heldout"]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging

from tabletop.sim.sound_bank import SoundBank
from tabletop.train.audio import AudioTrainConfig, train_audio


def validation_bank(base: SoundBank, min_train: int = 3) -> SoundBank:
    """``base``'s training clips, the last of each category with ``min_train`` or more of them
    marked "heldout" (the validation clips); ``base``'s own held-out clips left out."""
    train = [c for c in base.clips() if c.split == "train"]
    by_category: dict[str, list] = {}
    for c in train:
        by_category.setdefault(c.category, []).append(c)
    val = {v[-1].id for v in by_category.values() if len(v) >= min_train}
    clips = [dataclasses.replace(c, split="heldout" if c.id in val else "train") for c in train]
    captions = {k: base.caption(k) for k in base.categories}
    return SoundBank(clips, sample_rate=base.sample_rate, captions=captions, name="validation")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="checkpoint to write")
    ap.add_argument("--set", default="{}", help="AudioTrainConfig fields as JSON")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    overrides = json.loads(args.set)
    cfg = AudioTrainConfig(out=args.out, n_threads=args.threads, **overrides)
    train_audio(cfg, bank=validation_bank(SoundBank.default()))


if __name__ == "__main__":
    main()

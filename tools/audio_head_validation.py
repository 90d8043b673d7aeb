"""Choose the YAMNet head's recipe on a validation split carved from the training clips.

The bank's held-out clips are never loaded: :func:`tabletop.train.audio_head.validation_bank`
marks the last training clip of every category with three or more as a validation clip, the
head trains on the others, and :func:`tabletop.train.audio.evaluate_audio` measures it on the
validation clips (its ``*_heldout`` figures are then validation figures).

Usage (``--set`` overrides fields of :class:`tabletop.train.audio_head.HeadTrainConfig`)::

    python tools/audio_head_validation.py --out out/audval/head.npz --set '{"copies": 8}'

With ``--tune-tail`` (``--tail-set`` overrides fields of
:class:`tabletop.train.audio_tail.TailTrainConfig`), YAMNet's last two blocks are first
fine-tuned on the same training clips and the head reads their embeddings; ``first_layer``
starts the tuned tail at an earlier block (``--tail-set '{"first_layer": 11}'``). The tail's
training figures are kept in the head file's meta (``tail_train``), and a summary (the tail's
figures, the validation figures and the wall time) is written beside the head as
``<stem>_summary.json``.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from dataclasses import asdict, replace
from pathlib import Path

from tabletop.mapping.encoders.yamnet_audio import load_head, save_head
from tabletop.sim.sound_bank import SoundBank
from tabletop.train.audio_head import HeadTrainConfig, train_audio_head, validation_bank


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="head file to write")
    ap.add_argument("--set", default="{}", help="HeadTrainConfig fields as JSON")
    ap.add_argument("--tune-tail", action="store_true", help="fine-tune YAMNet's tail first")
    ap.add_argument("--tail-set", default="{}", help="TailTrainConfig fields as JSON")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    bank = validation_bank(SoundBank.default())
    t0 = time.perf_counter()
    extra, tail_info = {}, None
    if args.tune_tail:
        from tabletop.train.audio_tail import TailTrainConfig, train_tail

        tail_cfg = TailTrainConfig(**json.loads(args.tail_set))
        extra["tail"] = Path(args.out).with_name(Path(args.out).stem + "_tail.npz")
        tail_info = {**train_tail(bank, extra["tail"], tail_cfg), "config": asdict(tail_cfg)}
    cfg = HeadTrainConfig(out=args.out, **json.loads(args.set), **extra)
    path = train_audio_head(cfg, bank=bank)
    head = load_head(path)
    if tail_info is not None:  # the head's file says how its tail was tuned
        save_head(path, replace(head, meta={**head.meta, "tail_train": tail_info}))
    figures = {k: v for k, v in head.meta["heldout"].items() if k.startswith("audio_")}
    summary = {"tail": tail_info, "validation": figures, "wall_s": time.perf_counter() - t0}
    summary["wall_s"] = round(summary["wall_s"], 1)
    Path(path).with_name(Path(path).stem + "_summary.json").write_text(
        json.dumps(summary, indent=1) + "\n"
    )
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()

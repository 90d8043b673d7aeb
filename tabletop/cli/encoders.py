"""``tabletop train`` and ``tabletop check-encoders``: retrain an embedded default encoder,
measure the committed ones on held-out data."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

from tabletop.cli.output import stdout_to_stderr

__all__ = ["TRAIN_OUT", "add_commands", "cmd_check_encoders", "cmd_train"]

TRAIN_OUT = {"audio": Path("out/weights/audio.pt"), "vision": Path("out/weights/vision_dense.pt")}
"""Where ``tabletop train WHAT`` writes its weights unless given ``--out``."""
_SHIPPED = {
    "audio": "tabletop/data/weights/audio.pt",
    "vision": "tabletop/data/weights/vision_dense.pt",
}


def cmd_check_encoders(args: argparse.Namespace) -> int:
    """Measure the committed weights on held-out data (figures are null where a learned
    encoder does not exist yet: never a stand-in value)."""
    from tabletop.train.audio import evaluate_audio

    out = {"vision_top1_heldout": None, "vision_miou_heldout": None, "vision_synonym_top1": None}
    try:
        from tabletop.train.vision import evaluate_vision
    except ImportError:
        evaluate_vision = None

    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        if evaluate_vision is not None:
            out.update({k: v for k, v in evaluate_vision().items() if k.startswith("vision_")})
        a = evaluate_audio()
    out.update({k: v for k, v in a.items() if k.startswith("audio_")})
    out["encoders"] = "embedded default (learned; held-out data)"
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    for k, v in out.items():
        shown = (
            "not available in this version"
            if v is None
            else (f"{v:.3f}" if isinstance(v, float) else v)
        )
        print(f"{k:36s} {shown}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    out = Path(args.out) if args.out is not None else TRAIN_OUT[args.what]
    if args.what == "audio":
        from tabletop.train.audio import AudioTrainConfig, train_audio

        path = train_audio(AudioTrainConfig(out=out))
    else:
        try:
            from tabletop.train.vision import VisionTrainConfig, train_vision
        except ImportError:
            print(
                "tabletop train vision: the vision encoder's training is not in this version",
                file=sys.stderr,
            )
            return 2
        path = train_vision(VisionTrainConfig(out=out))
    print(f"weights written: {path}")
    return 0


def add_commands(sub) -> None:
    """Register ``train`` and ``check-encoders`` on the ``tabletop`` sub-command parser."""
    p = sub.add_parser("train", help="train an embedded default encoder (seeded)")
    p.add_argument("what", choices=["audio", "vision"])
    p.add_argument(
        "--out",
        default=None,
        metavar="FILE",
        help="weights file to write (default: "
        + ", ".join(f"{k}: {v}" for k, v in TRAIN_OUT.items())
        + "). The default encoders load the shipped weights: to replace them, pass --out "
        + " or ".join(_SHIPPED.values()),
    )
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("check-encoders", help="measure the committed encoders on held-out data")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_check_encoders)

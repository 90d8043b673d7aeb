"""``tabletop train`` and ``tabletop check-encoders``: retrain an embedded default encoder,
measure the committed ones on held-out data."""

from __future__ import annotations

import argparse
import contextlib
import json
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
    """Measure the committed weights on held-out data."""
    from tabletop.train.audio import evaluate_audio
    from tabletop.train.vision import evaluate_vision

    out = {}
    with stdout_to_stderr() if args.json else contextlib.nullcontext():
        out.update({k: v for k, v in evaluate_vision().items() if k.startswith("vision_")})
        a = evaluate_audio()
    out.update({k: v for k, v in a.items() if k.startswith("audio_")})
    out["encoders"] = "embedded default (learned; held-out data)"
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    for k, v in out.items():
        shown = f"{v:.3f}" if isinstance(v, float) else v
        print(f"{k:36s} {shown}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    out = Path(args.out) if args.out is not None else TRAIN_OUT[args.what]
    if args.what == "audio":
        from tabletop.train.audio import AudioTrainConfig, train_audio

        path = train_audio(AudioTrainConfig(out=out))
    else:
        from tabletop.train.vision import VisionTrainConfig, train_vision

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

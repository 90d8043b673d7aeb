"""Held-out figures of audio encoders on two sound banks: the ablation of a bank build.

Measures, on each bank's held-out clips (and the out-of-bank set beside it), the log-mel network
of the earlier default (``tabletop/data/weights/audio.pt``) and any number of YAMNet heads, each
with the open sound scorer written beside it (``audio_open_scorer.json``, as ``tabletop train
audio`` writes it), and any number of aiSFX heads (``--aisfx-head``: trained with
``HeadTrainConfig(backbone="aisfx")``; no class logits, so their open-vocabulary figures are
left out, "—" in the tables). The keys are ``tabletop check-encoders``'
(``audio_recall1_heldout`` ..., ``audio_open_found``, ``audio_open_refused``), one row per
(bank, encoder). Nothing is trained here, and nothing is chosen on these figures.

Usage (the earlier bank from git, heads trained with ``tabletop train audio --out``)::

    git archive HEAD~1 tabletop/data/sounds | tar -x -C /tmp/old-bank
    OMP_NUM_THREADS=1 python tools/audio_bank_ablation.py \\
        --bank old=/tmp/old-bank/tabletop/data/sounds --bank new=tabletop/data/sounds \\
        --head "without new clips=out/old/audio_yamnet_head.npz" \\
        --head "with new clips=tabletop/data/weights/audio_yamnet_head.npz" \\
        --aisfx-head "aiSFX with new clips=out/heads/aisfx-new/audio_aisfx_head.npz" \\
        --out ablation.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

KEYS = (
    "audio_recall1_heldout",
    "audio_recall3_heldout",
    "audio_paraphrase_recall1_heldout",
    "audio_paraphrase_recall3_heldout",
    "audio_absent_rejected",
    "audio_present_found",
    "audio_open_found",
    "audio_open_refused",
    "n_clips",
    "n_queries",
    "n_open_categories",
    "n_open_clips",
)


def _pair(text: str) -> tuple[str, Path]:
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"expected NAME=PATH, got {text!r}")
    return name, Path(path)


def measure(
    banks: list[tuple[str, Path]],
    heads: list[tuple[str, Path]],
    aisfx_heads: list[tuple[str, Path]] = (),
) -> list[dict]:
    import tabletop.mapping.open_sounds as open_sounds
    from tabletop.mapping.encoders.audio import MelCNNAudioEncoder
    from tabletop.mapping.encoders.yamnet import YamnetBackbone
    from tabletop.mapping.encoders.yamnet_audio import YamnetAudioEncoder
    from tabletop.sim.sound_bank import OUT_OF_BANK_DIR, SoundBank
    from tabletop.train.audio import evaluate_audio
    from tabletop.train.audio_open import evaluate_open_sounds

    backbone = YamnetBackbone(num_threads=1)
    aisfx_backbone = None
    if aisfx_heads:
        from tabletop.mapping.encoders.aisfx_backbone import AisfxBackbone

        aisfx_backbone = AisfxBackbone(num_threads=1)
    rows = []
    shipped_scorer = open_sounds.DEFAULT_OPEN_SCORER
    for bank_name, root in banks:
        bank = SoundBank.from_manifest(root / "manifest.json")
        oob = SoundBank.from_manifest(root / OUT_OF_BANK_DIR.name / "manifest.json")
        fig = evaluate_audio(MelCNNAudioEncoder(), bank)
        rows.append({"bank": bank_name, "encoder": "log-mel network (audio.pt)", **fig})
        for head_name, path in heads:
            scorer = path.with_name("audio_open_scorer.json")
            open_sounds.DEFAULT_OPEN_SCORER = scorer if scorer.is_file() else shipped_scorer
            try:
                enc = YamnetAudioEncoder(path, backbone=backbone)
                fig = evaluate_audio(enc, bank)
                fig.update(evaluate_open_sounds(oob, enc, bank))
            finally:
                open_sounds.DEFAULT_OPEN_SCORER = shipped_scorer
            rows.append({"bank": bank_name, "encoder": f"YAMNet head, {head_name}", **fig})
        for head_name, path in aisfx_heads:
            from tabletop.mapping.encoders.aisfx_audio import AisfxAudioEncoder

            fig = evaluate_audio(AisfxAudioEncoder(path, backbone=aisfx_backbone), bank)
            rows.append({"bank": bank_name, "encoder": f"aiSFX head, {head_name}", **fig})
    return [{k: r[k] for k in ("bank", "encoder", *KEYS) if k in r} for r in rows]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--bank", type=_pair, action="append", required=True, help="NAME=DIR")
    p.add_argument("--head", type=_pair, action="append", default=[], help="NAME=HEAD.npz")
    p.add_argument(
        "--aisfx-head",
        type=_pair,
        action="append",
        default=[],
        help="NAME=HEAD.npz of a head on aiSFX (pip install --no-deps aisfx==0.1.2)",
    )
    p.add_argument("--out", type=Path, help="also write the rows here (JSON)")
    args = p.parse_args(argv)
    rows = measure(args.bank, args.head, args.aisfx_head)
    text = json.dumps(rows, indent=1)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

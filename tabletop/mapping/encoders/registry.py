"""Encoder sets chosen by name: "oracle" (simulator upper bound) and "default" (embedded)."""

from __future__ import annotations

from dataclasses import dataclass

from tabletop.errors import ConfigError

__all__ = ["ENCODER_SETS", "EncoderSet", "make_encoders"]

ENCODER_SETS = ("oracle", "default")


@dataclass(frozen=True)
class EncoderSet:
    text: object
    dense: object
    global_image: object
    audio: object
    names: dict


def make_encoders(name: str, recording=None) -> EncoderSet:
    """The named encoder set. The oracle needs the recording's ground truth."""
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    if name not in ENCODER_SETS:
        raise ConfigError(f"unknown encoder set {name!r}; valid: {list(ENCODER_SETS)}")
    text = MiniLMTextEncoder()
    if name == "oracle":
        from tabletop.mapping.encoders.oracle import (
            OracleAudioEncoder,
            OracleDenseEncoder,
            OracleGlobalImageEncoder,
            oracle_labels,
        )

        gt = getattr(recording, "ground_truth", None)
        if not gt:
            raise ConfigError(
                "the oracle encoders need a simulator recording with ground truth; "
                "use encoders='default' for real data"
            )
        labels = oracle_labels(gt)
        return EncoderSet(
            text,
            OracleDenseEncoder(text, labels),
            OracleGlobalImageEncoder(text, labels),
            OracleAudioEncoder(text, gt.get("sound_events", [])),
            {
                "set": "oracle (simulator upper bound)",
                "text": "minilm-l6-v2",
                "dense": "oracle segmentation labels",
                "global_image": "oracle label mean",
                "audio": "oracle inserted-clip caption",
            },
        )
    raise ConfigError(
        "the 'default' learned encoders are not available yet in this version; use 'oracle'"
    )

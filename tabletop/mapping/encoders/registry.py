"""Encoder sets chosen by name: "oracle" (simulator upper bound) and "default" (embedded)."""

from __future__ import annotations

from dataclasses import dataclass

from tabletop.errors import ConfigError

__all__ = ["ENCODER_SETS", "EncoderSet", "make_encoders", "make_encoders_from_rebuild"]

ENCODER_SETS = ("oracle", "default")


@dataclass(frozen=True)
class EncoderSet:
    """The four encoders of one embedding space, their names for reports, and what a saved
    map must record to re-create them (``rebuild``)."""

    text: object
    dense: object
    global_image: object
    audio: object
    names: dict
    rebuild: dict


def _check_name(name: str) -> None:
    if name not in ENCODER_SETS:
        raise ConfigError(f"unknown encoder set {name!r}; valid: {list(ENCODER_SETS)}")


def make_encoders(name: str, recording=None) -> EncoderSet:
    """The named encoder set. The oracle reads the recording's ground truth."""
    _check_name(name)
    if name == "oracle":
        from tabletop.mapping.encoders.oracle import oracle_labels

        gt = getattr(recording, "ground_truth", None)
        if not gt:
            raise ConfigError(
                "the oracle encoders need a simulator recording with ground truth; "
                "use encoders='default' for real data"
            )
        rebuild = {
            "labels": {str(k): v for k, v in oracle_labels(gt).items()},
            "sound_events": gt.get("sound_events", []),
        }
        return make_encoders_from_rebuild("oracle", rebuild)
    return make_encoders_from_rebuild(name, {})


def make_encoders_from_rebuild(name: str, rebuild: dict) -> EncoderSet:
    """Re-create an encoder set from what a saved map recorded about it."""
    from tabletop.mapping.encoders.minilm import MiniLMTextEncoder

    _check_name(name)
    text = MiniLMTextEncoder()
    if name == "oracle":
        from tabletop.mapping.encoders.oracle import (
            OracleAudioEncoder,
            OracleDenseEncoder,
            OracleGlobalImageEncoder,
        )

        try:
            labels = {int(k): v for k, v in rebuild["labels"].items()}
            events = list(rebuild["sound_events"])
        except (KeyError, AttributeError, ValueError) as e:
            raise ConfigError(f"oracle encoders: rebuild info is incomplete ({e})") from None
        return EncoderSet(
            text,
            OracleDenseEncoder(text, labels, stride=1),
            OracleGlobalImageEncoder(text, labels),
            OracleAudioEncoder(text, events),
            {
                "set": "oracle (simulator upper bound)",
                "text": "minilm-l6-v2",
                "dense": "oracle segmentation labels",
                "global_image": "oracle label mean",
                "audio": "oracle inserted-clip caption",
            },
            {"labels": {str(k): v for k, v in labels.items()}, "sound_events": events},
        )
    raise ConfigError(
        "the 'default' learned encoders are not wired into the map yet in this version; "
        "use 'oracle'"
    )

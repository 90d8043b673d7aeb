"""Encoder sets chosen by name: "oracle" (simulator upper bound) and "default" (embedded)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from tabletop.errors import ConfigError

__all__ = [
    "AUDIO_ENCODERS",
    "ENCODER_SETS",
    "EncoderSet",
    "make_encoders",
    "make_encoders_from_rebuild",
]

ENCODER_SETS = ("oracle", "default", "openclip")
#: Audio encoders of the default set: frozen YAMNet with a trained head (the default), or the
#: log-mel network trained from the sound bank alone (``tabletop/data/weights/audio.pt``).
AUDIO_ENCODERS = ("yamnet", "melcnn")


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
    audio_text: object = None
    """Text encoder of sound queries when the audio encoder has its own space (CLAP); None =
    ``text``."""


def _check_name(name: str) -> None:
    if name not in ENCODER_SETS:
        raise ConfigError(f"unknown encoder set {name!r}; valid: {list(ENCODER_SETS)}")


def make_encoders(name: str, recording=None, options: dict | None = None) -> EncoderSet:
    """The named encoder set. The oracle reads the recording's ground truth; ``options``
    (default set: ``vision_weights``, ``audio_weights`` paths override the committed weights;
    ``vision_upscale`` (1 or 2) enlarges images before the network (``MapConfig.image_scale``);
    ``vision_network`` names the committed network, "table" or "room" (``MapConfig.image_network``);
    ``audio_encoder`` is one of :data:`AUDIO_ENCODERS`, default ``"yamnet"``;
    ``vision_backend`` is one of :data:`~tabletop.mapping.encoders.lseg.BACKENDS`, default
    ``"auto"``)."""
    _check_name(name)
    if name == "default":  # a fresh map hears through the YAMNet head unless told otherwise
        options = {"audio_encoder": "yamnet", **dict(options or {})}
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
    return make_encoders_from_rebuild(name, dict(options or {}))


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
        except (KeyError, AttributeError, ValueError, TypeError) as e:
            raise ConfigError(f"oracle encoders: rebuild info is incomplete ({e})") from None
        if not all(0 <= k < 65536 and isinstance(v, str) and v for k, v in labels.items()):
            raise ConfigError(
                "oracle encoders: rebuild labels must map instance ids 0..65535 to names"
            )

        def event_ok(e) -> bool:
            if not isinstance(e, dict) or not isinstance(e.get("caption"), str):
                return False
            t = (e.get("onset_s"), e.get("offset_s"))
            return all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                for x in t
            )

        if not all(event_ok(e) for e in events):
            raise ConfigError(
                "oracle encoders: rebuild sound_events must be {caption, onset_s, offset_s, ...}"
            )
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
    if name == "default":
        from tabletop.mapping.encoders.lseg import LSegEncoder

        network = rebuild.get("vision_network") or "table"  # MapConfig.image_network
        vision_w = rebuild.get("vision_weights") or str(vision_network_path(network))
        # "int8": the quantised graph (faster, other embeddings); recorded only when asked
        backend = rebuild.get("vision_backend") or "auto"
        upscale = rebuild.get("vision_upscale") or 1  # MapConfig.image_scale
        image = LSegEncoder(vision_w, backend=backend, upscale=upscale)  # dense and global
        # a map saved before the YAMNet head recorded no audio encoder: it heard with the CNN
        kind = rebuild.get("audio_encoder") or "melcnn"
        audio, audio_w, audio_name = _default_audio(kind, rebuild.get("audio_weights"))
        return EncoderSet(
            text,
            image,
            image,
            audio,
            {
                "set": "default (embedded learned encoders)",
                "text": "minilm-l6-v2",
                "dense": f"lseg-style {image.arch} ({_short(vision_w)})"
                + (", int8" if backend == "int8" else "")
                + (f", images x{upscale}" if upscale != 1 else ""),
                "global_image": f"lseg-style {image.arch}, mean of cell embeddings",
                "audio": f"{audio_name} ({_short(audio_w)})",
            },
            # None = the committed weights, wherever the package lives when the map is loaded
            {
                "vision_weights": rebuild.get("vision_weights"),
                "audio_weights": rebuild.get("audio_weights"),
                "audio_encoder": kind,
                **({"vision_backend": backend} if backend != "auto" else {}),
                **({"vision_upscale": upscale} if upscale != 1 else {}),
                **({"vision_network": network} if network != "table" else {}),
            },
        )
    if name == "openclip":
        return _openclip_set(rebuild)
    raise AssertionError(name)  # _check_name guards


def vision_network_path(name: str):
    """The committed weights of the default set's image network ``name`` (one of
    :data:`~tabletop.mapping.encoders.lseg.VISION_NETWORKS`)."""
    from tabletop.mapping.encoders.lseg import VISION_NETWORKS

    if name not in VISION_NETWORKS:
        raise ConfigError(f"unknown image network {name!r}; valid: {list(VISION_NETWORKS)}")
    return VISION_NETWORKS[name]


def _default_audio(kind: str, weights: str | None) -> tuple[object, str, str]:
    """The default set's audio encoder of ``kind`` (one of :data:`AUDIO_ENCODERS`) from
    ``weights`` (None: the committed ones): (encoder, weights path, name for reports)."""
    if kind == "yamnet":
        from tabletop.mapping.encoders.yamnet_audio import DEFAULT_HEAD_WEIGHTS, YamnetAudioEncoder

        path = weights or str(DEFAULT_HEAD_WEIGHTS)
        return YamnetAudioEncoder(path), path, "YAMNet (AudioSet) + trained head"
    if kind == "melcnn":
        from tabletop.mapping.encoders.audio import DEFAULT_AUDIO_WEIGHTS, MelCNNAudioEncoder

        path = weights or str(DEFAULT_AUDIO_WEIGHTS)
        audio = MelCNNAudioEncoder(path)
        return audio, path, f"log-mel {audio.backbone}"
    raise ConfigError(f"unknown audio_encoder {kind!r}; valid: {list(AUDIO_ENCODERS)}")


_OPENCLIP_KEYS = ("checkpoint", "model_name", "model_cfg", "space")
_CLAP_KEYS = ("clap_checkpoint", "clap_text_model", "clap_version")


def _openclip_set(options: dict) -> EncoderSet:
    """open_clip for text, dense and global image embeddings; CLAP for audio when given.

    ``options``: ``checkpoint`` (a local open_clip weights file) and ``model_name`` (or
    ``model_cfg``); optional ``space``; optional ``clap_checkpoint`` + ``clap_text_model``
    (+ ``clap_version``) for the audio module. Without CLAP the map has no audio module.
    """
    from tabletop.mapping.encoders.openclip import OpenClipEncoder

    unknown = sorted(set(options) - set(_OPENCLIP_KEYS) - set(_CLAP_KEYS))
    if unknown:
        raise ConfigError(
            f"openclip encoders: unknown options {unknown}; valid: "
            f"{list(_OPENCLIP_KEYS + _CLAP_KEYS)}"
        )
    if not options.get("checkpoint"):
        raise ConfigError(
            "the 'openclip' encoder set needs options={'checkpoint': <local weights file>, "
            "'model_name': <open_clip architecture>} (nothing is downloaded)"
        )
    clip = OpenClipEncoder(
        options["checkpoint"],
        model_name=options.get("model_name"),
        model_cfg=options.get("model_cfg"),
        space=options.get("space"),
    )
    audio = audio_text = None
    if options.get("clap_checkpoint"):
        from tabletop.mapping.encoders.clap import MSClapEncoder

        if not options.get("clap_text_model"):
            raise ConfigError("clap_checkpoint needs clap_text_model (a local text model dir)")
        audio = audio_text = MSClapEncoder(
            options["clap_checkpoint"],
            options["clap_text_model"],
            version=str(options.get("clap_version", "2023")),
        )
    arch = options.get("model_name") or "custom architecture"
    return EncoderSet(
        clip,
        clip,
        clip,
        audio,
        {
            "set": "openclip (foundation-model backends from local weights)",
            "text": f"open_clip {arch} ({_short(options['checkpoint'])})",
            "dense": f"open_clip {arch}, MaskCLIP dense head",
            "global_image": f"open_clip {arch}",
            "audio": "msclap" if audio is not None else "none (no CLAP checkpoint given)",
        },
        {k: options[k] for k in _OPENCLIP_KEYS + _CLAP_KEYS if k in options},
        audio_text,
    )


def _short(path: str) -> str:
    """A weights path as shown in reports: relative to the package data when it is there."""
    from pathlib import Path

    from tabletop.paths import DATA_DIR

    p = Path(path)
    try:
        return str(p.resolve().relative_to(DATA_DIR.resolve().parent))
    except ValueError:
        return str(p)

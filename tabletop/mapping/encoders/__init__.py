"""Encoders behind small protocols: text, dense image, global image, audio.

Backends with heavy imports are not imported here: ``tabletop.mapping.encoders.audio``
(``MelCNNAudioEncoder``, the embedded default audio encoder; torch),
``tabletop.mapping.encoders.clap`` (``MSClapEncoder``; the ``clap`` extra),
``tabletop.mapping.encoders.oracle`` (the simulator oracle).
"""

from tabletop.mapping.encoders.base import (
    AudioEncoder,
    DenseImageEncoder,
    EncoderMismatchError,
    GlobalImageEncoder,
    TextEncoder,
    check_same_space,
    l2_normalize,
)
from tabletop.mapping.encoders.minilm import MINILM_SPACE, MiniLMTextEncoder

__all__ = [
    "MINILM_SPACE",
    "AudioEncoder",
    "DenseImageEncoder",
    "EncoderMismatchError",
    "GlobalImageEncoder",
    "MiniLMTextEncoder",
    "TextEncoder",
    "check_same_space",
    "l2_normalize",
]

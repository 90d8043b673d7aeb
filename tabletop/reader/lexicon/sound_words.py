"""The words of a sound query that name what made the sound: the source after "of" ("the
pitter-patter of feet"), and the words after "of" that name none ("the sound of it").

Read by the sound matcher (:class:`~tabletop.mapping.sound_vocabulary.SoundMatcher`) at query
time.
"""

from __future__ import annotations

__all__ = ["source_after_of"]

#: Words after "of" that name no source ("the sound of it", "a bit of").
_NO_SOURCE = frozenset("it that this them something anything some sort kind bit".split())


def source_after_of(query: str) -> str:
    """What a sound query names after its last "of" ("the pitter-patter of feet" -> "feet",
    "the sound of a flock of geese" -> "geese"); "" where it has no "of" or nothing but
    articles and :data:`_NO_SOURCE` words follow it."""
    words = str(query).lower().split()
    if "of" not in words:
        return ""
    k = len(words) - 1 - words[::-1].index("of")
    tail = words[k + 1 :]
    content = [w for w in tail if w not in ("a", "an", "the", "some") and w not in _NO_SOURCE]
    return " ".join(tail) if content else ""

"""Errors of reading: one base class shared with the language stage, and the reader's refusal."""

from __future__ import annotations

from tabletop.errors import TabletopError

__all__ = ["LLMError", "LanguageError", "ParseError"]


class LanguageError(TabletopError):
    """Base class of the language stage's errors."""


class ParseError(LanguageError, ValueError):
    """The offline parser did not understand (part of) an instruction; nothing was generated.

    ``fragment`` is the part it did not understand, ``instruction`` the whole sentence.
    ``out_of_range``: the words were read, but a number in them is beyond what the robot does
    ("21 times", "-5 cm"); no other reading is tried, and the message names the valid range.
    ``final``: the words were read, and what they ask is not a place to go ("take the mug");
    no other reading is tried either.
    """

    def __init__(
        self,
        instruction: str,
        fragment: str,
        why: str,
        out_of_range: bool = False,
        final: bool = False,
    ) -> None:
        head = "out of range:" if out_of_range else "did not understand"
        super().__init__(f"{head} {fragment!r} in {instruction!r}: {why}")
        self.instruction = instruction
        self.fragment = fragment
        self.why = why
        self.out_of_range = bool(out_of_range)
        self.final = bool(out_of_range or final)


class LLMError(LanguageError, RuntimeError):
    """The chat endpoint could not be reached or gave no usable code."""

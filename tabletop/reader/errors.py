"""Errors of reading: one base class shared with the language stage, and the reader's refusal."""

from __future__ import annotations

from tabletop.errors import TabletopError

__all__ = ["LLMError", "LanguageError", "ParseError"]


class LanguageError(TabletopError):
    """Base class of the language stage's errors."""


class ParseError(LanguageError, ValueError):
    """The offline parser did not understand (part of) an instruction; nothing was generated.

    ``fragment`` is the part it did not understand, ``instruction`` the whole sentence.
    """

    def __init__(self, instruction: str, fragment: str, why: str) -> None:
        super().__init__(f"did not understand {fragment!r} in {instruction!r}: {why}")
        self.instruction = instruction
        self.fragment = fragment
        self.why = why


class LLMError(LanguageError, RuntimeError):
    """The chat endpoint could not be reached or gave no usable code."""

"""Errors of the language-to-code stage: one base class, one subclass per failure."""

from __future__ import annotations

from tabletop.reader.errors import LanguageError, LLMError, ParseError

__all__ = [
    "CodeRejected",
    "LLMError",
    "LanguageError",
    "ParseError",
    "SandboxError",
    "SandboxLimit",
]


class SandboxError(LanguageError):
    """Generated code was refused or stopped by the sandbox."""


class CodeRejected(SandboxError, ValueError):
    """The code failed the static check; none of it ran, so the robot did not move.

    ``problems`` holds one ``"line N: ..."`` message per refused construct.
    """

    def __init__(self, problems: list[str]) -> None:
        shown = "; ".join(problems[:5]) + (
            f"; ... ({len(problems)} in all)" if len(problems) > 5 else ""
        )
        super().__init__(f"code rejected, nothing ran: {shown}")
        self.problems = list(problems)


class SandboxLimit(SandboxError, RuntimeError):
    """Running code hit a limit (steps, robot calls, moves or time) and was stopped."""

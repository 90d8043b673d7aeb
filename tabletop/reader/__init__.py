"""Reading: one place where the words of a request get their meaning.

A request becomes a plan (:mod:`tabletop.reader.plan`): steps over typed references (an object,
a sound, an image, a place on the table) and relations between them. Readers sit behind one
protocol and are chosen by name, the way encoder sets are; the robot API, the instruction path,
the CLI and the evaluation all ask the same one.
"""

from tabletop.reader.errors import LanguageError, ParseError
from tabletop.reader.rules import parse_instruction

__all__ = ["LanguageError", "ParseError", "parse_instruction"]

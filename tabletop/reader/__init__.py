"""Reading: one place where the words of a request get their meaning.

A request becomes a plan (:mod:`tabletop.reader.plan`): steps over typed references (an object,
a sound, an image, a place on the table) and relations between them. Readers sit behind one
protocol and are chosen by name, the way encoder sets are; the robot API, the instruction path,
the CLI and the evaluation all ask the same one.
"""

from tabletop.reader.errors import LanguageError, ParseError

__all__ = [
    "READERS",
    "LanguageError",
    "ParseError",
    "get_reader",
    "parse_instruction",
    "understand",
]

#: Names read from :mod:`tabletop.reader.reading` when first asked for (the readers load their
#: models only then): ``tabletop.reader.get_reader()``, ``tabletop.reader.understand(text)``.
_FROM_READING = ("READERS", "get_reader", "understand")


def __getattr__(name: str):
    # The grammar (tabletop.reader.rules) too is loaded when first asked for: the map imports
    # the lexicon (tabletop.reader.lexicon), and with it this package, but never the grammar.
    if name in _FROM_READING:
        from tabletop.reader import reading

        return getattr(reading, name)
    if name == "parse_instruction":
        from tabletop.reader.rules import parse_instruction

        return parse_instruction
    raise AttributeError(f"module 'tabletop.reader' has no attribute {name!r}")

"""The lexicon: the one place the package's English word lists live, with the small pure
functions that read text with them.

- :mod:`~tabletop.reader.lexicon.words`: closed word classes that carry structure
  (negations, ordinals, superlatives, the words that relate one thing to another);
- :mod:`~tabletop.reader.lexicon.colour_names`: the colour lexicon (everyday colour names
  with a typical sRGB value each, the basic colour terms, the colour modifiers);
- :mod:`~tabletop.reader.lexicon.colour_words`: which words of a query are colour words,
  and the readings a noun phrase allows;
- :mod:`~tabletop.reader.lexicon.object_words`: likenesses, pointing and the plain forms of
  a thing's description;
- :mod:`~tabletop.reader.lexicon.sound_words`: the source a sound query names after "of".

Its own layer (tests/test_layers.py): it imports only the core (``tabletop.errors``,
``tabletop.paths``, ...), never the map nor the rest of the reader, so that the map and every
layer above it may ask it. A test (tests/test_word_lists.py) keeps word lists out of the
modules that read words anywhere else.
"""

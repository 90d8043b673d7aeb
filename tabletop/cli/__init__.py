"""The ``tabletop`` command line: the top layer, which may import every other package (nothing
in the library imports it). One module per command group:

- :mod:`~tabletop.cli.scan`: ``scan``, ``scenes``, ``sounds``
- :mod:`~tabletop.cli.maps`: ``build-map``, ``query``
- :mod:`~tabletop.cli.evaluate`: ``eval``, ``eval-map``, ``demo``, ``calibrate``
- :mod:`~tabletop.cli.language`: ``parse``, ``run``
- :mod:`~tabletop.cli.encoders`: ``train``, ``check-encoders``
- :mod:`~tabletop.cli.bench`: ``bench``

:mod:`~tabletop.cli.progress` draws the progress bars (on a terminal only).
"""

from tabletop.cli.app import build_parser, main

__all__ = ["build_parser", "main"]

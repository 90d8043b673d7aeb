"""The ``tabletop`` command line: the top layer, which may import every other package (nothing
in the library imports it). One module per command group:

- :mod:`~tabletop.cli.scan`: ``scan``, ``scenes``, ``sounds``
- :mod:`~tabletop.cli.maps`: ``build-map``, ``query``
- :mod:`~tabletop.cli.evaluate`: ``eval``, ``eval-map``, ``demo``, ``calibrate``
- :mod:`~tabletop.cli.language`: ``parse``, ``run``
- :mod:`~tabletop.cli.encoders`: ``train``, ``check-encoders``
- :mod:`~tabletop.cli.bench`: ``bench``
- :mod:`~tabletop.cli.view`: ``view`` (the optional viewer extra)

:mod:`~tabletop.cli.progress` draws the progress bars (on a terminal only).
"""

import sys

__all__ = ["build_parser", "main"]


def main(argv: list[str] | None = None) -> int:
    """Run one ``tabletop`` command (:func:`tabletop.cli.app.main`); returns its exit status.

    ``tabletop view`` starts without the other commands' imports (the viewer draws the map's
    first picture from its file while the rest loads: :mod:`tabletop.cli.view`)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["view"]:
        from tabletop.cli.view import main_view

        return main_view(args[1:])
    from tabletop.cli.app import main as app_main

    return app_main(argv)


def __getattr__(name: str):
    if name == "build_parser":
        from tabletop.cli.app import build_parser

        return build_parser
    raise AttributeError(f"module 'tabletop.cli' has no attribute {name!r}")

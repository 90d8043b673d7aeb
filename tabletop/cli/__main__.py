"""``python -m tabletop.cli``: the same as the ``tabletop`` command."""

import sys

from tabletop.cli.app import main

sys.exit(main())

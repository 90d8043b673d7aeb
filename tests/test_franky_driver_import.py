"""FrankyDriver without franky installed: the error names the extra to install."""

import sys

import pytest

from tabletop.arm.errors import DriverError
from tabletop.arm.franky_driver import FrankyDriver


def test_a_missing_franky_names_the_real_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "franky", None)  # what Python does for a missing module
    with pytest.raises(DriverError, match=r"pip install 'tabletop\[real\]' \(the franky-control"):
        FrankyDriver("127.0.0.1", realtime=False)

"""The workspace box."""

import numpy as np
import pytest

from tabletop.arm.workspace import Workspace
from tabletop.errors import ConfigError


def test_default_covers_the_table_up_to_80cm():
    ws = Workspace()
    assert ws.contains([0.75, 0.45, 0.0]) and ws.contains([-0.2, -0.6, 0.8])
    assert not ws.contains([0.81, 0.0, 0.1]) and not ws.contains([0.5, 0.0, -0.01])
    assert ws.contains([0.81, 0.0, 0.1], tol=0.02)
    np.testing.assert_allclose(ws.clip([2.0, 0.0, -1.0]), [0.8, 0.0, 0.0])


def test_inverted_box_is_refused():
    with pytest.raises(ConfigError, match="lower < upper"):
        Workspace(lower=(0, 0, 0), upper=(1, -1, 1))

"""The values of visual localization (tabletop/mapping/visual/localization.py): the config's
checks name the problem; a result freezes its pose."""

import numpy as np
import pytest

from tabletop.errors import ConfigError
from tabletop.mapping.visual import VisualLocalization, VisualLocalizationConfig, look_at_point


def test_check_settings_are_validated():
    with pytest.raises(ConfigError, match=r"verify_min_inliers must be in \[4, min_inliers=15\]"):
        VisualLocalizationConfig(verify_min_inliers=20)
    with pytest.raises(ConfigError, match="min_kappa must be in"):
        VisualLocalizationConfig(min_kappa=1.5)
    with pytest.raises(ConfigError, match="colour_tolerance"):
        VisualLocalizationConfig(colour_tolerance=0)


def test_a_result_freezes_its_pose_and_looks_down_at_the_table():
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # optical axis (+z) pointing straight down
    T[:3, 3] = (0.4, 0.1, 0.5)
    p = look_at_point(T)
    np.testing.assert_allclose(p, [0.4, 0.1, 0.0])
    loc = VisualLocalization(True, "", T, p, inliers=30, matches=40)
    assert not loc.T_world_cam.flags.writeable and not loc.look_at_point.flags.writeable
    T[0, 3] = 9.0  # the result holds a copy
    np.testing.assert_array_equal(loc.position, [0.4, 0.1, 0.5])
    assert loc.inlier_ratio == 0.75
    assert VisualLocalization(False, "blank image", None, None).inlier_ratio == 0.0
    assert look_at_point(np.eye(4)) is None  # at table height, looking level

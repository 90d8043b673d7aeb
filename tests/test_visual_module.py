"""The visual localization module's map side: the image target and its refusals."""

import numpy as np
import pytest
from module_helpers import GRID, labelled_voxels

from tabletop.errors import ConfigError
from tabletop.mapping.visual import VisualLocalizationConfig
from tabletop.mapping.visual.module import VisualModule, VisualModuleConfig

K = np.array([[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
DOWN = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _pose(x, y, z=0.4):
    T = np.eye(4)
    T[:3, :3] = DOWN
    T[:3, 3] = [x, y, z]
    return T


def test_the_image_target_is_the_surface_at_the_image_centre():
    vm = labelled_voxels({"tray": ((0.2, -0.1, 0.01), (0.4, 0.1, 0.05))})
    m = VisualModule(vm, None)
    p = m.image_target(_pose(0.3, 0.0), K, (320, 240))
    np.testing.assert_allclose(p, [0.3, 0.0, 0.05], atol=0.011)  # the tray's top
    q = m.image_target(_pose(0.1, -0.2), K, (320, 240))
    np.testing.assert_allclose(q, [0.1, -0.2, 0.01], atol=0.011)  # the table beside it


def test_without_reference_frames_an_image_is_not_found():
    m = VisualModule(labelled_voxels({}), None)
    h = m.heatmap(np.zeros((240, 320, 3), np.uint8), 10.0, lambda mod, x: (1.0, True))
    assert not h.found and "no visual localization module" in h.reason
    assert h.grid == GRID
    with pytest.raises(ConfigError):
        m.heatmap(np.zeros((240, 320), np.uint8), 10.0, lambda mod, x: (1.0, True))


def test_config_is_checked():
    with pytest.raises(ConfigError, match="target_px"):
        VisualModuleConfig(target_px=0.0)
    with pytest.raises(ConfigError, match="VisualLocalizationConfig"):
        VisualModuleConfig(localization={"matcher": "sift"})
    assert (
        VisualModuleConfig(VisualLocalizationConfig(matcher="sift")).localization.matcher == "sift"
    )

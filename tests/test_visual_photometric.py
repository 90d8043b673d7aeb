"""The photometric check (tabletop/mapping/visual/photometric.py): the map seen from the true
camera pose of a query image reproduces it; seen from a pose 8 cm off, it does not."""

import numpy as np
import pytest
from helpers import visual_scene

from tabletop.errors import ConfigError
from tabletop.mapping.visual import PhotometricCheck


@pytest.fixture(scope="module")
def queries():
    """Image goals of a short scan's objects: (goal, object label)."""
    return visual_scene()[1]


@pytest.fixture(scope="module")
def avlmap():
    return visual_scene()[2]


def shifted(T: np.ndarray, dx: float, dy: float) -> np.ndarray:
    out = T.copy()
    out[:2, 3] += (dx, dy)
    return out


def test_the_map_seen_from_the_true_pose_reproduces_the_image(avlmap, queries):
    check, K = avlmap.photometric_check(), avlmap.visual.K
    assert len(check) == len(avlmap.voxels.indices)
    cfg = avlmap.config.visual.localization
    for g, label in queries:
        cov, agree, kappa = check.score(g.T_world_cam, K, g.image, cfg)
        assert cov > 0.5 and agree >= cfg.min_agreement and kappa >= cfg.min_kappa, label
        # 8 cm to the side, the same picture no longer agrees with the map beyond chance
        _, agree_off, kappa_off = check.score(shifted(g.T_world_cam, 0.08, 0.0), K, g.image, cfg)
        assert kappa_off < cfg.min_kappa < kappa and agree_off < agree, label
    # a camera looking away from the map sees none of it
    up = np.eye(4)
    up[2, 3] = 1.0  # 1 m above the table, optical axis (+z) pointing up
    assert check.score(up, K, queries[0][0].image, cfg) == (0.0, 0.0, 0.0)
    with pytest.raises(ConfigError, match=r"\(n, 3\) indices"):
        PhotometricCheck(avlmap.grid, np.zeros((4, 2), int), np.zeros((4, 3), np.uint8))

"""The area module: frames' embeddings tied to where the camera looked."""

import numpy as np
import pytest
from module_helpers import GRID, judge_at, text_encoder

from tabletop.errors import ConfigError
from tabletop.mapping.area_module import AreaConfig, AreaModule, look_at_table, normalize_scores
from tabletop.mapping.targets import max_position

DOWN = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # optical axis -z


def _pose(x, y, z=0.4):
    T = np.eye(4)
    T[:3, :3] = DOWN
    T[:3, 3] = [x, y, z]
    return T


def test_look_at_table_meets_the_plane():
    T = _pose(0.3, 0.1)
    np.testing.assert_allclose(look_at_table(T[None]), [[0.3, 0.1]])
    up = np.eye(4)  # optical axis +z: never meets the table
    assert np.all(np.isfinite(look_at_table(up[None])))


def test_an_area_query_heats_where_its_views_looked():
    text = text_encoder()
    m = AreaModule(GRID)
    for name, (x, y) in {"the fruit bowl area": (0.1, 0.2), "the tray area": (0.5, -0.2)}.items():
        m.add(text.encode_text([name])[0], _pose(x, y))
    for i in range(4):  # views of plain table
        m.add(text.encode_text(["an empty wooden table"])[0], _pose(0.3, -0.1 + 0.05 * i))
    h = m.heatmap("the tray area", 10.0, text, judge_at(0.1))
    assert h.found and h.modality == "area"
    p = max_position(h, np.zeros(GRID.shape, bool))
    np.testing.assert_allclose(p[:2], [0.5, -0.2], atol=0.011)
    refused = m.heatmap("the tray area", 10.0, text, judge_at(5.0))
    assert not refused.found and refused.reason


def test_no_frames_is_not_found_and_config_is_checked():
    h = AreaModule(GRID).heatmap("anything", 10.0, text_encoder(), judge_at(0.0))
    assert not h.found and "no frame embeddings" in h.reason
    with pytest.raises(ConfigError, match="top_score"):
        AreaConfig(top_score=0.0)
    np.testing.assert_array_equal(normalize_scores(np.array([2.0, 2.0])), [1.0, 1.0])

"""The local feature backends (tabletop/mapping/visual/features.py), on a seeded picture."""

import numpy as np

from tabletop.mapping.visual import DESCRIPTOR_DIMS, VisualLocalizationConfig
from tabletop.mapping.visual.features import _backend, _Features


def test_sift_gives_unit_rootsift_descriptors_and_matches_an_image_with_itself():
    rng = np.random.default_rng(0)  # seeded random rectangles, rich in corners
    img = np.zeros((240, 320, 3), np.uint8)
    for _ in range(60):
        x, y = rng.integers(0, 300), rng.integers(0, 220)
        img[y : y + rng.integers(5, 40), x : x + rng.integers(5, 40)] = rng.integers(0, 255, 3)
    backend = _backend("sift")
    assert _backend("sift") is backend  # loaded once per process
    xy, desc = backend.extract(img, 200)
    assert xy.dtype == desc.dtype == np.float32 and 50 <= len(xy) <= 200
    assert xy.shape == (len(xy), 2) and desc.shape == (len(xy), DESCRIPTOR_DIMS["sift"])
    np.testing.assert_allclose(np.linalg.norm(desc, axis=1), 1.0, atol=1e-5)
    f = _Features(xy, desc, (320, 240))
    m = backend.match(f, f, VisualLocalizationConfig(matcher="sift"))
    assert m.dtype == np.int64 and m.shape[1] == 2 and len(m) >= 0.9 * len(xy)
    assert np.mean(m[:, 0] == m[:, 1]) >= 0.95

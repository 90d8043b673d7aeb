"""Geometry helpers shared by the packages."""

import numpy as np
import pytest

from tabletop.transforms import aabb_distance


def test_aabb_distance_is_zero_inside_and_euclidean_outside():
    lo, hi = [0.0, 0.0, 0.0], [1.0, 2.0, 1.0]
    assert aabb_distance([0.5, 1.0, 0.5], lo, hi) == 0.0
    assert aabb_distance([1.0, 2.0, 1.0], lo, hi) == 0.0  # on a corner
    assert aabb_distance([2.0, 1.0, 0.5], lo, hi) == pytest.approx(1.0)
    assert aabb_distance(np.array([-3.0, 6.0, 0.5]), lo, hi) == pytest.approx(5.0)
    assert aabb_distance((4.0, 6.0, 1.0), lo, hi) == pytest.approx(5.0)

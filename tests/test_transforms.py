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


def test_pixel_rays_go_through_their_pixels():
    from tabletop.transforms import make_transform, pixel_rays, rotation_about

    K = np.array([[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    T = make_transform(rotation_about("x", np.pi), [0.1, 0.2, 0.5])  # looking straight down
    rays = pixel_rays(K, T, [160, 460], [120, 120])
    np.testing.assert_allclose(rays[0], [0, 0, -1], atol=1e-12)  # the principal point: +z_cam
    np.testing.assert_allclose(rays[1], np.array([1, 0, -1]) / np.sqrt(2), atol=1e-12)

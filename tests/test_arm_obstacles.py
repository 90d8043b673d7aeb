"""Obstacle values: validation, containment, the table slab, voxel boxes."""

import numpy as np
import pytest

from tabletop.arm.obstacles import (
    Box,
    ConvexObstacle,
    Cylinder,
    boxes_from_voxels,
    obstacle_aabb,
    table_box,
)
from tabletop.errors import ConfigError
from tabletop.transforms import rotation_about


def test_table_top_is_the_plane_z0_and_spans_the_table():
    lo, hi = obstacle_aabb(table_box())
    np.testing.assert_allclose(lo, [-0.2, -0.6, -0.05])
    np.testing.assert_allclose(hi, [0.8, 0.6, 0.0])


def test_rotated_box_aabb_and_containment():
    b = Box([0.5, 0.0, 0.1], [0.1, 0.02, 0.1], rotation_about("z", np.pi / 2))
    lo, hi = obstacle_aabb(b)
    np.testing.assert_allclose(hi - lo, [0.04, 0.2, 0.2], atol=1e-12)
    assert b.contains([0.5, 0.09, 0.1]) and not b.contains([0.59, 0.0, 0.1])
    assert b.vertices().shape == (8, 3)


def test_cylinder_and_convex_containment():
    c = Cylinder([0.4, 0.1, 0.05], 0.03, 0.1)
    assert c.contains([0.42, 0.1, 0.0]) and not c.contains([0.44, 0.1, 0.05])
    cv = ConvexObstacle(c.vertices())
    assert cv.contains([0.4, 0.1, 0.05]) and not cv.contains([0.4, 0.1, 0.2])


def test_invalid_obstacles_are_refused_with_the_reason():
    with pytest.raises(ConfigError, match="half_extents must be positive"):
        Box([0, 0, 0], [0.1, 0.0, 0.1])
    with pytest.raises(ConfigError, match="finite 3-vector"):
        Box([0, 0], [0.1, 0.1, 0.1])
    with pytest.raises(ConfigError, match=r"\(3, 3\) rotation"):
        Box([0, 0, 0], [0.1, 0.1, 0.1], np.ones((3, 3)))
    with pytest.raises(ConfigError, match="coplanar"):
        ConvexObstacle([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    with pytest.raises(ConfigError, match="radius and height must be positive"):
        Cylinder([0, 0, 0], -1.0, 0.1)


def test_boxes_from_voxels():
    boxes = boxes_from_voxels([[0.5, 0.0, 0.005], [0.51, 0.0, 0.005]], 0.01)
    assert len(boxes) == 2
    np.testing.assert_allclose(boxes[1].half_extents, [0.005] * 3)
    with pytest.raises(ConfigError, match=r"shape \(N, 3\)"):
        boxes_from_voxels(np.zeros((2, 2)), 0.01)
